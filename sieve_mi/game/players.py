"""The two players of the sieve game (paper Secs. 5 and 6).

Player B (:class:`PlayerB`) minimises how much of each blocked shape sticks out of a hole, over
rotations and translations, with Adam from many random starts; every start of every shape against
every candidate hole runs in one batched Dr.Jit kernel per step. Player A (:class:`PlayerA`)
chooses the rotation of its shape so that B's best attempt is as bad as possible (eq. 7), with a
particle swarm whose particles are evaluated together, or with an nlopt global method.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from sieve_mi.backend import release_cached_memory
from sieve_mi.errors import SieveError, signals_received
from sieve_mi.game.attack import Attack, AttackMemory
from sieve_mi.game.scoring import score_poses, with_core
from sieve_mi.geometry.hole import Hole, build_hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import (
    angle_between,
    from_rotvec,
    normalize,
    quat_multiply,
    random_uniform,
    to_rotvec,
)
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.objectives import OBJECTIVES, Objective, make_objective
from sieve_mi.optim import (
    POSE_KEYS,
    QUAT_KEYS,
    live_poses,
    nlopt_maximise,
    particle_swarm,
    pose_adam,
    renormalise_quaternions,
)
from sieve_mi.scene import Fabrication, Solver

__all__ = [
    "BYTES_PER_PAIR",
    "MEMORY_SHARE",
    "available_memory",
    "pair_budget",
    "CPU_FREEZE_PAIRS",
    "PlayerA",
    "PlayerB",
]

#: On the CPU (LLVM variants) descents with more (pose, segment) pairs than this trace their steps
#: even with ``freeze``: there a big step is bound by arithmetic and the frozen step's fixed-size
#: buffer passes cost more than tracing saves (docs/performance.md: a 70k-face bunny at 100 poses,
#: 15M pairs, steps 15 % slower frozen; spot/cow's verdict, 2.7M pairs, is 1.1x faster frozen).
CPU_FREEZE_PAIRS = 5_000_000


class _BufferOverflow(Exception):
    """A frozen descent's active-pair buffer overflowed: its results are wrong."""


#: Memory one (pose, segment) pair of a descent holds, bytes: 32 measured on the CPU at 5M pairs
#: (traced or frozen, docs/performance.md), doubled for the AD graph, buffers and allocator slack.
BYTES_PER_PAIR = 64
#: Share of the machine's available memory player B's descents use by default (``[solver] memory
#: = 0``) ...
MEMORY_SHARE = 0.25
#: ... at most this many GB on the CPU: chunks of 4M pairs keep both cores busy, and a larger
#: budget only raises the peak (cow-bunny's verdict, one run: 0.125 / 0.25 / 0.5 GB / a quarter
#: of 23 GB gave peaks of 0.94 / 1.05 / 1.15 / 1.73 GB in the same time, docs/performance.md).
#: Not on a GPU, where fewer, larger launches pay.
CPU_MEMORY_CAP_GB = 0.25


def available_memory() -> int:
    """Bytes of memory available to new allocations (Linux's MemAvailable; else physical memory)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def _on_gpu() -> bool:
    """Whether the active Mitsuba variant runs on CUDA."""
    import mitsuba as mi

    return bool((mi.variant() or "").startswith("cuda"))


def pair_budget(memory_gb: float = 0.0, *, cap: bool = True) -> int:
    """(pose, segment) pairs one descent may bind at once, for a memory budget in GB.

    ``0`` means :data:`MEMORY_SHARE` of :func:`available_memory`, as measured now, and with
    ``cap`` at most :data:`CPU_MEMORY_CAP_GB` unless a CUDA variant is active (the cap sizes
    chunks; the uncapped share decides whether a scene fits at all).
    """
    budget = memory_gb * 2**30 if memory_gb > 0 else MEMORY_SHARE * available_memory()
    if cap and memory_gb <= 0 and not _on_gpu():
        budget = min(budget, CPU_MEMORY_CAP_GB * 2**30)
    return max(1, int(budget // BYTES_PER_PAIR))


def _interruption(exc: BaseException) -> BaseException | None:
    """The interrupt (KeyboardInterrupt, SystemExit, a termination signal) behind ``exc``, if any.

    Dr.Jit re-raises whatever a frozen function raised while recording as a RuntimeError whose
    cause is the original exception, or with the original only as text; a signal that arrived
    then must still stop the run. Where the chain holds no interrupt but the command line's
    handler ran (:func:`sieve_mi.errors.signals_received`), a KeyboardInterrupt stands for it.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if not isinstance(exc, Exception):
            return exc
        exc = exc.__cause__ or exc.__context__
    return KeyboardInterrupt() if signals_received() else None


class _FrozenStepFailed(Exception):
    """Dr.Jit failed to record or replay a frozen step (the cause is chained)."""


#: A descent whose poses settle (:meth:`PlayerB.attack`'s ``settle``) checks every this many
#: steps whether all of its groups have: one read-back of a flag.
SETTLE_CHECK = 5


class _Settle:
    """The groups of one descent that stop when one of their poses fits.

    Parameters
    ----------
    group : mi.UInt32
        Each pose's group (K,), numbered from 0.
    groups : int
    fit_loss : float
        The objective's loss of a fitting pose.
    """

    def __init__(self, group, groups: int, fit_loss: float):
        self.group, self.groups, self.fit_loss = group, int(groups), float(fit_loss)

    @classmethod
    def make(cls, group, loss) -> _Settle | None:
        """Settling for poses in groups ``group`` ((K,) ints, or None: no settling) under the
        objective ``loss`` (None where it has no ``fit_loss``)."""
        import mitsuba as mi

        fit_loss = getattr(loss, "fit_loss", None)
        if group is None or fit_loss is None or len(group) == 0:
            return None
        _, dense = np.unique(np.asarray(group), return_inverse=True)
        return cls(mi.UInt32(dense.astype(np.uint32)), int(dense.max()) + 1, fit_loss)

    def live(self, best_loss):
        """(K,) mi.Bool: the poses whose group has not settled."""
        return live_poses(best_loss, self.group, self.groups, self.fit_loss)

    @staticmethod
    def due(step: int) -> bool:
        """Whether to check after step ``step`` (0-based)."""
        return (step + 1) % SETTLE_CHECK == 0

    def subset(self, keep) -> _Settle:
        """The same groups for the poses ``keep`` (mi.UInt32) only."""
        import drjit as dr
        import mitsuba as mi

        return _Settle(dr.gather(mi.UInt32, self.group, keep), self.groups, self.fit_loss)


def _settle_groups(settle, pose_hole, pose_shape, n_b: int):
    """Each pose's settling group for :meth:`PlayerB.attack`'s ``settle`` (None: no settling)."""
    if settle is None:
        return None
    return {
        "start": np.arange(len(pose_hole)),
        "shape": pose_hole * n_b + pose_shape,
        "hole": pose_hole,
    }[settle]


def _rows(best) -> np.ndarray:
    """A descent's best poses (list of 6 mi.Float, :data:`~sieve_mi.optim.POSE_KEYS` order) as
    a (K, 6) float64 array."""
    return np.stack([np.asarray(b, dtype=np.float64) for b in best], axis=1)


def _keep_poses(opt, keep, best, best_loss, settle):
    """Keep only the poses ``keep`` (mi.UInt32) of a descent: of its
    :func:`~sieve_mi.optim.pose_adam` optimiser (with their Adam moments and the shared step
    count, Dr.Jit's ``(t, m, v, v_max)`` state), of ``best``, ``best_loss`` and ``settle``;
    returns the last three."""
    import drjit as dr
    import mitsuba as mi

    for key in POSE_KEYS:
        value, promoted, lr, (t, m, v, v_max) = opt.state[key]
        value = dr.gather(mi.Float, dr.detach(value), keep)
        dr.enable_grad(value)
        moments = (dr.gather(mi.Float, m, keep), dr.gather(mi.Float, v, keep))
        opt.state[key] = (value, promoted, lr, (t, *moments, v_max))
        dr.make_opaque(value, *moments)
    best = [dr.gather(mi.Float, b, keep) for b in best]
    best_loss = dr.gather(mi.Float, best_loss, keep)
    dr.make_opaque(best, best_loss)
    return best, best_loss, settle.subset(keep)


class _Descent:
    """The state of one batched descent of :meth:`PlayerB.descend`: Adam over the poses still
    descending, each start's best pose and loss, and the final poses of those that left."""

    def __init__(self, player, holes, pose_hole, pose_shape, q0, t0, learning_rate, group):
        import drjit as dr
        import mitsuba as mi

        from sieve_mi.geometry.hole import HoleStack

        self.loss = player.objective
        self.stack = HoleStack(holes, corners=getattr(self.loss, "hole_corners", False))
        self.pose_hole, self.pose_shape = np.asarray(pose_hole), np.asarray(pose_shape)
        self.scale = player.frame.half_extent
        self.opt = pose_adam(q0, np.asarray(t0) / self.scale, learning_rate)
        self.best = [dr.detach(self.opt[key]) for key in POSE_KEYS]
        self.best_loss = dr.opaque(mi.Float, np.inf, len(q0))
        self.settle = _Settle.make(group, self.loss)
        self.final = np.empty((len(q0), len(POSE_KEYS)))
        self.where = np.arange(len(q0))  # the original index of each pose still descending
        self._bind()

    def _bind(self) -> None:
        import mitsuba as mi

        self.loss.bind(self.pose_shape[self.where])
        self.hole_idx = mi.UInt32(self.pose_hole[self.where].astype(np.uint32))

    def evaluate(self, live=None):
        """Total and per-pose loss at the optimiser's poses; with ``live`` (mi.Bool), the
        others sum nothing and get an infinite loss (a settled pose keeps its best)."""
        import drjit as dr

        opt, scale = self.opt, self.scale
        q = tuple(opt[key] for key in QUAT_KEYS)
        t = (opt["tx"] * scale, opt["ty"] * scale)
        if live is None:
            return self.loss.loss(q, t, self.stack, self.hole_idx)
        total, per_pose = self.loss.loss(q, t, self.stack, self.hole_idx, live=live)
        return total, dr.select(live, per_pose, np.inf)

    def keep_best(self, per_pose) -> None:
        """Each start keeps the best pose it visited (Adam may step past a fit)."""
        import drjit as dr

        improved = per_pose < self.best_loss
        self.best = [
            dr.select(improved, dr.detach(self.opt[key]), b) for key, b in zip(POSE_KEYS, self.best)
        ]
        self.best_loss = dr.select(improved, per_pose, self.best_loss)

    def traced_step(self) -> None:
        """One Adam step, traced."""
        import drjit as dr

        live = None if self.settle is None else self.settle.live(self.best_loss)
        total, per_pose = self.evaluate(live)
        # every pose settled between two checks: nothing depends on the poses any more
        dr.backward(total, flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
        self.keep_best(per_pose)
        self.opt.step(eval=False)
        renormalise_quaternions(self.opt, self.best, self.best_loss)

    def shrink(self, live: np.ndarray) -> bool:
        """Keep descending only the ``live`` poses ((K,) bool); the others' best poses are
        final. Returns whether any pose is left."""
        import mitsuba as mi

        self.final[self.where[~live]] = _rows(self.best)[~live]
        self.where = self.where[live]
        if not len(self.where):
            return False
        keep = mi.UInt32(np.flatnonzero(live).astype(np.uint32))
        self.best, self.best_loss, self.settle = _keep_poses(
            self.opt, keep, self.best, self.best_loss, self.settle
        )
        self._bind()
        return True

    def result(self, stepped: bool) -> tuple[np.ndarray, np.ndarray]:
        """Every start's best pose: quaternions (K, 4) and translations (K, 2), scene units;
        ``stepped``: the last step's pose is scored too."""
        import drjit as dr

        if len(self.where):
            if stepped:
                with dr.suspend_grad():
                    self.keep_best(self.evaluate()[1])
            self.final[self.where] = _rows(self.best)
        return normalize(self.final[:, :4]), self.final[:, 4:] * self.scale


class PlayerB:
    """Fits B's shapes into holes by batched Adam from random starts.

    Parameters
    ----------
    shapes : list of Shape
        The shapes that must be blocked.
    frame : Frame
        The raster frame of the holes it will be tested against.
    objective : {"clearance", "overlap", "overlap-mitsuba"}
        Differentiable loss used by Adam; scores are always binary beta.
    samples_per_segment : int, optional
        Edge samples per segment for the clearance objective (default: from the edge lengths).
    freeze : bool
        Record the Adam step once and replay it (:mod:`sieve_mi.game.frozen`) where the objective
        allows it (``clearance``) and it pays (on the CPU only up to :data:`CPU_FREEZE_PAIRS`
        (pose, segment) pairs per step); the results are the same either way.
    """

    def __init__(
        self,
        shapes: list[Shape],
        frame: Frame,
        objective: str = "clearance",
        samples_per_segment: int | None = None,
        freeze: bool = True,
        memory: float = 0.0,
    ):
        if objective not in OBJECTIVES:
            raise ValueError(f"unknown objective {objective!r}")
        self.shapes = shapes
        self.frame = frame
        #: The objective's name (a key of :data:`sieve_mi.objectives.OBJECTIVES`).
        self.objective_name = objective
        self.renderers = [with_core(SilhouetteRenderer(s)) for s in shapes]
        self._samples = samples_per_segment
        self._loss = None
        self.freeze = bool(freeze)
        self._frozen = None
        #: Memory budget of one descent, GB (0: a share of the machine's available memory).
        self.memory = float(memory)
        #: (pose, segment) pairs one descent binds at once; more poses run in chunks.
        self.max_pairs = pair_budget(self.memory)

    @classmethod
    def from_settings(
        cls, shapes: list[Shape], frame: Frame, solver: Solver, objective: str | None = None
    ) -> PlayerB:
        """Player B with the ``[solver]`` table's ``objective`` (unless given), ``freeze`` and
        ``memory``."""
        return cls(
            shapes, frame, objective or solver.objective, freeze=solver.freeze, memory=solver.memory
        )

    @property
    def objective(self) -> Objective:
        """The objective bound to this player's shapes and frame, made on first use.

        Its :meth:`~sieve_mi.objectives.Objective.loss` is what Adam minimises (see
        :mod:`sieve_mi.objectives`); each descent binds it to its poses first.
        """
        if self._loss is None:
            self._loss = make_objective(self.objective_name, self.shapes, self.frame, self._samples)
        return self._loss

    def attack(
        self,
        holes: list[Hole],
        starts: int,
        steps: int,
        learning_rate: float,
        rng: np.random.Generator,
        progress: Callable[[int], None] | None = None,
        centres: np.ndarray | None = None,
        memory: AttackMemory | None = None,
        keep: int = 0,
        settle: str | None = None,
    ) -> Attack:
        """Player B's best attempt on each hole, for each shape.

        Starts are uniform random rotations and translations in +-0.1 of the frame's half extent
        (paper Sec. 6.1); translations are optimised in units of the half extent.

        Parameters
        ----------
        holes : list of Hole
            Candidate holes, all on ``self.frame``.
        starts : int
            Random starts per hole and shape.
        steps : int
            Adam steps.
        learning_rate : float
            Adam's learning rate for quaternion components and normalised translations.
        rng : numpy.random.Generator
        progress : callable, optional
            Called with the number of steps done after each step.
        centres : (H, 2) or (H, C, 2) ndarray, optional
            Where each hole's starts are centred (scene units); default the origin. With C
            centres per hole, start ``s`` is centred on centre ``s % C``.
        memory : AttackMemory, optional
            B's remembered best poses replace the first random starts of every hole (at most
            ``starts - 1`` per shape, so at least one start stays random); the memory is then
            updated with this attack's results.
        keep : int
            Keep the ``keep`` best poses per hole and shape in ``Attack.candidates``.
        settle : {None, "start", "shape", "hole"}
            Stop descending the starts of a group as soon as one of its starts fits (its loss is
            at most the objective's ``fit_loss``; objectives without one ignore this):
            ``"start"`` each start alone (a start that fits is done: the verdict, which counts
            the fitting starts); ``"shape"`` the starts of one shape against one hole, whose β
            is 0 either way; ``"hole"`` all starts against one hole, whose value (the min over
            shapes) is 0 either way (the search). The settled starts keep the best pose they had
            reached, and a descent whose groups have all settled ends early. None: every start
            runs every step.
        """
        n_h, n_b = len(holes), len(self.shapes)
        k = n_h * n_b * starts
        pose_hole = np.repeat(np.arange(n_h), n_b * starts)
        pose_shape = np.tile(np.repeat(np.arange(n_b), starts), n_h)
        q0 = random_uniform(k, rng)
        t0 = rng.uniform(-0.1, 0.1, size=(k, 2)) * self.frame.half_extent
        if centres is not None:
            c = np.asarray(centres, dtype=np.float64)
            c = c[:, None, :] if c.ndim == 2 else c
            which = np.tile(np.arange(starts) % c.shape[1], n_h * n_b)
            t0 += c[pose_hole, which]
        if memory is not None:
            q0, t0 = q0.reshape(n_h, n_b, starts, 4), t0.reshape(n_h, n_b, starts, 2)
            for b in range(n_b):
                mq, mt = memory.poses(b)
                w = min(len(mq), starts - 1)
                q0[:, b, :w], t0[:, b, :w] = mq[:w], mt[:w]
            q0, t0 = q0.reshape(k, 4), t0.reshape(k, 2)
        group = _settle_groups(settle, pose_hole, pose_shape, n_b)
        quats, trans = self.descend(
            holes, pose_hole, pose_shape, q0, t0, steps, learning_rate, progress, group=group
        )
        attack = self._score(holes, quats, trans, pose_hole, pose_shape, starts, keep)
        if memory is not None:
            memory.update(attack)
        release_cached_memory()  # else the process holds this attack's peak from now on
        return attack

    def descend(
        self,
        holes: list[Hole],
        pose_hole: np.ndarray,
        pose_shape: np.ndarray,
        q0: np.ndarray,
        t0: np.ndarray,
        steps: int,
        learning_rate: float,
        progress: Callable[[int], None] | None = None,
        group: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Batched Adam from given starting poses; returns each start's best pose.

        Parameters
        ----------
        holes : list of Hole
            On ``self.frame``.
        pose_hole, pose_shape : (K,) ndarrays of int
            Which hole and which shape each pose belongs to.
        q0 : (K, 4) ndarray
            Starting rotations.
        t0 : (K, 2) ndarray
            Starting translations, scene units.
        steps : int
        learning_rate : float
        progress : callable, optional
        group : (K,) ndarray of int, optional
            Groups of poses that settle together (see :meth:`attack`'s ``settle``): once one
            pose of a group fits, the others stop where their best pose is; when every group has
            settled the descent ends.

        Returns
        -------
        quats : (K, 4) ndarray
        trans : (K, 2) ndarray
            Scene units.

        Notes
        -----
        Frozen steps (:mod:`sieve_mi.game.frozen`) whose buffer overflowed make this descent run again
        traced; if Dr.Jit fails to record or replay one, this player warns and traces from then
        on. Either way the result is the traced one.

        Poses whose (pose, segment) pairs exceed :attr:`max_pairs` descend in chunks of
        consecutive poses (:meth:`chunks`), one after another: every pose's descent is its own
        (Adam is per parameter, the loss a sum of per-pose terms), so the poses are the same bit
        for bit, and the memory no longer grows with shapes x starts x holes x segments.
        """
        parts = self.chunks(pose_shape)
        if len(parts) == 1:
            return self._descend_falling_back(
                holes, pose_hole, pose_shape, q0, t0, steps, learning_rate, progress, group
            )
        quats, trans = np.empty((len(q0), 4)), np.empty((len(q0), 2))
        for i, part in enumerate(parts):  # the progress bar follows the last chunk
            quats[part], trans[part] = self._descend_falling_back(
                holes, pose_hole[part], pose_shape[part], np.asarray(q0)[part],
                np.asarray(t0)[part], steps, learning_rate,
                progress if i == len(parts) - 1 else None,
                None if group is None else np.asarray(group)[part],
            )  # fmt: skip
        return quats, trans

    def chunks(self, pose_shape: np.ndarray) -> list[slice]:
        """Consecutive ranges of poses whose (pose, segment) pairs fit :attr:`max_pairs` each.

        Parameters
        ----------
        pose_shape : (K,) ndarray of int

        Returns
        -------
        list of slice
            Covering ``range(K)`` in order; one slice where everything fits (or the objective
            is not edge-sampled).

        Raises
        ------
        SieveError
            When one pose alone needs more than the budget (the scene cannot fit).
        """
        pose_shape = np.asarray(pose_shape, dtype=np.int64)
        counts = getattr(self.objective, "counts", None)
        if counts is None or len(pose_shape) == 0:
            return [slice(0, len(pose_shape))]
        per = np.asarray(counts)[pose_shape]
        # the default's CPU cap only sizes chunks: a pose bigger than the cap gets a chunk of its own
        limit = max(self.max_pairs, int(per.max())) if self.memory <= 0 else self.max_pairs
        if per.max() > min(limit, pair_budget(self.memory, cap=False)):
            worst = self.shapes[int(pose_shape[int(np.argmax(per))])].name
            need = per.max() * BYTES_PER_PAIR / 2**30
            have = pair_budget(self.memory, cap=False) * BYTES_PER_PAIR / 2**30
            raise SieveError(
                f"[solver] memory: one pose of {worst} needs {need:.2f} GB ({int(per.max()):,} "
                f"edge segments), more than the {have:.2f} GB budget; raise [solver] memory or "
                "lower [solver] resolution"
            )
        ends = np.cumsum(per)
        bounds = [0]
        while bounds[-1] < len(per):
            start = bounds[-1]
            base = ends[start - 1] if start else 0
            bounds.append(int(np.searchsorted(ends, base + limit, side="right")))
        return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    def _descend_falling_back(
        self, holes, pose_hole, pose_shape, q0, t0, steps, learning_rate, progress=None, group=None
    ):
        """One descent of all given poses at once, with the frozen steps' fallbacks."""
        args = (holes, pose_hole, pose_shape, q0, t0, steps, learning_rate)
        try:
            return self._descend(*args, progress, group=group)
        except _FrozenStepFailed as failure:
            self._stop_freezing(failure.__cause__)
        except _BufferOverflow:  # more active pairs than the buffer held: this descent traced
            return self._descend(*args, group=group, may_freeze=False)
        return self._descend(*args, group=group)

    def _descend(
        self,
        holes,
        pose_hole,
        pose_shape,
        q0,
        t0,
        steps,
        learning_rate,
        progress=None,
        *,
        group=None,
        may_freeze: bool = True,
    ):
        """:meth:`descend` without its fallbacks; raises :class:`_BufferOverflow` or
        :class:`_FrozenStepFailed` when a frozen descent must run again traced. ``may_freeze=False``
        traces every step.

        With ``group``, every :data:`SETTLE_CHECK` steps the poses of settled groups leave the
        descent (their best poses are final) once they are at least half of it: the rest goes on
        as a smaller batch, with its Adam state, so that settled poses cost nothing.
        """
        run = _Descent(self, holes, pose_hole, pose_shape, q0, t0, learning_rate, group)

        def freeze():
            if not (may_freeze and steps > 0):
                return None
            return self._frozen_steps(
                run.loss, run.opt, run.stack, run.hole_idx, run.scale, run.settle
            )

        frozen, first_frozen = freeze(), 2  # steps 1, 2 differ in layout: traced
        try:
            for step in range(steps):
                if frozen is not None and step >= first_frozen:
                    run.best, run.best_loss = frozen(run.best, run.best_loss)
                else:
                    run.traced_step()
                if progress:
                    progress(step + 1)
                if run.settle is None or not run.settle.due(step):
                    continue
                live = np.asarray(run.settle.live(run.best_loss), dtype=bool)
                if 2 * live.sum() > len(live):  # too few settled to pay for a smaller batch
                    continue
                if frozen is not None and frozen.overflowed():
                    raise _BufferOverflow
                if not run.shrink(live):  # every group settled: the descent is over
                    if progress:
                        progress(steps)
                    break
                frozen, first_frozen = freeze(), step + 1
        except Exception as exc:  # drjit.freeze is experimental: trace instead of failing
            if frozen is None or isinstance(exc, _BufferOverflow):
                raise
            interrupt = _interruption(exc)
            if interrupt is not None:  # Ctrl-C or SIGTERM while Dr.Jit recorded: never eaten
                raise interrupt from None
            raise _FrozenStepFailed from exc
        if frozen is not None and frozen.overflowed():
            raise _BufferOverflow
        return run.result(steps > 0)

    def _stop_freezing(self, exc: Exception) -> None:
        """Trace every later step of this player, after Dr.Jit failed on a frozen one."""
        import warnings

        self.freeze = False
        self._frozen = None
        warnings.warn(
            f"drjit.freeze failed on player B's Adam step ({type(exc).__name__}: {exc}); "
            "tracing every step instead (same results, slower); [solver] freeze = false "
            "skips the attempt",
            RuntimeWarning,
            stacklevel=3,
        )

    def _frozen_steps(self, loss, opt, stack, hole_idx, scale, settle=None):
        """The frozen Adam step of one descent (:mod:`sieve_mi.game.frozen`), or None if not frozen.

        Returns a callable ``step(best, best_loss) -> (best, best_loss)`` that updates ``opt``,
        with ``step.overflowed()`` telling whether any step's buffer overflowed (its results
        are then wrong).
        """
        import drjit as dr
        import mitsuba as mi

        if not (self.freeze and getattr(loss, "freezable", False)):
            return None
        if loss.pair_count > CPU_FREEZE_PAIRS and mi.variant().startswith("llvm"):
            return None
        from sieve_mi.game.frozen import frozen_step

        self._frozen = self._frozen or frozen_step()
        capacity = loss.capacity(tuple(opt[name] for name in QUAT_KEYS))
        record = (scale, capacity, loss.pose_count, loss.pair_count)
        if settle is not None:
            record += (settle.groups, settle.fit_loss)
        state = {"overflow": dr.opaque(mi.Bool, False)}
        group = None if settle is None else settle.group

        def step(best, best_loss):
            # Literals (Adam's step counter after the traced steps) become evaluated arrays, so
            # the first frozen step has the layout of the later ones (else it is recorded twice).
            dr.make_opaque(opt.state, best, best_loss)
            best, best_loss, state["overflow"] = self._frozen(
                opt, best, best_loss, state["overflow"], loss, stack, hole_idx, record, group
            )
            return best, best_loss

        step.overflowed = lambda: bool(state["overflow"][0])
        return step

    def _score(self, holes, quats, trans, pose_hole, pose_shape, starts, keep=0) -> Attack:
        n_h, n_b = len(holes), len(self.shapes)
        beta = np.ones(len(quats))
        prot = np.zeros(len(quats))
        for b in range(n_b):
            sel = pose_shape == b
            s = score_poses(
                self.renderers[b], holes, quats[sel], trans[sel], pose_hole=pose_hole[sel]
            )
            beta[sel], prot[sel] = s.beta, s.protrusion
        beta = beta.reshape(n_h, n_b, starts)
        prot = prot.reshape(n_h, n_b, starts)
        # Best start: lowest beta, then lowest protrusion.
        key = beta + 1e-9 * prot / (1.0 + prot)
        best = np.argmin(key, axis=-1)
        idx = np.arange(n_h)[:, None], np.arange(n_b)[None, :]
        qs = quats.reshape(n_h, n_b, starts, 4)
        ts = trans.reshape(n_h, n_b, starts, 2)
        candidates = None
        if keep > 0:
            order = np.argsort(key, axis=-1, kind="stable")[..., : min(keep, starts)]
            candidates = (
                np.take_along_axis(qs, order[..., None], axis=2),
                np.take_along_axis(ts, order[..., None], axis=2),
            )
        return Attack(
            candidates=candidates,
            beta=beta[idx + (best,)],
            protrusion=prot[idx + (best,)],
            quats=qs[idx + (best,)],
            trans=ts[idx + (best,)],
            fits=(beta == 0).sum(-1),
        )


_POOL = None


def _pool():
    """A shared thread pool for per-pose raster work (distance transforms, hole filling)."""
    global _POOL
    if _POOL is None:
        from concurrent.futures import ThreadPoolExecutor

        _POOL = ThreadPoolExecutor(
            max_workers=max(1, min(8, os.cpu_count() or 1)), thread_name_prefix="sieve-mi-raster"
        )
    return _POOL


class PlayerA:
    """Chooses A's rotation so that B's best attempt fails by as much as possible (eq. 7).

    Parameters
    ----------
    shape : Shape
        The shape that must pass.
    frame : Frame
        Raster frame of the hole (covers A's dilated silhouette at every rotation).
    tolerance : float
        Dilation of A's silhouette, scene units.
    fill_holes : bool
        Whether holes in A's silhouette are filled.
    """

    def __init__(self, shape: Shape, frame: Frame, tolerance: float, fill_holes: bool = True):
        self.shape = shape
        self.frame = frame
        self.tolerance = tolerance
        self.fill_holes = fill_holes
        self.renderer = with_core(SilhouetteRenderer(shape))
        #: How player B's attacks on this player's holes settle (:meth:`PlayerB.attack`): per
        #: hole, since a hole's value is 0 once any B fits it; only for filled holes, where the
        #: clearance loss is 0 exactly when B fits (an island of plate inside H would let a
        #: silhouette's edges all lie in H while the silhouette covers the island).
        self.settle = "hole" if fill_holes else None

    @classmethod
    def from_settings(
        cls, shape: Shape, frame: Frame, fabrication: Fabrication, solver: Solver | None = None
    ) -> PlayerA:
        """Player A with the ``[fabrication]`` table's ``tolerance`` and ``fill_holes``, and the
        ``[solver]`` table's ``settle`` where given."""
        player = cls(shape, frame, fabrication.tolerance, fabrication.fill_holes)
        if solver is not None and not solver.settle:
            player.settle = None
        return player

    def silhouettes(self, quats: np.ndarray, trans: np.ndarray | None = None) -> np.ndarray:
        """A's silhouettes on the frame for K poses, (K, N, N) bool (translations default to zero)."""
        quats = np.atleast_2d(normalize(quats))
        trans = np.zeros((len(quats), 2)) if trans is None else np.atleast_2d(trans)
        zero = np.zeros(len(quats), int)
        return self.renderer.masks(quats, trans, self.frame, zero, zero, self.frame.resolution)

    def holes(
        self, quats: np.ndarray, trans: np.ndarray | None = None, base: np.ndarray | None = None
    ) -> list[Hole]:
        """The hole H for each pose: silhouette, dilated by the tolerance, holes filled.

        Parameters
        ----------
        quats : (K, 4) ndarray
        trans : (K, 2) ndarray, optional
            Translations in scene units (default zero).
        base : (N, N) bool ndarray, optional
            Part of the hole made by other shapes (already dilated); each hole is its union with
            this shape's dilated silhouette, then filled.
        """
        extra = [] if base is None else [base]
        masks = self.silhouettes(quats, trans)

        def one(m):
            return build_hole([m], self.frame, self.tolerance, self.fill_holes, extra=extra)

        if len(masks) < 2:
            return [one(m) for m in masks]
        # SciPy's distance transforms release the GIL: build the particles' holes in parallel.
        return list(_pool().map(one, masks))

    def search(
        self,
        player_b: PlayerB,
        solver: Solver,
        *,
        rng: np.random.Generator,
        seed: int | None = None,
        progress: Callable[[int, float], None] | None = None,
        stage: Callable[[str], None] | None = None,
    ):
        """Global search over A's rotation: canonical views, then the swarm, then a local polish.

        Parameters
        ----------
        player_b : PlayerB
            The shapes to block, on this player's frame.
        solver : sieve_mi.scene.Solver
            The ``[solver]`` table: ``outer`` (PSO or an nlopt method) with ``particles``,
            ``iterations``, ``inertia``, ``c_personal`` and ``c_global``; B's ``starts``, ``steps``
            and ``learning_rate`` for every evaluation; ``canonical`` views evaluated first
            (:mod:`sieve_mi.geometry.canonical`; the best of them start half of the swarm's
            particles, nlopt starts from the best one); ``polish`` rounds of :meth:`polish` after
            the global method (0: none). Its ``resolution``, ``objective`` and ``freeze`` are
            the frame's and player B's.
        rng : numpy.random.Generator
        seed : int, optional
            Seed of nlopt's own generator and of the polish's common starts (default
            ``solver.seed``).
        progress : callable, optional
            Called as ``progress(iteration, best)`` by the global method.
        stage : callable, optional
            Called with "canonical", "swarm" and "polish" as each stage starts (progress bars).

        Returns
        -------
        quat : (4,) ndarray
            Best rotation found.
        value : float
            Its game value (min over B of beta).
        history : SwarmHistory
            Best value after each iteration (PSO) or evaluation (nlopt); ``history.polish`` holds
            the polish's record.
        """

        s = solver
        seed = s.seed if seed is None else seed

        def evaluate(qs: np.ndarray) -> np.ndarray:
            return self.values(player_b, qs, s.starts, s.steps, s.learning_rate, rng)

        def say(name: str) -> None:
            if stage is not None:
                stage(name)

        if s.canonical > 0:
            say("canonical")
        seeds, evaluated = self._canonical_seeds(evaluate, s.canonical, max(1, s.particles // 2))
        say("swarm" if s.outer == "pso" else s.outer)
        q, f, history = self._global(evaluate, seeds, s, rng, seed, progress)
        history.evaluations += evaluated
        if s.polish > 0:
            say("polish")
            q, f, history.polish = self.polish(player_b, q, s, seed=seed)
        return q, f, history

    def values(self, player_b: PlayerB, quats, starts, steps, learning_rate, rng) -> np.ndarray:
        """The game value (min over B of β, eq. 10) of the holes of rotations (K, 4), one attack.

        An empty raster hole (A seen edge-on, thinner than a pixel) blocks everything on the
        raster but not on the plate: it gets -1, below every real hole.
        """
        holes = self.holes(quats)
        attack = player_b.attack(holes, starts, steps, learning_rate, rng, settle=self.settle)
        values = attack.value()
        return np.where([h.mask.any() for h in holes], values, -1.0)

    def _canonical_seeds(self, evaluate, count: int, keep: int) -> tuple[np.ndarray, int]:
        """The ``keep`` best of ``count`` canonical orientations (k, 4), evaluated in one batch,
        and how many were evaluated."""
        from sieve_mi.geometry.canonical import canonical_orientations

        if count <= 0:
            return np.zeros((0, 4)), 0
        views = canonical_orientations(self.shape, count)
        values = evaluate(views)
        return views[np.argsort(-values, kind="stable")[:keep]], len(views)

    def _global(self, evaluate, seeds, solver: Solver, rng, seed: int, progress):
        """The swarm (or nlopt) of ``solver`` over A's rotation, started from ``seeds`` where given."""
        particles, iterations, method = solver.particles, solver.iterations, solver.outer
        if method == "pso":
            x0 = random_uniform(particles, rng)
            x0[: len(seeds)] = seeds[:particles]
            return particle_swarm(
                evaluate,
                x0,
                iterations,
                rng,
                solver.inertia,
                solver.c_personal,
                solver.c_global,
                project=normalize,
                progress=progress,
                patience=solver.patience,
            )
        lower, upper = -np.pi * np.ones(3), np.pi * np.ones(3)
        x0 = rng.uniform(-np.pi, np.pi, 3)
        if len(seeds):
            x0 = np.clip(to_rotvec(seeds[0]), lower, upper)
        x, f, history = nlopt_maximise(
            lambda v: float(evaluate(from_rotvec(v)[None])[0]),
            lower,
            upper,
            method,
            particles * (iterations + 1),
            x0,
            seed,
            progress,
        )
        return from_rotvec(x), f, history

    def polish(
        self,
        player_b: PlayerB,
        quat: np.ndarray,
        solver: Solver,
        *,
        seed: int | None = None,
        first: float = 1.0,
        last: float = 0.05,
        gain: float = 0.01,
    ) -> tuple[np.ndarray, float, dict]:
        """Refine A's rotation locally: a batched compass search on the view direction.

        The starting rotation is evaluated once; then each round tilts the current one by ``step``
        about the x and y axes, both ways (turning about z only turns the hole), and evaluates the
        four holes in one attack whose B starts are the same every time (common random numbers, so differences come from
        the holes, not from luck). A tilt that is better by more than ``gain`` (relative, and at
        least 1e-3: less is a pixel's worth of raster noise) is taken; otherwise the step is
        halved, from ``first`` down to ``last`` degrees.

        Parameters
        ----------
        player_b : PlayerB
        quat : (4,) ndarray
            The rotation to start from.
        solver : sieve_mi.scene.Solver
            B's ``starts``, ``steps`` and ``learning_rate`` for every attack; at most ``polish``
            rounds.
        seed : int, optional
            Seed of the common starts (default ``solver.seed``).
        first, last : float
            The first and the smallest tilt, degrees.
        gain : float
            Relative improvement a tilt must bring to be taken.

        Returns
        -------
        quat : (4,) ndarray
        value : float
            The value of ``quat`` with the common starts (comparable with ``record["before"]``).
        record : dict
            ``before`` and ``after`` values with the common starts, the rotation's ``moved``
            angle (degrees) and the ``rounds`` run.
        """
        tilts = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])

        seed, rounds = (solver.seed if seed is None else seed), solver.polish

        def values(qs):
            common = np.random.default_rng([int(seed), 0x501])
            return self.values(
                player_b, qs, solver.starts, solver.steps, solver.learning_rate, common
            )

        start = normalize(np.asarray(quat, dtype=np.float64))
        best, step, done = start, np.radians(first), 0
        current = float(values(best[None])[0])
        before = current
        while done < rounds and step >= np.radians(last) * (1 - 1e-9):
            tried = normalize(quat_multiply(from_rotvec(tilts * step), best))
            v = values(tried)
            done += 1
            k = int(np.argmax(v))
            if v[k] > current + max(1e-3, gain * abs(current)):
                best, current = tried[k], float(v[k])
            else:
                step /= 2
        moved = float(np.degrees(angle_between(best, start)))
        record = {"before": before, "after": current, "moved": moved, "rounds": done}
        return best, current, record
