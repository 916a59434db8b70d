"""The size measure that orders a mixture, coarsest first.

A shape's *passage radius* is the radius of the largest disk inscribed in its smallest-looking
projection: over the canonical view directions (:func:`sieve_mi.geometry.canonical.view_directions`:
principal axes, minimum width and area directions, largest hull facets), the projection of the
convex hull is a convex polygon, and its largest inscribed disk (Chebyshev centre, one small
linear program) is measured; the smallest over the views is the passage radius. A round hole of
that radius, grown by the tolerance, lets the shape through in that view; a shape with a larger
passage radius in every view needs a larger hole, so it is the coarser of the two.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.canonical import view_directions
from sieve_mi.geometry.meshes import Shape

__all__ = ["inscribed_radius", "passage_radius"]


def inscribed_radius(points: np.ndarray) -> float:
    """Radius of the largest disk inside the convex hull of 2D points ``points`` (n, 2).

    Zero for points on a line (a flat part seen edge-on).

    Examples
    --------
    >>> import numpy as np
    >>> round(inscribed_radius(np.array([[0, 0], [4, 0], [4, 2], [0, 2.0]])), 6)
    1.0
    """
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(np.asarray(points, dtype=np.float64))
    except (QhullError, ValueError):
        return 0.0
    normals, offsets = hull.equations[:, :2], hull.equations[:, 2]  # n . x + b <= 0, |n| = 1
    # maximise r subject to n_i . c + r <= -b_i
    a = np.column_stack([normals, np.ones(len(normals))])
    res = linprog([0.0, 0.0, -1.0], A_ub=a, b_ub=-offsets, bounds=[(None, None)] * 2 + [(0, None)])
    return float(res.x[2]) if res.success else 0.0


def passage_radius(shape: Shape, views: int = 20) -> tuple[float, np.ndarray]:
    """The shape's passage radius (scene units) and the view direction that gives it (3,).

    Parameters
    ----------
    shape : Shape
    views : int
        Canonical view directions to try.
    """
    best, best_dir = np.inf, None
    for d in view_directions(shape, views):
        u = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        r = inscribed_radius(shape.hull @ np.column_stack([u, v]))
        if r < best:
            best, best_dir = r, d
    return float(best), best_dir
