"""The raster frames of the game's holes, and the separate layout's row of holes.

One A's hole is drawn on a frame that covers its dilated silhouette at every rotation
(:func:`hole_frame`). Several A in one hole get a frame that holds any placement the search may
choose (:func:`union_frame`) or, once placed, the smallest centred frame that holds them
(:func:`frame_for`). ``layout.mode = "separate"`` puts each A's hole in a row, the trivially valid
answer of paper Sec. 5.3 (:func:`separate_layout`).
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame

__all__ = ["frame_for", "hole_frame", "separate_layout", "union_frame"]


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
