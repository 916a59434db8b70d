"""Scoring poses with binary masks: the normalised outside area beta (paper eq. 12) and the
protrusion, the largest distance by which a pose's silhouette sticks out of the hole.

Every pose is rasterised in a window of the hole's pixel lattice that covers its bounding disk, so
parts of the shape outside the hole's frame are counted too. Rays, hole lookups and the per-pose
reductions run in one Dr.Jit kernel for all poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.silhouettes import SilhouetteRenderer

__all__ = ["MaskWindow", "PoseScores", "mask_window", "score_poses", "window_for"]


class MaskWindow(NamedTuple):
    """A shape's silhouette on a window of a hole's pixel lattice (for images and figures)."""

    #: (x0, x1, y0, y1): the window's outer edges, scene units.
    extent: tuple
    #: (S, S) bool: pixel centres covered by the silhouette, row 0 at the top.
    mask: np.ndarray


@dataclass
class PoseScores:
    """Binary scores of K poses of one shape.

    Attributes
    ----------
    beta : (K,) ndarray
        area(proj(B') minus H) / area(proj(B')), from pixel-centre masks; 0 means the pose fits.
    protrusion : (K,) ndarray
        Largest distance (scene units) from a silhouette pixel centre of the pose to H; 0 if it fits.
    """

    beta: np.ndarray
    protrusion: np.ndarray


def window_for(renderer: SilhouetteRenderer, frame: Frame, trans: np.ndarray):
    """Lattice windows covering each pose's bounding disk: (row0, col0, size).

    The window side is capped at twice the frame plus a margin; a capped window is centred on the
    pose (a projection larger than it cannot fit anyway, see :func:`score_poses`).
    """
    h = frame.pixel_size
    r = renderer.shape.radius
    full = int(np.ceil(2 * r / h)) + 3
    size = min(full, 2 * frame.resolution + 3)
    trans = np.atleast_2d(trans)
    # Centre the window on the pose when it is capped, else put its corner at the disk's corner.
    start = (
        frame.to_pixel(trans) - size / 2
        if size < full
        else frame.to_pixel(trans + np.array([-r, r]))
    )
    start = np.floor(start).astype(np.int64) - 1
    return start[:, 1], start[:, 0], size


def score_poses(
    renderer: SilhouetteRenderer,
    holes,
    quats: np.ndarray,
    trans: np.ndarray,
    pose_hole: np.ndarray | None = None,
    return_masks: bool = False,
    chunk_rays: int = 1 << 24,
):
    """Beta and protrusion of poses of one shape against one or several holes.

    Parameters
    ----------
    renderer : SilhouetteRenderer
        The shape's renderer.
    holes : Hole or list of Hole
        On one frame.
    quats : (K, 4) ndarray
        Rotations (w, x, y, z).
    trans : (K, 2) ndarray
        Translations, scene units.
    pose_hole : (K,) ndarray of int, optional
        Which hole each pose is scored against (default: the first).
    return_masks : bool
        Also return the windows and masks (for figures).

    Returns
    -------
    PoseScores, and if asked (row0, col0, size, masks)
    """
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.geometry.hole import HoleStack

    holes = [holes] if isinstance(holes, Hole) else list(holes)
    frame = holes[0].frame
    quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
    k_total = len(quats)
    pose_hole = np.zeros(k_total, int) if pose_hole is None else np.asarray(pose_hole)
    stack = HoleStack(holes)
    row0, col0, size = window_for(renderer, frame, trans)
    n, npix = frame.resolution, size * size
    beta, prot = np.ones(k_total), np.zeros(k_total)
    masks = np.zeros((k_total, size, size), dtype=bool) if return_masks else None
    per = max(1, chunk_rays // npix)
    for s in range(0, k_total, per):
        sl = slice(s, min(k_total, s + per))
        hit, pose, row, col = renderer.trace(quats[sl], trans[sl], frame, row0[sl], col0[sl], size)
        rc, cc = dr.clip(row, 0, n - 1), dr.clip(col, 0, n - 1)
        hole_of = dr.gather(mi.UInt32, mi.UInt32(pose_hole[sl].astype(np.uint32)), pose)
        d = stack.gather(hole_of, mi.UInt32(rc), mi.UInt32(cc))
        inside = (row == rc) & (col == cc) & (d == 0)
        dist = (d + dr.sqrt(mi.Float(dr.square(row - rc) + dr.square(col - cc)))) * frame.pixel_size
        out = hit & ~inside
        per_ray = (dr.select(hit, 1.0, 0.0), dr.select(out, 1.0, 0.0), dr.select(out, dist, 0.0))
        dr.eval(*per_ray)  # one ray-casting kernel; unevaluated, each reduction would trace again
        area = dr.block_sum(per_ray[0], npix)
        outside = dr.block_sum(per_ray[1], npix)
        worst = dr.block_reduce(dr.ReduceOp.Max, per_ray[2], npix)
        area, outside, worst = (np.asarray(a, dtype=np.float64) for a in (area, outside, worst))
        beta[sl] = np.where(area > 0, outside / np.maximum(area, 1), 1.0)
        prot[sl] = worst
        if return_masks:
            masks[sl] = np.asarray(hit, dtype=bool).reshape(-1, size, size)
    _score_clipped(renderer, holes, quats, trans, pose_hole, (row0, col0, size), beta, prot)
    scores = PoseScores(beta=beta, protrusion=prot)
    if return_masks:
        return scores, (row0, col0, size, masks)
    return scores


def _score_clipped(renderer, holes, quats, trans, pose_hole, window, beta, prot) -> None:
    """Poses whose projection leaves their (capped) window: never a fit.

    Their protrusion is at least the hole's outside distance at the corners of the projection's
    bounding box and their β at least one pixel's worth; ``beta`` and ``prot`` (K,) are updated
    in place. ``window`` is :func:`window_for`'s (row0, col0, size).
    """
    row0, col0, size = window
    frame = holes[0].frame
    lo, hi = renderer.projected_extent(quats, trans)
    h = frame.pixel_size
    x0 = -frame.half_extent + (col0 + 0.5) * h
    y0 = frame.half_extent - (row0 + 0.5) * h
    clipped = (
        (lo[:, 0] < x0 - h)
        | (hi[:, 0] > x0 + (size - 1) * h + h)
        | (hi[:, 1] > y0 + h)
        | (lo[:, 1] < y0 - (size - 1) * h - h)
    )
    for k in np.flatnonzero(clipped):
        corners = np.array(
            [[lo[k, 0], lo[k, 1]], [lo[k, 0], hi[k, 1]], [hi[k, 0], lo[k, 1]], [hi[k, 0], hi[k, 1]]]
        )
        prot[k] = max(prot[k], float(holes[pose_hole[k]].outside_distance(corners).max()))
        beta[k] = max(beta[k], 1.0 / (size * size))


def mask_window(
    renderer: SilhouetteRenderer, hole: Hole, quat: np.ndarray, trans: np.ndarray
) -> MaskWindow:
    """One pose's silhouette on the lattice window of :func:`score_poses` around it.

    Parameters
    ----------
    renderer : SilhouetteRenderer
    hole : Hole
        Its frame fixes the lattice.
    quat : (4,) ndarray
    trans : (2,) ndarray
        Scene units.
    """
    _, (row0, col0, size, masks) = score_poses(
        renderer, hole, np.atleast_2d(quat), np.atleast_2d(trans), return_masks=True
    )
    x, y = hole.frame.window_centres(row0, col0, size)
    half = hole.frame.pixel_size / 2
    extent = (x[0, 0] - half, x[0, -1] + half, y[0, -1] - half, y[0, 0] + half)
    return MaskWindow(tuple(float(e) for e in extent), masks[0])
