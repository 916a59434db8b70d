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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ANGLE_MARGIN",
    "Cells",
    "centres",
    "corners",
    "covering_angles",
    "displacement",
    "face_quaternions",
    "roots",
    "split",
    "volumes",
]

#: Added to every covering angle (radians): covers rounding in the corner angles (~1e-15).
ANGLE_MARGIN = 1e-12


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
