"""One batched descent of player B: its state, its one Adam step and its loop (paper Sec. 6.1).

Every start of every shape against every candidate hole is one pose of a batch; a step is loss,
gradient, "each start keeps the best pose it visited" and Adam's update, for the whole batch in a
few Dr.Jit kernels. A :class:`Batch` holds the poses of one descent (their holes, shapes, starting
poses and settling groups) and splits into consecutive parts, descended one after another where
the memory budget asks for it. :func:`adam_step` is that step, written once: :class:`Descent` runs it traced,
and :mod:`sieve_mi.game.frozen` records it once with :func:`drjit.freeze` and replays it, so the
two give the same poses to the bit. Starts may settle in groups (:class:`Settle`): once one pose
of a group fits, the group stops where its best poses are, and the settled poses leave the batch.
Player B (:mod:`sieve_mi.game.player_b`) chooses the starts, sizes the batches and scores the
results.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from sieve_mi.backend import aligned
from sieve_mi.errors import interruption
from sieve_mi.geometry.rotations import normalize
from sieve_mi.optim import (
    POSE_KEYS,
    QUAT_KEYS,
    live_poses,
    pose_adam,
    pose_columns,
    renormalise_quaternions,
)

__all__ = [
    "CONVERGED",
    "SETTLE_CHECK",
    "Batch",
    "BufferOverflow",
    "Descent",
    "FrozenStepFailed",
    "Settle",
    "adam_step",
    "halving_live",
    "pose_loss",
    "settle_groups",
]

#: A descent whose poses settle (:meth:`~sieve_mi.game.player_b.PlayerB.attack`'s ``settle``)
#: checks every this many steps whether all of its groups have: one read-back of a flag.
SETTLE_CHECK = 5
#: Converged starts leave every descent (issue 45's "adaptive stopping"): ``(window, rtol)``:
#: every ``window`` steps, a start whose best loss fell by less than ``rtol`` of itself since the
#: last check stops where its best pose is. None: only descents whose :class:`Batch` asks for it
#: (the verdict's, :data:`sieve_mi.game.verdict.CONVERGED`) stop converged starts.
CONVERGED = None


class BufferOverflow(Exception):
    """A frozen descent's active-pair buffer overflowed: its results are wrong."""


class FrozenStepFailed(Exception):
    """Dr.Jit failed to record or replay a frozen step (the cause is chained)."""


def pose_loss(opt, loss, stack, pose_hole, scale: float, live=None, capacity: int | None = None):
    """The loss at the poses of a :func:`~sieve_mi.optim.pose_adam` optimiser.

    Parameters
    ----------
    opt : drjit.opt.Adam
        Translations in units of ``scale``.
    loss : Objective
        Bound to the K poses.
    stack : HoleStack
    pose_hole : mi.UInt32
        Each pose's hole (K,).
    scale : float
        The frame's half extent, scene units.
    live : mi.Bool, optional
        (K,): the other poses have settled; they sum nothing and get an infinite loss (a settled
        pose keeps its best).
    capacity : int, optional
        Use the objective's fixed-size ``loss_fixed`` with this buffer (inside
        :func:`drjit.freeze`) instead of ``loss``.

    Returns
    -------
    total : mi.Float
    per_pose : mi.Float
        (K,).
    overflow : mi.Bool or None
        Whether ``loss_fixed``'s buffer overflowed; None without ``capacity``.
    """
    import drjit as dr

    q = tuple(opt[key] for key in QUAT_KEYS)
    t = (opt["tx"] * scale, opt["ty"] * scale)
    if capacity is not None:
        total, per_pose, overflow = loss.loss_fixed(q, t, stack, pose_hole, capacity, live=live)
    else:
        (total, per_pose), overflow = loss.loss(q, t, stack, pose_hole, live=live), None
    if live is not None:
        per_pose = dr.select(live, per_pose, np.inf)  # a settled pose keeps its best
    return total, per_pose, overflow


def _keep_best(opt, best, best_loss, per_pose):
    """Each start keeps the best pose it visited (Adam may step past a fit): the new
    ``(best, best_loss)``."""
    import drjit as dr

    improved = per_pose < best_loss
    best = [dr.select(improved, dr.detach(opt[key]), b) for key, b in zip(POSE_KEYS, best)]
    return best, dr.select(improved, per_pose, best_loss)


def adam_step(opt, best, best_loss, evaluate: Callable[[], tuple]):
    """One Adam step of a descent, traced or inside :func:`drjit.freeze` alike.

    Loss and gradient at the optimiser's poses, each start's best pose, Adam's update and the
    quaternions projected back onto the unit sphere (one evaluation).

    Parameters
    ----------
    opt : drjit.opt.Adam
        From :func:`~sieve_mi.optim.pose_adam`; updated in place.
    best : list of 6 mi.Float
        Each start's best pose so far (:data:`~sieve_mi.optim.POSE_KEYS` order).
    best_loss : mi.Float
        Its loss (K,).
    evaluate : callable
        ``evaluate()`` returns :func:`pose_loss`'s ``(total, per_pose, overflow)`` at the
        optimiser's poses.

    Returns
    -------
    best, best_loss
        Updated.
    overflow : mi.Bool or None
        ``evaluate``'s overflow flag.
    """
    import drjit as dr

    total, per_pose, overflow = evaluate()
    # every pose settled between two checks: nothing depends on the poses any more
    dr.backward(total, flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
    best, best_loss = _keep_best(opt, best, best_loss, per_pose)
    opt.step(eval=False)
    renormalise_quaternions(opt, best, best_loss)
    return best, best_loss, overflow


class Settle:
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
    def make(cls, group, loss) -> Settle | None:
        """Settling for poses in groups ``group`` ((K,) ints, or None: no settling) under the
        objective ``loss`` (None where its ``fit_loss`` is None)."""
        import mitsuba as mi

        fit_loss = loss.fit_loss
        if group is None or fit_loss is None or len(group) == 0:
            return None
        _, dense = np.unique(np.asarray(group), return_inverse=True)
        return cls(mi.UInt32(aligned(dense, np.uint32)), int(dense.max()) + 1, fit_loss)

    def live(self, best_loss):
        """(K,) mi.Bool: the poses whose group has not settled."""
        return live_poses(best_loss, self.group, self.groups, self.fit_loss)

    @staticmethod
    def due(step: int) -> bool:
        """Whether to check after step ``step`` (0-based)."""
        return (step + 1) % SETTLE_CHECK == 0

    def subset(self, keep) -> Settle:
        """The same groups for the poses ``keep`` (mi.UInt32) only."""
        import drjit as dr
        import mitsuba as mi

        return Settle(dr.gather(mi.UInt32, self.group, keep), self.groups, self.fit_loss)


def halving_live(best_loss: np.ndarray, pose_hole: np.ndarray, pose_shape: np.ndarray):
    """One rung of successive halving: of each (hole, shape)'s poses, the better half (rounded
    up: 10 -> 5 -> 3 -> 2 -> 1) by best loss so far, ties in order.

    Parameters
    ----------
    best_loss : (K,) ndarray
        Each pose's best loss so far.
    pose_hole, pose_shape : (K,) ndarrays of int

    Returns
    -------
    (K,) ndarray of bool
        The poses that go on descending.

    Examples
    --------
    >>> halving_live(np.array([3.0, 1.0, 2.0, 0.5]), np.zeros(4, int), np.zeros(4, int)).tolist()
    [False, True, False, True]
    """
    group = np.asarray(pose_hole, np.int64) * (int(np.max(pose_shape, initial=0)) + 1)
    group = group + np.asarray(pose_shape, np.int64)
    order = np.lexsort((np.arange(len(group)), np.asarray(best_loss, np.float64), group))
    first = np.r_[True, group[order][1:] != group[order][:-1]]
    begins = np.maximum.accumulate(np.where(first, np.arange(len(order)), 0))
    rank = np.arange(len(order)) - begins  # place within its group, best first
    size = np.bincount(np.cumsum(first) - 1)[np.cumsum(first) - 1]
    live = np.empty(len(group), dtype=bool)
    live[order] = rank < -(-size // 2)
    return live


def settle_groups(settle, pose_hole, pose_shape, n_b: int):
    """Each pose's settling group for :meth:`~sieve_mi.game.player_b.PlayerB.attack`'s
    ``settle`` (None: no settling)."""
    if settle is None:
        return None
    return {
        "start": np.arange(len(pose_hole)),
        "shape": pose_hole * n_b + pose_shape,
        "hole": pose_hole,
    }[settle]


@dataclass(frozen=True)
class Batch:
    """The K poses of one descent of player B: what each descends against, and where it starts.

    Attributes
    ----------
    holes : list of Hole
        The candidate holes, all on player B's frame.
    pose_hole, pose_shape : (K,) ndarrays of int
        Each pose's hole (index into ``holes``) and shape (index into player B's shapes).
    q0 : (K, 4) ndarray
        Starting rotations, quaternions (w, x, y, z).
    t0 : (K, 2) ndarray
        Starting translations, scene units.
    group : (K,) ndarray of int, optional
        Groups of poses that settle together (:class:`Settle`); None: no settling.
    starts : int, optional
        Starts per hole and shape where the poses are laid out hole by shape by start (as
        :meth:`~sieve_mi.game.player_b.PlayerB.attack` lays them out, K = H x B x starts);
        None for any other layout.
    converged : tuple of (int, float), optional
        ``(window, rtol)``: its starts leave the descent once converged (:data:`CONVERGED`, which
        overrides it when set); None: every start runs every step.
    halving : float
        Successive halving of the starts (:func:`halving_live`): after every ``halving`` of the
        descent's steps, the worse half of each (hole, shape)'s starts still descending stop
        (masked out of the step like settled ones; they leave the batch once at most half of it
        descends). 0: every start runs every step.
    """

    holes: list
    pose_hole: np.ndarray
    pose_shape: np.ndarray
    q0: np.ndarray
    t0: np.ndarray
    group: np.ndarray | None = None
    starts: int | None = None
    converged: tuple | None = None
    halving: float = 0.0

    def __post_init__(self) -> None:
        for name in ("pose_hole", "pose_shape", "q0", "t0"):
            object.__setattr__(self, name, np.asarray(getattr(self, name)))
        if self.group is not None:
            object.__setattr__(self, "group", np.asarray(self.group))

    def __len__(self) -> int:
        """K, the number of poses."""
        return len(self.q0)

    def part(self, poses: slice) -> Batch:
        """The poses ``poses`` (consecutive) alone, against the same holes."""
        group = None if self.group is None else self.group[poses]
        return replace(
            self,
            pose_hole=self.pose_hole[poses],
            pose_shape=self.pose_shape[poses],
            q0=self.q0[poses],
            t0=self.t0[poses],
            group=group,
            starts=None,
        )

    def split(self, parts: list[slice]) -> list[Batch]:
        """The batch cut into ``parts`` (consecutive ranges of poses, e.g. the memory chunks of
        :meth:`~sieve_mi.game.player_b.PlayerB.chunks`): one :meth:`part` each, in order."""
        return [self.part(p) for p in parts]


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
    return best, best_loss, None if settle is None else settle.subset(keep)


class Descent:
    """One batched descent of :meth:`~sieve_mi.game.player_b.PlayerB.descend`: Adam over the
    poses still descending, each start's best pose and loss, and the final poses of those that
    left.

    Parameters
    ----------
    player : PlayerB
        Its ``objective`` and its frame's half extent (translations are optimised in its units).
    batch : Batch
        The poses, their holes and starts, and their settling groups.
    learning_rate : float
        Adam's, for quaternion components and normalised translations.
    """

    def __init__(self, player, batch: Batch, learning_rate: float):
        import drjit as dr
        import mitsuba as mi

        from sieve_mi.geometry.hole import HoleStack

        self.loss = player.objective
        self.stack = HoleStack(batch.holes, corners=self.loss.hole_corners)
        self.pose_hole, self.pose_shape = batch.pose_hole, batch.pose_shape
        self.scale = player.frame.half_extent
        self.opt = pose_adam(batch.q0, batch.t0 / self.scale, learning_rate)
        # copies, not the optimiser's own variables: the first frozen step then has the layout
        # of the later ones (no aliased inputs), and is recorded once, not traced
        self.best = [mi.Float(x) for x in pose_columns(batch.q0, batch.t0 / self.scale)]
        self.best_loss = dr.opaque(mi.Float, np.inf, len(batch))
        self.settle = Settle.make(batch.group, self.loss)
        self.final = np.empty((len(batch), len(POSE_KEYS)))
        self.where = np.arange(len(batch))  # the original index of each pose still descending
        self._last = None  # each pose's best loss at the last convergence check (CONVERGED)
        self.converged = CONVERGED or batch.converged
        self.halving = float(batch.halving)
        self._rung, self._steps = 0, 0  # halving's rung and the descent's steps, set by run()
        #: With halving: which poses still descend ((K,) bool, and as an mi.Bool for the step);
        #: the others are masked out of the step, as settled ones, until the batch shrinks.
        self.alive, self.alive_mask = None, None
        self._bind()

    def _bind(self) -> None:
        import mitsuba as mi

        self.loss.bind(self.pose_shape[self.where])
        self.hole_idx = mi.UInt32(aligned(self.pose_hole[self.where], np.uint32))

    def evaluate(self, live=None):
        """:func:`pose_loss` at the optimiser's poses (``live``: mi.Bool, the poses not settled)."""
        return pose_loss(self.opt, self.loss, self.stack, self.hole_idx, self.scale, live)

    def step(self) -> None:
        """One :func:`adam_step`, traced."""
        live = None if self.settle is None else self.settle.live(self.best_loss)
        if self.alive_mask is not None:
            live = self.alive_mask if live is None else live & self.alive_mask
        self.best, self.best_loss, _ = adam_step(
            self.opt, self.best, self.best_loss, lambda: self.evaluate(live)
        )

    def _live(self, step: int) -> np.ndarray | None:
        """After step ``step``: the poses that go on descending ((K,) bool), or None when
        nothing is checked at this step (settled groups, :class:`Settle`; converged starts,
        :data:`CONVERGED`)."""
        settle = self.settle is not None and self.settle.due(step)
        converge = self.converged is not None and (step + 1) % self.converged[0] == 0
        halve = self._rung > 0 and (step + 1) % self._rung == 0 and step + 1 < self._steps
        if not (settle or converge or halve):
            return None
        live = np.ones(len(self.where), dtype=bool) if self.alive is None else self.alive.copy()
        if settle:
            live &= np.asarray(self.settle.live(self.best_loss), dtype=bool)
        if converge:
            now = np.asarray(self.best_loss, dtype=np.float64)
            last = self._last
            if last is not None:
                with np.errstate(invalid="ignore"):
                    live &= ~np.isfinite(last) | (now < last - self.converged[1] * np.abs(last))
            self._last = now
        if halve:
            self._halve(np.asarray(self.best_loss, dtype=np.float64))
            live &= self.alive
        return live

    def _halve(self, best_loss: np.ndarray) -> None:
        """One rung of successive halving (:func:`halving_live`) among the poses still alive:
        the others are masked out of the step from now on (:attr:`alive_mask`)."""
        import mitsuba as mi

        alive = np.ones(len(self.where), dtype=bool) if self.alive is None else self.alive
        idx = np.flatnonzero(alive)
        where = self.where[idx]
        keep = halving_live(best_loss[idx], self.pose_hole[where], self.pose_shape[where])
        alive = alive.copy()
        alive[idx[~keep]] = False
        masks = self.loss.fit_loss is not None  # objectives without one take no live mask
        self.alive, self.alive_mask = alive, (mi.Bool(aligned(alive, bool)) if masks else None)

    def _stays(self, live: np.ndarray) -> bool:
        """Whether the batch goes on whole after a check that left ``live`` poses: more than half
        descend, and no halved pose is left unmasked (an objective that takes no live mask)."""
        unmasked = self.alive is not None and self.alive_mask is None and not self.alive.all()
        return 2 * live.sum() > len(live) and not unmasked

    def shrink(self, live: np.ndarray) -> bool:
        """Keep descending only the ``live`` poses ((K,) bool); the others' best poses are
        final. Returns whether any pose is left."""
        import mitsuba as mi

        self.final[self.where[~live]] = _rows(self.best)[~live]
        self.where = self.where[live]
        if not len(self.where):
            return False
        keep = mi.UInt32(aligned(np.flatnonzero(live), np.uint32))
        self.best, self.best_loss, self.settle = _keep_poses(
            self.opt, keep, self.best, self.best_loss, self.settle
        )
        if self.alive is not None:
            self.alive = self.alive[live]
            self.alive_mask = (
                None if self.alive_mask is None else mi.Bool(aligned(self.alive, bool))
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
                    per_pose = self.evaluate()[1]
                    self.best, self.best_loss = _keep_best(
                        self.opt, self.best, self.best_loss, per_pose
                    )
            self.final[self.where] = _rows(self.best)
        return normalize(self.final[:, :4]), self.final[:, 4:] * self.scale

    def run(self, steps: int, progress=None, freeze=None) -> tuple[np.ndarray, np.ndarray]:
        """Descend ``steps`` Adam steps; returns :meth:`result`.

        Parameters
        ----------
        steps : int
        progress : callable, optional
            Called with the number of steps done after each step.
        freeze : callable, optional
            ``freeze(descent)`` returns this descent's frozen steps
            (:func:`sieve_mi.game.frozen.replay`) or None (traced). Called again whenever the
            batch shrinks. Every step is frozen: the first step of a descent (and the first
            after a shrink) records, or replays a recording of the same sizes.

        Raises
        ------
        BufferOverflow, FrozenStepFailed
            When a frozen descent must run again traced.

        Notes
        -----
        With settling groups, every :data:`SETTLE_CHECK` steps the poses of settled groups leave
        the descent (their best poses are final) once they are at least half of it: the rest
        goes on as a smaller batch, with its Adam state, so that settled poses cost nothing.
        """
        frozen = None if freeze is None else freeze(self)
        self._steps = steps
        self._rung = max(1, round(self.halving * steps)) if self.halving > 0 else 0
        try:
            for step in range(steps):
                if frozen is not None:
                    self.best, self.best_loss = frozen(self.best, self.best_loss)
                else:
                    self.step()
                if progress:
                    progress(step + 1)
                live = self._live(step)
                if live is None or self._stays(live):
                    continue  # too few left to pay for a smaller batch
                if frozen is not None and frozen.overflowed():
                    raise BufferOverflow
                if self._last is not None:
                    self._last = self._last[live]
                if not self.shrink(live):  # every group settled: the descent is over
                    if progress:
                        progress(steps)
                    break
                frozen = None if freeze is None else freeze(self)
        except Exception as exc:  # drjit.freeze is experimental: trace instead of failing
            if frozen is None or isinstance(exc, BufferOverflow):
                raise
            interrupt = interruption(exc)
            if interrupt is not None:  # Ctrl-C or SIGTERM while Dr.Jit recorded: never eaten
                raise interrupt from None
            raise FrozenStepFailed from exc
        if frozen is not None and frozen.overflowed():
            raise BufferOverflow
        return self.result(steps > 0)
