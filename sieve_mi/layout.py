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

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import ndimage

from sieve_mi.hole import Hole, dilate
from sieve_mi.optim import SwarmHistory, particle_swarm
from sieve_mi.players import PlayerA, PlayerB
from sieve_mi.raster import Frame
from sieve_mi.rotations import from_axis_angle, normalize


@dataclass
class LayoutSettings:
    """Parameters of eq. 14 and of the placement swarm (paper defaults)."""

    tau: float = 10.0
    rho: float = 200.0
    eta: float = 0.02
    alpha: float = 5.0
    c_personal: float = 0.05
    c_global: float = 0.05


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (w, x, y, z): rotation b, then a."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def union_frame(radii: list[float], tolerance: float, resolution: int) -> Frame:
    """A frame for a hole made of several shapes: every shape's centre may lie anywhere within the
    largest radius of the origin, so the frame covers twice the largest radius plus the tolerance."""
    r = max(radii)
    return Frame.covering(2.0 * r + tolerance, resolution)


def separate_layout(radii: list[float], tolerance: float, gap: float, resolution: int) -> tuple[np.ndarray, Frame]:
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


def eq14(beta: np.ndarray, area_fraction: np.ndarray, pieces: np.ndarray, s: LayoutSettings) -> np.ndarray:
    """The energy of eq. 14, minus tau for every hole that falls apart into several pieces."""
    return s.tau / 2 * np.tanh(s.rho * (beta - s.eta)) - s.alpha * area_fraction - s.tau * (pieces > 1)


def pieces(mask: np.ndarray) -> int:
    """Number of 8-connected pieces of a mask."""
    return int(ndimage.label(mask, structure=np.ones((3, 3)))[1])


def best_overlaps(player: PlayerA, base: np.ndarray, quat: np.ndarray, count: int, reach: float, angles: int = 72):
    """In-plane placements of a shape that overlap a hole most.

    For each of ``angles`` rotations about z (applied after ``quat``), the overlap of the shape's
    dilated silhouette with ``base`` is computed for every translation at once as an FFT
    cross-correlation; the best translation per angle (within ``reach`` of the origin) is kept, and
    the ``count`` best angles are returned.

    Returns
    -------
    quats : (count, 4) ndarray
    trans : (count, 2) ndarray
        Scene units.
    """
    frame = player.frame
    n, h = frame.resolution, frame.pixel_size
    theta = np.arange(angles) * (2 * np.pi / angles)
    quats = normalize(quat_multiply(np.stack([from_axis_angle([0, 0, 1], t) for t in theta]), np.asarray(quat)[None]))
    sils = np.stack([dilate(m, frame, player.tolerance) for m in player.silhouettes(quats)]).astype(np.float32)
    size = 2 * n
    fb = np.fft.rfft2(base.astype(np.float32), s=(size, size))
    corr = np.fft.irfft2(fb[None] * np.conj(np.fft.rfft2(sils, s=(size, size))), s=(size, size))
    shift = np.fft.fftfreq(size, 1.0 / size)  # wrapped shift index -> signed pixel shift
    sr, sc = np.meshgrid(shift, shift, indexing="ij")
    allowed = np.hypot(sr, sc) * h <= reach
    corr = np.where(allowed[None], corr, -np.inf)
    flat = corr.reshape(angles, -1).argmax(1)
    score = corr.reshape(angles, -1)[np.arange(angles), flat]
    order = np.argsort(score)[::-1][:count]
    r, c = np.unravel_index(flat[order], (size, size))
    trans = np.stack([shift[c] * h, -shift[r] * h], axis=1)
    if len(order) < count:  # fewer angles than particles: repeat with small jitter
        extra = count - len(order)
        quats_o = np.concatenate([quats[order], quats[order][np.arange(extra) % len(order)]])
        trans = np.concatenate([trans, trans[np.arange(extra) % len(order)] + h])
        return quats_o, trans
    return quats[order], trans


def place(player: PlayerA, player_b: PlayerB, base: np.ndarray, quat: np.ndarray, *, particles: int,
          iterations: int, starts: int, steps: int, learning_rate: float, settings: LayoutSettings,
          rng: np.random.Generator, progress: Callable[[int, float], None] | None = None, recheck: int = 3,
          finalists: int = 5):
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
    recheck : int
        The swarm's ``finalists`` best placements are re-ranked with an attack ``recheck`` times
        longer in both starts and steps (1: no re-ranking).
    finalists : int

    Returns
    -------
    quat : (4,) ndarray
    trans : (2,) ndarray
        Scene units.
    value : float
        Best eq. 14 energy.
    history : SwarmHistory
    """
    frame = player.frame
    reach = frame.half_extent / 2.0  # centres stay within the largest radius of the origin
    # Starts: the in-plane rotations and translations of the shape's own best rotation that overlap
    # the current hole most (an exhaustive search by FFT cross-correlation, in place of the paper's
    # gradient steps from random in-plane transforms).
    q0, t0 = best_overlaps(player, base, quat, particles, reach)
    x0 = np.concatenate([q0, t0 / reach], axis=1)

    def project(x):
        x = x.copy()
        x[:, :4] = normalize(x[:, :4])
        norm = np.linalg.norm(x[:, 4:], axis=1, keepdims=True)
        x[:, 4:] = x[:, 4:] / np.maximum(norm, 1.0)
        return x

    def evaluate(x):
        holes = player.holes(x[:, :4], x[:, 4:] * reach, base=base)
        attack = player_b.attack(holes, starts, steps, learning_rate, rng)
        area = np.array([h.mask.mean() for h in holes])
        n = np.array([pieces(h.mask) for h in holes])
        return eq14(attack.value(), area, n, settings)

    best, value, history = particle_swarm(evaluate, project(x0), iterations, rng, c_personal=settings.c_personal,
                                          c_global=settings.c_global, project=project, progress=progress)
    # The swarm ranks placements with a short attack, which can miss a narrow passage. Re-rank its
    # best few placements with an attack `recheck` times longer and keep the best of those.
    if recheck > 1 and len(history.finalists) > 1:
        xs = np.stack([x for x, _ in history.finalists[:finalists]])
        holes = player.holes(xs[:, :4], xs[:, 4:] * reach, base=base)
        attack = player_b.attack(holes, starts * recheck, steps * recheck, learning_rate, rng)
        area = np.array([h.mask.mean() for h in holes])
        n = np.array([pieces(h.mask) for h in holes])
        energy = eq14(attack.value(), area, n, settings)
        i = int(np.argmax(energy))
        best, value = xs[i], float(energy[i])
    return normalize(best[:4]), best[4:] * reach, value, history


def sort_by_area(players: list[PlayerA], quats: np.ndarray) -> list[int]:
    """Indices of the A shapes, largest silhouette first."""
    areas = [p.silhouettes(q[None])[0].sum() for p, q in zip(players, quats)]
    return list(np.argsort(areas)[::-1])


def compose(players: list[PlayerA], quats: np.ndarray, trans: np.ndarray, fill_holes: bool = True) -> Hole:
    """The hole made of every A shape at its placement: union of dilated silhouettes, filled."""
    frame = players[0].frame
    union = np.zeros((frame.resolution, frame.resolution), dtype=bool)
    for p, q, t in zip(players, quats, trans):
        union |= dilate(p.silhouettes(q[None], t[None])[0], frame, p.tolerance)
    if fill_holes:
        union = ndimage.binary_fill_holes(union)
    return Hole.from_mask(union, frame)


