"""Solids for the engine: the plate as exact convex prisms, each part as convex pieces.

The plate is an extrusion, so a convex partition of its top face (rectangle minus the holes),
extruded, is an exact convex decomposition (:mod:`sieve_mi.geometry.plate`). A convex part goes
in as it is (MuJoCo collides a mesh through its convex hull); a non-convex part is decomposed
with CoACD, refined to a bound, and the Hausdorff distance between the decomposition and the
mesh is measured (:mod:`sieve_mi.shake.decompose`).
Everything here is in scene units; :mod:`sieve_mi.shake.model` converts to metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import manifold3d
import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.plate import convex_pieces, plate_region
from sieve_mi.geometry.sieve import plate_holes, read_plate
from sieve_mi.shake.decompose import hausdorff

__all__ = [
    "Part",
    "Plate",
    "collision_hull",
    "collision_pieces",
    "part_from_mesh",
    "plate_from_mesh",
    "plate_from_outline",
    "section_holes",
    "simplify_loop",
]

#: A mesh is taken as convex when its volume is within this fraction of its hull's.
CONVEX_TOLERANCE = 1e-4
#: CoACD cuts each part in its principal axes' frame (its ``pca`` option). On the letters of
#: scenes/letters.toml this brings the decomposition's Hausdorff distance under 1 mm where the
#: default left a piece bridging a concavity (G: 3.29 to 0.78 mm, R: 1.90 to 0.84 mm; a lower
#: threshold did not: G at 0.01 gave 87 pieces and still 3.07 mm); see
#: benchmarks/notes/performance-history.md.
COACD_PCA = True


@dataclass
class Plate:
    """A sieve plate: z from ``-thickness`` to 0, its top face's centre at the origin.

    Attributes
    ----------
    loops : list of (k, 2) float
        The top face's boundary: its outer loop counter-clockwise, each hole's clockwise, scene
        units (:attr:`pieces` and :meth:`collision` split it into convex pieces).
    thickness : float
        Scene units.
    half_size : (2,) float
        Half the plate's width and depth (x, y), scene units.
    hole_area : float
        Total area of the holes, scene units squared.
    offset : (3,) float
        Where the plate's top-face centre was in the mesh file (to move it back), scene units.
    volume_error : float
        Relative difference between the mesh's volume and the extruded pieces' (0 for a plate
        built from an outline; large when the plate is more than its slab: a post, a rim).
    warnings : list of str
        What the model leaves out of the plate's mesh (a plate that is not a uniform slab).
    """

    loops: list
    thickness: float
    half_size: np.ndarray
    hole_area: float
    offset: np.ndarray
    volume_error: float = 0.0
    warnings: list = field(default_factory=list)

    @property
    def pieces(self) -> list:
        """The exact convex pieces (CCW, (k, 2) float each) tiling the top face, made on first
        use (a tray-sized sheet of 80 windowed holes takes minutes; the engine needs only
        :meth:`collision`)."""
        memo = self.__dict__.setdefault("_memo", {})
        if "pieces" not in memo:
            memo["pieces"] = collision_pieces(self.loops, 0.0)
        return memo["pieces"]

    def collision(self, tolerance: float) -> list:
        """The convex pieces the engine collides, the outline within ``tolerance`` (scene units;
        :func:`collision_pieces`), made once per tolerance (and carried to worker processes)."""
        memo = self.__dict__.setdefault("_memo", {})
        if tolerance not in memo:
            memo[tolerance] = collision_pieces(self.loops, tolerance)
        return memo[tolerance]

    def to_dict(self, tolerance: float | None = None) -> dict:
        """JSON-ready summary (scene units); ``convex_pieces`` counts the engine's pieces at
        ``tolerance`` (:meth:`collision`), the exact ones without it."""
        pieces = self.pieces if tolerance is None else self.collision(tolerance)
        return {
            "thickness": float(self.thickness),
            "size": [float(2 * self.half_size[0]), float(2 * self.half_size[1])],
            "hole_area": float(self.hole_area),
            "convex_pieces": len(pieces),
            "volume_error": float(self.volume_error),
            "warnings": list(self.warnings),
        }


def plate_from_outline(outline: manifold3d.CrossSection, margin: float, thickness: float) -> Plate:
    """A plate of ``thickness`` around the hole ``outline`` (its bounding box grown by ``margin``).

    Parameters
    ----------
    outline : manifold3d.CrossSection
        The hole(s), scene units.
    margin, thickness : float
        Scene units, > 0.
    """
    if thickness <= 0:
        raise SieveError("shake: the plate's thickness must be positive")
    region = plate_region(outline, margin)
    x0, y0, x1, y1 = region.bounds()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    loops = [np.asarray(c, np.float64) - centre for c in region.to_polygons()]
    half = np.array([(x1 - x0) / 2, (y1 - y0) / 2])
    offset = np.array([centre[0], centre[1], 0.0])
    return Plate(loops, float(thickness), half, float(outline.area()), offset)


def plate_from_mesh(mesh, path: str = "plate", units: str = "scene units") -> Plate:
    """Recover a plate from its mesh as ``check`` reads it (:func:`sieve_mi.geometry.sieve.
    read_plate`): the holes straight through along z, the slab around them for thickness.

    The top face is the slab's section (the plate's outline minus the holes), split into convex
    pieces. A plate that is not a uniform slab (a post, a raised rim) is shaken as its slab, and
    ``warnings`` says so; ``volume_error`` compares the mesh's volume with the slab's, so it
    counts what the slab leaves out.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The plate, scene units.
    path : str
        Its file, for messages.
    units : str
        The scene's units, for the warning.

    Raises
    ------
    SieveError
        One line: a flat plate, an open mesh, no through-hole, or a plate with no slab across z
        (a tilted plate among them: it says by how much, and to export it lying flat).
    """
    plate = read_plate(mesh, "z", path)  # it merges an STL's corners first
    region = plate.region
    x0, y0, x1, y1 = plate.footprint.bounds()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    half = np.array([(x1 - x0) / 2, (y1 - y0) / 2])
    loops = [np.asarray(c, np.float64) - centre for c in region.to_polygons()]
    extruded = region.area() * plate.thickness
    error = abs(plate.volume - extruded) / max(extruded, 1e-300)
    offset = np.array([centre[0], centre[1], plate.slab[1]])
    hole_area = float(sum(h.area() for h in plate.holes))
    out = Plate(loops, plate.thickness, half, hole_area, offset, float(error))
    if not plate.uniform:
        out.warnings.append(f"{path}: {plate.describe(units)}; shaken as its slab")
    return out


def collision_pieces(pieces: list[np.ndarray], tolerance: float) -> list[np.ndarray]:
    """The plate's convex pieces with its outline simplified within ``tolerance``: each loop
    (a hole, the rim) keeps, walking from its sharpest corner, the farthest vertex whose chord
    stays within ``tolerance`` of every vertex it skips (:func:`simplify_loop`).

    A round hole cut as a 256-gon is one convex piece per segment, since each piece of material
    can hold only one of the hole's (concave, seen from the material) edges; hundreds of pieces
    all touching a part seated on the rim make hundreds of contacts. Merging the segments that
    stay within ``tolerance`` of the exact outline (a 256-gon of 22 mm: 37 pieces at 0.05 mm, the
    fewest chords of its vertices that do) moves every point of the plate's outline by at most
    ``tolerance``; on a convex hole the chords lie inside it, so the hole only shrinks.

    Parameters
    ----------
    pieces : list of (k, 2) float
        Polygons whose union (positive winding) is the plate's top face: its convex pieces, or
        its boundary loops (:attr:`Plate.loops`).
    tolerance : float
        Largest move of the outline, the pieces' units; 0: the exact convex pieces.

    Returns
    -------
    list of (k, 2) float
        Convex polygons (CCW) tiling the simplified face.
    """
    if not pieces:
        return []
    region = manifold3d.CrossSection([np.asarray(p, dtype=np.float64) for p in pieces])
    if tolerance <= 0:
        return convex_pieces(region)
    loops = [simplify_loop(np.asarray(c, np.float64), tolerance) for c in region.to_polygons()]
    return convex_pieces(manifold3d.CrossSection(loops))


def simplify_loop(loop: np.ndarray, tolerance: float) -> np.ndarray:
    """A closed polygon's vertices with those dropped that lie within ``tolerance`` of the chord
    that replaces them (greedy: from the sharpest corner, each chord reaches as far as it can).

    Parameters
    ----------
    loop : (n, 2) float
        A closed polygon (the last vertex joins the first).
    tolerance : float
        Largest distance of a dropped vertex from its chord, the loop's units.

    Returns
    -------
    (k, 2) float
        The kept vertices, in the loop's order, ``3 <= k <= n`` (or the loop, if shorter).
    """
    n = len(loop)
    if n <= 3:
        return loop
    turn = np.abs(_turn(loop))
    start = int(np.argmax(turn))
    pts = np.roll(loop, -start, axis=0)
    pts = np.concatenate([pts, pts[:1]])  # closed: the walk ends where it began
    keep, i = [0], 0
    while i < n:
        j = i + 1
        while j + 1 <= n and _within(pts[i], pts[j + 1], pts[i + 1 : j + 1], tolerance):
            j += 1
        keep.append(j)
        i = j
    kept = pts[keep[:-1]]
    return kept if len(kept) >= 3 else loop


def _turn(loop: np.ndarray) -> np.ndarray:
    """The turning angle at each vertex of a closed polygon, radians."""
    a = loop - np.roll(loop, 1, axis=0)
    b = np.roll(loop, -1, axis=0) - loop
    return np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b))


def _within(p: np.ndarray, q: np.ndarray, mid: np.ndarray, tolerance: float) -> bool:
    """Every point of ``mid`` (m, 2) lies within ``tolerance`` of the segment ``p``-``q``."""
    d = q - p
    t = np.clip((mid - p) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
    return bool(np.all(np.linalg.norm(mid - (p + t[:, None] * d), axis=1) <= tolerance))


def collision_hull(points: np.ndarray, tolerance: float) -> np.ndarray:
    """The few of a convex piece's vertices whose hull stays within ``tolerance`` of the piece's
    hull, for the engine (as :func:`collision_pieces` does for the plate).

    Quickhull with a tolerance: start from four extreme vertices; each round, every face of the
    current hull takes the vertex farthest above it among those that see it farthest, while that
    vertex lies more than ``tolerance`` outside the hull. The result's hull lies inside the
    piece's hull (its vertices are the piece's), and every vertex left out is within
    ``tolerance`` of it (its exact distance, to the nearest face it sees), so the engine's part
    is the real one shrunk by at most ``tolerance``. A 19.75 mm coin cut as a 96-gon prism keeps
    about 40 vertices of each face's 96 at 0.05 mm; the engine's contact search walks fewer.

    Parameters
    ----------
    points : (n, 3) float
        The piece's vertices (its hull's, or more), scene units.
    tolerance : float
        Largest distance of a left-out vertex from the kept hull, scene units; 0 keeps every
        vertex.

    Returns
    -------
    (k, 3) float
        The kept vertices, ``k <= n``.
    """
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    if tolerance <= 0 or len(pts) <= 8:
        return pts
    try:
        keep = _extreme_four(pts)
        while True:
            hull = ConvexHull(pts[keep])
            above = pts @ hull.equations[:, :3].T + hull.equations[:, 3]  # (n, faces)
            face, height = np.argmax(above, axis=1), above.max(axis=1)
            order = [i for i in np.argsort(-height) if height[i] > tolerance]
            _, first = np.unique(face[order], return_index=True)
            far = [int(order[j]) for j in first]  # the farthest above each face
            if not far:  # a face's height is a lower bound of the distance: check the exact one
                far = _too_far(pts, pts[keep][hull.simplices], above, tolerance)
                if not far:
                    return pts[keep]
            keep.extend(far)
    except QhullError:  # flat or degenerate: no simplification
        return pts


def _extreme_four(pts: np.ndarray) -> list[int]:
    """Indices of four vertices spanning a tetrahedron: the extremes along x, the farthest from
    their line, the farthest from their plane."""
    a, b = int(np.argmin(pts[:, 0])), int(np.argmax(pts[:, 0]))
    u = (pts[b] - pts[a]) / max(np.linalg.norm(pts[b] - pts[a]), 1e-300)
    off = (pts - pts[a]) - np.outer((pts - pts[a]) @ u, u)
    c = int(np.argmax(np.linalg.norm(off, axis=1)))
    n = np.cross(pts[b] - pts[a], pts[c] - pts[a])
    d = int(np.argmax(np.abs((pts - pts[a]) @ n)))
    return [a, b, c, d]


def _too_far(pts, triangles, above, tolerance: float) -> list[int]:
    """The vertices farther than ``tolerance`` from the hull bounded by ``triangles`` (F, 3, 3),
    ``above`` (n, F) their heights over its faces' planes.

    A vertex outside a convex solid is nearest to a point of a face it lies above (the vector
    to it is a positive sum of the normals of the faces there, so it has a positive component
    along one of them), so only those faces are measured."""
    import trimesh

    vertex, face = np.nonzero(above > 0)
    if not len(vertex):
        return []
    p = pts[vertex]
    d = np.linalg.norm(trimesh.triangles.closest_point(triangles[face], p) - p, axis=1)
    nearest = np.full(len(pts), np.inf)
    np.minimum.at(nearest, vertex, d)
    return [int(i) for i in np.nonzero(np.isfinite(nearest) & (nearest > tolerance))[0]]


def section_holes(mesh, path: str = "plate") -> list[np.ndarray]:
    """The holes of a plate mesh straight through along z, as (k, 2) loops (scene units).

    Each hole's outer loop, as read by :func:`sieve_mi.geometry.sieve.plate_holes`.
    """
    out = []
    for hole in plate_holes(mesh, "z", path):
        loops = [np.asarray(c, dtype=np.float64) for c in hole.to_polygons()]
        out.append(max(loops, key=lambda c: abs(_area(c))))
    return out


def _area(loop: np.ndarray) -> float:
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@dataclass
class Part:
    """A part as the engine sees it (scene units, about its centre of mass).

    Attributes
    ----------
    name : str
    role : str or None
        ``"A"`` (must pass), ``"B"`` (must be blocked) or None.
    hulls : list of (n, 3) float
        Vertices of each convex piece, relative to the centre of mass.
    volume : float
        Scene units cubed.
    inertia : (3, 3) float
        Inertia tensor per unit density about the centre of mass (scene units^5).
    radius : float
        Largest distance from the centre of mass to a vertex, scene units.
    convex : bool
        Whether the mesh went in as one convex piece.
    hausdorff : float
        Sampled Hausdorff distance between the mesh and the union of ``hulls``, scene units.
    hausdorff_resolution : float
        Spacing of the samples (the distance's uncertainty), scene units.
    hausdorff_bound : float
        The bound the pieces were refined to, scene units (0: none).
    warnings : list of str
    com : (3,) float
        The centre of mass in the mesh's frame, scene units.
    """

    name: str
    role: str | None
    hulls: list
    volume: float
    inertia: np.ndarray
    radius: float
    convex: bool
    hausdorff: float
    hausdorff_resolution: float
    warnings: list
    com: np.ndarray | None = None
    hausdorff_bound: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready geometry summary (scene units)."""
        return {
            "convex": self.convex,
            "pieces": len(self.hulls),
            "volume": float(self.volume),
            "radius": float(self.radius),
            "hausdorff": float(self.hausdorff),
            "hausdorff_resolution": float(self.hausdorff_resolution),
            "hausdorff_bound": float(self.hausdorff_bound),
            "within_bound": None
            if self.hausdorff_bound <= 0
            else bool(self.hausdorff <= self.hausdorff_bound),
        }


def part_from_mesh(
    mesh, name: str, role: str | None, threshold: float, seed: int = 0, bound: float = 0.0
) -> Part:
    """Convex pieces, volume and inertia of one part.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The part, scene units (any pose).
    name : str
    role : str or None
    threshold : float
        CoACD's concavity threshold (used only for a non-convex part).
    seed : int
        CoACD's seed.
    bound : float
        Largest Hausdorff distance wanted between the part and its pieces, scene units: a piece
        bulging out further is split again (:func:`sieve_mi.shake.decompose.refine`); a part
        left over it gets a warning. 0: CoACD's pieces as they are, no warning.
    """
    import trimesh

    warnings = []
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)  # merge an STL's corners
    try:
        with np.errstate(invalid="ignore", divide="ignore"):
            hull = mesh.convex_hull
            flat = not hull.volume > 0
    except Exception:  # qhull refuses flat or degenerate point sets
        flat = True
    if flat:
        raise SieveError(f"{name}: the part is flat (no volume); it cannot be simulated")
    solid = mesh if mesh.is_volume else hull
    if solid is hull and not mesh.is_volume:
        warnings.append(
            f"{name}: mesh is not a closed volume; its convex hull gives mass and shape"
        )
    volume = float(solid.volume)
    convex = bool(solid is hull or hull.volume - volume <= CONVEX_TOLERANCE * hull.volume)
    com = np.asarray(solid.center_mass, dtype=np.float64)
    if convex:
        hulls = [np.asarray(hull.vertices) - com]
    else:
        hulls = [p - com for p in _coacd_pieces(mesh, threshold, seed, bound)]
    inertia = np.asarray(solid.moment_inertia, dtype=np.float64) / solid.density
    radius = float(np.linalg.norm(np.asarray(hull.vertices) - com, axis=1).max())
    h, res = hausdorff(solid, hulls, com) if not convex else (0.0, 0.0)
    if bound > 0 and h > bound:
        warnings.append(
            f"{name}: its {len(hulls)} convex pieces are {h:.3g} scene units from the part "
            f"(Hausdorff, sampled to {res:.2g}), over the bound of {bound:.3g}: the part is "
            "fatter in the engine than it is, so its pass fraction may be too low"
        )
    return Part(name, role, hulls, volume, inertia, radius, convex, h, res, warnings, com, bound)


def _coacd_pieces(mesh, threshold: float, seed: int, bound: float = 0.0) -> list[np.ndarray]:
    """CoACD's convex pieces of a mesh, vertices (n, 3) float each (cached on disk:
    :mod:`sieve_mi.shake.decompose`)."""
    from sieve_mi.shake.decompose import coacd_pieces

    return coacd_pieces(
        np.asarray(mesh.vertices, np.float64),
        np.asarray(mesh.faces, np.int64),
        bound=float(bound),
        threshold=float(threshold),
        seed=int(seed),
        pca=COACD_PCA,
    )
