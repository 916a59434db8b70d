"""Loading meshes and preparing them for the silhouette and clearance computations.

Any triangle mesh that trimesh reads is valid input, including open, non-manifold, disconnected,
self-intersecting and flat (zero-thickness) meshes: nothing here assumes a solid. Empty meshes,
point clouds, non-finite coordinates and unreadable files raise a one-line
:class:`~sieve_mi.errors.SieveError`.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.errors import SieveError

__all__ = [
    "CONVEX_SLACK",
    "Segments",
    "Shape",
    "bodies",
    "convex_solid",
    "edge_length",
    "edge_topology",
    "load_shape",
    "load_trimesh",
    "mesh_sha256",
    "segments",
    "shape_from_arrays",
    "shape_from_trimesh",
]


@dataclass
class Shape:
    """A mesh centred at its bounding-box centre and scaled to scene units.

    Attributes
    ----------
    name : str
        Label used in reports (the file stem unless given).
    path : str
        Source file ("" for generated shapes).
    vertices : (V, 3) ndarray of float64
        Vertex positions relative to the centre, scene units.
    faces : (F, 3) ndarray of int64
        Triangle vertex indices.
    centre : (3,) ndarray
        Where the centre lies in the file's coordinates times the scale (scene units).
    radius : float
        Largest distance from the centre to a vertex (scene units): every rotation's silhouette
        lies in the disk of this radius.
    hull : (H, 3) ndarray
        Vertices of the convex hull (or all vertices if the hull is degenerate); the extremes of
        every projection are among them.
    """

    name: str
    path: str
    vertices: np.ndarray
    faces: np.ndarray
    centre: np.ndarray
    radius: float
    hull: np.ndarray = field(repr=False)

    @property
    def face_count(self) -> int:
        return int(len(self.faces))


def _fail(path: str, what: str) -> SieveError:
    return SieveError(f"{path}: {what}")


def _check_binary_stl(path: str) -> None:
    """Raise if ``path`` is a binary STL shorter than its header's triangle count says (cut off
    while copying or downloading), or a file named .stl that is not one; other files pass."""
    if not path.lower().endswith(".stl"):
        return
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        head = fh.read(84)
        if len(head) < 84 or head[:5].lower() == b"solid":  # ASCII STL (or too short to tell)
            return
        count = int.from_bytes(head[80:84], "little")
        if size >= 84 + 50 * count:
            return
        records = fh.read(50 * min(count, (size - 84) // 50, 1000))
    says = f"its header says {count:,} triangles ({84 + 50 * count:,} bytes), the file has {size:,}"
    if not records:
        raise _fail(path, f"is a truncated binary STL, or not an STL file: {says} bytes; copy or "
                    "export it again")  # fmt: skip
    corners = np.frombuffer(records, np.uint8).reshape(-1, 50)[:, :48].copy().view("<f4")
    if not np.all(np.isfinite(corners)) or np.abs(corners).max() > 1e12:  # not coordinates
        raise _fail(path, f"could not be read as a mesh: not an STL file (its bytes are not "
                    f"triangles, and as a binary STL {says} bytes); {_WHAT_TO_DO}")  # fmt: skip
    raise _fail(path, f"is a truncated binary STL: {says} bytes; copy or export it again")


def load_trimesh(path: str):
    """Read a triangle mesh with trimesh, merging scenes into one mesh.

    Raises
    ------
    SieveError
        If the file is missing, unreadable, or holds no triangles.
    """
    import trimesh

    if not os.path.exists(path):
        raise _fail(path, "mesh file not found")
    if os.path.isdir(path):
        raise _fail(path, "is a directory, not a mesh file")
    if not os.path.isfile(path):
        raise _fail(path, "is not a regular file; give a mesh file")
    _check_binary_stl(path)
    try:
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many exception types for bad files
        detail = (str(exc).splitlines() or ["no detail"])[0][:120]
        raise _fail(
            path, f"could not be read as a mesh ({type(exc).__name__}: {detail}); {_WHAT_TO_DO}"
        ) from None
    if isinstance(loaded, trimesh.Scene):
        parts = loaded.dump() if loaded.geometry else []
        geoms = [g for g in parts if isinstance(g, trimesh.Trimesh)]
        if not parts:  # trimesh found nothing it knows in the file
            raise _fail(path, f"could not be read as a mesh: no triangles found in it; {_WHAT_TO_DO}")  # fmt: skip
        if not geoms:
            raise _fail(path, f"holds {_kind(parts[0])} but no triangles; give a triangle mesh")
        loaded = trimesh.util.concatenate(geoms)
    if not isinstance(loaded, trimesh.Trimesh):
        raise _fail(path, f"holds {_kind(loaded)} but no triangles; give a triangle mesh")
    return loaded


#: What to do with a file that is not a readable mesh (the end of its one-line error).
_WHAT_TO_DO = (
    "check that it is a triangle mesh file (STL, OBJ, PLY, OFF, GLB, 3MF) and not empty, "
    "or export the part again"
)


def _kind(geometry) -> str:
    """What a non-triangle geometry that trimesh read is, in words (``"points (a point
    cloud)"``, ``"lines (a drawing)"``)."""
    import trimesh

    if isinstance(geometry, trimesh.PointCloud):
        return "points (a point cloud)"
    if isinstance(geometry, trimesh.path.Path):
        return "lines (a drawing)"
    return f"a {type(geometry).__name__}"


def shape_from_arrays(
    vertices: np.ndarray, faces: np.ndarray, *, name: str, path: str = "", scale: float = 1.0
) -> Shape:
    """Validate, scale and centre a triangle mesh.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertex positions in file units.
    faces : (F, 3) array_like of int
        Triangles.
    name, path : str
        Labels for reports and error messages.
    scale : float
        Uniform scale applied before centring (file units to scene units).

    Raises
    ------
    SieveError
        On empty meshes, non-finite coordinates, bad indices, or zero total area.
    """
    where = path or name
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) == 0:
        raise _fail(where, "has no vertices; give a non-empty triangle mesh")
    if faces.size == 0:
        raise _fail(where, "has no faces (a point cloud?); give a triangle mesh")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise _fail(where, "faces are not triangles")
    if not np.all(np.isfinite(vertices)):
        raise _fail(where, "has NaN or infinite vertex coordinates; repair or re-export the mesh")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise _fail(where, "has face indices outside the vertex list")
    if not (np.isfinite(scale) and scale > 0):
        raise _fail(where, f"scale {scale} must be a positive number")
    # Weld vertices at identical positions (STL stores every triangle's corners separately), so
    # that edges shared by two triangles are recognised as such.
    vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
    faces = inverse.ravel()[faces.astype(np.int64)]
    used = np.unique(faces)
    vertices = vertices * scale
    lo, hi = vertices[used].min(0), vertices[used].max(0)
    centre = 0.5 * (lo + hi)
    v = vertices - centre
    tri = v[faces]
    area = (
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )
    extent = float(np.max(hi - lo))
    if extent <= 0 or area <= 1e-12 * extent * extent:
        raise _fail(
            where,
            "has zero surface area (all triangles degenerate); give a mesh with real triangles",
        )
    radius = float(np.linalg.norm(v[used], axis=1).max())
    return Shape(
        name=name,
        path=path,
        vertices=v,
        faces=faces,
        centre=centre,
        radius=radius,
        hull=_hull_vertices(v[used]),
    )


def bodies(shape: Shape) -> int:
    """How many separate bodies a shape's mesh has: groups of triangles joined by shared
    vertices (welded at identical positions when loaded).

    One body is a connected set, so every projection of it is connected (what a perforated
    sheet's argument needs, :mod:`sieve_mi.geometry.pattern`). Several bodies may still touch or
    overlap in space; counting them as separate only makes a claim more cautious.

    Examples
    --------
    >>> import trimesh
    >>> two = trimesh.util.concatenate([trimesh.creation.box((1, 1, 1)),
    ...                                 trimesh.creation.box((1, 1, 1)).apply_translation((3, 0, 0))])
    >>> bodies(shape_from_trimesh(two, name="two")), bodies(shape_from_trimesh(
    ...     trimesh.creation.box((1, 1, 1)), name="one"))
    (2, 1)
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(shape.faces, dtype=np.int64)
    n = len(shape.vertices)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return int(len(np.unique(labels[np.unique(f)])))


#: :func:`convex_solid`'s tolerance: distances to the hull's planes within this fraction of the
#: shape's radius, and areas within this fraction, count as equal (float rounding of a mesh).
CONVEX_SLACK = 1e-9


def convex_solid(shape: Shape) -> bool:
    """Whether the shape's surface is the boundary of its convex hull (so the solid is convex).

    Every triangle must lie in the hull's boundary (its corners and centroid on a hull facet's
    plane, within :data:`CONVEX_SLACK` of the radius) and the triangles' area must be the hull's:
    a surface inside the boundary of a convex body with all of its area is that boundary. Then
    every slab section of the solid is convex, hence connected (what a perforated sheet's section
    proofs need, :mod:`sieve_mi.geometry.pattern`). A flat or degenerate shape is not.

    Examples
    --------
    >>> import trimesh
    >>> convex_solid(shape_from_trimesh(trimesh.creation.box((1, 2, 3)), name="box"))
    True
    >>> convex_solid(shape_from_trimesh(trimesh.creation.torus(10, 1), name="ring"))
    False
    """
    from scipy.spatial import ConvexHull

    try:
        hull = ConvexHull(shape.vertices)
    except Exception:  # flat or degenerate: no solid hull
        return False
    eps = CONVEX_SLACK * max(shape.radius, 1e-300)
    tri = shape.vertices[shape.faces]
    points = np.concatenate([tri.reshape(-1, 3), tri.mean(axis=1)])
    plane = hull.equations[:, :3] @ points.T + hull.equations[:, 3:4]  # (facets, points), <= 0
    if not np.all(np.abs(plane.max(axis=0)) <= eps):
        return False
    area = (
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )
    return bool(abs(area - hull.area) <= CONVEX_SLACK * hull.area)


def _hull_vertices(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of ``points`` (all points if the hull is degenerate, e.g. flat)."""
    try:
        from scipy.spatial import ConvexHull

        return points[ConvexHull(points).vertices]
    except Exception:  # flat or collinear input: the hull is 2D, keep every point
        return points


def load_shape(path: str, *, scale: float = 1.0, name: str | None = None) -> Shape:
    """Read, validate, scale and centre a mesh file (STL, OBJ, PLY, OFF, GLB, ... as trimesh reads).

    Parameters
    ----------
    path : str
        Mesh file.
    scale : float
        Uniform scale from file units to scene units.
    name : str, optional
        Label; defaults to the file stem.
    """
    mesh = load_trimesh(path)
    stem = os.path.splitext(os.path.basename(path))[0]
    return shape_from_arrays(mesh.vertices, mesh.faces, name=name or stem, path=path, scale=scale)


def shape_from_trimesh(mesh, *, name: str, scale: float = 1.0) -> Shape:
    """A :class:`Shape` from an in-memory ``trimesh.Trimesh`` (generated shapes, tests)."""
    return shape_from_arrays(mesh.vertices, mesh.faces, name=name, scale=scale)


@dataclass
class Segments:
    """A mesh's edges cut into short segments, with what is needed to tell silhouette edges.

    An edge lies on the outline of the projection only if it is a *silhouette edge*: a boundary
    edge (one face), a non-manifold edge (three or more faces), or an edge whose two faces project
    to the same side of it. For an edge a-b with opposite vertices o1, o2 this is the sign test
    ``(r3 . m1) (r3 . m2) >= 0`` with ``m_i = (b - a) x (o_i - a)`` and r3 the third row of the
    rotation; it does not depend on how faces are oriented, so polygon soups work too.

    Attributes
    ----------
    a, b : (S, 3) ndarrays
        Segment end points (centred mesh frame, scene units).
    m1, m2 : (S, 3) ndarrays
        The two faces' cross products of the segment's parent edge (zeros where ``always``).
    always : (S,) ndarray of bool
        Boundary or non-manifold parent edge: always a silhouette candidate.
    parent : (S,) ndarray of int or None
        Index of each segment's parent edge (ascending: an edge's segments are consecutive).
    """

    a: np.ndarray
    b: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    always: np.ndarray
    parent: np.ndarray | None = None

    def __len__(self) -> int:
        return int(len(self.a))


def edge_topology(vertices: np.ndarray, faces: np.ndarray):
    """Unique edges and, per edge, the cross products that decide whether it is a silhouette edge.

    Returns
    -------
    edges : (E, 2) ndarray of int
    m1, m2 : (E, 3) ndarrays
    always : (E,) ndarray of bool
    """
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    opposite = np.concatenate([faces[:, 2], faces[:, 0], faces[:, 1]])
    key = np.sort(e, axis=1)
    keep = key[:, 0] != key[:, 1]
    key, e, opposite = key[keep], e[keep], opposite[keep]
    edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    a, b = vertices[e[:, 0]], vertices[e[:, 1]]
    # Use the canonical direction (sorted vertex order) so both faces' cross products are comparable.
    flip = e[:, 0] != key[:, 0]
    a, b = np.where(flip[:, None], b, a), np.where(flip[:, None], a, b)
    m = np.cross(b - a, vertices[opposite] - a)
    order = np.argsort(inverse, kind="stable")
    first = np.zeros(len(edges), dtype=np.int64)
    np.cumsum(counts[:-1], out=first[1:])
    m1 = m[order[first]]
    second = np.minimum(first + 1, len(order) - 1)
    m2 = np.where((counts >= 2)[:, None], m[order[second]], 0.0)
    always = counts != 2
    m1 = np.where(always[:, None], 0.0, m1)
    m2 = np.where(always[:, None], 0.0, m2)
    return edges, m1, m2, always


def edge_length(shape: Shape) -> float:
    """Total length of a shape's edges, each counted once, scene units: what
    :func:`segments` samples (one sample per ``spacing`` along it).

    Examples
    --------
    >>> import trimesh
    >>> cube = shape_from_trimesh(trimesh.creation.box((1.0, 1.0, 1.0)), name="cube")
    >>> round(edge_length(cube), 4)  # 12 sides and 6 face diagonals
    20.4853
    """
    f = np.asarray(shape.faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    e = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
    v = shape.vertices
    return float(np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1).sum())


def segments(shape: Shape, spacing: float, samples_per_segment: int) -> Segments:
    """Cut every edge of ``shape`` into segments holding ``samples_per_segment`` samples each,
    so that samples along an edge are at most ``spacing`` apart.

    Parameters
    ----------
    shape : Shape
    spacing : float
        Largest distance between neighbouring samples, scene units (typically one pixel).
    samples_per_segment : int
        Samples per segment; segments are as long as ``samples_per_segment * spacing`` at most.
    """
    edges, m1, m2, always = edge_topology(shape.vertices, shape.faces)
    a, b = shape.vertices[edges[:, 0]], shape.vertices[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    pieces = np.maximum(1, np.ceil(length / (spacing * samples_per_segment))).astype(np.int64)
    parent = np.repeat(np.arange(len(edges)), pieces)
    start = np.cumsum(pieces) - pieces
    k = np.arange(len(parent)) - np.repeat(start, pieces)
    f0 = (k / pieces[parent])[:, None]
    f1 = ((k + 1) / pieces[parent])[:, None]
    d = b[parent] - a[parent]
    return Segments(
        a=a[parent] + f0 * d,
        b=a[parent] + f1 * d,
        m1=m1[parent],
        m2=m2[parent],
        always=always[parent],
        parent=parent,
    )


def mesh_sha256(vertices: np.ndarray, faces: np.ndarray) -> str:
    """Hex SHA-256 of a mesh's arrays: vertices as float64, then faces as int64 (C order).

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int

    Examples
    --------
    >>> import numpy as np
    >>> len(mesh_sha256(np.zeros((3, 3)), np.array([[0, 1, 2]])))
    64
    """
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    return h.hexdigest()
