"""What the exact containment rules need of one shape: its convex hull, principal axes, largest
inscribed ball and canonical sizes (:class:`Body`), and whether its mesh is its hull's solid.

Used by the cascade's rules (:mod:`sieve_mi.cascade.rules`, which re-exports these names) and by
the solver's feasibility test (:mod:`sieve_mi.game.feasible`): both prove that a hole passing one
shape A passes another shape X, and both need hull(A) to be A's solid (or, for the feasibility
test, A's filled silhouette to be its hull's: :mod:`sieve_mi.game.feasible`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sieve_mi.geometry.canonical import principal_axes
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.size import canonical_extents, end_first_radius

__all__ = [
    "SAFETY",
    "Body",
    "ball_in_facets",
    "body",
    "hull_ball",
    "hull_edges_on_surface",
    "is_convex_solid",
]

#: A rule needs this much to spare, as a fraction of the passing shape's radius (round-off and
#: the 1e-5 of trimesh's convexity test).
SAFETY = 1e-4


@dataclass
class Body:
    """What the rules need of one shape (scene units, the shape's centre at the origin).

    Attributes
    ----------
    name : str
    points : (H, 3) ndarray
        Its convex hull's vertices.
    axes : (3, 3) ndarray
        Its principal axes, one per row (:func:`sieve_mi.geometry.canonical.principal_axes`).
    radius : float
        Largest distance from the centre to a vertex.
    convex : bool
        Its mesh is its hull's solid (closed, one body, convex): only then does it rule out holds.
    ball : float
        Radius of the largest ball inside its hull (0 when it is not convex or is flat).
    end_first : float
        :func:`sieve_mi.geometry.size.end_first_radius`.
    extents : (3,) ndarray
        :func:`sieve_mi.geometry.size.canonical_extents`, largest first.
    widths : (3,) ndarray
        Its hull's widths along ``axes``, in their order.
    """

    name: str
    points: np.ndarray
    axes: np.ndarray
    radius: float
    convex: bool
    ball: float
    end_first: float
    extents: np.ndarray
    widths: np.ndarray
    _grown: dict = field(default_factory=dict, repr=False, compare=False)


def body(shape: Shape) -> Body:
    """The :class:`Body` of a shape."""
    from scipy.spatial import ConvexHull, QhullError

    convex, ball = is_convex_solid(shape), 0.0
    axes = principal_axes(shape)
    along = shape.hull @ axes.T
    if convex:
        try:
            ball = hull_ball(ConvexHull(shape.hull).equations)
        except (QhullError, ValueError):
            convex = False
    return Body(
        name=shape.name,
        points=np.asarray(shape.hull, dtype=np.float64),
        axes=axes,
        radius=float(shape.radius),
        convex=convex,
        ball=ball,
        end_first=end_first_radius(shape)[0],
        extents=canonical_extents(shape),
        widths=along.max(axis=0) - along.min(axis=0),
    )


def is_convex_solid(shape: Shape) -> bool:
    """Watertight (vertices merged), one body, convex at every edge, and its volume equals its
    hull's (to 1e-6)."""
    import trimesh

    try:
        mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=True)
        if not trimesh.convex.is_convex(mesh):
            return False
        hull = mesh.convex_hull.volume
        return bool(hull > 0 and abs(abs(mesh.volume) - hull) <= 1e-6 * hull)
    except Exception:  # noqa: BLE001 - a degenerate mesh (flat, empty) is simply not convex
        return False


def hull_ball(equations: np.ndarray) -> float:
    """Radius of the largest ball inside {x : n . x + d <= 0} (qhull's unit-normal facets)."""
    return ball_in_facets(equations)[1]


def ball_in_facets(equations: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of the largest ball inside {x : n . x + d <= 0} (qhull's
    unit-normal facets); radius 0 where the program fails."""
    from scipy.optimize import linprog

    a = np.column_stack([equations[:, :3], np.ones(len(equations))])
    res = linprog(
        [0, 0, 0, -1.0], A_ub=a, b_ub=-equations[:, 3], bounds=[(None, None)] * 3 + [(0, None)]
    )
    return (res.x[:3], float(res.x[3])) if res.success else (np.zeros(3), 0.0)


def hull_edges_on_surface(shape: Shape, tol: float = 1e-7) -> bool:
    """Whether every edge of the shape's convex hull is covered by the mesh's own edges.

    Then, in every view, the outline of the hull's projection (made of projected hull edges)
    lies in the mesh's projection, so filling the gaps of that projection
    (``[fabrication] fill_holes``) gives the hull's projection: a hex nut's bore or a washer's
    hole is filled, an L's notch is not (the hull edge across it is no mesh edge).

    Parameters
    ----------
    shape : Shape
    tol : float
        Distance allowed off a hull edge and gap allowed between mesh edges along it, as a
        fraction of the shape's radius.
    """
    import trimesh

    try:
        hull = trimesh.convex.convex_hull(shape.hull)
    except Exception:  # noqa: BLE001 - a flat or degenerate hull: no claim
        return False
    sharp = hull.face_adjacency_edges[hull.face_adjacency_angles > 1e-6]
    ends = np.asarray(shape.vertices, dtype=np.float64)[_mesh_edges(shape.faces)]  # (E, 2, 3)
    eps = tol * max(shape.radius, 1e-300)
    return all(_covered(hull.vertices[a], hull.vertices[b], ends, eps) for a, b in sharp)


def _mesh_edges(faces: np.ndarray) -> np.ndarray:
    """The mesh's distinct edges as vertex index pairs, (E, 2)."""
    f = np.asarray(faces)
    pairs = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    return np.unique(pairs, axis=0)


def _covered(p: np.ndarray, q: np.ndarray, ends: np.ndarray, eps: float) -> bool:
    """Whether the mesh edges ``ends`` (E, 2, 3) lying on segment pq cover it (gaps <= eps)."""
    d = q - p
    length = float(np.linalg.norm(d))
    u = d / length
    rel = ends - p
    s = rel @ u  # (E, 2) along the segment
    off = np.linalg.norm(rel - s[..., None] * u, axis=-1)
    on = np.all(off <= eps, axis=1) & np.all((s >= -eps) & (s <= length + eps), axis=1)
    spans = np.sort(s[on], axis=1)
    reach = 0.0
    for lo, hi in spans[np.argsort(spans[:, 0])]:
        if lo > reach + eps:
            return False
        reach = max(reach, hi)
    return reach >= length - eps
