"""How much one convex shape must grow to hold another: the geometry of the feasibility test.

For convex bodies K (a passing shape's hull) and X (a held shape's hull), the *growth* that X
needs is the least g such that some rigid motion puts X inside K + ball(g). Its upper bound,
:func:`least_growth`, comes with a certificate: a rotation R and translation t (X's centre in
K's frame) with every vertex of R X + t within the exact distance g of K
(:func:`distance_to_hull`, point-to-triangle distances, no sampling); since K + ball(g) is
convex, X's whole hull is then inside it. The rotation is searched, so the bound may be above
the true least growth, never below it: a bound's certificate is checked exactly.

The search: for candidate rotations (every proper signed permutation between X's and K's
principal frames and their largest-facet frames: a hexagon's sides onto a hexagon's sides), one
small linear program gives the least g for which R X + t lies in the polytope K + g D, where D
is the hull of :data:`DIRECTIONS` (unit vectors, so K + g D lies inside K + ball(g)); its facet
normals do not depend on g, so g and t are the LP's variables. The best rotations are polished
(Nelder-Mead on a rotation vector), then t (on the exact distance).

:func:`growth_lower_bound` is a quick necessary condition from measures that only grow under
inclusion (minimum width, diameter, volume with Steiner's formula): below it no rigid motion of
X fits inside K + ball(g), so the search is skipped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from sieve_mi.geometry.canonical import proper_signed_permutations
from sieve_mi.geometry.rotations import from_matrix

__all__ = [
    "DIRECTIONS",
    "Growth",
    "distance_to_hull",
    "growth_lower_bound",
    "hull_frames",
    "least_growth",
    "min_width",
]

#: Unit directions (42, 3) whose hull stands in for the unit ball in the search's linear programs
#: (an icosphere's vertices); only the search uses them, the certificate is checked exactly.
DIRECTIONS = trimesh.creation.icosphere(subdivisions=1).vertices
DIRECTIONS = DIRECTIONS / np.linalg.norm(DIRECTIONS, axis=1, keepdims=True)

_TURNS = proper_signed_permutations()


@dataclass
class Growth:
    """A certified containment: X, turned by ``rotation`` and moved by ``translation``, lies in
    K + ball(``grow``) (scene units, both shapes about their centres).

    Attributes
    ----------
    grow : float
        The largest exact distance from a vertex of X's placed hull to K.
    rotation : (3, 3) ndarray
    translation : (3,) ndarray
    """

    grow: float
    rotation: np.ndarray
    translation: np.ndarray

    @property
    def quaternion(self) -> list[float]:
        """``rotation`` as (w, x, y, z)."""
        return [float(x) for x in from_matrix(self.rotation)]


def _hull(points: np.ndarray) -> trimesh.Trimesh:
    """The convex hull of ``points`` as a trimesh."""
    return trimesh.convex.convex_hull(np.asarray(points, dtype=np.float64))


@dataclass(frozen=True)
class _Faces:
    """A convex hull's triangles (f, 3, 3), unit normals (f, 3) and plane offsets (f,), read
    from the trimesh once (its cached properties re-hash the mesh on every read)."""

    triangles: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray

    @classmethod
    def of(cls, hull) -> _Faces:
        tri, n = np.asarray(hull.triangles), np.asarray(hull.face_normals)
        return cls(tri, n, np.sum(n * tri[:, 0], axis=1))


def distance_to_hull(points: np.ndarray, hull) -> np.ndarray:
    """Exact distance (n,) from each point (n, 3) to the solid convex hull ``hull`` (a trimesh):
    0 inside, else the distance to the nearest of its triangles.

    Only the triangles a point sees (its plane's signed distance > 0) are tested: the nearest
    point q of a convex body to an outside point p has p - q in the normal cone at q, a
    non-negative sum of the normals of the faces through q, so (p - q)·(p - q) > 0 makes
    n·(p - q) > 0 for one of those faces, which p therefore sees.
    """
    faces = hull if isinstance(hull, _Faces) else _Faces.of(hull)
    pts = np.asarray(points, dtype=np.float64)
    eq = pts @ faces.normals.T - faces.offsets[None, :]
    out = np.zeros(len(pts))
    outside = np.flatnonzero(eq.max(axis=1) > 0.0)
    if len(outside):
        rows, seen = np.nonzero(eq[outside] > 0.0)
        q = pts[outside][rows]
        near = trimesh.triangles.closest_point(faces.triangles[seen], q)
        best = np.full(len(outside), np.inf)
        np.minimum.at(best, rows, np.linalg.norm(near - q, axis=1))
        out[outside] = best
    return out


def min_width(points: np.ndarray) -> float:
    """The exact minimum width of the hull of ``points`` (n, 3): over its facet normals and the
    cross products of every two hull edges (where the minimum of a polytope is attained)."""
    hull = _hull(points)
    v = hull.vertices
    e = hull.vertices[hull.edges_unique[:, 1]] - hull.vertices[hull.edges_unique[:, 0]]
    dirs = [hull.face_normals]
    for chunk in np.array_split(np.arange(len(e)), max(1, len(e) // 64)):
        c = np.cross(e[chunk][:, None, :], e[None, :, :]).reshape(-1, 3)
        n = np.linalg.norm(c, axis=1)
        dirs.append(c[n > 1e-12 * (1.0 + n.max())] / n[n > 1e-12 * (1.0 + n.max())][:, None])
    best = np.inf
    for d in dirs:
        proj = v @ d.T
        best = min(best, float((proj.max(axis=0) - proj.min(axis=0)).min()))
    return best


def _steiner_growth(volume: float, area: float, diameter: float, target: float) -> float:
    """The least g >= 0 with volume + area g + 2 pi diameter g^2 + 4/3 pi g^3 >= target (Steiner's
    formula for the volume of K + ball(g), the mean width bounded by the diameter)."""
    if volume >= target:
        return 0.0
    lo, hi = 0.0, 1.0 + (target / (4.0 / 3.0 * math.pi)) ** (1.0 / 3.0)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        v = volume + area * mid + 2.0 * math.pi * diameter * mid**2 + 4.0 / 3.0 * math.pi * mid**3
        lo, hi = (lo, mid) if v >= target else (mid, hi)
    return lo


def _diameter(points: np.ndarray) -> float:
    p = np.asarray(points, dtype=np.float64)
    return float(max(np.linalg.norm(p - q, axis=1).max() for q in p))


def growth_lower_bound(
    held: np.ndarray, passing: np.ndarray, held_ball: float = 0.0, max_edges: int = 400
) -> float:
    """A lower bound on the growth that ``held``'s hull needs to fit in ``passing``'s (both
    (n, 3) point sets, scene units): X inside K + ball(g) needs min width, diameter and volume
    of X at most those of K + ball(g) (width + 2g, diameter + 2g, and Steiner's volume).

    The held shape's minimum width is exact when its hull has at most ``max_edges`` edges, else
    twice ``held_ball``, the radius of a ball inside its hull (a lower bound on every width).
    """
    hx, hk = _hull(held), _hull(passing)
    dk = _diameter(hk.vertices)
    bound = max(0.0, (_diameter(hx.vertices) - dk) / 2.0)
    small = len(hx.edges_unique) <= max_edges
    wx = min_width(hx.vertices) if small else 2.0 * held_ball
    proj = hk.vertices @ hk.face_normals.T  # any direction's width bounds K's minimum above
    wk = float((proj.max(axis=0) - proj.min(axis=0)).min())
    bound = max(bound, (wx - wk) / 2.0)
    return max(bound, _steiner_growth(hk.volume, hk.area, dk, hx.volume))


def hull_frames(points: np.ndarray, axes: np.ndarray, facets: int = 2) -> list[np.ndarray]:
    """Frames (3, 3), one unit axis per row, that a containment may align: the principal
    ``axes`` and, for each of the ``facets`` largest hull facets, (its longest edge, the
    in-facet normal to it, the facet's outward normal)."""
    hull = _hull(points)
    out = [np.asarray(axes, dtype=np.float64)]
    if len(hull.facets) == 0:
        return out
    for k in np.argsort(-hull.facets_area)[:facets]:
        n = hull.facets_normal[k]
        edges = hull.facets_boundary[k]
        vec = hull.vertices[edges[:, 1]] - hull.vertices[edges[:, 0]]
        e = vec[np.argmax(np.linalg.norm(vec, axis=1))]
        e = e - (e @ n) * n
        e /= np.linalg.norm(e)
        out.append(np.array([e, np.cross(n, e), n]))
    return out


class _Program:
    """The linear program of one pair: least g and t with R X + t inside K + g D."""

    def __init__(self, held: np.ndarray, passing: np.ndarray):
        from scipy.spatial import ConvexHull

        d = DIRECTIONS
        k = np.asarray(passing, dtype=np.float64)
        summed = ConvexHull((k[:, None, :] + d[None]).reshape(-1, 3))
        normals = np.unique(np.round(summed.equations[:, :3], 9), axis=0)
        self.normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        self.h_k = (self.normals @ k.T).max(axis=1)
        self.h_d = (self.normals @ d.T).max(axis=1)
        self.held = np.asarray(held, dtype=np.float64)
        self.a = np.column_stack([self.normals, -self.h_d])

    def solve(self, rot: np.ndarray) -> tuple[float, np.ndarray]:
        """(g, t) for rotation ``rot`` (3, 3); g = inf where the program fails."""
        from scipy.optimize import linprog

        h_x = (self.normals @ rot @ self.held.T).max(axis=1)
        res = linprog([0, 0, 0, 1.0], A_ub=self.a, b_ub=self.h_k - h_x,
                      bounds=[(None, None)] * 3 + [(0, None)])  # fmt: skip
        if not res.success:
            return np.inf, np.zeros(3)
        return float(res.x[3]), res.x[:3]


def _turned(rot: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``rot`` turned further by the rotation vector ``w`` (3,) (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-15:
        return rot
    k = w / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return (np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx) @ rot


def _candidates(lp: _Program, frames_x, frames_k) -> list[tuple[float, np.ndarray]]:
    """Every distinct frame-to-frame rotation with its program's g, best first."""
    rotations = {}
    for fk in frames_k:
        for fx in frames_x:
            for turn in _TURNS:
                rot = fk.T @ turn @ fx
                rotations.setdefault(tuple(np.round(rot, 6).ravel()), rot)
    out = [(lp.solve(rot)[0], rot) for rot in rotations.values()]
    out.sort(key=lambda gr: gr[0])
    return out


class _Reached(Exception):
    """Raised inside the polish when a containment reaches the lower bound (nothing to gain)."""

    def __init__(self, x: np.ndarray):
        super().__init__()
        self.x = x


def _polish(held: np.ndarray, hull, rot: np.ndarray, t: np.ndarray, evaluations: int,
            floor: float = -np.inf):  # fmt: skip
    """Nelder-Mead on (rotation vector, t) from (``rot``, ``t``) for the exact largest distance
    of R X + t to K: (distance, rotation, t). It stops at once where the distance is within
    1e-9 of ``floor`` (a lower bound on every containment's growth: none can do better)."""
    from scipy.optimize import minimize

    def worst(x: np.ndarray) -> float:
        return float(distance_to_hull(held @ _turned(rot, x[:3]).T + x[3:], hull).max())

    def watched(x: np.ndarray) -> float:
        value = worst(x)
        if value <= floor + 1e-9:
            raise _Reached(np.array(x, dtype=np.float64))
        return value

    x0 = np.concatenate([np.zeros(3), t])
    step = max(1e-3, 0.02 * float(np.ptp(held, axis=0).max()))
    simplex = np.vstack([x0, x0 + np.diag([0.03] * 3 + [step] * 3)])
    try:
        res = minimize(watched, x0, method="Nelder-Mead",
                       options={"maxfev": evaluations, "initial_simplex": simplex,
                                "xatol": 1e-7, "fatol": 1e-9})  # fmt: skip
        x = res.x if res.fun <= worst(x0) else x0
    except _Reached as reached:
        x = reached.x
    return worst(x), _turned(rot, x[:3]), x[3:]


def least_growth(
    held: np.ndarray,
    passing: np.ndarray,
    frames_held: list[np.ndarray],
    frames_passing: list[np.ndarray],
    polish: int = 2,
    target: float | None = None,
    floor: float = -np.inf,
) -> Growth | None:
    """An upper bound on the growth ``held``'s hull needs to fit in ``passing``'s, certified.

    Parameters
    ----------
    held, passing : (n, 3) ndarray
        The two shapes' hull vertices about their centres, scene units.
    frames_held, frames_passing : list of (3, 3) ndarray
        Their :func:`hull_frames`.
    polish : int
        How many of the best frame-to-frame rotations are polished on the exact distance.
    target : float, optional
        The growth that matters: where the best rotation's unpolished distance exceeds 1.5 times
        it (and 1 % of the held shape's size), that distance is returned unpolished.
    floor : float, optional
        A lower bound on the growth (:func:`growth_lower_bound`): a containment within 1e-9 of
        it is the best there is, so the search stops there.

    Returns
    -------
    Growth or None
        The best containment found, its ``grow`` the exact largest vertex distance (None when
        no program succeeded).
    """
    held = np.asarray(held, dtype=np.float64)
    lp = _Program(held, passing)
    ranked = [c for c in _candidates(lp, frames_held, frames_passing) if np.isfinite(c[0])]
    if not ranked:
        return None
    hull = _Faces.of(_hull(passing))
    rot, t = ranked[0][1], lp.solve(ranked[0][1])[1]
    first = float(distance_to_hull(held @ rot.T + t, hull).max())
    if first <= floor + 1e-9:
        return Growth(first, rot, np.asarray(t, dtype=np.float64))  # the lower bound: optimal
    if target is not None and first > 1.5 * target + 0.01 * float(np.ptp(held, axis=0).max()):
        return Growth(first, rot, np.asarray(t, dtype=np.float64))  # far from target: as is
    best = (np.inf, rot, t)
    for _, turn in ranked[:polish]:
        best = min(
            best, _polish(held, hull, turn, lp.solve(turn)[1], 300, floor), key=lambda f: f[0]
        )
        if best[0] <= floor + 1e-9:
            break
    return Growth(best[0], best[1], np.asarray(best[2], dtype=np.float64))
