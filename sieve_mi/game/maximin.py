"""Player A's values with maximin pruning: B attacked in rounds, the most dangerous first.

A candidate hole's value is the least β over B (eq. 10), and the search only asks of most
candidates whether they beat a *floor*: a swarm particle whether it beats its personal best, the
polish whether a tilt beats the current rotation by its gain, the canonical views which of them
are the best few. Once the B attacked so far leave a candidate at or below its floor, attacking the
others can only lower its value further: it cannot change what the search does. So
:class:`Pruned` attacks B in rounds (1/16 of them, then twice as many each round), the most
dangerous first (the lowest β each B reached in its last attack, :func:`note`), and each round
attacks only the candidates still above their floors; a pruned candidate's value is then an
upper bound at or below its floor. A B far from fitting (:data:`FAR`) gets only :data:`FEW` of
its starts there.

Every start is drawn up front, as one attack of every B draws them
(:meth:`~sieve_mi.game.player_b.PlayerB.start_batch`), and a start's descent does not depend on
which other starts descend beside it (Adam is per parameter, the loss a sum of per-pose terms; see
:meth:`~sieve_mi.game.player_b.PlayerB.descend`): a candidate that stays above its floor gets the
value one attack of every B gives it, so the search takes the same steps with pruning as without
(a test holds the two together, with ``FAR = inf``). With player B's attacks reused across
congruent holes (:mod:`sieve_mi.game.reuse`, the search's default) every pair of hole and B gets
its β from its class alone, so the same holds (and every B gets every start). The verdict is not
pruned: it attacks every B on the printed polygon (:mod:`sieve_mi.game.verdict`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sieve_mi.backend import release_cached_memory
from sieve_mi.game import reuse
from sieve_mi.game.attack import Starts
from sieve_mi.game.descent import Batch, settle_groups
from sieve_mi.game.scoring import score_poses

__all__ = ["FAR", "FEW", "FIRST", "PRUNE", "Best", "Pruned", "groups", "note"]

#: Player A's search prunes its candidates at their floors (False: every candidate is attacked
#: by every B, as the verdict always is; the search's choices are the same either way).
PRUNE = True
#: The first round attacks this fraction of B (at least one); each later round twice the last.
FIRST = 1 / 16
#: A B whose danger (its lowest β in its last attack) is above ``(1 + FAR)`` times the most
#: dangerous B's is *far from fitting*: a pruned evaluation attacks it with only :data:`FEW` of
#: its starts (a heuristic, unlike the pruning itself: such a B sets a candidate's value only if
#: its attack does far better than last time). ``inf``: every B gets every start.
FAR = 0.25
#: The share of its starts (at least one) a B far from fitting gets in a pruned evaluation.
FEW = 0.3


@dataclass(frozen=True)
class Best:
    """A floor that asks for a ranking: which ``count`` candidates are best (ties in order);
    the candidates ``exact`` (indices) need their full values (:meth:`Pruned.best`)."""

    count: int
    exact: tuple = ()


def note(player_b, beta: np.ndarray) -> None:
    """Remember each B's lowest β over the holes of an attack (``beta``: (H, B), NaN or inf where
    a B was not attacked) as its danger: :class:`Pruned` attacks the lowest first."""
    beta = np.asarray(beta, dtype=np.float64)
    if beta.size == 0:
        return
    low = np.where(np.isfinite(beta), beta, np.inf).min(axis=0)
    seen = np.isfinite(low)
    if player_b.danger is None:
        player_b.danger = np.zeros(len(player_b.shapes))
    player_b.danger[seen] = low[seen]


def groups(player_b) -> list[np.ndarray]:
    """B's indices in rounds: the most dangerous first (:func:`note`; never attacked: in order,
    first), :data:`FIRST` of them, then twice as many each round (a last round smaller than the
    one before joins it)."""
    n_b = len(player_b.shapes)
    danger = np.zeros(n_b) if player_b.danger is None else player_b.danger
    order = np.argsort(danger, kind="stable")
    out, at, size = [], 0, max(1, int(np.ceil(n_b * FIRST)))
    while at < n_b:
        take = size if n_b - at >= 2 * size else n_b - at  # a short tail joins this round
        out.append(order[at : at + take])
        at, size = at + take, 2 * size
    return out


class Pruned:
    """Game values of candidate holes, attacked in rounds of B and pruned at floors.

    Parameters
    ----------
    player_b : PlayerB
    holes : list of Hole
        The H candidate holes, on player B's frame.
    starts : int
        Random starts per hole and B.
    steps : int
        Adam steps of every descent.
    learning_rate : float
    rng : numpy.random.Generator
        Draws every start now, as one attack of every B would.
    settle : {None, "start", "shape", "hole"}
        :meth:`~sieve_mi.game.player_b.PlayerB.attack`'s ``settle``.
    progress : callable, optional
        Passed to the first descent (steps done), so a progress bar moves once per evaluation.
    classes : Classes, optional
        The search's classes of congruent holes (:mod:`sieve_mi.game.reuse`): every pair of
        hole and B is then attacked as :func:`sieve_mi.game.reuse.attack` does, and every B
        gets all its starts.
    halving : float
        Successive halving of each hole and B's starts in every descent (``[solver] halving``,
        :func:`~sieve_mi.game.descent.halving_live`; 0: off).

    Attributes
    ----------
    value : (H,) ndarray
        Each candidate's value so far: the least β over the B attacked (inf before any; -1 for an
        empty raster hole, which is never attacked, as :meth:`PlayerA.values` scores it).
    reached : (H,) ndarray of int
        How many rounds of :func:`groups` each candidate has been attacked in.
    """

    def __init__(self, player_b, holes, starts, steps, learning_rate, rng, settle, progress=None,
                 classes=None, halving=0.0):  # fmt: skip
        self.player_b, self.holes, self.steps, self.rate = player_b, holes, steps, learning_rate
        self.halving = halving
        self.settle, self.progress = settle, progress
        self.batch = player_b.start_batch(holes, Starts.of(starts), rng, settle)
        count = Starts.of(starts).count
        self.members = None if classes is None else classes.place(holes, self.batch, count)
        self.rounds = groups(player_b)
        self.value = np.full(len(holes), np.inf)
        self.value[[not h.mask.any() for h in holes]] = -1.0
        self.reached = np.where(self.value < 0, len(self.rounds), 0)
        self.low = np.full((len(holes), len(player_b.shapes)), np.inf)  # β per hole and B
        self.start = np.arange(len(self.batch)) % count  # each pose's start, in hole x B x start
        danger = player_b.danger
        self.few = np.zeros(len(player_b.shapes), dtype=bool)  # B far from fitting
        far = classes is None and np.isfinite(FAR)  # with reuse, every B gets every start
        if danger is not None and far and len(danger) and danger.min() > 0:
            self.few = danger > (1 + FAR) * danger.min()  # none while some B fits (β 0)
        self.few_starts = max(1, int(np.ceil(FEW * count)))

    def advance(self, which=None, floor=-np.inf) -> np.ndarray:
        """Attack the candidates ``which`` (indices; default all) round after round until each is
        done or at or below its ``floor`` (scalar or (H,)); returns :attr:`value`."""
        which = np.arange(len(self.holes)) if which is None else np.asarray(which, dtype=int)
        chosen = np.zeros(len(self.holes), dtype=bool)
        chosen[which] = True
        floor = np.broadcast_to(np.asarray(floor, dtype=np.float64), self.value.shape)
        if self.members is not None and np.all(floor[chosen] == -np.inf):  # every B at once
            for r in np.unique(self.reached[chosen & (self.reached < len(self.rounds))]):
                todo = chosen & (self.reached == r)
                self._attack(np.flatnonzero(todo), np.concatenate(self.rounds[r:]))
                self.reached[todo] = len(self.rounds)
        for r, group in enumerate(self.rounds):
            todo = chosen & (self.reached == r) & (self.value > floor)
            if todo.any():
                self._attack(np.flatnonzero(todo), group)
                self.reached[todo] = r + 1
        note(self.player_b, self.low)
        release_cached_memory()
        return self.value

    def best(self, count: int, exact=()) -> np.ndarray:
        """Values that rank the ``count`` best candidates as full attacks would (ties in order)
        and are exact at the candidates ``exact``; returns :attr:`value`.

        One round for every candidate, then every round for the ``count`` best so far (and
        ``exact``): the least of their values, ``t``, is at most the ``count``-th best value, so
        a candidate left below ``t`` cannot be among the best, and the others are attacked on.
        """
        self.advance(floor=np.finfo(np.float64).max)  # the first round, for every candidate
        top = np.argsort(-self.value, kind="stable")[:count]
        self.advance(np.union1d(top, np.asarray(exact, dtype=int)))
        if len(top):
            self.advance(floor=np.nextafter(self.value[top].min(), -np.inf))
        return self.value

    def _attack(self, holes: np.ndarray, shapes: np.ndarray) -> None:
        """One descent of the starts of B ``shapes`` against the candidates ``holes``, scored."""
        if self.members is not None:
            self._reuse(holes, shapes)
            return
        b = self.batch
        sel = np.isin(b.pose_hole, holes) & np.isin(b.pose_shape, shapes)
        sel &= ~self.few[b.pose_shape] | (self.start < self.few_starts)
        local = np.full(len(self.holes), -1)
        local[holes] = np.arange(len(holes))
        pose_hole, pose_shape = local[b.pose_hole[sel]], b.pose_shape[sel]
        n_b = len(self.player_b.shapes)
        sub = Batch([self.holes[h] for h in holes], pose_hole, pose_shape, b.q0[sel], b.t0[sel],
                    settle_groups(self.settle, pose_hole, pose_shape, n_b),
                    halving=self.halving)  # fmt: skip
        quats, trans = self.player_b.descend(sub, self.steps, self.rate, self.progress)
        self.progress = None  # the bar counts one descent per evaluation
        beta = np.ones(len(quats))
        for j in shapes:
            on = pose_shape == j
            beta[on] = score_poses(self.player_b.renderers[j], sub.holes, quats[on], trans[on],
                                   pose_hole=pose_hole[on]).beta  # fmt: skip
        low = np.full((len(holes), n_b), np.inf)
        np.minimum.at(low, (pose_hole, pose_shape), beta)
        self.low[holes] = np.minimum(self.low[holes], low)
        self.value[holes] = np.minimum(self.value[holes], low.min(axis=1))

    def _reuse(self, holes: np.ndarray, shapes: np.ndarray) -> None:
        """:meth:`_attack` with reuse across congruent holes (:func:`sieve_mi.game.reuse.attack`)."""
        hole_of = np.repeat(holes, len(shapes))
        shape_of = np.tile(shapes, len(holes))
        beta = reuse.attack(self.player_b, self.holes, self.members, hole_of, shape_of,
                            self.steps, self.rate, self.settle, self.progress,
                            halving=self.halving)  # fmt: skip
        self.progress = None
        self.low[hole_of, shape_of] = np.minimum(self.low[hole_of, shape_of], beta)
        self.value[holes] = np.minimum(self.value[holes], self.low[holes].min(axis=1))
