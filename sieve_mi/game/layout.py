"""Many shapes in A (paper Sec. 5.3): one hole made of several placed silhouettes.

The sequential scheme of the paper: solve each A_i alone against all of B (Sec. 5.2), sort the A_i
by silhouette area (largest first), start with H = the first one's hole, and add the others one by
one (:func:`merge`). Each placement (:func:`place`) maximises eq. 14,

    tau/2 * tanh(rho * (beta_H - eta)) - alpha * area(H),

where beta_H is player B's best beta against the new hole and area(H) is the hole's area as a
fraction of the frame; a placement that splits the hole into several pieces is penalised by tau,
so the final hole stays one simply connected region. How a placement is found (where the paper
pushes random in-plane transforms into H by gradient steps):

1. *Candidates*: every in-plane rotation (:data:`ANGLES` of them) and translation of A_i's own
   best rotation that touches the current hole, scored exactly by FFT cross-correlation of the
   dilated silhouette with H; the most compact filled holes first (:func:`candidate_placements`).
2. *Screening*: ``SCREEN x particles`` distinct candidates get one short attack of B each; the best
   ``particles`` start a particle swarm (accelerations ``c_personal``, ``c_global``).
3. *Re-ranking*: the swarm's :data:`FINALISTS` best placements are attacked as long as the verdict
   will attack, and the best survivor is kept.
4. *Rounds*: while every finalist still lets some B through, the round is repeated (at most
   ``[layout] rounds``); B's attacks remember the passing poses found so far.
5. *Alternatives*: if the placement still fails, the next-best rotations of A_i (and, for the
   first pair, of the base shape) from their own searches are tried (``[layout] alternatives``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from sieve_mi.game.attack import AttackMemory
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.hole import Hole, build_hole, dilate, fill_gaps, pieces
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import angle_between, from_axis_angle, normalize, quat_multiply
from sieve_mi.optim import SwarmHistory, particle_swarm
from sieve_mi.scene import Layout, Solver

__all__ = [
    "ANGLES",
    "DISTINCT_ANGLE",
    "DISTINCT_SHIFT",
    "FINALISTS",
    "MIN_OVERLAP",
    "Merged",
    "PEAK_SPACING",
    "PER_ANGLE",
    "Placement",
    "SCREEN",
    "alternative_rotations",
    "candidate_placements",
    "compose",
    "eq14",
    "frame_for",
    "hole_frame",
    "merge",
    "place",
    "separate_layout",
    "sort_by_area",
    "union_frame",
]

#: In-plane rotations of a shape tried by :func:`candidate_placements` (every 5 degrees).
ANGLES = 72
#: Candidate translations kept per in-plane rotation (the strongest overlap peaks).
PER_ANGLE = 6
#: Overlap peaks are at least this fraction of the reach apart.
PEAK_SPACING = 0.05
#: A candidate must overlap the hole by more than this many pixels (it must touch it).
MIN_OVERLAP = 0.5
#: Candidates closer than this (radians) *and* :data:`DISTINCT_SHIFT` (fraction of the reach) to
#: an earlier one are the same placement.
DISTINCT_ANGLE = 0.2
DISTINCT_SHIFT = 0.1
#: ``SCREEN * particles`` distinct candidates are screened with a short attack.
SCREEN = 5
#: The swarm's best placements re-ranked by the long attack.
FINALISTS = 5


class Placement(NamedTuple):
    """One shape's place in a merged hole, as :func:`place` found it."""

    #: (4,) rotation (w, x, y, z).
    quat: np.ndarray
    #: (2,) translation, scene units.
    trans: np.ndarray
    #: Best eq. 14 energy.
    value: float
    #: The weakest B's loss against this placement in the long re-ranking attack (> 0: every B
    #: was blocked there).
    beta: float
    history: SwarmHistory

    @property
    def blocks(self) -> bool:
        """Whether every B was blocked by the hole with this placement."""
        return self.beta > 0


def union_frame(radii: list[float], tolerance: float, resolution: int) -> Frame:
    """A frame for a hole made of several shapes: every shape's centre may lie anywhere within the
    largest radius of the origin, so the frame covers twice the largest radius plus the tolerance."""
    r = max(radii)
    return Frame.covering(2.0 * r + tolerance, resolution)


def hole_frame(shape: Shape, tolerance: float, resolution: int) -> Frame:
    """The raster frame for one A's hole: covers A's dilated silhouette at every rotation."""
    return Frame.covering(shape.radius + tolerance, resolution)


def frame_for(
    passes: list[Shape], tolerance: float, resolution: int, trans: np.ndarray | None = None
) -> Frame:
    """The frame of the final hole.

    One shape: its own frame. Several shapes at known in-plane translations ``trans`` (scene
    units): the smallest centred frame that holds every shape's bounding disk at its place, so the
    verdict's pixels are as fine as the placed hole allows. Without ``trans``: the union frame,
    which holds any placement the search may choose.
    """
    if len(passes) == 1:
        return hole_frame(passes[0], tolerance, resolution)
    if trans is None:
        return union_frame([p.radius for p in passes], tolerance, resolution)
    reach = max(float(np.hypot(*t)) + p.radius for p, t in zip(passes, trans))
    return Frame.covering(reach + tolerance, resolution)


def separate_layout(
    radii: list[float], tolerance: float, gap: float, resolution: int
) -> tuple[np.ndarray, Frame]:
    """Holes side by side for ``layout.mode = "separate"``: the trivially valid answer (paper Sec. 5.3).

    Each shape's hole lies within its bounding circle grown by the tolerance; the circles are put in
    a row along x with ``gap`` of material between neighbours, centred on the origin. The frame has
    the pixel size a single hole of the largest shape would get at ``resolution``.

    Parameters
    ----------
    radii : list of float
        Bounding radii of the shapes, scene units.
    tolerance, gap : float
        Dilation and material between holes, scene units.
    resolution : int
        Pixels per side of the largest single shape's frame.

    Returns
    -------
    trans : (m, 2) ndarray
        Each shape's translation, scene units.
    frame : Frame
    """
    r = np.asarray(radii, dtype=np.float64) + tolerance
    x = np.concatenate([[0.0], np.cumsum(r[:-1] + r[1:] + gap)])
    x -= 0.5 * (x[0] - r[0] + x[-1] + r[-1])
    trans = np.column_stack([x, np.zeros_like(x)])
    h = Frame.covering(float(r.max()), resolution).pixel_size
    half = float(np.max(np.abs(x) + r)) + 3.0 * h
    n = int(np.ceil(2.0 * half / h))
    return trans, Frame(n, 0.5 * n * h)


def eq14(beta: np.ndarray, area_fraction: np.ndarray, pieces: np.ndarray, s: Layout) -> np.ndarray:
    """The energy of eq. 14, minus tau for every hole that falls apart into several pieces."""
    return (
        s.tau / 2 * np.tanh(s.rho * (beta - s.eta)) - s.alpha * area_fraction - s.tau * (pieces > 1)
    )


def _rotated_silhouettes(
    player: PlayerA, quat: np.ndarray, angles: int
) -> tuple[np.ndarray, np.ndarray]:
    """The shape's dilated silhouettes under ``angles`` rotations about z applied after ``quat``."""
    theta = np.arange(angles) * (2 * np.pi / angles)
    quats = normalize(
        quat_multiply(
            np.stack([from_axis_angle([0, 0, 1], t) for t in theta]), np.asarray(quat)[None]
        )
    )
    sils = np.stack([dilate(m, player.frame, player.tolerance) for m in player.silhouettes(quats)])
    return quats, sils


def _shifted(mask: np.ndarray, dr: int, dc: int) -> np.ndarray:
    """``mask`` moved by (dr, dc) pixels, zero-filled (no wrap-around)."""
    n0, n1 = mask.shape
    out = np.zeros_like(mask)
    out[max(dr, 0) : n0 + min(dr, 0), max(dc, 0) : n1 + min(dc, 0)] = mask[
        max(-dr, 0) : n0 - max(dr, 0), max(-dc, 0) : n1 - max(dc, 0)
    ]
    return out


def candidate_placements(
    player: PlayerA,
    base: np.ndarray,
    quat: np.ndarray,
    reach: float,
    *,
    angles: int = ANGLES,
    per_angle: int = PER_ANGLE,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """In-plane placements of a shape that touch a hole, ranked by the area of the hole they make.

    For each of ``angles`` rotations about z (applied after ``quat``), the overlap of the shape's
    dilated silhouette with ``base`` is computed for every pixel translation at once (FFT
    cross-correlation), and its ``per_angle`` strongest local maxima within ``reach`` of the origin
    become candidates. Each candidate's hole, ``fill(base | silhouette)``, is then built and
    measured. Ranking by that *filled* area rather than by the overlap alone matters: the placement
    that overlaps most often closes a cavity of the hole (a letter laid across the mouth of a G),
    and filling the closed cavity adds exactly the room a blocked shape needs to pass.

    Parameters
    ----------
    player : PlayerA
        The shape to add, on the union frame.
    base : (N, N) bool ndarray
        The current hole (dilated, filled).
    quat : (4,) ndarray
        The shape's best rotation when solved alone.
    reach : float
        Largest distance of the shape's centre from the origin, scene units.
    angles, per_angle : int
        In-plane rotations tried, and candidates kept per rotation.

    Returns
    -------
    quats : (K, 4) ndarray
    trans : (K, 2) ndarray
        Scene units.
    area : (K,) ndarray
        Filled hole area in pixels; candidates that leave the hole in several pieces are dropped.
        Sorted ascending (most compact first).
    """
    frame = player.frame
    n, h = frame.resolution, frame.pixel_size
    quats, sils = _rotated_silhouettes(player, quat, angles)
    size = 2 * n
    fb = np.fft.rfft2(base.astype(np.float32), s=(size, size))
    corr = np.fft.irfft2(
        fb[None] * np.conj(np.fft.rfft2(sils.astype(np.float32), s=(size, size))), s=(size, size)
    )
    shift = np.rint(np.fft.fftfreq(size, 1.0 / size)).astype(
        int
    )  # wrapped index -> signed pixel shift
    sr, sc = np.meshgrid(shift, shift, indexing="ij")
    allowed = np.hypot(sr, sc) * h <= reach
    spacing = max(3, int(round(PEAK_SPACING * reach / h)))
    qs, ts, areas = [], [], []
    for k in range(angles):
        c = np.where(allowed, corr[k], -np.inf)
        peaks = (c >= ndimage.maximum_filter(c, size=spacing, mode="wrap")) & (c > MIN_OVERLAP)
        idx = np.flatnonzero(peaks)
        idx = idx[np.argsort(c.ravel()[idx])[::-1][:per_angle]]
        for i in idx:
            dr_, dc_ = int(sr.flat[i]), int(sc.flat[i])
            union = base | _shifted(sils[k], dr_, dc_)
            filled = fill_gaps(union)
            if pieces(filled) != 1:
                continue
            qs.append(quats[k])
            ts.append((dc_ * h, -dr_ * h))
            areas.append(int(filled.sum()))
    if not qs:  # nothing touches the hole: fall back to the shape at the origin
        return np.asarray(quats[:1]), np.zeros((1, 2)), np.array([np.inf])
    order = np.argsort(areas, kind="stable")
    return (
        np.asarray(qs)[order],
        np.asarray(ts, dtype=np.float64)[order],
        np.asarray(areas, dtype=np.float64)[order],
    )


def _diverse(
    quats: np.ndarray, trans: np.ndarray, count: int, min_angle: float, min_distance: float
) -> np.ndarray:
    """Indices of up to ``count`` entries, in order, skipping any that is within ``min_angle``
    radians *and* ``min_distance`` of one already taken (so the starts are not one placement many
    times over)."""
    taken: list[int] = []
    for i, (q, t) in enumerate(zip(quats, trans)):
        near = [
            angle_between(q, quats[j]) < min_angle and np.linalg.norm(t - trans[j]) < min_distance
            for j in taken
        ]
        if not any(near):
            taken.append(i)
            if len(taken) == count:
                break
    return np.asarray(taken, dtype=int)


def _stratified(total: int, count: int) -> np.ndarray:
    """``count`` of ``range(total)``: the first half in order, the rest evenly spread over the
    remainder (so a screen sees the most compact candidates and a sample of all the others)."""
    if total <= count:
        return np.arange(total)
    head = count // 2
    tail = np.linspace(head, total - 1, count - head).round().astype(int)
    return np.concatenate([np.arange(head), tail])


def place(
    player: PlayerA,
    player_b: PlayerB,
    base: np.ndarray,
    quat: np.ndarray,
    *,
    solver: Solver,
    layout: Layout,
    rng: np.random.Generator,
    progress: Callable[[int, float], None] | None = None,
    recheck: tuple[int, int] | None = None,
    finalists: int = FINALISTS,
    screen: int = SCREEN,
    memory: AttackMemory | None = None,
    rounds: int | None = None,
):
    """Place one more A shape into a hole (one step of the sequential scheme).

    Parameters
    ----------
    player : PlayerA
        The shape to add, on the union frame.
    player_b : PlayerB
        The shapes to block, on the union frame.
    base : (N, N) bool ndarray
        The current hole (dilated, filled).
    quat : (4,) ndarray
        The shape's best rotation when it was solved alone.
    solver : sieve_mi.scene.Solver
        Its ``particles``, ``iterations`` and ``patience`` are the placement swarm's; its ``starts``,
        ``steps`` and ``learning_rate`` player B's attack on every candidate hole.
    layout : sieve_mi.scene.Layout
        Eq. 14's tau, rho, eta, alpha, the swarm's accelerations and ``rounds``.
    rng, progress :
        Random generator; per-iteration callback of the swarm.
    recheck : (int, int), optional
        Starts and Adam steps of the attack that re-ranks the swarm's ``finalists`` best placements
        (the solver passes the verdict's settings, so the placement kept is the one that survives
        the attack the winner is decided by); default three times ``starts`` and ``steps``.
    finalists : int
    screen : int
        ``screen * particles`` distinct candidate placements (half the most compact, half spread
        over the others, see :func:`candidate_placements`) are scored with one short attack each;
        the best ``particles`` of them start the swarm.
    memory : AttackMemory, optional
        B's best poses so far (shared across placements); every attack starts from them too.
    rounds : int, optional
        Screening + swarm + re-ranking is repeated (at most this many times, default
        ``layout.rounds``) while every re-ranked placement still lets some B through; each
        round's attacks start from the passing poses the previous rounds found.

    Returns
    -------
    Placement
    """
    reach = player.frame.half_extent / 2.0  # centres stay within the largest radius of the origin
    starts, steps, particles = solver.starts, solver.steps, solver.particles
    if memory is None:
        memory = AttackMemory.for_starts(len(player_b.shapes), starts)
    game = _PlacementGame(player, player_b, base, reach, memory, layout, solver.learning_rate, rng)
    pool = _candidate_pool(player, base, quat, reach, screen * particles)
    recheck = recheck if recheck is not None else (3 * starts, 3 * steps)
    rounds = layout.rounds if rounds is None else rounds
    return game.play(
        pool, particles, solver.iterations, (starts, steps), recheck, finalists, rounds, progress,
        patience=solver.patience,
    )  # fmt: skip


@dataclass
class _PlacementGame:
    """Eq. 14 for placements of one A into a base hole, each scored by one batched attack of B."""

    player: PlayerA
    player_b: PlayerB
    base: np.ndarray
    reach: float
    memory: AttackMemory
    settings: Layout
    learning_rate: float
    rng: np.random.Generator

    def energy(self, x: np.ndarray, starts: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Eq. 14 energy and the weakest B's β of placements ``x`` (P, 6): (P,) and (P,)."""
        holes = self.player.holes(x[:, :4], x[:, 4:] * self.reach, base=self.base)
        attack = self.player_b.attack(
            holes, starts, steps, self.learning_rate, self.rng, memory=self.memory,
            settle=self.player.settle,
        )  # fmt: skip
        area = np.array([hh.mask.mean() for hh in holes])
        n = np.array([pieces(hh.mask) for hh in holes])
        return eq14(attack.value(), area, n, self.settings), attack.value()

    def play(self, pool, particles, iterations, attack, recheck, finalists, rounds, progress,
             patience: int = 0):  # fmt: skip
        """Rounds of screening, swarm and re-ranking over the candidate ``pool`` (see :func:`place`).

        ``attack`` and ``recheck`` are (starts, steps) of the swarm's and the re-ranking's attacks;
        ``patience`` is the swarm's (``[solver] patience``).
        """
        reach, rng, settings = self.reach, self.rng, self.settings

        def evaluate(x):
            return self.energy(x, *attack)[0]

        history = SwarmHistory()
        best, value, best_beta = pool[0], -np.inf, -np.inf
        for _ in range(rounds):
            x0 = _swarm_starts(pool, evaluate, particles, self.player.frame.pixel_size / reach)
            x, _, h = particle_swarm(
                evaluate, _project(x0), iterations, rng, c_personal=settings.c_personal,
                c_global=settings.c_global, project=_project, progress=progress,
                patience=patience,
            )  # fmt: skip
            history.extend(h)
            history.finalists = h.finalists
            # The swarm ranks placements with a short attack, which can miss a narrow passage.
            # Re-rank its best few placements with a long attack and keep the best of those.
            xs = np.stack([f for f, _ in h.finalists[:finalists]]) if h.finalists else x[None]
            values, betas = self.energy(xs, *recheck)
            i = int(np.argmax(values))
            if values[i] > value:
                best, value, best_beta = xs[i], float(values[i]), float(betas[i])
            if best_beta > 0:
                break
            # Every finalist lets some B through. The memory now holds the passing poses, so
            # another round of screening and swarming sees through the placements that looked
            # safe before.
        return Placement(normalize(best[:4]), best[4:] * reach, value, best_beta, history)


def _project(x: np.ndarray) -> np.ndarray:
    """Placements (P, 6) with unit quaternions and translations inside the unit disc."""
    x = x.copy()
    x[:, :4] = normalize(x[:, :4])
    norm = np.linalg.norm(x[:, 4:], axis=1, keepdims=True)
    x[:, 4:] = x[:, 4:] / np.maximum(norm, 1.0)
    return x


def _candidate_pool(
    player: PlayerA, base: np.ndarray, quat: np.ndarray, reach: float, count: int
) -> np.ndarray:
    """``count`` distinct candidate placements (P, 6): quaternion, translation / ``reach``.

    In-plane rotations and translations of the shape's own best rotation that touch the current
    hole, most compact filled hole first (an exhaustive search by FFT cross-correlation, in place
    of the paper's gradient steps from random in-plane transforms), thinned to distinct ones and
    stratified (see :func:`candidate_placements`).
    """
    qc, tc, _ = candidate_placements(player, base, quat, reach)
    distinct = _diverse(
        qc, tc, len(qc), min_angle=DISTINCT_ANGLE, min_distance=DISTINCT_SHIFT * reach
    )
    pick = _stratified(len(distinct), count)
    qc, tc = qc[distinct[pick]], tc[distinct[pick]]
    return np.concatenate([qc, tc / reach], axis=1)


def _swarm_starts(pool: np.ndarray, evaluate, particles: int, nudge: float) -> np.ndarray:
    """The swarm's first ``particles`` placements (P, 6): the pool's best by ``evaluate``.

    With no more candidates than particles, the pool is repeated, the copies moved by ``nudge``
    along x (in units of the reach: a pixel).
    """
    if len(pool) > particles:
        return pool[np.argsort(evaluate(pool), kind="stable")[::-1][:particles]]
    extra = particles - len(pool)
    shift = np.array([0, 0, 0, 0, nudge, 0])
    return np.concatenate([pool, pool[np.arange(extra) % len(pool)] + shift])


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
    """Where every A sits in a merged hole, as :func:`merge` left it.

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
    player_b: PlayerB,
    quats: np.ndarray,
    alternatives: dict,
    *,
    solver: Solver,
    layout: Layout,
    recheck: tuple[int, int],
    rng: np.random.Generator,
    progress: Callable[[str, float], None] | None = None,
) -> Merged:
    """The sequential scheme of Sec. 5.3: place every A, largest first, into one hole.

    Parameters
    ----------
    players : list of PlayerA
        Every A on the union frame (:func:`union_frame`).
    player_b : PlayerB
        The shapes to block, on the same frame.
    quats : (m, 4) ndarray
        Each A's best rotation when solved alone.
    alternatives : dict of int to list of (4,) ndarray
        Per A, other good rotations from its own search (:func:`alternative_rotations`).
    solver, layout : sieve_mi.scene.Solver, sieve_mi.scene.Layout
        Swarm and attack settings; eq. 14, ``rounds`` and ``alternatives``.
    recheck : (int, int)
        Starts and steps of the attack that re-ranks each placement's finalists.
    rng : numpy.random.Generator
    progress : callable, optional
        Called as ``progress(stage_label, best)`` after every swarm iteration.

    Returns
    -------
    Merged
    """
    quats = np.array(quats, dtype=np.float64)
    trans = np.zeros((len(players), 2))
    history, stages, value = SwarmHistory(), [], float("nan")
    order = sort_by_area(players, quats)
    placed = [order[0]]
    memory = AttackMemory.for_starts(len(player_b.shapes), solver.starts)
    lost = False  # a placement already lets some B through: later ones cannot mend that
    for i in order[1:]:
        name = players[i].shape.name
        tries = _tries(
            quats[i],
            alternatives.get(i, []),
            alternatives.get(placed[0], []),
            layout.rounds,
            lost,
            len(placed) == 1,
        )
        label = (
            None if progress is None else (lambda it, best, _n=name: progress(f"place {_n}", best))
        )

        def place_one(base, q, rounds, _i=i, _label=label):
            return place(
                players[_i], player_b, base, q, solver=solver, layout=layout, rng=rng,
                progress=_label, memory=memory, recheck=recheck, rounds=rounds,
            )  # fmt: skip

        kept, kept_base = _best_try(
            players, placed, quats, trans, tries, place_one, history, stages, name
        )
        quats[i], trans[i], value = kept.quat, kept.trans, kept.value
        quats[placed[0]] = kept_base
        lost = lost or not kept.blocks
        placed.append(i)
    origin = trans[order[0]].copy()
    trans -= origin  # the first (largest) shape sits at the origin
    return Merged(quats, trans, value, history, stages, memory.shifted(-origin), not lost)


def _best_try(players, placed, quats, trans, tries, place_one, history, stages, name):
    """Run the ``tries`` of one placement until one blocks; the best placement and base rotation.

    Parameters
    ----------
    players, placed, quats, trans :
        All A, the indices already placed, and the current rotations and translations.
    tries : list of (base_q or None, q, rounds)
        From :func:`_tries`.
    place_one : callable
        ``place_one(base_mask, q, rounds) -> Placement``.
    history, stages :
        Appended to (swarm values; one stage per try).
    name : str
        The shape's name, for the stage labels.

    Returns
    -------
    Placement, (4,) ndarray
        The placement kept and the base shape's rotation it was made against.
    """
    current = compose([players[j] for j in placed], quats[placed], trans[placed]).mask
    kept, kept_base = None, quats[placed[0]]
    for attempt, (base_q, q, rounds) in enumerate(tries):
        base = current
        if base_q is not None:  # the first pair, with another rotation of the base shape
            base = compose([players[placed[0]]], base_q[None], trans[placed]).mask
        got = place_one(base, q, rounds)
        history.extend(got.history)
        suffix = f" (try {attempt + 1})" if attempt else ""
        stages.append((f"place {name}{suffix}", len(got.history.best)))
        if kept is None or (got.blocks, got.value) > (kept.blocks, kept.value):
            kept, kept_base = got, (quats[placed[0]] if base_q is None else base_q).copy()
        if kept.blocks:
            break
    return kept, kept_base
