"""The sieve hole H as a raster, and how shapes compare with it.

H is built from player A's silhouette(s): dilated by the fabrication tolerance and with its holes
filled (paper Sec. 5.4). Because proj(A + ball_r) = proj(A) + disk_r, the dilation is done exactly
in 2D with a Euclidean distance transform rather than the paper's 3D signed distance and marching
cubes. Alongside the mask, a hole keeps its *outside distance*: for every pixel centre, the
distance (scene units) to the nearest pixel centre of H, zero inside. It drives the clearance loss
and measures protrusions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from sieve_mi.backend import aligned
from sieve_mi.geometry.raster import Frame, crop_window

__all__ = [
    "Hole",
    "HoleStack",
    "bounding_box",
    "build_hole",
    "dilate",
    "fill_gaps",
    "pieces",
    "split_pieces",
]


@dataclass
class Hole:
    """A sieve hole on a raster frame.

    Attributes
    ----------
    frame : Frame
    mask : (N, N) ndarray of bool
        True on pixel centres inside H.
    outside : (N, N) ndarray of float32
        Distance from each pixel centre to the nearest pixel centre of H, scene units (0 inside).
    """

    frame: Frame
    mask: np.ndarray
    outside: np.ndarray

    @property
    def area(self) -> float:
        """Area of H in square scene units (pixel count times pixel area)."""
        return float(self.mask.sum()) * self.frame.pixel_size**2

    @classmethod
    def from_mask(cls, mask: np.ndarray, frame: Frame) -> Hole:
        """Wrap a binary mask (N x N) as a hole, computing its outside distance."""
        mask = np.asarray(mask, dtype=bool)
        if not mask.any():
            outside = np.full(mask.shape, np.float32(frame.half_extent * 4), dtype=np.float32)
        else:
            outside = (ndimage.distance_transform_edt(~mask) * frame.pixel_size).astype(np.float32)
        return cls(frame=frame, mask=mask, outside=outside)

    @classmethod
    def from_outline(cls, section, frame: Frame) -> Hole:
        """The raster of an exact outline H (a manifold3d CrossSection) on ``frame``.

        ``outside`` is the distance from each pixel centre to H itself (not to other pixel
        centres), zero at centres inside H, so losses see sub-pixel detail; ``mask`` is
        conservative: every pixel whose centre lies within half a pixel diagonal of H, so no
        part of H (a slot thinner than a pixel) disappears from the raster.
        """
        from sieve_mi.geometry.outline import Boundary

        n, h = frame.resolution, frame.pixel_size
        boundary = Boundary(section, spacing=h / 16)
        if len(boundary.a) == 0:
            return cls.from_mask(np.zeros((n, n), dtype=bool), frame)
        x, y = frame.centres()
        xx, yy = np.meshgrid(x, y)
        pts = np.column_stack([xx.ravel(), yy.ravel()])
        inside = boundary.inside(pts).reshape(n, n)
        if inside.any() and not inside.all():
            # Distance transforms are within a pixel of the truth; within two pixels of the
            # outline (where it matters) the distances are measured to the outline itself.
            d_out = ndimage.distance_transform_edt(~inside) * h
            d_in = ndimage.distance_transform_edt(inside) * h
            signed = np.where(inside, -d_in, d_out)
            band = np.abs(signed) <= 2 * h
        else:  # H thinner than a pixel, or covering the frame: measure everywhere
            signed = np.zeros((n, n))
            band = np.ones((n, n), dtype=bool)
        near = boundary.approx_distance(pts[band.ravel()])
        signed[band] = np.where(inside[band], -near, near)
        mask = signed <= h * np.sqrt(0.5)
        outside = np.maximum(signed, 0.0).astype(np.float32)
        return cls(frame=frame, mask=mask, outside=outside)

    def outside_distance(self, xy: np.ndarray) -> np.ndarray:
        """Distance from points ``xy`` (..., 2) to H, scene units, by bilinear lookup.

        Points beyond the frame get the distance at the nearest frame point plus the distance to it,
        which keeps the value growing (and the gradient pointing back) far from the hole.
        """
        n = self.frame.resolution
        uv = self.frame.to_pixel(xy)
        c = np.clip(uv, 0, n - 1)
        extra = np.linalg.norm(uv - c, axis=-1) * self.frame.pixel_size
        i0 = np.clip(np.floor(c).astype(int), 0, n - 2)
        f = c - i0
        d = self.outside
        v = (
            d[i0[..., 1], i0[..., 0]] * (1 - f[..., 0]) * (1 - f[..., 1])
            + d[i0[..., 1], i0[..., 0] + 1] * f[..., 0] * (1 - f[..., 1])
            + d[i0[..., 1] + 1, i0[..., 0]] * (1 - f[..., 0]) * f[..., 1]
            + d[i0[..., 1] + 1, i0[..., 0] + 1] * f[..., 0] * f[..., 1]
        )
        return v + extra

    def window(self, row0: int, col0: int, size: int) -> tuple[np.ndarray, np.ndarray]:
        """The hole's mask and outside distance over a lattice window (padded beyond the frame).

        Beyond the frame the mask is False and the outside distance is extended by the distance to
        the frame's nearest pixel, as in :meth:`outside_distance`.
        """
        mask = crop_window(self.mask, row0, col0, size, fill=False)
        x, y = self.frame.window_centres(np.array([row0]), np.array([col0]), size)
        xx, yy = np.meshgrid(x[0], y[0])
        dist = self.outside_distance(np.stack([xx, yy], -1)).astype(np.float32)
        dist[mask] = 0.0
        return mask, dist


class HoleStack:
    """Several holes on one frame as one flat Dr.Jit texture of outside distances, in pixels.

    The texture holds hole ``k``'s pixel (row, col) at ``k N^2 + row N + col``; :meth:`gather` is
    the one place that knows it. Losses and scores on the Dr.Jit side read holes only through it.

    Parameters
    ----------
    holes : list of Hole
        All on the same frame.
    corners : bool, optional
        Also build :attr:`corners` (4 times the memory of :attr:`texture`), for the clearance
        loss' bilinear reads. True by default.

    Attributes
    ----------
    frame : Frame
    count : int
        Number of holes.
    texture : mi.Float
        ``count * N^2`` outside distances in pixels (0 inside a hole).
    corners : mi.Float or None
        ``4 count N^2`` entries: for every pixel, its own outside distance and those of its
        right, lower and lower-right neighbours (the last row and column repeat themselves), so
        that :meth:`gather_corners` reads them as one packet. None when built with
        ``corners=False`` (scores read single pixels only).
    """

    #: The Dr.Jit arrays a frozen function (:func:`drjit.freeze`) must see as its inputs.
    DRJIT_STRUCT = {"texture": object, "corners": object}

    def __init__(self, holes: list[Hole], corners: bool = True):
        import mitsuba as mi

        frame = holes[0].frame
        if any(h.frame != frame for h in holes):
            raise ValueError("all holes of a stack must share one frame")
        self.frame = frame
        self.count = len(holes)
        stack = np.stack([h.outside for h in holes]) / frame.pixel_size
        self.texture = mi.Float(aligned(stack.ravel(), np.float32))
        self.corners = self._corner_table() if corners else None

    def _corner_table(self):
        """:attr:`corners`, built on the device from :attr:`texture` (one kernel)."""
        import drjit as dr
        import mitsuba as mi

        n = self.frame.resolution
        i = dr.arange(mi.UInt32, self.count * n * n * 4)
        texel, corner = i >> 2, i & 3
        col, row = texel % n, (texel // n) % n
        right = dr.select(((corner & 1) != 0) & (col < n - 1), 1, 0)
        below = dr.select(((corner & 2) != 0) & (row < n - 1), n, 0)
        table = dr.gather(mi.Float, self.texture, texel + right + below)
        dr.eval(table)
        return table

    def gather_corners(self, hole, row, col):
        """The outside distances (pixels) at the four pixels (row, col), (row, col + 1),
        (row + 1, col) and (row + 1, col + 1) of hole ``hole``, in that order.

        What bilinear interpolation needs, read as one packet (:attr:`corners`) instead of
        four gathers; the values are :meth:`gather`'s, bit for bit.

        Parameters
        ----------
        hole, row, col : mi.UInt32
            Hole index and pixel indices, ``row`` and ``col`` at most N - 2.

        Returns
        -------
        mi.Vector4f
        """
        import drjit as dr
        import mitsuba as mi

        n = self.frame.resolution
        return dr.gather(mi.Vector4f, self.corners, hole * (n * n) + row * n + col)

    def gather(self, hole, row, col, active=True):
        """Outside distance in pixels at pixel (row, col) of hole ``hole``.

        Parameters
        ----------
        hole, row, col : mi.UInt32
            Hole index and pixel indices, each in range (no clamping here).
        active : mi.Bool or bool
            Lanes to read; inactive lanes give 0.

        Returns
        -------
        mi.Float
        """
        import drjit as dr
        import mitsuba as mi

        n = self.frame.resolution
        return dr.gather(mi.Float, self.texture, hole * (n * n) + row * n + col, active)


def bounding_box(mask: np.ndarray, grow: int = 1) -> tuple[slice, slice] | None:
    """The rows and columns of a mask's pixels, each way grown by ``grow`` pixels and cut to
    the frame; None for an empty mask.

    A raster operation whose answer on the box equals the whole frame's runs on the box alone
    (:func:`dilate`, :func:`fill_gaps`, :attr:`sieve_mi.geometry.congruence.Outline.signed`).

    Examples
    --------
    >>> m = np.zeros((6, 6), dtype=bool); m[2, 4] = True
    >>> bounding_box(m)
    (slice(1, 4, None), slice(3, 6, None))
    """
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    if not len(rows):
        return None
    r0, r1, c0, c1 = (int(v) for v in (rows[0], rows[-1], cols[0], cols[-1]))
    return (slice(max(r0 - grow, 0), min(r1 + grow + 1, mask.shape[0])),
            slice(max(c0 - grow, 0), min(c1 + grow + 1, mask.shape[1])))  # fmt: skip


def dilate(mask: np.ndarray, frame: Frame, tolerance: float) -> np.ndarray:
    """Pixel centres within ``tolerance`` of the mask, rounded to the nearest half pixel.

    On average the raster dilation then equals the tolerance instead of falling short of it.
    The distance transform runs on the mask's bounding box grown by the radius only: every
    centre within reach lies there, and its nearest mask pixel too, so the result is the
    whole frame's transform, thresholded.
    """
    if tolerance <= 0 or not mask.any():
        return np.asarray(mask, dtype=bool)
    reach = tolerance + 0.5 * frame.pixel_size
    box = bounding_box(mask, int(np.ceil(reach / frame.pixel_size)) + 1)
    out = np.zeros(mask.shape, dtype=bool)
    crop = ~np.asarray(mask[box], dtype=bool)
    out[box] = ndimage.distance_transform_edt(crop) * frame.pixel_size <= reach
    return out


def fill_gaps(mask: np.ndarray) -> np.ndarray:
    """The mask with every gap it encloses filled: ``scipy.ndimage.binary_fill_holes``'s result.

    A pixel outside the mask stays empty iff a 4-connected path of such pixels joins it to the
    frame's border; one labelling of the complement finds them all at once (scipy's filling
    grows the border region a pixel a pass instead). The labelling runs on the mask's bounding
    box grown by a pixel: every pixel of that ring is empty and joined to the frame's border
    straight across the rest of the frame, and a path out of the box crosses its edge, so the
    box's edge stands for the frame's border (the same result on a fraction of the pixels).
    """
    mask = np.asarray(mask, dtype=bool)
    out = np.zeros(mask.shape, dtype=bool)
    box = bounding_box(mask)
    if box is None:
        return out
    labels, _ = ndimage.label(~mask[box])  # the default structure: 4-connected
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    out[box] = ~np.isin(labels, border[border > 0])
    return out


def build_hole(
    silhouettes: list[np.ndarray],
    frame: Frame,
    tolerance: float,
    fill_holes: bool = True,
    extra: list[np.ndarray] | None = None,
) -> Hole:
    """H from player A's silhouettes: their union, dilated by ``tolerance``, holes filled.

    Parameters
    ----------
    silhouettes : list of (N, N) bool ndarrays
        A's silhouettes (already placed) on ``frame``.
    frame : Frame
    tolerance : float
        Dilation radius in scene units (printer clearance); 0 for none.
    fill_holes : bool
        Fill enclosed gaps so H is simply connected (paper Fig. 4).
    extra : list of (N, N) bool ndarrays, optional
        Already dilated parts (other shapes' holes) to join before filling.
    """
    union = np.zeros((frame.resolution, frame.resolution), dtype=bool)
    for s in silhouettes:
        union |= s
    union = dilate(union, frame, tolerance)
    for e in extra or []:
        union |= e
    if fill_holes:
        union = fill_gaps(union)
    return Hole.from_mask(union, frame)


def pieces(mask: np.ndarray) -> int:
    """Number of 8-connected pieces of a mask (N, N) bool."""
    return int(ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))[1])


def split_pieces(mask: np.ndarray) -> list[np.ndarray]:
    """The 8-connected pieces of a mask, each as its own (N, N) bool mask, largest first."""
    labels, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    return [labels == (k + 1) for k in np.argsort(-sizes, kind="stable")]
