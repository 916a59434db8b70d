"""Rotation-space cells: boxes on the four faces of the quaternion cube, and their covering radii.

Every unit quaternion q (w, x, y, z), up to sign, has a largest component in absolute value; with
that component k made positive, q = v / |v| for a v with v_k = 1 and the other three components
in [-1, 1]. So the four *faces* k = 0..3, each the box [-1, 1]^3 of the other three components,
cover all of SO(3). A *cell* is a box ``[lo, hi]`` of one face; cells are split into their eight
octants. Boxes are halved exactly in binary floating point, so the replay rebuilds the same boxes.

Covering radius: the angle on S^3 between the cell's centre q0 and a point q of the cell is
largest at one of the box's eight corners (the set {v : angle(q0, v / |v|) <= a} is a convex cone
for a < pi / 2, so the angle is a quasi-convex function of v and its maximum over a box is at a
vertex). A rotation at S^3-angle theta from R0 rotates by 2 theta relative to it, which moves a
point p by at most 2 sin(theta) |p|.

First-order bound (:class:`Frames`, :func:`first_order`): with u(v) the face's vector (1 in slot
``face``), D = |u|^2 and M(u) = D R(u / |u|) the rotation formula's homogeneous quadratic form,
the projection f(v) = P R(q(v)) p = P M(u) p / D satisfies, exactly, for delta = v - v_c,

    f(v) - f(v_c) = (D_c / D) J delta + (P M(delta~) p - f(v_c) |delta|^2) / D,

with J = d f / d v at the centre and delta~ the 4-vector of delta (0 in slot ``face``). Since
|M(w) p| = |w|^2 |p|, every point moves at most
(D_c max_corners |J delta| + |h|^2 (|p| + |f(v_c)|)) / D_min over the cell (h the half-widths,
D_min the least D over the box); docs/certify.md has the derivation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ANGLE_MARGIN",
    "Cells",
    "FIRST_ORDER_MARGIN",
    "Frames",
    "centres",
    "corners",
    "covering_angles",
    "displacement",
    "face_quaternions",
    "first_order",
    "frames",
    "quadratic_form",
    "roots",
    "split",
    "volumes",
]

#: Added to every covering angle (radians): covers rounding in the corner angles (~1e-15).
ANGLE_MARGIN = 1e-12
#: Relative margin on every first-order displacement bound: covers rounding (~1e-15 relative).
FIRST_ORDER_MARGIN = 1e-9
#: Sign patterns of a box's corners up to a common sign (|J delta| is even in delta).
_SIGNS = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, -1.0], [1.0, -1.0, 1.0], [1.0, -1.0, -1.0]])


@dataclass
class Cells:
    """A batch of cells.

    Attributes
    ----------
    face : (n,) ndarray of int
        Index 0..3 of the quaternion component fixed to 1.
    lo, hi : (n, 3) ndarray of float64
        Box corners in the face's other three components.
    """

    face: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def __len__(self) -> int:
        return int(len(self.face))

    def take(self, idx: np.ndarray) -> Cells:
        """The cells at ``idx`` (index array or boolean mask)."""
        return Cells(self.face[idx], self.lo[idx], self.hi[idx])


def face_quaternions(face: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit quaternions v / |v| with component ``face`` equal to 1 before normalising.

    Parameters
    ----------
    face : (n,) int ndarray
    v : (n, 3) or (n, m, 3) float ndarray
        The other three components, in order.

    Returns
    -------
    (n, 4) or (n, m, 4) ndarray
        Unit quaternions (w, x, y, z).
    """
    v = np.asarray(v, dtype=np.float64)
    shape = v.shape[:-1] + (4,)
    q = np.empty(shape)
    cols = np.arange(4)
    for k in range(4):
        sel = face == k
        if sel.any():
            others = cols[cols != k]
            q[sel, ..., k] = 1.0
            q[sel, ..., others[0]] = v[sel, ..., 0]
            q[sel, ..., others[1]] = v[sel, ..., 1]
            q[sel, ..., others[2]] = v[sel, ..., 2]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def centres(cells: Cells) -> np.ndarray:
    """Centre quaternions of the cells, (n, 4)."""
    return face_quaternions(cells.face, 0.5 * (cells.lo + cells.hi))


def corners(cells: Cells) -> np.ndarray:
    """The eight box corners of every cell, (n, 8, 3)."""
    bits = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)], dtype=bool)
    return np.where(bits[None], cells.hi[:, None, :], cells.lo[:, None, :])


def covering_angles(cells: Cells) -> np.ndarray:
    """Largest S^3 angle from each cell's centre to any rotation of the cell, radians, (n,).

    The maximum over the eight corners (see the module docstring), computed as
    2 asin(|q0 - q| / 2), which is accurate for small angles, plus :data:`ANGLE_MARGIN`.
    """
    q0 = centres(cells)
    qc = face_quaternions(cells.face, corners(cells))
    chord = np.linalg.norm(qc - q0[:, None, :], axis=-1).max(axis=1)
    return 2.0 * np.arcsin(np.minimum(1.0, 0.5 * chord)) + ANGLE_MARGIN


def displacement(theta: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Bound on how far a rotation within S^3-angle ``theta`` moves points at distance ``lengths``.

    Parameters
    ----------
    theta : (n,) ndarray
        Covering angles, radians (below pi / 2).
    lengths : (k,) ndarray
        Distances of the points from the rotation centre, scene units.

    Returns
    -------
    (n, k) ndarray
        2 sin(theta) |p|, scene units.
    """
    return 2.0 * np.sin(theta)[:, None] * np.asarray(lengths)[None, :]


def split(cells: Cells) -> Cells:
    """The eight octants of every cell, grouped per parent (8 n cells, parent i's at 8i..8i+7)."""
    mid = 0.5 * (cells.lo + cells.hi)
    bits = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)], dtype=bool)
    lo = np.where(bits[None], mid[:, None, :], cells.lo[:, None, :]).reshape(-1, 3)
    hi = np.where(bits[None], cells.hi[:, None, :], mid[:, None, :]).reshape(-1, 3)
    return Cells(np.repeat(cells.face, 8), lo, hi)


def roots(faces: list[int], half: float) -> Cells:
    """One cell per face in ``faces``, the box [-half, half]^3."""
    n = len(faces)
    return Cells(
        np.asarray(faces, dtype=np.int64), np.full((n, 3), -float(half)), np.full((n, 3), half)
    )


def volumes(cells: Cells) -> np.ndarray:
    """Box volumes in face coordinates (the measure the excluded fraction is reported in), (n,)."""
    return np.prod(cells.hi - cells.lo, axis=1)


def quadratic_form(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The symmetric bilinear form B(a, b) of the homogeneous rotation formula.

    M(w) = B(w, w) = |w|^2 R(w / |w|) for every 4-vector w != 0 (w, x, y, z order), each entry a
    quadratic form in w; B(a, b) = (M(a + b) - M(a - b)) / 4.

    Parameters
    ----------
    a, b : (..., 4) ndarray
        4-vectors (need not be unit).

    Returns
    -------
    (..., 3, 3) ndarray
    """

    def m(w):
        w0, x, y, z = np.moveaxis(w, -1, 0)
        rows = [
            [w0 * w0 + x * x - y * y - z * z, 2 * (x * y - w0 * z), 2 * (x * z + w0 * y)],
            [2 * (x * y + w0 * z), w0 * w0 - x * x + y * y - z * z, 2 * (y * z - w0 * x)],
            [2 * (x * z - w0 * y), 2 * (y * z + w0 * x), w0 * w0 - x * x - y * y + z * z],
        ]
        return np.stack([np.stack(r, -1) for r in rows], -2)

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return 0.25 * (m(a + b) - m(a - b))


@dataclass
class Frames:
    """What the first-order displacement bound needs of each cell (:func:`frames`).

    Attributes
    ----------
    rot : (n, 3, 3) ndarray
        Rotation at the cell's centre, R0.
    steps : (n, 3, 3, 3) ndarray
        ``steps[i, j]`` = h_j dR/dv_j at the centre: the rotation's change over half the box
        along face coordinate j, to first order (h_j the half-width).
    scale : (n,) ndarray
        D_c / D_min >= 1: the centre's D = |u|^2 over the least D on the box.
    quad : (n,) ndarray
        |h|^2 / D_min, dimensionless.
    """

    rot: np.ndarray
    steps: np.ndarray
    scale: np.ndarray
    quad: np.ndarray

    def take(self, idx) -> Frames:
        """The frames of the cells at ``idx``."""
        return Frames(self.rot[idx], self.steps[idx], self.scale[idx], self.quad[idx])


def _embed(face: np.ndarray, v: np.ndarray, slot: float) -> np.ndarray:
    """4-vectors with ``slot`` in component ``face`` and ``v`` (n, 3) in the others, (n, 4)."""
    u = np.empty((len(face), 4))
    cols = np.arange(4)
    for k in range(4):
        sel = face == k
        u[sel, k] = slot
        u[np.ix_(sel, cols[cols != k])] = v[sel]
    return u


def frames(cells: Cells) -> Frames:
    """Centre rotations and first-order data of every cell (see the module docstring)."""
    vc = 0.5 * (cells.lo + cells.hi)
    h = 0.5 * (cells.hi - cells.lo)
    u = _embed(cells.face, vc, 1.0)
    dc = (u * u).sum(1)
    rot = quadratic_form(u, u) / dc[:, None, None]
    steps = np.empty((len(cells), 3, 3, 3))
    for j in range(3):
        e = _embed(cells.face, np.eye(3)[np.full(len(cells), j)], 0.0)
        d = (2.0 * quadratic_form(u, e) - 2.0 * vc[:, j, None, None] * rot) / dc[:, None, None]
        steps[:, j] = h[:, j, None, None] * d
    straddle = (cells.lo <= 0) & (cells.hi >= 0)
    dmin = 1.0 + np.where(straddle, 0.0, np.minimum(cells.lo**2, cells.hi**2)).sum(1)
    return Frames(rot, steps, dc / dmin, (h * h).sum(1) / dmin)


def first_order(fr: Frames, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Projections at the centre and first-order displacement bounds, for every cell and point.

    For every rotation R of cell i, |P R p - P R0 p| <= bound (the module docstring; P keeps x
    and y).

    Parameters
    ----------
    fr : Frames
        n cells.
    points : (k, 3) or (n, k, 3) ndarray
        Points about the shape's centre, scene units; shared by all cells or one set per cell.

    Returns
    -------
    proj : (n, k, 2) ndarray
        P R0 p, scene units.
    bound : (n, k) ndarray
        (D_c max_corners |J delta| + |h|^2 (|p| + |P R0 p|)) / D_min, times 1 +
        :data:`FIRST_ORDER_MARGIN`, scene units.
    """
    p = np.asarray(points, dtype=np.float64)
    rows = np.concatenate([fr.rot[:, :2], fr.steps[:, :, :2].reshape(-1, 6, 3)], axis=1)
    out = rows @ (p.T if p.ndim == 2 else np.swapaxes(p, 1, 2))  # (n, 8, k)
    a, b, c = out[:, 2:4], out[:, 4:6], out[:, 6:8]
    plus, minus = a + b, a - b
    lin2 = np.zeros(out.shape[::2])
    for d in (plus + c, plus - c, minus + c, minus - c):
        lin2 = np.maximum(lin2, d[:, 0] ** 2 + d[:, 1] ** 2)
    proj = np.stack([out[:, 0], out[:, 1]], axis=-1)
    centre = np.sqrt(out[:, 0] ** 2 + out[:, 1] ** 2)
    second = fr.quad[:, None] * (np.sqrt((p * p).sum(-1)) + centre)
    bound = (fr.scale[:, None] * np.sqrt(lin2) + second) * (1.0 + FIRST_ORDER_MARGIN)
    return proj, bound
