"""The exact hole polygon H: projections of triangle meshes, offsets and booleans (manifold3d).

The raster hole drives the search; everything that must hold for the printed plate is computed on
polygons:

1. the projection of every placed A is the union of its projected triangles (manifold3d
   :class:`~manifold3d.CrossSection`, positive fill rule after orienting every triangle
   counter-clockwise), which is exact for any triangle soup, open or non-manifold;
2. that union is offset outward by the tolerance with round joins. Round joins are polygons whose
   chords fall inside the true arcs, so the offset distance is raised by the chord sagitta and by
   the simplification tolerance: the outline never comes inward of the exact dilation
   proj(A) + disk(tolerance), and lies at most 0.3 % of the tolerance outside it;
3. enclosed gaps are filled (only outer contours kept) when ``fill_holes`` is set.

Also here, for any region: :func:`silhouette` (a shape's exact projection at a pose),
:func:`union`, and :class:`Boundary` (exact and fast approximate signed distances to a region's
outline, with :func:`along` to sample segments).
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import shapely
import trimesh

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import to_matrix

__all__ = [
    "ARC_ERROR",
    "Boundary",
    "SIMPLIFY",
    "along",
    "dilated",
    "dilated_segments",
    "edge_on_segments",
    "filled",
    "hole_outline",
    "is_closed",
    "placed_vertices",
    "projection",
    "raster_agreement",
    "rasterize",
    "round_segments",
    "silhouette",
    "union",
]

#: Largest distance by which a round join's chords may fall short of the true arc, as a fraction of
#: the tolerance (the offset is raised by this much so the outline is never inside the exact one).
ARC_ERROR = 0.002
#: Simplification tolerance as a fraction of the tolerance (the offset is raised by it too).
SIMPLIFY = 0.001


def placed_vertices(
    shape: Shape, quat: np.ndarray, trans_xy: np.ndarray, z: float = 0.0
) -> np.ndarray:
    """The shape's vertices rotated about its centre by ``quat`` and moved to (tx, ty, z).

    Parameters
    ----------
    shape : Shape
    quat : (4,) array_like
        Rotation (w, x, y, z).
    trans_xy : (2,) array_like
        Translation in the hole's plane, scene units.
    z : float
        Height added to every vertex, scene units.

    Returns
    -------
    (V, 3) ndarray
    """
    v = shape.vertices @ to_matrix(np.asarray(quat, dtype=np.float64)).T
    return v + np.array([trans_xy[0], trans_xy[1], z])


def is_closed(shape: Shape) -> bool:
    """Whether the shape's mesh is watertight and consistently wound (enables the front-face shortcut)."""
    try:
        m = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
        return bool(m.is_watertight and m.is_winding_consistent and m.volume > 0)
    except Exception:  # noqa: BLE001 - any doubt means: use every triangle
        return False


def projection(
    vertices: np.ndarray, faces: np.ndarray, *, closed: bool = False
) -> manifold3d.CrossSection:
    """Exact projection of a triangle mesh onto the xy-plane: the union of its projected triangles.

    Parameters
    ----------
    vertices : (V, 3) ndarray
        Positions, scene units.
    faces : (F, 3) ndarray of int
    closed : bool
        The mesh is watertight with consistent outward orientation; then the triangles facing +z
        already cover the projection and the others are skipped (half the work).

    Returns
    -------
    manifold3d.CrossSection
        Empty if every triangle is seen edge-on.
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)][:, :, :2]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    scale = float(np.abs(tri).max()) if len(tri) else 1.0
    keep = np.abs(signed) > 1e-14 * max(scale, 1e-300) ** 2
    if closed:
        front = signed > 0
        if (keep & front).any():
            keep &= front
    if not keep.any():
        return manifold3d.CrossSection()
    loops = boundary_loops(np.asarray(faces)[keep], signed[keep] < 0)
    xy = np.asarray(vertices, dtype=np.float64)[:, :2]
    return manifold3d.CrossSection([xy[loop] for loop in loops], manifold3d.FillRule.Positive)


def boundary_loops(faces: np.ndarray, flip: np.ndarray) -> list[np.ndarray]:
    """The oriented boundary of a set of triangles, as closed loops of vertex indices.

    Each triangle (counter-clockwise in the projection once the ``flip`` ones are reversed)
    contributes its three edges; an edge met once each way (two neighbours side by side) cancels,
    so what is left is the boundary chain of the set, and every point of the plane has the same
    winding number about it as the number of triangles that cover it. Filled with the positive
    rule it is therefore exactly the union of the triangles, from a few edges instead of all the
    triangles (a closed mesh's front faces leave only its silhouette edges: 8 % of the cow's;
    the 525k-face beetle, open, every triangle counted, keeps 1.1 % of its edges).

    Parameters
    ----------
    faces : (F, 3) ndarray of int
    flip : (F,) bool ndarray
        Triangles to reverse.

    Returns
    -------
    list of (n,) int ndarrays
        Closed loops (the last vertex joins the first); every vertex has as many boundary edges
        in as out, so the edges split into such loops.
    """
    f = np.asarray(faces, dtype=np.int64).copy()
    f[flip] = f[flip][:, ::-1]
    a = f.ravel()
    b = f[:, [1, 2, 0]].ravel()
    n = int(max(a.max(initial=-1), b.max(initial=-1))) + 1
    keys, counts = np.unique(a * n + b, return_counts=True)
    reverse = (keys % n) * n + keys // n  # the key of the same edge the other way
    at = np.minimum(np.searchsorted(keys, reverse), len(keys) - 1)
    net = counts - np.where(keys[at] == reverse, counts[at], 0)
    keys, net = keys[net > 0], net[net > 0]
    edges = np.repeat(keys, net)
    out: dict[int, list[int]] = {}
    for start, end in zip((edges // n).tolist(), (edges % n).tolist()):
        out.setdefault(start, []).append(end)
    loops = []
    for first in list(out):
        while out.get(first):
            loop, at = [first], out[first].pop()
            while at != first:
                loop.append(at)
                at = out[at].pop()
            loops.append(np.asarray(loop))
    return loops


def filled(section: manifold3d.CrossSection) -> manifold3d.CrossSection:
    """The section with every enclosed gap filled: only its outer (counter-clockwise) contours."""
    outer = [c for c in section.to_polygons() if _signed_area(c) > 0]
    if not outer:
        return manifold3d.CrossSection()
    return manifold3d.CrossSection(outer, manifold3d.FillRule.Positive)


def _signed_area(contour: np.ndarray) -> float:
    x, y = np.asarray(contour, dtype=np.float64).T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def round_segments(tolerance: float, arc_error: float = ARC_ERROR) -> int:
    """Segments per full circle so that a chord's sagitta is at most ``arc_error * tolerance``."""
    # sagitta r (1 - cos(pi / n)) <= e r  <=>  n >= pi / acos(1 - e)
    return max(16, int(math.ceil(math.pi / math.acos(1.0 - arc_error))))


def dilated(section: manifold3d.CrossSection, tolerance: float) -> manifold3d.CrossSection:
    """Outward offset by ``tolerance`` that contains the exact dilation and stays within 0.3 % of it.

    Parameters
    ----------
    section : manifold3d.CrossSection
    tolerance : float
        Offset distance, scene units; 0 returns the section unchanged.
    """
    if tolerance <= 0 or section.is_empty():
        return section
    n = round_segments(tolerance)
    sagitta = tolerance * (1.0 - math.cos(math.pi / n)) / math.cos(math.pi / n)
    eps = SIMPLIFY * tolerance
    grown = section.offset(
        tolerance + sagitta + eps, manifold3d.JoinType.Round, circular_segments=n
    )
    return grown.simplify(eps)


def edge_on_segments(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Projections of the triangles seen exactly edge-on: each its longest projected edge, (S, 2, 2).

    :func:`projection` drops them (they have no area), but a flat part seen edge-on still makes a
    slot once the tolerance dilates these segments.
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)][:, :, :2]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    scale = float(np.abs(tri).max()) if len(tri) else 1.0
    flat = tri[np.abs(signed) <= 1e-14 * max(scale, 1e-300) ** 2]
    if len(flat) == 0:
        return np.zeros((0, 2, 2))
    ends = np.stack([flat[:, [0, 1]], flat[:, [1, 2]], flat[:, [2, 0]]], axis=1)  # (T, 3, 2, 2)
    length = np.linalg.norm(ends[:, :, 1] - ends[:, :, 0], axis=-1)
    segs = ends[np.arange(len(flat)), np.argmax(length, axis=1)]
    key = np.round(np.sort(segs.reshape(-1, 4), axis=1), 12)
    return segs[np.unique(key, axis=0, return_index=True)[1]]


def dilated_segments(segments: np.ndarray, tolerance: float) -> manifold3d.CrossSection:
    """The union of ``segments`` (S, 2, 2) dilated by ``tolerance``, as :func:`dilated` would."""
    if tolerance <= 0 or len(segments) == 0:
        return manifold3d.CrossSection()
    n = round_segments(tolerance)
    radius = tolerance / math.cos(math.pi / n) + SIMPLIFY * tolerance
    disk = manifold3d.CrossSection.circle(radius, n)
    stadiums = [
        manifold3d.CrossSection.batch_hull([disk.translate(list(a)), disk.translate(list(b))])
        for a, b in segments
    ]
    return manifold3d.CrossSection.batch_boolean(stadiums, manifold3d.OpType.Add)


def hole_outline(
    shapes: list[Shape],
    quats: np.ndarray,
    trans: np.ndarray,
    tolerance: float,
    fill_holes: bool = True,
    closed: list[bool] | None = None,
) -> manifold3d.CrossSection:
    """The exact hole H: the union of the placed A projections, dilated, gaps filled.

    Parameters
    ----------
    shapes : list of Shape
        The shapes that must pass.
    quats : (m, 4) ndarray
        Their rotations (w, x, y, z).
    trans : (m, 2) ndarray
        Their translations in the hole's plane, scene units.
    tolerance : float
        Dilation radius, scene units.
    fill_holes : bool
        Keep only outer contours (paper Fig. 4).
    closed : list of bool, optional
        Per shape, whether it is watertight (see :func:`projection`); default False.
    """
    parts, flat = [], []
    for i, shape in enumerate(shapes):
        v = placed_vertices(shape, quats[i], trans[i])
        is_closed_i = bool(closed[i]) if closed else False
        parts.append(projection(v, shape.faces, closed=is_closed_i))
        if not is_closed_i:  # a closed mesh's edge-on triangles lie inside its projection
            flat.append(edge_on_segments(v, shape.faces))
    union = (
        manifold3d.CrossSection.batch_boolean(parts, manifold3d.OpType.Add)
        if len(parts) > 1
        else parts[0]
    )
    out = dilated(union, tolerance)
    if flat and sum(len(f) for f in flat) and tolerance > 0:
        out = out + dilated_segments(np.concatenate(flat), tolerance)
    return filled(out) if fill_holes else out


def rasterize(section: manifold3d.CrossSection, frame: Frame) -> np.ndarray:
    """Pixel centres of ``frame`` inside ``section`` (even-odd over its contours), (N, N) bool."""
    from matplotlib.path import Path

    x, y = frame.centres()
    xx, yy = np.meshgrid(x, y)
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    inside = np.zeros(len(pts), dtype=np.int32)
    for contour in section.to_polygons():
        c = np.asarray(contour, dtype=np.float64)
        lo, hi = c.min(0), c.max(0)
        sel = np.flatnonzero(
            (pts[:, 0] >= lo[0])
            & (pts[:, 0] <= hi[0])
            & (pts[:, 1] >= lo[1])
            & (pts[:, 1] <= hi[1])
        )
        if len(sel):
            inside[sel] += Path(c).contains_points(pts[sel])
    return (inside % 2 == 1).reshape(frame.resolution, frame.resolution)


def raster_agreement(section: manifold3d.CrossSection, mask: np.ndarray, frame: Frame) -> dict:
    """Compare the exact outline with the raster hole.

    Returns
    -------
    dict
        ``polygon_area`` and ``raster_area`` (square scene units), their relative difference
        ``area_difference``, and ``pixels_only_raster`` / ``pixels_only_polygon``: pixel centres
        inside one but not the other.
    """
    poly = rasterize(section, frame)
    raster_area = float(mask.sum()) * frame.pixel_size**2
    area = float(section.area())
    return {
        "polygon_area": area,
        "raster_area": raster_area,
        "area_difference": (area - raster_area) / max(raster_area, 1e-300),
        "pixels_only_raster": int((mask & ~poly).sum()),
        "pixels_only_polygon": int((poly & ~mask).sum()),
    }


def along(a: np.ndarray, b: np.ndarray, spacing: float, most: int | None = None):
    """Points along segments a -> b (E, D), at most ``spacing`` apart (at most ``most`` per segment).

    Each segment contributes its start and evenly spaced points up to (not including) its end.

    Returns
    -------
    points : (P, D) ndarray
    segment : (P,) ndarray of int
        The segment each point lies on.
    start : (P,) ndarray of bool
        The point is its segment's start.
    """
    seg = b - a
    n = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / spacing)).astype(int)
    if most is not None:
        n = np.minimum(n, most)
    idx = np.repeat(np.arange(len(seg)), n)
    first = np.repeat(np.cumsum(n) - n, n)
    k = np.arange(n.sum())
    t = (k - first) / np.repeat(n, n)
    return a[idx] + t[:, None] * seg[idx], idx, k == first


class Boundary:
    """The exact outline of a region, for signed distances.

    Parameters
    ----------
    section : manifold3d.CrossSection
        The region (even-odd over its contours).
    spacing : float, optional
        Sample spacing along the boundary for :meth:`approx_signed`, scene units (default: 1/2000
        of the region's size).

    Attributes
    ----------
    a, b : (E, 2) ndarrays
        Each boundary segment's end points, scene units.
    size : float
        The larger side of the region's bounding box, scene units.
    """

    def __init__(self, section: manifold3d.CrossSection, spacing: float | None = None):
        from matplotlib.path import Path

        self.contours = [np.asarray(c, dtype=np.float64) for c in section.to_polygons()]
        self.paths = [Path(c) for c in self.contours]
        if self.contours:
            self.a = np.concatenate(self.contours)
            self.b = np.concatenate([np.roll(c, -1, axis=0) for c in self.contours])
            lo, hi = self.a.min(0), self.a.max(0)
            self.size = float(max(hi - lo))
        else:
            self.a = self.b = np.zeros((0, 2))
            self.size = 0.0
        self.spacing = spacing if spacing is not None else max(self.size, 1e-12) / 2000
        self._tree = None
        self._lines = None

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """(P,) bool: points (P, 2) inside the region (even-odd over the contours)."""
        xy = np.atleast_2d(xy)
        count = np.zeros(len(xy), dtype=np.int32)
        for p in self.paths:
            count += p.contains_points(xy)
        return count % 2 == 1

    def distance(self, xy: np.ndarray) -> np.ndarray:
        """(P,) exact distances from points (P, 2) to the boundary, scene units (GEOS, through
        shapely's vectorised ``distance`` on the prepared contours)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        if len(self.a) == 0:
            return np.full(len(xy), np.inf)
        if self._lines is None:
            rings = [np.vstack([c, c[:1]]) for c in self.contours]
            self._lines = shapely.MultiLineString(rings)  # rings of any lengths (many holes)
            shapely.prepare(self._lines)
        return shapely.distance(shapely.points(xy), self._lines)

    def signed(self, xy: np.ndarray) -> np.ndarray:
        """(P,) exact signed distances: positive outside the region, negative inside."""
        dist = self.distance(xy)
        return np.where(self.inside(xy), -dist, dist)

    def _nearest(self, xy: np.ndarray):
        """Distance to the nearest boundary sample and its index, for points (P, 2)."""
        if self._tree is None:
            self._build_tree()
        return self._tree.query(np.atleast_2d(np.asarray(xy, dtype=np.float64)))

    def approx_distance(self, xy: np.ndarray) -> np.ndarray:
        """(P,) distances to the boundary sampled every ``spacing``: at most half of it off."""
        return self._nearest(xy)[0]

    def approx_signed(self, xy: np.ndarray) -> np.ndarray:
        """Signed distances to the boundary sampled every ``spacing`` (fast: a k-d tree).

        The magnitude is at most half the spacing off. The sign comes from the nearest sample's
        outward normal (the mean of both edges' normals at a corner), which can be wrong only
        within about a spacing of the boundary.
        """
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        dist, k = self._nearest(xy)
        side = ((xy - self._samples[k]) * self._normals[k]).sum(-1)
        return np.where(side < 0, -dist, dist)

    def _build_tree(self) -> None:
        from scipy.spatial import cKDTree

        seg = self.b - self.a
        # Region on the left of every edge (manifold3d: outer contours CCW, holes CW).
        normal = np.column_stack([seg[:, 1], -seg[:, 0]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        prev = np.concatenate([np.roll(np.arange(len(c)), 1) for c in self.contours])
        prev += np.repeat(
            np.cumsum([0] + [len(c) for c in self.contours[:-1]]), [len(c) for c in self.contours]
        )
        self._samples, idx, corner = along(self.a, self.b, self.spacing)
        normals = normal[idx].copy()
        normals[corner] += normal[prev[idx[corner]]]  # a segment's start is a corner
        self._normals = normals
        self._tree = cKDTree(self._samples)


def silhouette(shape: Shape, quat, trans, closed: bool = False) -> manifold3d.CrossSection:
    """B's exact silhouette S at a pose: the union of its projected triangles."""
    return projection(placed_vertices(shape, quat, trans), shape.faces, closed=closed)


def union(sections: list):
    """The union of several CrossSections."""
    if len(sections) == 1:
        return sections[0]
    return manifold3d.CrossSection.batch_boolean(sections, manifold3d.OpType.Add)
