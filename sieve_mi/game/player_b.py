"""Player B: fit the blocked shapes into the holes (paper Sec. 6.1).

Player B minimises how much of each blocked shape sticks out of a hole, over rotations and
translations, with Adam from many random starts; every start of every shape against every
candidate hole runs in one batched descent (:mod:`sieve_mi.game.descent`), in chunks that fit the
memory budget (:func:`sieve_mi.backend.pair_budget`), with frozen steps where they pay
(:mod:`sieve_mi.game.frozen`); the best poses are then scored on the raster (binary β).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from sieve_mi.backend import BYTES_PER_PAIR, pair_budget, release_cached_memory
from sieve_mi.errors import SieveError
from sieve_mi.game.attack import Attack, Starts
from sieve_mi.game.descent import Batch, BufferOverflow, Descent, FrozenStepFailed, settle_groups
from sieve_mi.game.scoring import score_poses, with_core
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import random_uniform
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.objectives import OBJECTIVES, Objective, make_objective
from sieve_mi.scene import Solver

__all__ = ["PlayerB"]


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
        allows it (``clearance``) and it pays (on the CPU only up to
        :data:`~sieve_mi.game.frozen.CPU_FREEZE_PAIRS` (pose, segment) pairs per step); the
        results are the same either way.
    memory : float
        Memory budget of one descent, GB (0: a share of the machine's available memory, see
        :func:`sieve_mi.backend.pair_budget`); more poses descend in chunks.
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
        #: Each B's lowest β in its last attack (None: none yet); the search's pruned rounds
        #: attack the lowest first (:mod:`sieve_mi.game.maximin`).
        self.danger: np.ndarray | None = None

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
        starts: int | Starts,
        steps: int,
        learning_rate: float,
        rng: np.random.Generator,
        progress: Callable[[int], None] | None = None,
        *,
        keep: int = 0,
        settle: str | None = None,
        converged: tuple | None = None,
        halving: float = 0.0,
    ) -> Attack:
        """Player B's best attempt on each hole, for each shape.

        Starts are uniform random rotations and translations in +-0.1 of the frame's half extent
        (paper Sec. 6.1), about the origin or the given centres (:class:`Starts`); translations
        are optimised in units of the half extent.

        Parameters
        ----------
        holes : list of Hole
            Candidate holes, all on ``self.frame``.
        starts : int or Starts
            Random starts per hole and shape; or a :class:`~sieve_mi.game.attack.Starts` that
            also says where they are centred (scene units) and which remembered poses replace
            the first of them (its memory is then updated with this attack's results).
        steps : int
            Adam steps.
        learning_rate : float
            Adam's learning rate for quaternion components and normalised translations.
        rng : numpy.random.Generator
        progress : callable, optional
            Called with the number of steps done after each step.
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
        converged : (int, float), optional
            ``(window, rtol)``: every ``window`` steps, starts whose best loss fell by less than
            ``rtol`` of itself leave the descent (:data:`sieve_mi.game.descent.CONVERGED`).
        halving : float
            Successive halving of the starts (``[solver] halving``): after every this fraction
            of ``steps``, the worse half of each hole and shape's starts leave the descent
            (:func:`~sieve_mi.game.descent.halving_live`). 0: every start runs every step.
        """
        starts = Starts.of(starts)
        batch = self.start_batch(holes, starts, rng, settle)
        batch = replace(batch, converged=converged, halving=halving)
        quats, trans = self.descend(batch, steps, learning_rate, progress)
        attack = self._score(batch, quats, trans, keep)
        if starts.memory is not None:
            starts.memory.update(attack)
        release_cached_memory()  # else the process holds this attack's peak from now on
        return attack

    def start_batch(
        self, holes: list[Hole], starts: Starts, rng: np.random.Generator, settle: str | None
    ) -> Batch:
        """The starts of an :meth:`attack`, laid out hole by shape by start.

        Parameters
        ----------
        holes : list of Hole
            H holes, on ``self.frame``.
        starts : Starts
            How many starts per hole and shape, where centred (scene units), from which memory.
        rng : numpy.random.Generator
            Draws the rotations, then the translations.
        settle : {None, "start", "shape", "hole"}
            The settling groups (:meth:`attack`'s ``settle``).

        Returns
        -------
        Batch
            H x B x ``starts.count`` poses (B shapes), translations in scene units, with
            ``starts`` set.
        """
        n_h, n_b, count = len(holes), len(self.shapes), starts.count
        k = n_h * n_b * count
        pose_hole = np.repeat(np.arange(n_h), n_b * count)
        pose_shape = np.tile(np.repeat(np.arange(n_b), count), n_h)
        q0 = random_uniform(k, rng)
        t0 = rng.uniform(-0.1, 0.1, size=(k, 2)) * self.frame.half_extent
        if starts.centres is not None:
            c = np.asarray(starts.centres, dtype=np.float64)
            c = c[:, None, :] if c.ndim == 2 else c
            which = np.tile(np.arange(count) % c.shape[1], n_h * n_b)
            t0 += c[pose_hole, which]
        if starts.memory is not None:
            q0, t0 = q0.reshape(n_h, n_b, count, 4), t0.reshape(n_h, n_b, count, 2)
            for b in range(n_b):
                mq, mt = starts.memory.poses(b)
                w = min(len(mq), count - 1)
                q0[:, b, :w], t0[:, b, :w] = mq[:w], mt[:w]
            q0, t0 = q0.reshape(k, 4), t0.reshape(k, 2)
        group = settle_groups(settle, pose_hole, pose_shape, n_b)
        return Batch(holes, pose_hole, pose_shape, q0, t0, group, starts=count)

    def descend(
        self,
        batch: Batch,
        steps: int,
        learning_rate: float,
        progress: Callable[[int], None] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Batched Adam from given starting poses; returns each start's best pose.

        Parameters
        ----------
        batch : Batch
            The K poses: their holes (on ``self.frame``) and shapes, starting rotations and
            translations (scene units), and the groups of poses that settle together (see
            :meth:`attack`'s ``settle``: once one pose of a group fits, the others stop where
            their best pose is; when every group has settled the descent ends).
        steps : int
        learning_rate : float
        progress : callable, optional

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
        consecutive poses (:meth:`chunks`, :meth:`~sieve_mi.game.descent.Batch.split`), one
        after another: every pose's descent is its own (Adam is per parameter, the loss a sum of
        per-pose terms), so the poses are the same bit for bit, and the memory no longer grows
        with shapes x starts x holes x segments. ``progress`` then follows every chunk: step n
        of chunk i of c counts as (i steps + n) / c steps of the whole (:func:`_chunk_progress`).
        """
        parts = self.chunks(batch.pose_shape)
        if len(parts) == 1:
            return self._descend_falling_back(batch, steps, learning_rate, progress)
        quats, trans = np.empty((len(batch), 4)), np.empty((len(batch), 2))
        reached = [0]  # the steps of the whole descent reported so far
        for i, (part, chunk) in enumerate(zip(parts, batch.split(parts))):
            share = _chunk_progress(progress, i, len(parts), steps, reached)
            quats[part], trans[part] = self._descend_falling_back(
                chunk, steps, learning_rate, share
            )
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
        counts = self.objective.counts
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

    def _descend_falling_back(self, batch, steps, learning_rate, progress=None):
        """One descent of all the poses of ``batch`` at once, with the frozen steps' fallbacks."""
        try:
            return self._descend(batch, steps, learning_rate, progress)
        except FrozenStepFailed as failure:
            self._stop_freezing(failure.__cause__)
        except BufferOverflow:  # more active pairs than the buffer held: this descent traced
            return self._descend(batch, steps, learning_rate, may_freeze=False)
        return self._descend(batch, steps, learning_rate)

    def _descend(self, batch, steps, learning_rate, progress=None, *, may_freeze: bool = True):
        """:meth:`descend` without its fallbacks (:meth:`~sieve_mi.game.descent.Descent.run`);
        raises :class:`~sieve_mi.game.descent.BufferOverflow` or
        :class:`~sieve_mi.game.descent.FrozenStepFailed` when a frozen descent must run again
        traced. ``may_freeze=False`` traces every step."""
        run = Descent(self, batch, learning_rate)
        freeze = self._frozen_steps if may_freeze and steps > 0 else None
        return run.run(steps, progress, freeze)

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

    def _frozen_steps(self, run: Descent):
        """The frozen Adam steps of the descent ``run`` (:func:`sieve_mi.game.frozen.replay`),
        or None where this player does not freeze or it does not pay
        (:func:`sieve_mi.game.frozen.pays`)."""
        from sieve_mi.game import frozen

        if not (self.freeze and frozen.pays(run.loss)):
            return None
        self._frozen = self._frozen or frozen.frozen_step()
        return frozen.replay(self._frozen, run)

    def _score(self, batch: Batch, quats, trans, keep: int = 0) -> Attack:
        """The attack of ``batch`` (laid out by :meth:`start_batch`) from its best poses ``quats``
        (K, 4) and ``trans`` (K, 2, scene units), scored on the raster."""
        holes, pose_hole, pose_shape = batch.holes, batch.pose_hole, batch.pose_shape
        n_h, n_b, starts = len(holes), len(self.shapes), batch.starts
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


def _chunk_progress(progress, i: int, count: int, steps: int, reached: list):
    """``progress`` for chunk ``i`` of ``count`` of a descent of ``steps``: called with the whole
    descent's steps done, (i steps + n) // count after the chunk's step n, once per new value
    (``reached[0]`` holds the last one); None without ``progress``."""
    if progress is None:
        return None
    if count == 1:
        return progress

    def report(n: int) -> None:
        whole = (i * steps + n) // count
        if whole > reached[0]:
            reached[0] = whole
            progress(whole)

    return report
