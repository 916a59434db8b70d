"""The replay's own geometry: exact tests that re-prove a certificate's evidence.

Written apart from the search (no manifold3d, nothing of :mod:`sieve_mi.certify.bounds` or
``search``), so that a certificate is checked by a second implementation
(:mod:`sieve_mi.certify.replay` walks the certificate and calls these):

* :class:`Hole`: H from the certificate's contours, with exact point-to-segment distances and
  even-odd point in polygon (matplotlib's ``Path``);
* rotations of a cell: :func:`quaternion`, :func:`rotation`, :func:`cell_angle` (the covering
  angle) and :func:`first_order_bounds` (each point's displacement over a cell by the chain rule
  through the normalised quaternion; docs/certify.md);
* exclusions by quadtree: :func:`no_translation` (no translation puts every point within its
  bound of H) and :func:`disk_never_fits` (no disk of a radius fits in H);
* a passage's exactness: :func:`segments_cross` and :func:`points_in_triangles`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "MAX_BOXES",
    "SAMPLE_SPACING",
    "Hole",
    "cell_angle",
    "disk_never_fits",
    "first_order_bounds",
    "no_translation",
    "points_in_triangles",
    "quaternion",
    "rotation",
    "segments_cross",
]

#: Most boxes a quadtree of :func:`no_translation` or :func:`disk_never_fits` may hold at once.
MAX_BOXES = 400_000
#: Boundary sample spacing of :meth:`Hole.beyond`, relative to the hole's size.
SAMPLE_SPACING = 2e-4


class Hole:
    """H from its contours: exact distance to the boundary and even-odd point in polygon."""

    def __init__(self, contours: list):
        from matplotlib.path import Path

        self.contours = [np.asarray(c, dtype=np.float64) for c in contours]
        self.paths = [Path(c) for c in self.contours]
        self.a = np.concatenate(self.contours)
        self.b = np.concatenate([np.roll(c, -1, axis=0) for c in self.contours])
        self.vertices = self.a
        self._tree = None

    def contains(self, p: np.ndarray) -> np.ndarray:
        count = np.zeros(len(p), dtype=np.int64)
        for path in self.paths:
            count += path.contains_points(p)
        return count % 2 == 1

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Distance from each point to the boundary, via complex arithmetic, (n,)."""
        za = self.a[:, 0] + 1j * self.a[:, 1]
        zd = (self.b[:, 0] + 1j * self.b[:, 1]) - za
        out = np.empty(len(p))
        for s in range(0, len(p), 1024):
            z = (p[s : s + 1024, 0] + 1j * p[s : s + 1024, 1])[:, None] - za[None]
            u = (z * np.conj(zd)).real / np.maximum(np.abs(zd) ** 2, 1e-300)
            out[s : s + 1024] = np.abs(z - np.clip(u, 0, 1) * zd).min(axis=1)
        return out

    def outside_by(self, p: np.ndarray) -> np.ndarray:
        """Distance from each point to H (0 inside), (n,)."""
        return np.where(self.contains(p), 0.0, self.distance(p))

    def beyond(self, p: np.ndarray, bound: np.ndarray) -> np.ndarray:
        """(n,) bool: each point lies outside H further than its ``bound`` (decided exactly).

        A k-d tree over boundary samples (spacing at most ``spacing``) settles most points: the
        distance to the nearest sample is at least the distance to the boundary and at most
        half a spacing more (every boundary point has a sample within half a spacing). Points
        it cannot settle get the exact distance.
        """
        if self._tree is None:
            self._sample()
        out = ~self.contains(p)
        near = self._tree.query(p[out])[0]
        lower = near - self._slack
        sure, unsure = lower > bound[out], (lower <= bound[out]) & (near > bound[out])
        idx = np.flatnonzero(out)
        decided = sure.copy()
        if unsure.any():
            decided[unsure] = self.distance(p[idx[unsure]]) > bound[out][unsure]
        out[idx] = decided
        return out

    def _sample(self) -> None:
        from scipy.spatial import cKDTree

        size = float(np.max(self.vertices.max(0) - self.vertices.min(0)))
        spacing = max(size, 1e-300) * SAMPLE_SPACING
        length = np.linalg.norm(self.b - self.a, axis=1)
        n = np.ceil(length / spacing).astype(np.int64) + 1
        u = np.concatenate([np.linspace(0.0, 1.0, k) for k in n])
        seg = np.repeat(np.arange(len(n)), n)
        pts = self.a[seg] + u[:, None] * (self.b - self.a)[seg]
        self._tree = cKDTree(pts)
        self._slack = 0.5 * spacing * (1 + 1e-9) + 1e-12 * size


def rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def quaternion(face: int, v: np.ndarray) -> np.ndarray:
    q = np.insert(np.asarray(v, dtype=np.float64), face, 1.0)
    return q / np.linalg.norm(q)


def cell_angle(face: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre quaternion and covering angle (largest over the 8 corners, plus 1e-12), radians."""
    q0 = quaternion(face, 0.5 * (lo + hi))
    worst = 0.0
    for c in range(8):
        corner = [hi[j] if (c >> (2 - j)) & 1 else lo[j] for j in range(3)]
        worst = max(worst, float(np.linalg.norm(quaternion(face, corner) - q0)))
    return q0, 2.0 * math.asin(min(1.0, worst / 2.0)) + 1e-12


def _rotation_partials(q: np.ndarray) -> list[np.ndarray]:
    """dM/dq_a (a = w, x, y, z) of the homogeneous rotation formula M(q) (:func:`rotation` for
    unit q), each a 3 x 3 matrix linear in q."""
    w, x, y, z = q
    return [
        2.0 * np.array([[w, -z, y], [z, w, -x], [-y, x, w]]),
        2.0 * np.array([[x, y, z], [y, -x, -w], [z, w, -x]]),
        2.0 * np.array([[-y, x, w], [x, y, z], [-w, z, -y]]),
        2.0 * np.array([[-z, -w, x], [w, -z, y], [x, y, z]]),
    ]


def first_order_bounds(
    face: int, lo: np.ndarray, hi: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Projections at the cell's centre and a bound on every point's displacement over the cell.

    q(v) = u / |u| with u = v and 1 in slot ``face``; J's column j is P (dR/dv_j) p with
    dR/dv_j = sum_a dM/dq_a (q0) dq_a/dv_j and dq/dv_j = (e_j - q0 q0_j) / |u_c|. The bound is
    (D_c max_corners |J delta| + |h|^2 (|p| + |P R0 p|)) / D_min (D = |u|^2, h the half-widths;
    docs/certify.md), times 1 + 1e-9 for rounding.

    Parameters
    ----------
    face : int
    lo, hi : (3,) ndarray
        The cell's box in face coordinates.
    points : (k, 3) ndarray
        Scene units.

    Returns
    -------
    proj : (k, 2) ndarray
    bound : (k,) ndarray
        Scene units.
    """
    vc, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    uc = np.insert(vc, face, 1.0)
    norm = float(np.linalg.norm(uc))
    q0 = uc / norm
    partials = _rotation_partials(q0)
    slots = [a for a in range(4) if a != face]
    proj = points @ rotation(q0)[:2].T
    columns = []
    for j, slot in enumerate(slots):
        dq = -q0 * q0[slot]
        dq[slot] += 1.0
        dq /= norm
        d_rot = sum(dq[a] * partials[a] for a in range(4))
        columns.append(h[j] * (points @ d_rot[:2].T))
    lin = np.zeros(len(points))
    for sy in (1.0, -1.0):
        for sz in (1.0, -1.0):
            d = columns[0] + sy * columns[1] + sz * columns[2]
            lin = np.maximum(lin, np.hypot(d[:, 0], d[:, 1]))
    nearest = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    d_min = 1.0 + float(nearest @ nearest)
    second = float(h @ h) * (np.linalg.norm(points, axis=1) + np.hypot(proj[:, 0], proj[:, 1]))
    return proj, (norm * norm * lin + second) / d_min * (1.0 + 1e-9)


def no_translation(hole: Hole, proj: np.ndarray, radii: np.ndarray, resolve: float) -> bool:
    """True if no t puts every proj_i + t within radii_i of H (quadtree over t, exact distances)."""
    lo = hole.vertices.min(0) - radii[0] - proj[0]
    hi = hole.vertices.max(0) + radii[0] - proj[0]
    half = 0.5 * float(np.max(hi - lo))
    centres = (0.5 * (lo + hi))[None, :]
    while len(centres):
        e = half * math.sqrt(2.0)
        if len(centres) > MAX_BOXES or e < 0.25 * resolve:
            return False
        placed = (centres[:, None, :] + proj[None]).reshape(-1, 2)
        bound = np.broadcast_to(radii[None] + e, (len(centres), len(proj))).reshape(-1)
        far = hole.beyond(placed, bound).reshape(len(centres), -1)
        centres, half = centres[~far.any(axis=1)], 0.5 * half
        offsets = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]) * half
        centres = (centres[:, None, :] + offsets[None]).reshape(-1, 2)
    return True


def disk_never_fits(hole: Hole, rho: float) -> bool:
    """True if no disk of radius ``rho`` fits in H (quadtree over disk centres)."""
    lo, hi = hole.vertices.min(0), hole.vertices.max(0)
    half = 0.5 * float(np.max(hi - lo))
    centres = (0.5 * (lo + hi))[None, :]
    while len(centres):
        e = half * math.sqrt(2.0)
        if len(centres) > MAX_BOXES:
            return False
        d, ins = hole.distance(centres), hole.contains(centres)
        if np.any(ins & (d >= rho)):
            return False
        settled = (d + e < rho * (1 - 1e-9)) | (~ins & (d > e * (1 + 1e-9)))
        centres, half = centres[~settled], 0.5 * half
        offsets = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]) * half
        centres = (centres[:, None, :] + offsets[None]).reshape(-1, 2)
    return True


def _orient(a, b, c):
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (
        c[..., 0] - a[..., 0]
    )


def segments_cross(p0, p1, q0, q1) -> bool:
    """Whether any segment p0-p1 properly crosses any segment q0-q1."""
    for s in range(0, len(p0), 256):
        a, b = p0[s : s + 256, None], p1[s : s + 256, None]
        c, d = q0[None], q1[None]
        o1, o2 = _orient(a, b, c), _orient(a, b, d)
        o3, o4 = _orient(c, d, a), _orient(c, d, b)
        if np.any((o1 * o2 < 0) & (o3 * o4 < 0)):
            return True
    return False


def points_in_triangles(points: np.ndarray, tri: np.ndarray) -> bool:
    """Whether any point lies strictly inside any (non-degenerate) triangle."""
    for s in range(0, len(tri), 256):
        t = tri[s : s + 256, None]
        x = points[None]
        o = [_orient(t[..., i, :], t[..., (i + 1) % 3, :], x) for i in range(3)]
        if np.any(((o[0] > 0) & (o[1] > 0) & (o[2] > 0)) | ((o[0] < 0) & (o[1] < 0) & (o[2] < 0))):
            return True
    return False
