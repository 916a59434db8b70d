"""Unit quaternions (w, x, y, z) and rotation matrices, in NumPy (and one Dr.Jit helper).

Convention (also in ``report.json``): a rotation q acts on a mesh's points, p -> R(q) p, about the
mesh's centre; the silhouette is the projection of the rotated points onto the xy-plane.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "align",
    "angle_between",
    "from_axis_angle",
    "from_matrix",
    "from_rotvec",
    "normalize",
    "quat_multiply",
    "quat_rows",
    "random_uniform",
    "to_matrix",
    "to_rotvec",
]


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions with a non-negative w component (q and -q are the same rotation).

    Parameters
    ----------
    q : (..., 4) array_like
        Quaternions (w, x, y, z), not necessarily of unit length.

    Returns
    -------
    (..., 4) ndarray of float64
    """
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    q = q / np.where(n > 0, n, 1.0)
    return np.where(q[..., :1] < 0, -q, q)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions.

    Parameters
    ----------
    q : (..., 4) array_like
        Quaternions (w, x, y, z); normalised first.

    Returns
    -------
    (..., 3, 3) ndarray
        R such that a point p maps to R @ p.
    """
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a 3x3 rotation matrix."""
    m = np.asarray(m, dtype=np.float64)
    t = np.trace(m)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    return normalize(np.array(q))


def from_axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Unit quaternion rotating by ``angle`` radians about ``axis``."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    return normalize(np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis]))


def from_rotvec(v: np.ndarray) -> np.ndarray:
    """Unit quaternions of rotation vectors (axis times angle in radians), shape (..., 3) -> (..., 4)."""
    v = np.asarray(v, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = angle / 2
    scale = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return normalize(np.concatenate([np.cos(half), scale * v], axis=-1))


def to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (axis times angle in [0, pi], radians) of a unit quaternion (4,) -> (3,)."""
    q = normalize(np.asarray(q, dtype=np.float64))
    q = -q if q[0] < 0 else q
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-12:
        return 2.0 * q[1:]
    return q[1:] / s * 2.0 * np.arctan2(s, q[0])


def align(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit quaternion of the shortest rotation taking direction ``u`` to direction ``v``."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    v = np.asarray(v, float) / np.linalg.norm(v)
    c = np.cross(u, v)
    d = float(np.dot(u, v))
    if d < -1 + 1e-12:  # opposite: rotate by pi about any axis orthogonal to u
        axis = np.cross(u, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(u, [0.0, 1.0, 0.0])
        return from_axis_angle(axis, np.pi)
    return normalize(np.concatenate([[1.0 + d], c]))


def random_uniform(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotations drawn uniformly from SO(3) (Shoemake's method), shape (n, 4)."""
    u1, u2, u3 = rng.random((3, n))
    a, b = np.sqrt(1 - u1), np.sqrt(u1)
    q = np.stack(
        [
            a * np.sin(2 * np.pi * u2),
            a * np.cos(2 * np.pi * u2),
            b * np.sin(2 * np.pi * u3),
            b * np.cos(2 * np.pi * u3),
        ],
        -1,
    )
    return normalize(q)


def angle_between(q1: np.ndarray, q2: np.ndarray) -> float:
    """Angle in radians of the rotation taking q1 to q2."""
    d = abs(float(np.dot(normalize(q1), normalize(q2))))
    return 2.0 * float(np.arccos(min(1.0, d)))


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (w, x, y, z): rotation b, then a."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def quat_rows(qw, qx, qy, qz) -> tuple:
    """Rotation matrix entries of quaternions held in Dr.Jit arrays, same convention as
    :func:`to_matrix`.

    Parameters
    ----------
    qw, qx, qy, qz : Dr.Jit float arrays
        Quaternion components, one entry per pose; normalised here (differentiably).

    Returns
    -------
    tuple of 9 Dr.Jit arrays
        R00, R01, R02, R10, ..., R22 (row-major).
    """
    import drjit as dr

    n = dr.rsqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, x, y, z = qw * n, qx * n, qy * n, qz * n
    return (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )
