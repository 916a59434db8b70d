"""Congruent raster holes: two holes on one frame that are the same up to a motion of the plane.

A hole H2 is *congruent* to H1 when a rigid motion of the plane T (a rotation about the origin by
``angle``, after a mirror y -> -y where ``mirror``, then a shift) takes H1 onto H2 within the
raster's own precision. Both holes are compared through their *signed distance* in pixels,
``d = outside - 1/2`` outside and ``-(inside - 1/2)`` inside (the Euclidean distances to the nearest
pixel centre of the other kind), whose zero level runs half way between a hole's border pixels
and its neighbours; read bilinearly, ``d(T^-1 x) < 0`` is H1 moved by T, drawn at H2's pixels.

The test (:func:`congruent`) asks two things of a motion, both ways round (H1 moved onto H2's
pixels and H2 moved back onto H1's):

* **area**: the pixels where the moved hole and the other disagree are at most
  :data:`FRACTION` times the hole's border length in pixels (the symmetric difference is at most
  ``FRACTION`` of a pixel's area per pixel of perimeter: the outlines are on average within
  ``FRACTION`` of a pixel of each other);
* **everywhere**: at every pixel centre within a pixel of one outline, the two signed
  distances differ by at most :data:`LOCAL` pixels (no notch, slot or island of more than about
  that size in one hole and not in the other, however small its area).

Two rasters of one outline drawn in different positions disagree by their quantisation alone: a
hole's border is drawn twice to the pixel (the silhouette at pixel centres, then its dilation),
so it may sit up to a pixel or so differently along a whole edge. Measured on 256-pixel holes
(2026-12-04): a 20 mm cube's face view turned in the plane against itself unturned disagrees by
0.23-0.51 of a pixel per pixel of border and at most 1.15 pixels anywhere; a ball's views by
0.11-0.19 and 1.0. Hence 0.6 and 1.5: the same outline passes, while a cube tilted by 3° (its
square 1 mm, 7 pixels, wider one way) does not; a tilt of 0.5° (0.17 mm, 1.2 pixels: 0.52) does,
about what the raster resolves. Being congruent only decides where player B's attack
*starts* (:mod:`sieve_mi.game.reuse`); the β of every hole is still measured on that hole.

The motion is found from the holes' centroids (the shift) and a search over the angle (both
mirror senses) on the holes' angular profiles, refined on border points; the identity is tried
first (a ball's holes are the same in every view).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from sieve_mi.geometry.hole import Hole, bounding_box

__all__ = ["FRACTION", "LOCAL", "Motion", "Outline", "areas_plausible", "congruent"]

#: Symmetric difference allowed after alignment, in pixels per pixel of border length.
FRACTION = 0.6
#: Largest difference of the two signed distances at any border pixel, pixels.
LOCAL = 1.5
#: Border points used by the angle's refinement (a deterministic subset; the test uses all).
_SEARCH_POINTS = 256
#: Directions of :attr:`Outline.profile` (one a degree).
_BINS = 360


@dataclass(frozen=True)
class Motion:
    """A rigid motion of the plane, ``x -> R(angle) M x + shift`` (M: y -> -y where ``mirror``).

    Attributes
    ----------
    angle : float
        Radians, counter-clockwise (+x towards +y, y up).
    mirror : bool
    shift : (2,) ndarray
        Scene units.
    """

    angle: float
    mirror: bool
    shift: np.ndarray

    def points(self, xy: np.ndarray) -> np.ndarray:
        """The motion of points ``xy`` (..., 2), scene units."""
        xy = np.asarray(xy, dtype=np.float64)
        if self.mirror:
            xy = xy * np.array([1.0, -1.0])
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.stack([c * xy[..., 0] - s * xy[..., 1], s * xy[..., 0] + c * xy[..., 1]], -1) + (
            self.shift
        )

    def inverse_points(self, xy: np.ndarray) -> np.ndarray:
        """The inverse motion of points ``xy`` (..., 2)."""
        xy = np.asarray(xy, dtype=np.float64) - self.shift
        c, s = np.cos(self.angle), np.sin(self.angle)
        back = np.stack([c * xy[..., 0] + s * xy[..., 1], -s * xy[..., 0] + c * xy[..., 1]], -1)
        return back * np.array([1.0, -1.0]) if self.mirror else back

    def poses(self, quats: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Poses of a shape moved with the plane: its silhouette at the new pose is the old one
        moved by this motion.

        A pose is a rotation ``q`` about the shape's centre and a translation ``t`` in the plane;
        its silhouette is the projection along z. Turning the shape by ``angle`` about z turns its
        projection; turning it half a turn about x mirrors the projection in y.

        Parameters
        ----------
        quats : (K, 4) ndarray
            (w, x, y, z).
        trans : (K, 2) ndarray
            Scene units.

        Returns
        -------
        quats : (K, 4) ndarray
        trans : (K, 2) ndarray
        """
        from sieve_mi.geometry.rotations import normalize, quat_multiply

        q = np.atleast_2d(np.asarray(quats, dtype=np.float64))
        if self.mirror:
            q = quat_multiply(np.array([0.0, 1.0, 0.0, 0.0]), q)
        half = 0.5 * self.angle
        q = quat_multiply(np.array([np.cos(half), 0.0, 0.0, np.sin(half)]), q)
        return normalize(q), self.points(np.atleast_2d(trans))


@dataclass
class Outline:
    """What the congruence test needs of one hole, computed once.

    Attributes
    ----------
    hole : Hole
    area : int
        Pixels of the hole.
    centroid : (2,) ndarray
        Scene units.
    border : int
        Border length in pixels: the hole's pixels with a 4-neighbour outside it.
    radial : (R,) ndarray
        Pixels of the hole within each whole number of pixels of the centroid (cumulative); the
        same for congruent holes up to the quantisation, whatever the motion.
    profile : (360,) ndarray
        The hole's second moment about the centroid (pixels^4) in each degree of direction,
        counter-clockwise from +x: turning the hole turns it, mirroring reverses it.
    """

    hole: Hole
    area: int = 0
    centroid: np.ndarray = field(default_factory=lambda: np.zeros(2))
    border: int = 0
    radial: np.ndarray = field(default_factory=lambda: np.zeros(0))
    profile: np.ndarray = field(default_factory=lambda: np.zeros(_BINS))
    _signed: np.ndarray | None = None
    _band: np.ndarray | None = None
    _near: tuple | None = None

    @classmethod
    def of(cls, hole: Hole) -> Outline:
        """The outline of ``hole``."""
        mask = hole.mask
        out = cls(hole, int(mask.sum()))
        if out.area == 0:
            return out
        x, y = hole.frame.centres()
        rows, cols = np.nonzero(mask)
        out.centroid = np.array([x[cols].mean(), y[rows].mean()])
        box = bounding_box(mask)  # an erosion there is the whole frame's (its ring is empty)
        inner = mask[box] & ~ndimage.binary_erosion(mask[box], border_value=0)
        out.border = int(inner.sum())
        r = np.hypot(x[cols] - out.centroid[0], y[rows] - out.centroid[1]) / hole.frame.pixel_size
        out.radial = np.cumsum(np.bincount(r.astype(np.int64)))
        phi = np.arctan2(y[rows] - out.centroid[1], x[cols] - out.centroid[0])
        k = np.floor(np.degrees(phi) % 360.0 * _BINS / 360.0).astype(np.int64) % _BINS
        out.profile = np.bincount(k, weights=r**2, minlength=_BINS)
        return out

    @property
    def signed(self) -> np.ndarray:
        """(N, N) signed distance in pixels (negative inside), zero half way across the border."""
        if self._signed is None:
            mask, h = self.hole.mask, self.hole.frame.pixel_size
            inside, box = np.zeros(mask.shape), bounding_box(mask)
            if box is not None:  # the box's ring is outside the hole: the whole frame's values
                inside[box] = ndimage.distance_transform_edt(mask[box])
            outside = self.hole.outside / h
            self._signed = np.where(mask, 0.5 - inside, outside - 0.5).astype(np.float32)
        return self._signed

    @property
    def band(self) -> np.ndarray:
        """(P, 2) pixel centres (scene units) within a pixel of the outline, row by row."""
        if self._band is None:
            x, y = self.hole.frame.centres()
            rows, cols = np.nonzero(np.abs(self.signed) <= 1.0)
            self._band = np.column_stack([x[cols], y[rows]])
        return self._band

    @property
    def near(self) -> tuple[np.ndarray, np.ndarray]:
        """Pixel centres (P, 2) within :data:`LOCAL` + 1 pixels of the outline and whether each
        is in the hole (P,): beyond them two holes whose outlines are within :data:`LOCAL` of
        each other agree."""
        if self._near is None:
            x, y = self.hole.frame.centres()
            rows, cols = np.nonzero(np.abs(self.signed) <= LOCAL + 1.0)
            self._near = np.column_stack([x[cols], y[rows]]), self.hole.mask[rows, cols]
        return self._near

    def at(self, xy: np.ndarray) -> np.ndarray:
        """:attr:`signed` read bilinearly at points ``xy`` (..., 2), scene units (clamped to
        the frame)."""
        d, n = self.signed, self.hole.frame.resolution
        uv = np.clip(self.hole.frame.to_pixel(xy), 0, n - 1)
        i0 = np.minimum(np.floor(uv).astype(np.int64), n - 2)
        f = uv - i0
        c, r = i0[..., 0], i0[..., 1]
        return (
            d[r, c] * (1 - f[..., 0]) * (1 - f[..., 1])
            + d[r, c + 1] * f[..., 0] * (1 - f[..., 1])
            + d[r + 1, c] * (1 - f[..., 0]) * f[..., 1]
            + d[r + 1, c + 1] * f[..., 0] * f[..., 1]
        )


def areas_plausible(area, border, b: Outline) -> np.ndarray:
    """The first of :func:`congruent`'s necessary conditions for many outlines at once (their
    ``area`` and ``border``, arrays, pixels) against ``b``: areas within the area tolerance
    (twice it, since both are quantised). A class of :mod:`sieve_mi.game.reuse` whose reference
    fails it is not tried."""
    tol = FRACTION * np.maximum(border, b.border) + 4
    return np.abs(np.asarray(area) - b.area) <= tol


def _plausible(a: Outline, b: Outline) -> bool:
    """Necessary conditions, cheap: areas (:func:`areas_plausible`) and radial profiles within
    the area tolerance."""
    tol = FRACTION * max(a.border, b.border) + 4
    if not areas_plausible(a.area, a.border, b):
        return False
    n = max(len(a.radial), len(b.radial))
    ra = np.pad(a.radial, (0, n - len(a.radial)), mode="edge")
    rb = np.pad(b.radial, (0, n - len(b.radial)), mode="edge")
    return bool(np.abs(ra - rb).max() <= tol)


def _coarse_angles(a: Outline, b: Outline, mirror: bool) -> tuple[np.ndarray, np.ndarray]:
    """Each whole degree's mismatch of the two :attr:`Outline.profile` (``a`` turned by it, after
    the mirror, against ``b``): sum of squared differences, by FFT; (angles in radians, costs)."""
    pa = a.profile[(-np.arange(_BINS)) % _BINS] if mirror else a.profile
    corr = np.fft.irfft(np.fft.rfft(pb := b.profile) * np.conj(np.fft.rfft(pa)), _BINS)
    cost = (pa**2).sum() + (pb**2).sum() - 2 * corr  # cost[s]: a's bin k on b's bin k + s
    return np.radians(np.arange(_BINS) * 360.0 / _BINS), cost


def _motion(a: Outline, b: Outline, angle: float, mirror: bool) -> Motion:
    """The motion that turns ``a`` by ``angle`` (after the mirror) and puts its centroid on ``b``'s."""
    turn = Motion(angle, mirror, np.zeros(2))
    return Motion(angle, mirror, b.centroid - turn.points(a.centroid))


def _mismatch(a: Outline, b: Outline, points: np.ndarray, angles, mirror: bool) -> np.ndarray:
    """Mean |d_b(T p) - d_a(p)| over ``points`` of ``a``, for each angle (A,); one bilinear
    read of ``b`` for all the angles."""
    da = a.at(points)
    moved = np.stack([_motion(a, b, angle, mirror).points(points) for angle in angles])
    return np.abs(b.at(moved) - da).mean(axis=-1)


def _fits(a: Outline, b: Outline, motion: Motion) -> bool:
    """Whether ``motion`` takes ``a`` onto ``b`` within :data:`LOCAL` and :data:`FRACTION`,
    checked both ways.

    The outlines first: at every border pixel of either the two signed distances agree within
    :data:`LOCAL`, so the holes can only disagree within :data:`LOCAL` of an outline; there,
    the pixels where the moved hole and the other differ are counted (:attr:`Outline.near`).
    """
    pa, pb = a.band, b.band
    if np.abs(b.at(motion.points(pa)) - a.at(pa)).max(initial=0.0) > LOCAL:
        return False
    if np.abs(a.at(motion.inverse_points(pb)) - b.at(pb)).max(initial=0.0) > LOCAL:
        return False
    limit = FRACTION * max(a.border, b.border)
    xb, inside_b = b.near
    if np.count_nonzero((a.at(motion.inverse_points(xb)) < 0) != inside_b) > limit:
        return False  # a moved, on b's pixels
    xa, inside_a = a.near
    return bool(np.count_nonzero((b.at(motion.points(xa)) < 0) != inside_a) <= limit)


def congruent(a: Outline, b: Outline) -> Motion | None:
    """A motion taking hole ``a`` onto hole ``b`` within the raster's precision, or None.

    Tried in order: the identity up to the centroids' shift, then the four angles (both mirror
    senses) whose :attr:`Outline.profile` match best at whole degrees, each refined to 0.01° on
    up to :data:`_SEARCH_POINTS` border points of ``a``; the first that passes the test (module
    docstring) is returned. An angle whose mean border mismatch is already beyond what the test
    allows anywhere (:data:`LOCAL`, plus half a degree's turn before refining) is dropped.
    Deterministic. Empty holes are congruent to each other only.
    """
    if a.hole.frame != b.hole.frame:
        return None
    if a.area == 0 or b.area == 0:
        return Motion(0.0, False, np.zeros(2)) if a.area == b.area == 0 else None
    if not _plausible(a, b):
        return None
    first = _motion(a, b, 0.0, False)
    if _fits(a, b, first):
        return first
    pts = a.band[:: max(1, len(a.band) // _SEARCH_POINTS)]
    tries = []
    for mirror in (False, True):
        coarse, err = _coarse_angles(a, b, mirror)
        local = (err <= np.roll(err, 1)) & (err <= np.roll(err, -1))
        for k in np.flatnonzero(local):
            tries.append((err[k], coarse[k], mirror))
    # within half a degree of a congruent angle, a border point moves by at most reach / 115 px
    slack = LOCAL + len(a.radial) * np.radians(0.5)
    for _, angle, mirror in sorted(tries, key=lambda t: (t[0], t[1], t[2]))[:4]:
        if _mismatch(a, b, pts, [angle], mirror)[0] > slack:
            continue
        step = np.radians(0.5)
        while step > np.radians(0.01):  # compass search on the angle
            near = np.array([angle - step, angle, angle + step])
            err = _mismatch(a, b, pts, near, mirror)
            angle = float(near[int(np.argmin(err))])
            step /= 2
        if err.min() > LOCAL:  # the mean over border points exceeds the test's largest allowed
            continue
        motion = _motion(a, b, angle, mirror)
        if _fits(a, b, motion):
            return motion
    return None
