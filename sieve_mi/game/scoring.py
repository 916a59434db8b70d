"""Scoring poses with binary masks: the normalised outside area beta (paper eq. 12) and the
protrusion, the largest distance by which a pose's silhouette sticks out of the hole.

Every pose is rasterised in a window of the hole's pixel lattice that covers its projection's
bounding box, so parts of the shape outside the hole's frame are counted too. Rays and hole
lookups run in one Dr.Jit kernel for all poses, the per-pose sums in one more.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from sieve_mi.certify.bounds import inscribed_ball
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.silhouettes import SilhouetteRenderer

__all__ = [
    "CORE_MIN_RATIO",
    "MaskWindow",
    "core_ball",
    "PoseScores",
    "mask_window",
    "projection_windows",
    "score_poses",
    "window_for",
    "with_core",
]

#: A shape's certified inscribed ball becomes its renderer's core (no rays in the ball's shadow:
#: :attr:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.core`) when its radius is at least this
#: fraction of the shape's radius; a smaller ball's shadow saves fewer rays than its test costs.
CORE_MIN_RATIO = 0.5
#: Inscribed balls already found, by shape: ``id(shape) -> (weak reference to it, ball or None)``
#: (weak: the cache never keeps a mesh alive).
_CORES: dict = {}


def core_ball(shape: Shape) -> tuple[np.ndarray, float] | None:
    """The ball (centre (3,), radius, scene units) that :func:`with_core` gives the shape's renderer,
    or None: the certified inscribed ball (:func:`~sieve_mi.certify.bounds.inscribed_ball`, closed
    meshes only) where its radius is at least :data:`CORE_MIN_RATIO` times the shape's.

    Examples
    --------
    A 24 mm icosphere holds a ball of radius 11.95 mm; a letter's (radius 21 mm) is 2.3 mm thick:
    the sphere gets a core, the letter none.
    """
    known = _CORES.get(id(shape))
    if known is not None and known[0]() is shape:
        return known[1]
    ball = inscribed_ball(shape)
    if ball is not None and ball[1] < CORE_MIN_RATIO * shape.radius:
        ball = None
    for key in [k for k, (ref, _) in _CORES.items() if ref() is None]:
        del _CORES[key]  # shapes gone since
    _CORES[id(shape)] = (weakref.ref(shape), ball)
    return ball


def with_core(renderer: SilhouetteRenderer) -> SilhouetteRenderer:
    """``renderer`` with its core set to :func:`core_ball` of its shape: the same silhouettes
    (a ray through the ball's shadow enters the ball, inside the solid, so it hits), with no ray
    cast where the shadow is; returns the renderer."""
    renderer.core = core_ball(renderer.shape)
    return renderer


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
    """Square lattice windows covering each pose's bounding disk: (row0, col0, size).

    The window side is capped at twice the frame plus a margin; a capped window is centred on the
    pose (a projection larger than it cannot fit anyway, see :func:`score_poses`). These are the
    windows of the masks that figures show (:func:`mask_window`); scores use the smaller
    :func:`projection_windows`.
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


def projection_windows(frame: Frame, lo: np.ndarray, hi: np.ndarray):
    """Lattice windows covering each pose's projected bounding box, one pixel beyond it.

    Every pixel centre a pose's silhouette covers lies in its projection's bounding box, so these
    windows see the same covered pixels as :func:`window_for`'s bounding-disk squares; a flat or
    long shape needs far fewer rays (a letter seen edge-on: a tenth).

    Parameters
    ----------
    frame : Frame
    lo, hi : (K, 2) ndarrays
        Each projection's lower and upper (x, y) corners, scene units
        (:meth:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.projected_extent`).

    Returns
    -------
    row0, col0, rows, cols : (K,) ndarrays of int
        Top-left lattice pixel and size of each window; a side is capped at twice the frame
        plus a margin, centred on the box (a projection larger than that cannot fit anyway).
    """
    cap = 2 * frame.resolution + 3
    top_left = np.floor(frame.to_pixel(np.column_stack([lo[:, 0], hi[:, 1]]))).astype(np.int64) - 1
    bottom_right = np.ceil(frame.to_pixel(np.column_stack([hi[:, 0], lo[:, 1]]))).astype(np.int64)
    bottom_right += 1
    size = bottom_right - top_left + 1  # (columns, rows)
    start = np.where(size > cap, (top_left + bottom_right + 1) // 2 - cap // 2, top_left)
    size = np.minimum(size, cap)
    return start[:, 1], start[:, 0], size[:, 1], size[:, 0]


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
        Also return the windows and masks (for figures); the windows are then
        :func:`window_for`'s squares, else :func:`projection_windows` (same scores, fewer rays).
    chunk_rays : int
        Rays traced by one kernel at most (poses are split between kernels, never within one).

    Returns
    -------
    PoseScores, and if asked (row0, col0, size, masks) with masks (K, size, size) bool
    """
    from sieve_mi.geometry.hole import HoleStack

    holes = [holes] if isinstance(holes, Hole) else list(holes)
    frame = holes[0].frame
    quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
    k_total = len(quats)
    pose_hole = np.zeros(k_total, int) if pose_hole is None else np.asarray(pose_hole)
    stack = HoleStack(holes, corners=False)
    lo, hi = renderer.projected_extent(quats, trans)
    if return_masks:
        row0, col0, size = window_for(renderer, frame, trans)
        rows = cols = np.full(k_total, size, dtype=np.int64)
    else:
        row0, col0, rows, cols = projection_windows(frame, lo, hi)
    beta, prot = np.ones(k_total), np.zeros(k_total)
    masks = np.zeros((k_total, size, size), dtype=bool) if return_masks else None
    for sl in _ray_chunks(rows * cols, chunk_rays):
        window = (row0[sl], col0[sl], rows[sl], cols[sl])
        if return_masks:
            covered, area, outside, worst = _cast_and_count(
                renderer, stack, quats[sl], trans[sl], pose_hole[sl], window
            )
            # the evaluated 0/1 values: reading ``hit`` itself would cast the rays again
            masks[sl] = (np.asarray(covered) > 0).reshape(-1, size, size)
        else:
            area, outside, worst = _walk_and_count(
                renderer, stack, quats[sl], trans[sl], pose_hole[sl], window
            )
        beta[sl] = np.where(area > 0, outside / np.maximum(area, 1), 1.0)
        prot[sl] = worst
    _score_clipped(holes, (lo, hi), pose_hole, (row0, col0, rows, cols), beta, prot)
    scores = PoseScores(beta=beta, protrusion=prot)
    if return_masks:
        return scores, (row0, col0, size, masks)
    return scores


def _cast_and_count(renderer, stack, quats, trans, pose_hole, window):
    """One kernel of rays over K poses' windows: the covered pixels (mi.Float, 1 or 0 per window
    pixel, evaluated), and per pose (K,) float64 their count, those outside the hole, and the
    largest distance of one outside (scene units)."""
    import drjit as dr
    import mitsuba as mi

    hit, pose, row, col = renderer.trace(quats, trans, stack.frame, *window)
    hole_of = dr.gather(mi.UInt32, mi.UInt32(pose_hole.astype(np.uint32)), pose)
    out, dist = _outside(stack, hole_of, row, col, hit)
    per_ray = (dr.select(hit, 1.0, 0.0), dr.select(out, 1.0, 0.0), dr.select(out, dist, 0.0))
    dr.eval(pose, *per_ray)  # one ray-casting kernel; unevaluated, each reduction would trace again
    sums = [dr.zeros(mi.Float, len(quats)) for _ in range(3)]
    for target, value, op in zip(sums, per_ray, (dr.ReduceOp.Add,) * 2 + (dr.ReduceOp.Max,)):
        dr.scatter_reduce(op, target, value, pose)  # sums of 1s: exact in any order
    return (per_ray[0], *(np.asarray(a, dtype=np.float64) for a in sums))


def _outside(stack, hole_of, row, col, hit):
    """Per pixel: whether it is covered and outside its hole (mi.Bool), and its distance to the
    hole (mi.Float, scene units): the hole's distance at the nearest frame pixel plus the way
    to it; ``hole_of`` (mi.UInt32) is each pixel's hole in ``stack``."""
    import drjit as dr
    import mitsuba as mi

    n = stack.frame.resolution
    rc, cc = dr.clip(row, 0, n - 1), dr.clip(col, 0, n - 1)
    d = stack.gather(hole_of, mi.UInt32(rc), mi.UInt32(cc))
    inside = (row == rc) & (col == cc) & (d == 0)
    dist = (
        d + dr.sqrt(mi.Float(dr.square(row - rc) + dr.square(col - cc)))
    ) * stack.frame.pixel_size
    return hit & ~inside, dist


def _walk_and_count(renderer, stack, quats, trans, pose_hole, window):
    """:func:`_cast_and_count`'s per-pose counts, from one thread per window row
    (:meth:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.walk_rows`): the same pixels and
    the same arithmetic per pixel, so the same counts (integers, and a maximum), with each pose's
    data gathered once per row instead of once per pixel. Returns (K,) float64 each."""
    import drjit as dr
    import mitsuba as mi

    frame = stack.frame

    def visit(hit, row, col, extra, acc):
        area, outside, worst = acc
        out, dist = _outside(stack, extra[0], row, col, hit)
        return [
            area + dr.select(hit, 1.0, 0.0),
            outside + dr.select(out, 1.0, 0.0),
            dr.maximum(worst, dr.select(out, dist, 0.0)),
        ]

    lanes = int(np.sum(window[2]))
    start = [dr.zeros(mi.Float, lanes) for _ in range(3)]
    hole_of = mi.UInt32(np.asarray(pose_hole).astype(np.uint32))
    acc, pose = renderer.walk_rows(quats, trans, frame, window, visit, start, extra=[hole_of])
    dr.eval(pose, *acc)
    sums = [dr.zeros(mi.Float, len(quats)) for _ in range(3)]
    for target, value, op in zip(sums, acc, (dr.ReduceOp.Add,) * 2 + (dr.ReduceOp.Max,)):
        dr.scatter_reduce(op, target, value, pose)  # sums of whole numbers: exact in any order
    return tuple(np.asarray(a, dtype=np.float64) for a in sums)


def _ray_chunks(pixels: np.ndarray, chunk_rays: int) -> list[slice]:
    """Consecutive ranges of poses of at most ``chunk_rays`` window pixels each (at least one
    pose per range); ``pixels`` (K,) are the windows' pixel counts."""
    bounds, total, start = [], 0, 0
    for i, p in enumerate(np.asarray(pixels, dtype=np.int64)):
        if i > start and total + p > chunk_rays:
            bounds.append(slice(start, i))
            start, total = i, 0
        total += int(p)
    bounds.append(slice(start, len(pixels)))
    return bounds


def _score_clipped(holes, extent, pose_hole, window, beta, prot) -> None:
    """Poses whose projection leaves their (capped) window: never a fit.

    Their protrusion is at least the hole's outside distance at the corners of the projection's
    bounding box and their β at least one pixel's worth; ``beta`` and ``prot`` (K,) are updated
    in place. ``extent`` is the projections' (lo, hi) corners, ``window`` the windows'
    (row0, col0, rows, cols).
    """
    (lo, hi), (row0, col0, rows, cols) = extent, window
    frame = holes[0].frame
    h = frame.pixel_size
    x0 = -frame.half_extent + (col0 + 0.5) * h
    y0 = frame.half_extent - (row0 + 0.5) * h
    clipped = (
        (lo[:, 0] < x0 - h)
        | (hi[:, 0] > x0 + (cols - 1) * h + h)
        | (hi[:, 1] > y0 + h)
        | (lo[:, 1] < y0 - (rows - 1) * h - h)
    )
    for k in np.flatnonzero(clipped):
        corners = np.array(
            [[lo[k, 0], lo[k, 1]], [lo[k, 0], hi[k, 1]], [hi[k, 0], lo[k, 1]], [hi[k, 0], hi[k, 1]]]
        )
        prot[k] = max(prot[k], float(holes[pose_hole[k]].outside_distance(corners).max()))
        beta[k] = max(beta[k], 1.0 / (rows[k] * cols[k]))


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
