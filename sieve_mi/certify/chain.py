"""The chain test of the slab-section proof: a section too wide for any one copy of a sheet.

On a perforated sheet H is many copies, so H's diameter is the sheet's, and the section
search's diameter test excludes nothing; yet a section whose points hang together cannot use
two copies. The argument (docs/certify.md, "A section on a sheet: the chain test"):

* Let the contours of H have pairwise disjoint convex hulls, and let g > 0 be a lower bound on
  the distance between any two of them. H (even-odd) lies in the union of the hulls (a point
  outside a closed curve's hull is outside the curve), so two points of H less than g apart lie
  in the same hull.
* If band points q_0, ..., q_m of a cell are a *chain*, |x_k - x_{k+1}| + r_k + r_{k+1} < g for
  each step (x plane coordinates at the cell's centre direction, r their displacement bounds
  over the cell, so the true projected points are less than g apart for every direction of the
  cell, turn and offset), then in any pose that puts the section inside H all of them lie in
  one copy's hull.
* If moreover |x_0 - x_m| - r_0 - r_m exceeds D, the largest diameter of one contour's vertices
  (a hull's diameter), they cannot: no direction of the cell lets the section fit H.

The lower bound g between two hulls is the separating-axis gap: for a unit u, the least of
u . b over B's vertices less the largest u . a over A's is at most the distance between the
hulls, so the largest such gap over the hulls' edge normals is a proved lower bound (exact when
the closest features are an edge and a vertex). The replay
(:mod:`sieve_mi.certify.replay_section`) recomputes g and D with its own code.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Chain", "evidence", "fewest_steps", "hull_gap"]


def _hull(points: np.ndarray) -> np.ndarray:
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        return points


def _axis_gap(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> float:
    """The largest separating gap of hull vertices ``a`` and ``b`` over unit directions ``u``
    (m, 2), either way round."""
    pa, pb = a @ u.T, b @ u.T
    return float(np.maximum(pb.min(axis=0) - pa.max(axis=0), pa.min(axis=0) - pb.max(axis=0)).max())


def _normals(h: np.ndarray) -> np.ndarray:
    d = np.roll(h, -1, axis=0) - h
    n = np.column_stack([d[:, 1], -d[:, 0]])
    length = np.linalg.norm(n, axis=1)
    return n[length > 0] / length[length > 0, None]


def hull_gap(contours: list) -> float:
    """A proved lower bound on the distance between the convex hulls of any two contours, scene
    units (``inf`` for one contour; 0 or less where two hulls may meet).

    Parameters
    ----------
    contours : list of (n, 2) ndarray

    Examples
    --------
    >>> import numpy as np
    >>> sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> round(hull_gap([sq, sq + [3.0, 0.0]]), 12)
    2.0
    """
    hulls = [_hull(np.asarray(c, dtype=np.float64)) for c in contours]
    centre = np.array([h.mean(axis=0) for h in hulls])
    pairs = []
    for i in range(len(hulls)):
        for j in range(i + 1, len(hulls)):
            d = centre[j] - centre[i]
            u = (d / max(np.linalg.norm(d), 1e-300))[None]
            pairs.append((_axis_gap(hulls[i], hulls[j], u), i, j))
    best = math.inf
    for quick, i, j in sorted(pairs):  # a pair whose quick gap is no less cannot lower best
        if quick >= best:
            break
        u = np.concatenate([_normals(hulls[i]), _normals(hulls[j])])
        best = min(best, max(quick, _axis_gap(hulls[i], hulls[j], u)))
    return best


class Chain:
    """The chain test against H's contours (module docstring).

    Parameters
    ----------
    contours : list of (n, 2) ndarray
        H's contours, scene units (two or more).
    eta : float
        The search's slack on H, scene units.

    Attributes
    ----------
    step : float
        Each step of a chain must be shorter than this (g less twice ``eta``, with the relative
        margin), scene units; 0 when the hulls may meet (no chain test).
    diameter : float
        D plus ``eta`` with the margin: the chain's ends must be further apart, scene units.
    """

    def __init__(self, contours: list, eta: float, margin: float = 1e-9):
        gap = hull_gap(contours)
        self.step = max(0.0, gap * (1 - margin) - 2.0 * eta) if math.isfinite(gap) else 0.0
        d = max(math.dist(*_far(np.asarray(c, dtype=np.float64))) for c in contours)
        self.diameter = d * (1 + margin) + eta

    def path(self, x: np.ndarray, r: np.ndarray, i: int, j: int) -> list | None:
        """A chain of the points ``x`` (k, 2) with bounds ``r`` (k,) from ``i`` to ``j`` (indices
        into them) over the edges of their Delaunay triangulation, fewest steps; None when there
        is none (or the points are degenerate) or the ends are not far enough apart."""
        if self.step <= 0 or np.linalg.norm(x[i] - x[j]) - r[i] - r[j] <= self.diameter:
            return None
        return fewest_steps(x, r, self.step, i, j)


def fewest_steps(
    x: np.ndarray, r: np.ndarray, step: float, i: int, j: int, joins=()
) -> list | None:
    """The fewest-step path from point ``i`` to ``j`` of ``x`` (k, 2) over the edges of their
    Delaunay triangulation with ``|x_a - x_b| + r_a + r_b`` below ``step`` (scene units), plus the
    extra edges ``joins`` ((m, 2) int arrays); None when there is none or the points are
    degenerate. Shared by the chain test and the link test (:mod:`sieve_mi.certify.link`)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order
    from scipy.spatial import Delaunay, QhullError

    try:
        tri = Delaunay(x).simplices
    except (QhullError, ValueError):
        return None
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]])
    w = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) + r[e[:, 0]] + r[e[:, 1]]
    e = np.concatenate([e[w < step], *joins])
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(x), len(x)))
    _, pred = breadth_first_order(graph, i, directed=False, return_predecessors=True)
    if pred[j] < 0:
        return None
    out = [j]
    while out[-1] != i:
        out.append(int(pred[out[-1]]))
    return out[::-1]


def _far(points: np.ndarray) -> tuple:
    """The two vertices of ``points`` (n, 2) furthest apart (over the hull's vertices)."""
    h = _hull(points)
    d = ((h[:, None] - h[None]) ** 2).sum(-1)
    a, b = np.unravel_index(int(d.argmax()), d.shape)
    return tuple(h[a]), tuple(h[b])


def evidence(chain: Chain, cell: tuple, pair) -> dict | None:
    """Chain evidence for a cell of a :class:`~sieve_mi.certify.section.Plane` (``cell``: its
    ``Plane.cell``, the band points' indices, plane coordinates and bounds) from the pair of
    candidate indices ``pair`` furthest apart, or None."""
    cols, x, r = cell
    at = np.searchsorted(cols, pair)
    if (
        len(cols) < 3
        or np.any(at >= len(cols))
        or np.any(cols[np.minimum(at, len(cols) - 1)] != pair)
    ):
        return None
    found = chain.path(x, r, int(at[0]), int(at[1]))
    return None if found is None else {"kind": "chain", "points": cols[found].tolist()}
