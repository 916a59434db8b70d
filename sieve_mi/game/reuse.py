"""Player B's attacks reused across congruent holes of player A's search.

Player A's search meets the same hole again and again: a ball makes one hole in every view, a
cylinder along its axis one hole however it turns about it, a cube six congruent squares, and a
particle or a polish tilt that moves little makes a hole that differs from an attacked one by the
raster's quantisation only. The holes of one search fall into *classes* of holes congruent to
the class's first hole, its *reference* (:func:`sieve_mi.geometry.congruence.congruent`: the same
up to a rotation, a mirror and a shift of the plane, within a fraction of a pixel). Player B
attacks a reference as always, from its own random starts, and remembers each B's best
:data:`POSES` poses there; on every other hole of the class it moves those poses with the hole
(:meth:`~sieve_mi.geometry.congruence.Motion.poses`) and descends :data:`STEPS` Adam steps from
them instead of a full multi-start attack. The β of such a hole is still player B's real raster
score on that hole (its own attack, from better starts, for fewer steps), never a copy; the
verdict on the exact printed polygon decides the winner as before. A reference's attack that
missed a passage leaves its whole class overestimated, so a class whose hole would become the
search's best is attacked again from fresh starts once, and that caps its holes
(:class:`Incumbent`).

Every β is a function of its hole, its B and its class alone, whatever else one descent holds:
a reference's B is attacked from the starts drawn for the reference when it was first seen
(kept with the class), and descents settle per hole and B (``"shape"``) instead of per hole. So
maximin pruning (:mod:`sieve_mi.game.maximin`), which attacks B in rounds and leaves candidates
at their floors, takes the same search steps with reuse as the unpruned search with reuse (a
test holds the two together). A B far from fitting (:data:`~sieve_mi.game.maximin.FAR`) gets
all its starts on a reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sieve_mi.game.descent import Batch, settle_groups
from sieve_mi.game.scoring import score_poses
from sieve_mi.geometry.congruence import Motion, Outline, areas_plausible, congruent

__all__ = ["LIMIT", "POSES", "REUSE", "STEPS", "Classes", "Entry", "Incumbent", "Member", "attack"]

#: Player A's search reuses player B's attacks across congruent holes (False: every hole gets a
#: full multi-start attack).
REUSE = True
#: Best poses of each B on a reference hole that start its attack on the congruent holes.
POSES = 2
#: Adam steps from those poses on a congruent hole (at most the search's steps).
STEPS = 10
#: Classes kept by one search (the oldest are forgotten; a hole congruent to a forgotten one
#: starts a class of its own).
LIMIT = 64


@dataclass(eq=False)
class Entry:
    """One class of congruent holes: its reference and what player B found there.

    Attributes
    ----------
    outline : Outline
        The reference hole's (:mod:`sieve_mi.geometry.congruence`).
    q0 : (B, S, 4) ndarray
    t0 : (B, S, 2) ndarray
        The reference's random starts, per B (scene units).
    poses : dict
        B index -> ((K, 4), (K, 2)): that B's :data:`POSES` best poses on the reference (lowest
        raster β, then protrusion), reference coordinates.
    beta : dict
        B index -> that B's lowest β on the reference.
    """

    outline: Outline
    q0: np.ndarray
    t0: np.ndarray
    poses: dict = field(default_factory=dict)
    beta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Member:
    """A hole's place among the classes: its class, the motion from the reference onto it, and
    whether it is the reference itself (attacked from its own starts)."""

    entry: Entry
    motion: Motion
    ref: bool


class Classes:
    """The classes of congruent holes met by one search, oldest first (at most :data:`LIMIT`);
    every attack through them must use the same starts, steps and learning rate (a search's
    evaluations do)."""

    def __init__(self):
        self.entries: list[Entry] = []
        #: Holes placed so far, and how many of them joined an existing class.
        self.placed, self.reused = 0, 0

    def place(self, holes, batch: Batch, starts: int) -> list[Member]:
        """Each hole's :class:`Member`, in order; a hole congruent to no class starts one, with
        its starts in ``batch`` (laid out hole by B by start, ``starts`` each)."""
        n_b = len(batch) // max(1, len(holes) * starts)
        q0 = batch.q0.reshape(len(holes), n_b, starts, 4)
        t0 = batch.t0.reshape(len(holes), n_b, starts, 2)
        out = []
        for h, hole in enumerate(holes):
            outline = Outline.of(hole)
            found = None
            for entry in self._plausible(outline):
                motion = congruent(entry.outline, outline)
                if motion is not None:
                    found = Member(entry, motion, ref=False)
                    break
            if found is None:
                entry = Entry(outline, q0[h].copy(), t0[h].copy())
                self.entries.append(entry)
                del self.entries[:-LIMIT]
                found = Member(entry, Motion(0.0, False, np.zeros(2)), ref=True)
            self.placed += 1
            self.reused += not found.ref
            out.append(found)
        return out

    def _plausible(self, outline: Outline) -> list[Entry]:
        """The classes, oldest first, whose reference passes
        :func:`~sieve_mi.geometry.congruence.areas_plausible` against ``outline`` (one array
        test instead of a call of :func:`congruent` per class; it refuses the others)."""
        if not self.entries:
            return []
        area = np.array([e.outline.area for e in self.entries])
        border = np.array([e.outline.border for e in self.entries])
        near = areas_plausible(area, border, outline)
        near |= (area == 0) | (outline.area == 0)  # empty holes: congruent's own rule
        return [e for e, ok in zip(self.entries, near) if ok]


class Incumbent:
    """The best value of one search with reuse, each class confirmed by a fresh attack once.

    With reuse every hole of a class gets its β from the reference's attack: where that attack
    missed a passage (10 random starts can), the whole class keeps the overestimate, and the swarm,
    which keeps the highest values it sees, settles on it. On the authors' mechanical parts
    (seed 0, 2026-12-08) the beetle's search claimed 0.066 from its first iteration where a fresh
    attack found 0.0008 on the same view, and the merged hole's beetle front ended at β 0.0005
    (0.035 without reuse). So when a value would become the search's best, its hole is attacked
    again from fresh starts, without reuse, and the result *caps its class*: that hole and every
    later hole of the class gets the lower of its own value and the cap (congruent holes have the
    same β up to the raster's noise). The next highest is confirmed in turn while the best is not
    in a confirmed class. Each class is confirmed once (the first confirmation per hole, tried on
    2026-12-08, took 28 more attacks of 50 B on the ball of ``benchmarks.many_b``, whose every hole
    is one class and whose noise kept making new bests), and values at or below the best change
    nothing (the swarm keeps its best).

    Parameters
    ----------
    fresh : callable
        ``fresh(quats, k)`` gives the values (K,) of rotations (K, 4) from a full attack with
        fresh starts (its ``k``-th generator), no reuse.

    Attributes
    ----------
    best : float
        The highest value so far, after the caps (-inf before any).
    caps : dict
        :class:`Entry` -> its confirmed value.
    confirmed, lowered : int
        Classes confirmed, and how many of those confirmations lowered the value they checked.
    """

    def __init__(self, fresh):
        self.fresh = fresh
        self.best = -np.inf
        self.caps: dict[Entry, float] = {}
        self.confirmed, self.lowered = 0, 0

    def __call__(self, quats: np.ndarray, values: np.ndarray, members: list[Member]) -> np.ndarray:
        """``values`` of rotations ``quats`` (their holes' ``members``, :meth:`Classes.place`),
        capped by their classes' confirmations, a class confirmed where it would be the best."""
        values = np.array(values, dtype=np.float64)
        entries = [m.entry for m in members]
        for i, entry in enumerate(entries):
            values[i] = min(values[i], self.caps.get(entry, np.inf))
        while len(values):
            k = int(np.argmax(values))
            if values[k] <= self.best or entries[k] in self.caps:
                break
            cap = float(self.fresh(np.asarray(quats)[k : k + 1], self.confirmed)[0])
            self.caps[entries[k]] = cap
            self.confirmed += 1
            self.lowered += cap < values[k]
            for i, entry in enumerate(entries):
                if entry is entries[k]:
                    values[i] = min(values[i], cap)
        if len(values):
            self.best = max(self.best, float(values.max()))
        return values


def attack(player_b, holes, members, hole_of, shape_of, steps, rate, settle, progress=None, *,
           halving=0.0):  # fmt: skip
    """Player B's lowest β on each pair (hole ``hole_of[p]``, B ``shape_of[p]``), with reuse.

    A pair whose hole is its class's reference, or whose class has not met the B yet, gets the
    reference's full attack from all its own starts; every other pair :data:`STEPS` steps from
    the class's best poses moved onto its hole.

    Parameters
    ----------
    player_b : PlayerB
    holes : list of Hole
    members : list of Member
        Each hole's (:meth:`Classes.place`).
    hole_of, shape_of : (P,) ndarrays of int
    steps : int
        The full attack's Adam steps.
    rate : float
    settle : {None, "start", "shape", "hole"}
        ``"hole"`` settles per hole and B here (see the module docstring).
    progress : callable, optional
        Passed to the first descent.
    halving : float
        Successive halving of the references' starts (``[solver] halving``; 0: off).

    Returns
    -------
    beta : (P,) ndarray
    """
    settle = "shape" if settle == "hole" else settle
    n_b = len(player_b.shapes)
    # 1. the references' full attacks still missing, one descent
    need = []
    for h, j in zip(hole_of, shape_of):
        entry = members[h].entry
        if j not in entry.poses and (entry, j) not in need:
            need.append((entry, j))
    if need:
        _references(player_b, need, steps, rate, settle, progress, halving)
        progress = None
    # 2. the references' βs, and the other pairs from their classes' best poses
    out = np.empty(len(hole_of))
    rows = []
    for p, (h, j) in enumerate(zip(hole_of, shape_of)):
        m = members[h]
        if m.ref:
            out[p] = m.entry.beta[j]
        else:
            q, t = m.motion.poses(*m.entry.poses[j])
            rows += [(p, h, j, q[k], t[k]) for k in range(len(q))]
    if rows:
        pair, ph, ps = (np.array([r[i] for r in rows]) for i in range(3))
        used = np.unique(ph)
        at = np.searchsorted(used, ph)
        q0, t0 = np.array([r[3] for r in rows]), np.array([r[4] for r in rows])
        sub = [holes[h] for h in used]
        batch = Batch(sub, at, ps, q0, t0, settle_groups(settle, at, ps, n_b))
        quats, trans = player_b.descend(batch, min(STEPS, steps), rate, progress)
        beta, _ = _scores(player_b, sub, at, ps, quats, trans)
        low = np.full(len(hole_of), np.inf)
        np.minimum.at(low, pair, beta)
        done = np.isfinite(low)
        out[done] = low[done]
    return out


def _references(player_b, need: list, steps: int, rate, settle, progress, halving: float) -> None:
    """The full attacks of :func:`attack` still missing, one descent: ``need`` lists (class
    entry, B index) pairs; each entry gets that B's :data:`POSES` best poses and lowest β."""
    n_b = len(player_b.shapes)
    refs = list(dict.fromkeys(id(e) for e, _ in need))
    by_id = {id(e): e for e, _ in need}
    local = [by_id[i].outline.hole for i in refs]
    count = need[0][0].q0.shape[1]
    rows = []
    for e, j in need:
        rows += [(refs.index(id(e)), j, s) for s in range(count)]
    ph, ps = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    q0 = np.array([by_id[refs[a]].q0[j, s] for a, j, s in rows])
    t0 = np.array([by_id[refs[a]].t0[j, s] for a, j, s in rows])
    batch = Batch(local, ph, ps, q0, t0, settle_groups(settle, ph, ps, n_b), halving=halving)
    quats, trans = player_b.descend(batch, steps, rate, progress)
    beta, prot = _scores(player_b, local, ph, ps, quats, trans)
    key = beta + 1e-9 * prot / (1.0 + prot)
    for e, j in need:
        on = np.flatnonzero((ph == refs.index(id(e))) & (ps == j))
        best = on[np.argsort(key[on], kind="stable")[:POSES]]
        e.poses[j] = (quats[best], trans[best])
        e.beta[j] = float(beta[best[0]])


def _scores(player_b, holes, pose_hole, pose_shape, quats, trans):
    """Raster β and protrusion of each pose, one :func:`score_poses` per B."""
    beta, prot = np.ones(len(quats)), np.zeros(len(quats))
    for j in np.unique(pose_shape):
        on = pose_shape == j
        s = score_poses(player_b.renderers[j], holes, quats[on], trans[on], pose_hole=pose_hole[on])
        beta[on], prot[on] = s.beta, s.protrusion
    return beta, prot
