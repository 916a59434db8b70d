"""Where one more A could sit in a hole: candidate placements, found exhaustively by FFT.

The first step of a placement (:mod:`sieve_mi.game.layout`, paper Sec. 5.3, where the paper pushes
random in-plane transforms into H by gradient steps): every in-plane rotation (:data:`ANGLES` of
them) and translation of A_i's own best rotation that touches the current hole, scored exactly by
FFT cross-correlation of the dilated silhouette with H, ranked by the area of the filled hole they
make, most compact first (:func:`candidate_placements`); then thinned to distinct placements and
stratified, so that a screen sees the most compact ones and a sample of all the others
(:func:`candidate_pool`).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from sieve_mi.game.player_a import PlayerA
from sieve_mi.geometry.hole import dilate, fill_gaps, pieces
from sieve_mi.geometry.rotations import angle_between, from_axis_angle, normalize, quat_multiply

__all__ = [
    "ANGLES",
    "DISTINCT_ANGLE",
    "DISTINCT_SHIFT",
    "MIN_OVERLAP",
    "PEAK_SPACING",
    "PER_ANGLE",
    "candidate_placements",
    "candidate_pool",
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


def candidate_pool(
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
