"""Exact point queries against a triangle mesh: the distance to each triangle and the
generalised winding number (inside 1, outside 0).

Used by certify's ball proofs (:mod:`sieve_mi.certify.bounds`) and by the shake trials' measure of
a convex decomposition (:mod:`sieve_mi.shake.decompose`); plain NumPy, so no spatial index is
needed (trimesh's ``contains`` and ``proximity`` want rtree).
"""

from __future__ import annotations

import numpy as np

__all__ = ["triangle_distance", "winding_numbers"]


def triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Exact distance from point ``p`` (3,) to each triangle of ``tri`` (F, 3, 3), (F,); from
    points ``p`` (P, 3), (P, F).

    Examples
    --------
    >>> import numpy as np
    >>> tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    >>> float(triangle_distance(np.array([0.25, 0.25, 2.0]), tri)[0])
    2.0
    """
    p = np.asarray(p, dtype=np.float64)
    q = p[..., None, :]  # (..., 1, 3) against (F, 3)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.maximum((n * n).sum(1), 1e-300)
    h = ((q - a) * n).sum(-1) / nn
    foot = q - h[..., None] * n
    inside_tri = np.ones(h.shape, dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside_tri &= (np.cross(v - u, foot - u) * n).sum(-1) >= 0
    best = np.where(inside_tri, np.abs(h) * np.sqrt(nn), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        d = v - u
        t = np.clip(((q - u) * d).sum(-1) / np.maximum((d * d).sum(1), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(q - u - t[..., None] * d, axis=-1))
    return best


def winding_numbers(points: np.ndarray, tri: np.ndarray, chunk: int = 256) -> np.ndarray:
    """Generalised winding number of a closed, outward-oriented triangle mesh about each point:
    the triangles' solid angles (Van Oosterom and Strackee's formula) summed over 4 pi.

    Parameters
    ----------
    points : (P, 3) float
    tri : (F, 3, 3) float
    chunk : int
        Points per batch (memory: chunk x F x 9 floats).

    Returns
    -------
    (P,) float
        1 inside, 0 outside, between for a point on or near an open mesh's hole.

    Examples
    --------
    >>> import trimesh
    >>> box = trimesh.creation.box((2.0, 2.0, 2.0))
    >>> np.round(winding_numbers(np.array([[0.0, 0, 0], [3.0, 0, 0]]), box.triangles), 6)
    array([1., 0.])
    """
    points = np.asarray(points, dtype=np.float64)
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        v = tri[None] - points[s : s + chunk, None, None, :]  # (c, F, 3, 3)
        a, b, c = v[:, :, 0], v[:, :, 1], v[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = (a * np.cross(b, c)).sum(-1)
        den = la * lb * lc + (a * b).sum(-1) * lc + (b * c).sum(-1) * la + (c * a).sum(-1) * lb
        out[s : s + chunk] = np.arctan2(num, den).sum(axis=1) / (2.0 * np.pi)
    return out
