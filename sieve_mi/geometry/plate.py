"""The plate as solid geometry: B's diameter (the safe thickness) and an exact convex decomposition.

A sieve plate is the extrusion of a planar region R = (rectangle minus the hole H) over z in
[-thickness, 0]. Any partition of R into convex polygons, extruded, is an exact decomposition of
the plate into convex prisms: that is what collision engines (coal, MuJoCo) take. Triangulating R
(manifold3d's constrained triangulation of the exact outline) and merging triangles across
diagonals while the union stays convex (Hertel & Mehlhorn 1983) gives at most four times the
minimum number of convex pieces, so there are few seams.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np

__all__ = [
    "LENGTH_SLACK",
    "convex_pieces",
    "diameter",
    "plate_region",
    "prism_vertices",
    "safe_thickness",
]


#: Lengths within this many scene units count as equal in the thickness argument.
LENGTH_SLACK = 1e-6


def diameter(points: np.ndarray, chunk: int = 2048) -> float:
    """Largest distance between two of the points, scene units (exact, by brute force on chunks).

    Parameters
    ----------
    points : (n, 3) float
        A shape's vertices (its convex hull's are enough: the diameter is attained at hull
        vertices).
    chunk : int
        Rows per block of the pairwise computation (memory ``chunk * n`` floats).

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> round(diameter(cube), 6) == round(3 ** 0.5, 6)
    True
    """
    p = np.asarray(points, dtype=np.float64)
    best = 0.0
    for i in range(0, len(p), chunk):
        d2 = ((p[i : i + chunk, None, :] - p[None, :, :]) ** 2).sum(-1)
        best = max(best, float(d2.max()))
    return math.sqrt(best)


def safe_thickness(points_per_shape: list[np.ndarray]) -> float:
    """The thinnest plate on which every blocked verdict is proved: the largest diameter, rounded up.

    When a shape's highest point enters the plate's top face, every point of the shape lies within
    its diameter below that point, hence inside a slab as deep as the diameter: a plate at least
    that thick holds the whole shape inside the hole's prism at that moment, so the shape's
    projection must fit H (docs/fabrication.md). Rounded up to 0.1 scene units, ignoring excesses
    below :data:`LENGTH_SLACK` (a float32 mesh's 24 mm ball is 24.0000005 across).

    Parameters
    ----------
    points_per_shape : list of (n, 3) float
        Each shape's vertices (or hull vertices), placed as in the scene.

    Returns
    -------
    float
    """
    d = max(diameter(p) for p in points_per_shape)
    return math.ceil((d - LENGTH_SLACK) * 10.0) / 10.0


def plate_region(outline: manifold3d.CrossSection, margin: float) -> manifold3d.CrossSection:
    """The plate's material seen from above: the hole's bounding box grown by ``margin``, minus H.

    Parameters
    ----------
    outline : manifold3d.CrossSection
        The hole H, scene units.
    margin : float
        Material between H's bounding box and the plate's edge, scene units (> 0).
    """
    if margin <= 0:
        raise ValueError("the plate's margin around the hole must be positive")
    x0, y0, x1, y1 = outline.bounds()
    rect = manifold3d.CrossSection.square([x1 - x0 + 2 * margin, y1 - y0 + 2 * margin])
    return rect.translate([x0 - margin, y0 - margin]) - outline


def convex_pieces(region: manifold3d.CrossSection) -> list[np.ndarray]:
    """A partition of a polygonal region into convex polygons (counter-clockwise, (k, 2) float each).

    Parameters
    ----------
    region : manifold3d.CrossSection
        E.g. :func:`plate_region`; holes allowed.

    Returns
    -------
    list of (k, 2) float
        Convex polygons whose union is ``region`` and whose interiors are disjoint.
    """
    contours = [np.asarray(c, dtype=np.float64) for c in region.to_polygons()]
    if not contours:
        return []
    verts = np.concatenate(contours)
    tris = np.asarray(manifold3d.triangulate(contours), dtype=np.int64).reshape(-1, 3)
    polys = [_ccw(verts, list(t)) for t in tris]
    polys = _merge_convex(verts, polys)
    return [verts[p] for p in polys]


def prism_vertices(polygon: np.ndarray, z0: float, z1: float) -> np.ndarray:
    """The 2k corners of a polygon extruded from ``z0`` to ``z1``, as a (2k, 3) float array."""
    k = len(polygon)
    bottom = np.column_stack([polygon, np.full(k, z0)])
    top = np.column_stack([polygon, np.full(k, z1)])
    return np.concatenate([bottom, top])


def _ccw(verts: np.ndarray, idx: list[int]) -> list[int]:
    p = verts[idx]
    area = 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
    return idx if area >= 0 else idx[::-1]


def _is_convex(verts: np.ndarray, idx: list[int]) -> bool:
    p = verts[idx]
    a = np.roll(p, 1, axis=0)
    c = np.roll(p, -1, axis=0)
    cross = (p[:, 0] - a[:, 0]) * (c[:, 1] - p[:, 1]) - (p[:, 1] - a[:, 1]) * (c[:, 0] - p[:, 0])
    return bool(np.all(cross >= -1e-12 * max(1.0, float(np.abs(p).max()) ** 2)))


def _joined(a: list[int], b: list[int], u: int, v: int) -> list[int]:
    """Polygon ``a`` (with directed edge u->v) and ``b`` (with v->u) glued along that edge."""
    ia = a.index(u)
    a_rot = a[ia:] + a[:ia]  # starts u, v, ...
    ib = b.index(v)
    b_rot = b[ib:] + b[:ib]  # starts v, u, ...
    return a_rot[1:] + [u] + b_rot[2:]  # v, ..., u along a, then on along b back to v


def _merge_convex(verts: np.ndarray, polys: list[list[int]]) -> list[list[int]]:
    """Greedy Hertel-Mehlhorn: drop a shared diagonal whenever the glued polygon stays convex."""
    alive = dict(enumerate(polys))
    merged = True
    while merged:
        merged = False
        owner = {}
        for key, p in alive.items():
            for u, v in zip(p, p[1:] + p[:1]):
                owner[(u, v)] = key
        for (u, v), ka in list(owner.items()):
            kb = owner.get((v, u))
            if kb is None or ka == kb or ka not in alive or kb not in alive:
                continue
            a, b = alive[ka], alive[kb]
            if (u, v) not in zip(a, a[1:] + a[:1]) or (v, u) not in zip(b, b[1:] + b[:1]):
                continue
            glued = _joined(a, b, u, v)
            if _is_convex(verts, glued):
                alive[ka] = glued
                del alive[kb]
                merged = True
    return list(alive.values())
