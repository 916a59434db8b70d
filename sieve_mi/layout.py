"""Many shapes in A (paper Sec. 5.3): one hole made of several placed silhouettes.

The sequential scheme of the paper: solve each A_i alone against all of B (Sec. 5.2), sort the A_i
by silhouette area (largest first), start with H = the first one's hole, and add the others one by
one. Each new A_i starts from in-plane rigid transforms of its own best rotation that are pushed
into the current hole by gradient steps (the clearance loss of A_i, dilated, against H), and is
then placed by a particle swarm (accelerations 0.05) maximising eq. 14,

    tau/2 * tanh(rho * (beta_H - eta)) - alpha * area(H),

where beta_H is player B's best beta against the new hole and area(H) is the hole's area as a
fraction of the frame. A placement that splits the hole into several pieces is penalised by tau,
so the final hole stays one simply connected region.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from sieve_mi.hole import Hole, dilate
from sieve_mi.optim import SwarmHistory, particle_swarm
from sieve_mi.players import AttackMemory, PlayerA, PlayerB
from sieve_mi.raster import Frame
from sieve_mi.rotations import angle_between, from_axis_angle, normalize


@dataclass
class LayoutSettings:
    """Parameters of eq. 14 and of the placement swarm (paper defaults)."""

    tau: float = 10.0
    rho: float = 200.0
    eta: float = 0.02
    alpha: float = 5.0
    c_personal: float = 0.05
    c_global: float = 0.05


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


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (w, x, y, z): rotation b, then a."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def union_frame(radii: list[float], tolerance: float, resolution: int) -> Frame:
    """A frame for a hole made of several shapes: every shape's centre may lie anywhere within the
    largest radius of the origin, so the frame covers twice the largest radius plus the tolerance."""
    r = max(radii)
    return Frame.covering(2.0 * r + tolerance, resolution)


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


def eq14(
    beta: np.ndarray, area_fraction: np.ndarray, pieces: np.ndarray, s: LayoutSettings
) -> np.ndarray:
    """The energy of eq. 14, minus tau for every hole that falls apart into several pieces."""
    return (
        s.tau / 2 * np.tanh(s.rho * (beta - s.eta)) - s.alpha * area_fraction - s.tau * (pieces > 1)
    )


def pieces(mask: np.ndarray) -> int:
    """Number of 8-connected pieces of a mask."""
    return int(ndimage.label(mask, structure=np.ones((3, 3)))[1])


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
    angles: int = 72,
    per_angle: int = 6,
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
    spacing = max(3, int(round(0.05 * reach / h)))  # local maxima at least ~5 % of the reach apart
    qs, ts, areas = [], [], []
    for k in range(angles):
        c = np.where(allowed, corr[k], -np.inf)
        peaks = (c >= ndimage.maximum_filter(c, size=spacing, mode="wrap")) & (c > 0.5)
        idx = np.flatnonzero(peaks)
        idx = idx[np.argsort(c.ravel()[idx])[::-1][:per_angle]]
        for i in idx:
            dr_, dc_ = int(sr.flat[i]), int(sc.flat[i])
            union = base | _shifted(sils[k], dr_, dc_)
            filled = ndimage.binary_fill_holes(union)
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
    particles: int,
    iterations: int,
    starts: int,
    steps: int,
    learning_rate: float,
    settings: LayoutSettings,
    rng: np.random.Generator,
    progress: Callable[[int, float], None] | None = None,
    recheck: tuple[int, int] | None = None,
    finalists: int = 5,
    screen: int = 5,
    memory: AttackMemory | None = None,
    rounds: int = 3,
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
    particles, iterations : int
        Placement swarm size and iterations.
    starts, steps, learning_rate :
        Player B's attack settings for every candidate hole.
    settings : LayoutSettings
    rng : numpy.random.Generator
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
    rounds : int
        Screening + swarm + re-ranking is repeated (at most this many times) while every
        re-ranked placement still lets some B through; each round's attacks start from the
        passing poses the previous rounds found.

    Returns
    -------
    Placement
    """
    frame = player.frame
    reach = frame.half_extent / 2.0  # centres stay within the largest radius of the origin
    # Candidate starts: in-plane rotations and translations of the shape's own best rotation that
    # touch the current hole, most compact filled hole first (an exhaustive search by FFT
    # cross-correlation, in place of the paper's gradient steps from random in-plane transforms).
    qc, tc, _ = candidate_placements(player, base, quat, reach)
    distinct = _diverse(qc, tc, len(qc), min_angle=0.2, min_distance=0.1 * reach)
    pick = _stratified(len(distinct), screen * particles)
    qc, tc = qc[distinct[pick]], tc[distinct[pick]]
    x0 = np.concatenate([qc, tc / reach], axis=1)

    def project(x):
        x = x.copy()
        x[:, :4] = normalize(x[:, :4])
        norm = np.linalg.norm(x[:, 4:], axis=1, keepdims=True)
        x[:, 4:] = x[:, 4:] / np.maximum(norm, 1.0)
        return x

    if memory is None:
        memory = AttackMemory(len(player_b.shapes), size=max(1, starts // 3))

    def evaluate(x):
        holes = player.holes(x[:, :4], x[:, 4:] * reach, base=base)
        attack = player_b.attack(holes, starts, steps, learning_rate, rng, memory=memory)
        area = np.array([h.mask.mean() for h in holes])
        n = np.array([pieces(h.mask) for h in holes])
        return eq14(attack.value(), area, n, settings)

    r_starts, r_steps = recheck if recheck is not None else (3 * starts, 3 * steps)
    pool = x0
    history = SwarmHistory()
    best, value, best_beta = pool[0], -np.inf, -np.inf
    for _ in range(rounds):
        # Screen the candidates with one short attack each (one batch); the best start the swarm.
        if len(pool) > particles:
            x0 = pool[np.argsort(evaluate(pool), kind="stable")[::-1][:particles]]
        else:  # few candidates: repeat them, nudged by a pixel
            extra = particles - len(pool)
            x0 = np.concatenate(
                [
                    pool,
                    pool[np.arange(extra) % len(pool)]
                    + np.r_[0, 0, 0, 0, frame.pixel_size / reach, 0],
                ]
            )
        x, v, h = particle_swarm(
            evaluate,
            project(x0),
            iterations,
            rng,
            c_personal=settings.c_personal,
            c_global=settings.c_global,
            project=project,
            progress=progress,
        )
        history.best += h.best
        history.evaluations += h.evaluations
        history.finalists = h.finalists
        # The swarm ranks placements with a short attack, which can miss a narrow passage. Re-rank
        # its best few placements with a long attack and keep the best of those.
        xs = np.stack([f for f, _ in h.finalists[:finalists]]) if h.finalists else x[None]
        holes = player.holes(xs[:, :4], xs[:, 4:] * reach, base=base)
        attack = player_b.attack(holes, r_starts, r_steps, learning_rate, rng, memory=memory)
        area = np.array([hh.mask.mean() for hh in holes])
        n = np.array([pieces(hh.mask) for hh in holes])
        energy = eq14(attack.value(), area, n, settings)
        i = int(np.argmax(energy))
        if energy[i] > value:
            best, value, best_beta = xs[i], float(energy[i]), float(attack.value()[i])
        if best_beta > 0:
            break
        # Every finalist lets some B through. The memory now holds the passing poses, so another
        # round of screening and swarming sees through the placements that looked safe before.
    return Placement(normalize(best[:4]), best[4:] * reach, value, best_beta, history)


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


def compose(
    players: list[PlayerA], quats: np.ndarray, trans: np.ndarray, fill_holes: bool = True
) -> Hole:
    """The hole made of every A shape at its placement: union of dilated silhouettes, filled."""
    frame = players[0].frame
    union = np.zeros((frame.resolution, frame.resolution), dtype=bool)
    for p, q, t in zip(players, quats, trans):
        union |= dilate(p.silhouettes(q[None], t[None])[0], frame, p.tolerance)
    if fill_holes:
        union = ndimage.binary_fill_holes(union)
    return Hole.from_mask(union, frame)
