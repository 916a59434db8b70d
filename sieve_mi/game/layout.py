"""Many shapes in A merged into one hole (paper Sec. 5.3): the sequential scheme and its retries.

The sequential scheme of the paper: solve each A_i alone against all of B (Sec. 5.2), sort the A_i
by silhouette area (largest first, :func:`sort_by_area`), start with H = the first one's hole, and
add the others one by one (:func:`merge`); :func:`compose` draws the hole of every A at its place.
Each placement maximises eq. 14 (:func:`sieve_mi.game.placement.place`):

1. *Candidates*: every in-plane rotation and translation of A_i's own best rotation that touches
   the current hole, by FFT cross-correlation (:mod:`sieve_mi.game.candidates`).
2. *Screening*, 3. *re-ranking* and 4. *rounds*: a short attack of B on each candidate, a particle
   swarm, a long attack on its finalists, repeated while every finalist lets some B through
   (:mod:`sieve_mi.game.placement`).
5. *Alternatives*: if the placement still fails, the next-best rotations of A_i (and, for the
   first pair, of the base shape) from their own searches are tried (``[layout] alternatives``,
   :func:`alternative_rotations`), here.

The frames these holes are drawn on, and the separate layout (holes side by side), are
:mod:`sieve_mi.game.frames`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sieve_mi.game.attack import AttackMemory
from sieve_mi.game.placement import PlacementContext, place
from sieve_mi.game.player_a import PlayerA
from sieve_mi.geometry.hole import Hole, build_hole
from sieve_mi.geometry.rotations import angle_between, normalize
from sieve_mi.optim import SwarmHistory

__all__ = ["Merged", "alternative_rotations", "compose", "merge", "sort_by_area"]


def alternative_rotations(
    finalists: list, best: np.ndarray, count: int, min_angle: float = 0.35
) -> list[np.ndarray]:
    """Other good rotations of one A from its own search, for a placement that fails with the best.

    Parameters
    ----------
    finalists : list of (quat, value)
        The swarm's final personal bests, best first (:attr:`SwarmHistory.finalists`).
    best : (4,) ndarray
        The rotation already chosen.
    count : int
        At most this many are returned.
    min_angle : float
        Radians; every rotation returned differs from ``best`` and from each other by at least
        this much (q and -q are the same rotation).

    Returns
    -------
    list of (4,) ndarray
        Rotations whose value was > 0 (alone, that A blocked every B), best first.
    """
    chosen = [normalize(np.asarray(best, float))]
    out = []
    for q, v in finalists:
        if len(out) >= count or not v > 0:
            break
        q = normalize(np.asarray(q, float)[:4])
        if all(angle_between(q, c) >= min_angle for c in chosen):
            chosen.append(q)
            out.append(q)
    return out


def sort_by_area(players: list[PlayerA], quats: np.ndarray) -> list[int]:
    """Indices of the A shapes, largest silhouette first."""
    areas = [p.silhouettes(q[None])[0].sum() for p, q in zip(players, quats)]
    return list(np.argsort(areas)[::-1])


def compose(players: list[PlayerA], quats: np.ndarray, trans: np.ndarray) -> Hole:
    """The hole made of every A shape at its placement (:func:`sieve_mi.geometry.hole.build_hole`).

    Parameters
    ----------
    players : list of PlayerA
        On one frame, with one tolerance and one ``fill_holes`` setting.
    quats : (m, 4) ndarray
    trans : (m, 2) ndarray
        Scene units.
    """
    first = players[0]
    masks = [p.silhouettes(q[None], t[None])[0] for p, q, t in zip(players, quats, trans)]
    return build_hole(masks, first.frame, first.tolerance, first.fill_holes)


@dataclass
class Merged:
    """Where every A sits in a merged hole, as :func:`merge` left it (and, while it runs, where
    the A placed so far sit).

    Attributes
    ----------
    quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z); the first placed shape's may have been swapped for one of
        its alternatives.
    trans : (m, 2) ndarray
        Each A's translation, scene units; the largest shape sits at the origin.
    value : float
        The last placement's eq. 14 energy.
    history : SwarmHistory
        Best value per swarm iteration, all placements one after another.
    stages : list of (str, int)
        Label and number of iterations of every placement try.
    memory : AttackMemory or None
        Player B's best poses over all the placement attacks, in the same coordinates as
        ``trans`` (the verdict starts from them too).
    blocks : bool
        Every placement kept blocked all of B in its re-ranking attack.
    """

    quats: np.ndarray
    trans: np.ndarray
    value: float
    history: SwarmHistory
    stages: list
    memory: AttackMemory | None = None
    blocks: bool = True


def _tries(quat, own_alternatives, base_alternatives, rounds: int, lost: bool, first: bool):
    """The (base rotation or None, rotation, rounds) tries of one placement, in order.

    The shape's own best rotation first (several rounds); while no earlier placement let B through,
    then its next-best distinct rotations, and for the first pair also the base shape's (Sec. 5.3
    is greedy: a hole that lets B through cannot be mended by adding more shapes). One round each.
    """
    tries = [(None, quat, rounds)]
    if not lost:
        tries += [(None, q, 1) for q in own_alternatives]
        if first:
            tries += [(q, quat, 1) for q in base_alternatives]
    return tries


def merge(
    players: list[PlayerA],
    quats: np.ndarray,
    alternatives: dict,
    context: PlacementContext,
    *,
    progress: Callable[[str, float], None] | None = None,
) -> Merged:
    """The sequential scheme of Sec. 5.3: place every A, largest first, into one hole.

    Parameters
    ----------
    players : list of PlayerA
        Every A on the union frame (:func:`sieve_mi.game.frames.union_frame`).
    quats : (m, 4) ndarray
        Each A's best rotation when solved alone.
    alternatives : dict of int to list of (4,) ndarray
        Per A, other good rotations from its own search (:func:`alternative_rotations`).
    context : PlacementContext
        Player B (the shapes to block, on the same frame), the ``[solver]`` (swarm and attack)
        and ``[layout]`` (eq. 14, ``rounds``, ``alternatives``) settings, the random generator,
        the attack that re-ranks each placement's finalists, and B's memory, shared by every
        placement.
    progress : callable, optional
        Called as ``progress(stage_label, best)`` after every swarm iteration.

    Returns
    -------
    Merged
    """
    quats = np.array(quats, dtype=np.float64)
    out = Merged(quats, np.zeros((len(players), 2)), float("nan"), SwarmHistory(), [])
    order = sort_by_area(players, quats)
    placed = [order[0]]
    lost = False  # a placement already lets some B through: later ones cannot mend that
    for i in order[1:]:
        name = players[i].shape.name
        tries = _tries(
            quats[i],
            alternatives.get(i, []),
            alternatives.get(placed[0], []),
            context.layout.rounds,
            lost,
            len(placed) == 1,
        )
        label = (
            None if progress is None else (lambda it, best, _n=name: progress(f"place {_n}", best))
        )

        def place_one(base, q, rounds, _i=i, _label=label):
            return place(players[_i], base, q, context, progress=_label, rounds=rounds)

        kept, kept_base = _best_try(players, placed, out, tries, place_one, name)
        quats[i], out.trans[i], out.value = kept.quat, kept.trans, kept.value
        quats[placed[0]] = kept_base
        lost = lost or not kept.blocks
        placed.append(i)
    origin = out.trans[order[0]].copy()
    out.trans -= origin  # the first (largest) shape sits at the origin
    out.memory, out.blocks = context.memory.shifted(-origin), not lost
    return out


def _best_try(players, placed, merged: Merged, tries, place_one, name):
    """Run the ``tries`` of one placement until one blocks; the best placement and base rotation.

    Parameters
    ----------
    players, placed :
        All A and the indices already placed.
    merged : Merged
        The merge so far: the current rotations and translations are read, every try's swarm
        values appended to ``history`` and one stage per try to ``stages``.
    tries : list of (base_q or None, q, rounds)
        From :func:`_tries`.
    place_one : callable
        ``place_one(base_mask, q, rounds) -> Placement``.
    name : str
        The shape's name, for the stage labels.

    Returns
    -------
    Placement, (4,) ndarray
        The placement kept and the base shape's rotation it was made against.
    """
    quats, trans = merged.quats, merged.trans
    current = compose([players[j] for j in placed], quats[placed], trans[placed]).mask
    kept, kept_base = None, quats[placed[0]]
    for attempt, (base_q, q, rounds) in enumerate(tries):
        base = current
        if base_q is not None:  # the first pair, with another rotation of the base shape
            base = compose([players[placed[0]]], base_q[None], trans[placed]).mask
        got = place_one(base, q, rounds)
        merged.history.extend(got.history)
        suffix = f" (try {attempt + 1})" if attempt else ""
        merged.stages.append((f"place {name}{suffix}", len(got.history.best)))
        if kept is None or (got.blocks, got.value) > (kept.blocks, kept.value):
            kept, kept_base = got, (quats[placed[0]] if base_q is None else base_q).copy()
        if kept.blocks:
            break
    return kept, kept_base
