"""Size measures of a mixture's shapes: the base order (coarsest first) and the guesses that rank
the candidates of a cascade's sieves; the exact
rules of :mod:`sieve_mi.cascade.rules` and the solver's feasibility test
(:mod:`sieve_mi.game.feasible`) use :func:`end_first_radius` and :func:`canonical_extents`.

A shape's *passage radius* is the radius of the largest disk inscribed in its smallest-looking
projection: over the canonical view directions (:func:`sieve_mi.geometry.canonical.view_directions`:
principal axes, minimum width and area directions, largest hull facets), the projection of the
convex hull is a convex polygon, and its largest inscribed disk (Chebyshev centre, one small
linear program) is measured; the smallest over the views is the passage radius. Every hole the
shape passes holds a disk of that radius (in the view it passes in; in the canonical views the
smallest), so a shape with a larger passage radius is the coarser of the two. It orders the
mixture (:func:`sieve_mi.cascade.sort.prepare`). It does not see diameters: the 1, 2 and 5 cent
coins, all 1.67 mm thick, tie.

All three extents count in the finer measures:

* :func:`canonical_extents`: the hull's extents along its principal axes, largest first (a coin
  of diameter D and thickness t: (D, D, t));
* :func:`predicted_margin`: from two shapes' extents, a guess of how much a hole for one blocks
  the other (rectangles of the two smaller extents, turned as needed: :func:`rectangle_fits`),
  which ranks the shapes a sieve may hold (:mod:`sieve_mi.cascade.plan`); a guess, never used to
  rule a sieve out;
* :func:`end_first_radius`: the smallest disk that holds one of the shape's canonical
  silhouettes (:func:`enclosing_circle`), used by the exact rules of :mod:`sieve_mi.cascade.rules`
  and :mod:`sieve_mi.game.feasible`.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.canonical import principal_axes, view_directions
from sieve_mi.geometry.meshes import Shape

__all__ = [
    "canonical_extents",
    "enclosing_circle",
    "end_first_radius",
    "inscribed_radius",
    "passage_radius",
    "predicted_margin",
    "rectangle_fits",
]


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
        r = inscribed_radius(shape.hull @ _plane(d))
        if r < best:
            best, best_dir = r, d
    return float(best), best_dir


def canonical_extents(shape: Shape) -> np.ndarray:
    """The convex hull's extents along its three principal axes, largest first (scene units), (3,).

    A 30 x 10 x 4 mm bar: (30, 10, 4); a coin of diameter D and thickness t: about (D, D, t)
    (its rim polygon's width in the principal frame lies between D cos(pi / n) and D).
    """
    proj = shape.hull @ principal_axes(shape).T
    return np.sort(proj.max(axis=0) - proj.min(axis=0))[::-1]


def rectangle_fits(p: float, q: float, a: float, b: float) -> bool:
    """Whether a p x q rectangle fits, turned as needed, inside an a x b rectangle (any units).

    Carver's conditions (with p >= q, a >= b after sorting): it fits axis-parallel when p <= a
    and q <= b; a longer one (p > a) fits turned iff q <= b and
    ((a + b) / (p + q))**2 + ((a - b) / (p - q))**2 >= 2. A side <= 0 means nothing to fit.

    Examples
    --------
    >>> rectangle_fits(20.0, 1.5, 15.0, 15.0), rectangle_fits(20.0, 1.0, 15.0, 15.0)
    (False, True)
    """
    p, q = max(p, q), min(p, q)
    a, b = max(a, b), min(a, b)
    if q <= 0.0:
        return p <= 0.0 or p <= np.hypot(a, b)
    if b <= 0.0:
        return False
    if p <= a and q <= b:
        return True
    if q > b or p == q:
        return False
    return ((a + b) / (p + q)) ** 2 + ((a - b) / (p - q)) ** 2 >= 2.0


def predicted_margin(held: np.ndarray, passing: np.ndarray, grow: float) -> float:
    """A rough guess of the protrusion (scene units) by which a hole for ``passing`` blocks
    ``held``, from their :func:`canonical_extents` alone: used only to order candidates.

    Each shape is modelled by the rectangle of its two smaller extents (its end-on view along its
    longest axis, the smallest silhouette of a box or a coin); the passing shape's rectangle is
    grown by ``grow`` on every side. The result is the largest d such that the held rectangle,
    shrunk by d on every side, still does not fit the grown one turned in any way
    (:func:`rectangle_fits`); negative when it fits with room to spare.

    Examples
    --------
    A 5 cent coin (21.25 x 1.67 mm) over a 10 cent coin's slot (19.75 x 1.93 mm grown by 0.1):
    0.63 mm (half the diameters' difference less the tolerance, 0.65, a little less because a
    turned coin fits slightly sooner); the other way round 0.03 mm (the thicknesses).

    >>> round(predicted_margin(np.array([21.25, 21.25, 1.67]), np.array([19.75, 19.75, 1.93]), 0.1), 2)
    0.63
    """
    p, q = float(held[1]), float(held[2])
    a, b = float(passing[1]) + 2.0 * grow, float(passing[2]) + 2.0 * grow
    lo, hi = -max(a, b, p), p / 2.0  # grown by -lo it cannot fit; shrunk to nothing it does
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if rectangle_fits(p - 2.0 * mid, q - 2.0 * mid, a, b):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def enclosing_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """A smallest circle holding 2D points ``points`` (n, 2): centre (2,) and radius.

    Welzl's incremental algorithm (points shuffled with a fixed seed); the radius returned is the
    largest distance from that centre to a point, so the circle holds every point whatever the
    round-off.

    Examples
    --------
    >>> c, r = enclosing_circle(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]))
    >>> round(r, 9)
    2.5
    """
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    pts = pts[np.random.default_rng(0).permutation(len(pts))]
    c, r = pts[0], 0.0
    for i in range(1, len(pts)):
        if np.linalg.norm(pts[i] - c) <= r * (1 + 1e-12):
            continue
        c, r = pts[i], 0.0
        for j in range(i):
            if np.linalg.norm(pts[j] - c) <= r * (1 + 1e-12):
                continue
            c, r = 0.5 * (pts[i] + pts[j]), 0.5 * float(np.linalg.norm(pts[i] - pts[j]))
            for k in range(j):
                if np.linalg.norm(pts[k] - c) > r * (1 + 1e-12):
                    c, r = _circumcircle(pts[i], pts[j], pts[k], c, r)
    return c, float(np.linalg.norm(pts - c, axis=1).max())


def _circumcircle(a, b, c, centre, radius) -> tuple[np.ndarray, float]:
    """The circle through three points; for (nearly) collinear ones, the circle on the farthest
    pair as diameter."""
    d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-14 * max(1.0, float(np.abs([a, b, c]).max()) ** 2):
        pairs = [(a, b), (a, c), (b, c)]
        u, v = max(pairs, key=lambda uv: np.linalg.norm(uv[0] - uv[1]))
        return 0.5 * (u + v), 0.5 * float(np.linalg.norm(u - v))
    sa, sb, sc = a @ a, b @ b, c @ c
    x = (sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1])) / d
    y = (sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])) / d
    centre = np.array([x, y])
    return centre, float(np.linalg.norm(a - centre))


def end_first_radius(shape: Shape, views: int = 20) -> tuple[float, np.ndarray]:
    """The radius of the smallest disk that holds the shape's silhouette in one of its canonical
    views (scene units), and that view (3,): the round hole it goes through end first.

    A pencil: about its section's radius (seen end-on); a coin of diameter D and thickness t:
    sqrt(D**2 + t**2) / 2 (seen edge-on, a D x t rectangle); a ball: its radius. An upper bound
    on the smallest such disk over all views (only the canonical ones are tried).
    """
    best, best_dir = np.inf, None
    for d in view_directions(shape, views):
        r = enclosing_circle(shape.hull @ _plane(d))[1]
        if r < best:
            best, best_dir = r, d
    return float(best), best_dir


def _plane(d: np.ndarray) -> np.ndarray:
    """Two unit vectors (3, 2) spanning the plane perpendicular to unit ``d``."""
    u = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(d, u)])
