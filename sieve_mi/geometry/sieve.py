"""Reading a given plate mesh (a sieve): its through-holes along an axis and the slab around them.

Every reader of a user's plate (``check``, ``certify``, ``shake``, the viewer) goes through here,
so a plate is measured one way.

**Holes.** A straight line along the axis is free iff it misses every triangle, so the free region
is the plate's filled outline (its *footprint*) minus the union ``P`` of its projected triangles
(manifold3d); each connected free region is one through-hole. This holds for any mesh, also for
holes that narrow inside the plate.

**The slab.** For a proof a plate's thickness must be a lower bound of the material around the
holes. With the axis as height ``w``, let ``S(w)`` be the plate's section at height ``w``. Always
``S(w)`` lies in ``P`` (a point inside the solid projects onto some triangle), so ``S(w) = P``
exactly when ``area S(w) = area P``: the section is full, with nothing open but the holes. The
*slab* is the longest interval ``[w0, w1]`` over which every section is full; its length is the
thickness used. A post, boss or raised rim adds no thickness; a chamfer or a pocket takes its
depth off; a tilted plate has no full section at all. Between two consecutive vertex heights the
section's polygon moves linearly, so its area is a quadratic in ``w``; as it never exceeds
``area P``, equal values at three heights of the interval prove it constant there. A section's
area comes from Green's theorem, ``A = 1/2 sum (x_p y_q - x_q y_p)`` over the segments where the
triangles cross the plane, each oriented by its face's outward normal ``n`` along ``z x n``: no
polygon assembly, exact for a closed mesh, vectorised over all heights.

A plate whose slab is its whole extent along the axis is a *uniform slab*; any other is named as
such (:meth:`PlateReading.describe`), and one with no slab is refused. A tilted plate has none:
its holes' walls lean, so every section's holes are wider than the holes straight through.

**On a raster.** :func:`read_plate_holes` puts a plate's holes on one frame centred on them
(:class:`SieveHoles`), as ``check`` plays against them and its page draws them; a hole image's
holes come the same way from :func:`sieve_mi.geometry.hole_image.read_image_holes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import manifold3d
import numpy as np
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import load_trimesh
from sieve_mi.geometry.outline import filled, projection
from sieve_mi.geometry.raster import Frame

__all__ = [
    "AREA_TOLERANCE",
    "AXIS_INDEX",
    "SAME_HOLE",
    "PlateReading",
    "SieveHoles",
    "axis_frame",
    "distinct_holes",
    "frame_for_polygons",
    "full_slab",
    "plate_holes",
    "read_plate",
    "read_plate_holes",
    "section_areas",
    "tilt",
]

#: Index of each axis name among x, y, z.
AXIS_INDEX = {"x": 0, "y": 1, "z": 2}

#: A section counts as full when its area is within this fraction of the projection's.
AREA_TOLERANCE = 1e-6

#: Lengths below this fraction of the plate's size count as zero (flatness, uniformity, and
#: vertex heights closer than this are one level).
LENGTH_FRACTION = 1e-6

#: Most (triangle, height) pairs evaluated at once by :func:`section_areas`.
PAIR_CHUNK = 2_000_000


@dataclass
class PlateReading:
    """A plate mesh read along one axis (coordinates ``(u, v, w)``: the other two axes in a
    right-handed order, then the axis).

    Attributes
    ----------
    path : str
        The mesh's file (or a name), for messages.
    axis : str
        ``"x"``, ``"y"`` or ``"z"``.
    holes : list of manifold3d.CrossSection
        The through-holes in ``(u, v)``, scene units, largest first.
    footprint : manifold3d.CrossSection
        The plate's filled outline in ``(u, v)``.
    extent : (float, float)
        The mesh's lowest and highest ``w``, scene units.
    slab : (float, float)
        The longest ``w`` interval over which every section is the footprint minus the holes.
    tilt : float
        Angle between the axis and the plate's dominant face normal, degrees.
    volume : float
        The mesh's enclosed volume, scene units cubed.
    vertices : (V, 3) float
        The mesh's vertices in ``(u, v, w)``.
    faces : (F, 3) int
    """

    path: str
    axis: str
    holes: list
    footprint: manifold3d.CrossSection
    extent: tuple
    slab: tuple
    tilt: float
    volume: float
    vertices: np.ndarray
    faces: np.ndarray

    @property
    def thickness(self) -> float:
        """The slab's thickness: a lower bound of the material around the holes, scene units."""
        return float(self.slab[1] - self.slab[0])

    @property
    def overall(self) -> float:
        """The mesh's extent along the axis, scene units."""
        return float(self.extent[1] - self.extent[0])

    @property
    def uniform(self) -> bool:
        """Whether the plate is one slab: its full sections span its whole extent."""
        return self.overall - self.thickness <= LENGTH_FRACTION * _size(self.vertices)

    @property
    def region(self) -> manifold3d.CrossSection:
        """The slab's section: the footprint minus the holes, in ``(u, v)``."""
        return self.footprint - _union(self.holes)

    def describe(self, units: str = "mm") -> str:
        """``""`` for a uniform slab, else the line naming it (callers add what they use)."""
        if self.uniform:
            return ""
        text = (
            f"plate is not a uniform slab: {self.thickness:.4g} {units} where the holes are, "
            f"{self.overall:.4g} {units} overall"
        )
        if self.tilt >= 0.05:
            text += f" (tilted {self.tilt:.1f}° from {self.axis})"
        return text

    def to_dict(self) -> dict:
        """JSON-ready summary (scene units)."""
        return {
            "axis": self.axis,
            "thickness": self.thickness,
            "overall": self.overall,
            "slab": [float(w) for w in self.slab],
            "uniform": self.uniform,
            "tilt_deg": float(self.tilt),
        }


def axis_frame(vertices: np.ndarray, axis: str) -> np.ndarray:
    """Vertices in ``(u, v, w)``: the axis last, the other two in a right-handed order."""
    a = AXIS_INDEX[axis]
    order = [i for i in range(3) if i != a] + [a]
    v = np.asarray(vertices, dtype=np.float64)[:, order]
    return v[:, [1, 0, 2]] if a == 1 else v  # y: (z, x, y)


def _mesh(source, path: str | None):
    """A trimesh mesh and its name from a file path or a mesh; finite with triangles."""
    if isinstance(source, str):
        mesh, path = load_trimesh(source), path or source
    else:
        mesh, path = source, path or "plate"
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if len(mesh.faces) == 0 or not np.all(np.isfinite(v)):
        raise SieveError(
            f"{path}: the sieve mesh has no usable triangles (or non-finite coordinates)"
        )
    # an STL's corners merged: its outline is walked once, not triangle by triangle (a tray
    # sheet of 80 holes, 1.75 million corners: 4.6 s, against 285 s unmerged)
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=True), path


def _union(sections: list) -> manifold3d.CrossSection:
    out = manifold3d.CrossSection()
    for s in sections:
        out = out + s
    return out


def _perimeter(section: manifold3d.CrossSection) -> float:
    loops = [np.asarray(c, dtype=np.float64) for c in section.to_polygons()]
    return float(sum(np.linalg.norm(c - np.roll(c, 1, axis=0), axis=1).sum() for c in loops))


def _size(v: np.ndarray) -> float:
    return max(1.0, float(np.ptp(v, axis=0).max())) if len(v) else 1.0


def _holes(v: np.ndarray, faces: np.ndarray, path: str, axis: str):
    """The projection ``P``, the footprint and the through-holes (largest first)."""
    solid = projection(v, faces)
    foot = filled(solid)
    free = foot - solid
    holes = [h for h in free.decompose() if h.area() > 1e-9 * max(solid.area(), 1e-300)]
    if not holes:
        raise SieveError(
            f"{path}: no through-hole along {axis} (every line along {axis} inside the plate hits "
            "it); check --axis or the file"
        )
    return solid, foot, sorted(holes, key=lambda h: -h.area())


def plate_holes(source, axis: str = "z", path: str | None = None) -> list:
    """The through-holes of a plate mesh along ``axis`` (any triangle mesh, closed or not).

    Parameters
    ----------
    source : str or trimesh.Trimesh
        A mesh file or a loaded mesh, scene units.
    axis : {"x", "y", "z"}
    path : str, optional
        The name used in messages (default the file).

    Returns
    -------
    list of manifold3d.CrossSection
        Exact outlines in ``(u, v)`` (:func:`axis_frame`), largest first.

    Raises
    ------
    SieveError
        If the mesh cannot be read or has no through-hole along the axis.
    """
    mesh, path = _mesh(source, path)
    return _holes(axis_frame(mesh.vertices, axis), np.asarray(mesh.faces), path, axis)[2]


def _crossings(tri: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Each triangle's signed share of its section's area at height ``h`` (Green's theorem).

    ``tri`` (N, 3, 3) float; every triangle's lowest vertex is below ``h`` and its highest above.
    """
    p, q = tri, np.roll(tri, -1, axis=1)  # the edges a->b, b->c, c->a
    dz = q[..., 2] - p[..., 2]
    cross = (p[..., 2] - h[:, None]) * (q[..., 2] - h[:, None]) < 0
    s = np.where(cross, (h[:, None] - p[..., 2]) / np.where(cross, dz, 1.0), 0.0)
    pts = p[..., :2] + s[..., None] * (q[..., :2] - p[..., :2])
    first = np.argmax(cross, axis=1)
    second = 2 - np.argmax(cross[:, ::-1], axis=1)
    rows = np.arange(len(tri))
    a, b = pts[rows, first], pts[rows, second]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    along = (b[:, 0] - a[:, 0]) * -n[:, 1] + (b[:, 1] - a[:, 1]) * n[:, 0]  # on z x n
    return 0.5 * np.sign(along) * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])


def section_areas(vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Areas of a closed mesh's sections at the given heights (``w``, the third coordinate).

    Parameters
    ----------
    vertices : (V, 3) float
        Scene units; for a closed, outward-oriented mesh (inward: the areas come out negative).
    faces : (F, 3) int
    heights : (H,) float
        Ascending, none equal to a vertex's height.

    Returns
    -------
    (H,) float
        Scene units squared.

    Examples
    --------
    >>> import trimesh
    >>> box = trimesh.creation.box((2.0, 3.0, 4.0))
    >>> section_areas(box.vertices, box.faces, np.array([-1.0, 0.5])).round(9).tolist()
    [6.0, 6.0]
    """
    v = np.asarray(vertices, dtype=np.float64)
    v = v - np.array([*(0.5 * (v[:, :2].min(0) + v[:, :2].max(0))), 0.0])  # shoelace near 0
    tri = v[np.asarray(faces)]
    heights = np.asarray(heights, dtype=np.float64)
    first = np.searchsorted(heights, tri[..., 2].min(1), side="right")
    count = np.maximum(np.searchsorted(heights, tri[..., 2].max(1), side="left") - first, 0)
    areas = np.zeros(len(heights))
    ends = np.cumsum(count)
    start = 0
    while start < len(tri):
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + PAIR_CHUNK, side="right")))
        face = np.repeat(np.arange(start, stop), count[start:stop])
        offset = np.arange(len(face)) - np.repeat(ends[start:stop] - count[start:stop] - base,
                                                  count[start:stop])  # fmt: skip
        at = first[face] + offset
        areas += np.bincount(at, _crossings(tri[face], heights[at]), minlength=len(heights))
        start = stop
    return areas


def full_slab(
    vertices: np.ndarray, faces: np.ndarray, area: float, perimeter: float = 0.0
) -> tuple[float, float] | None:
    """The longest height interval over which every section of a closed mesh has ``area``.

    Sections count as full within ``AREA_TOLERANCE * area`` plus a sliver of width
    ``LENGTH_FRACTION`` times the plate's size along ``perimeter`` (a float32 file's rounding).

    Parameters
    ----------
    vertices : (V, 3) float
        In ``(u, v, w)``, scene units.
    faces : (F, 3) int
    area, perimeter : float
        The projection's area (no section is larger) and outline length, scene units.

    Returns
    -------
    (w0, w1) or None
        None when no interval between two vertex heights is full.
    """
    w = np.unique(np.asarray(vertices, dtype=np.float64)[:, 2])
    levels = w[np.concatenate([[True], np.diff(w) > LENGTH_FRACTION * _size(vertices)])]
    if len(levels) < 2:
        return None
    span = np.diff(levels)
    heights = (levels[:-1, None] + span[:, None] * np.array([0.25, 0.5, 0.75])).ravel()
    got = section_areas(vertices, faces, heights)
    got = got * (1.0 if got.sum() >= 0 else -1.0)  # an inward-wound mesh
    slack = AREA_TOLERANCE * area + perimeter * LENGTH_FRACTION * _size(vertices)
    full = np.all(np.abs(got - area).reshape(-1, 3) <= slack, axis=1)
    best, run = None, None
    for i, ok in enumerate(full):
        run = (run if run is not None else i) if ok else None
        if run is not None and (best is None or i + 1 - run > best[1] - best[0]):
            best = (run, i + 1)
    return None if best is None else (float(levels[best[0]]), float(levels[best[1]]))


def tilt(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The angle between the third axis and the plate's dominant face normal, degrees.

    The dominant normal is the top eigenvector of the area-weighted ``sum n n^T`` of the face
    normals: a plate's two large faces outweigh its rims (for a plate wider than it is thick).
    A tilted plate has no full section (its holes' walls lean), so this only names the cause.
    """
    v = np.asarray(vertices, dtype=np.float64)
    tri = v[np.asarray(faces)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    keep = length > 0
    if not keep.any():
        return 0.0
    m = (n[keep].T / np.sqrt(length[keep])) @ (n[keep] / np.sqrt(length[keep])[:, None])
    u = np.linalg.eigh(m)[1][:, -1]
    return math.degrees(math.acos(min(1.0, abs(float(u[2])))))


def _closed(v: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The mesh with coincident vertices merged, and its open (unpaired) edges' count (-1: closed
    but wound inconsistently)."""
    import trimesh

    merged = trimesh.Trimesh(v, faces, process=True, validate=False)
    edges = np.sort(merged.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = int((counts != 2).sum())
    if open_edges == 0 and not merged.is_winding_consistent:
        open_edges = -1
    return np.asarray(merged.vertices), np.asarray(merged.faces), open_edges


def _no_slab(path: str, axis: str, angle: float) -> SieveError:
    """The one line for a plate with no full section: tilted (its largest faces 0.5° to 89.5°
    from square to the axis; it has through-holes along the axis, so it does not lie along
    another one), or not a slab."""
    if 0.5 <= angle <= 89.5:
        return SieveError(
            f"{path}: the plate is tilted {angle:.1f}° from the {axis} axis (no slab of it lies "
            f"across {axis}); export it lying flat, with its holes along {axis}"
        )
    tilted = f", tilted {angle:.2g}° from {axis}" if 1e-3 <= angle < 0.5 else ""
    return SieveError(
        f"{path}: no section across {axis} holds the whole plate around its holes (not a slab "
        f"with straight holes along {axis}{tilted}); give a plate that is a slab with its holes "
        f"along {axis}"
    )


def read_plate(source, axis: str = "z", path: str | None = None) -> PlateReading:
    """Read a plate mesh once: its through-holes along ``axis`` and the slab around them.

    Parameters
    ----------
    source : str or trimesh.Trimesh
        A mesh file or a loaded mesh, scene units.
    axis : {"x", "y", "z"}
    path : str, optional
        The name used in messages (default the file).

    Returns
    -------
    PlateReading

    Raises
    ------
    SieveError
        One line: an unreadable mesh, no through-hole, a flat plate (no thickness), a mesh that is
        not closed, a tilted plate, or no full section around the holes.
    """
    mesh, path = _mesh(source, path)
    v = axis_frame(mesh.vertices, axis)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    solid, foot, holes = _holes(v, faces, path, axis)
    extent = (float(v[:, 2].min()), float(v[:, 2].max()))
    if extent[1] - extent[0] <= LENGTH_FRACTION * _size(v):
        raise SieveError(
            f"{path}: the plate is flat (no thickness along {axis}); give a closed plate mesh "
            "with thickness"
        )
    v, faces, open_edges = _closed(v, faces)
    if open_edges:
        what = (f"{open_edges} edges not shared by two faces" if open_edges > 0
                else "its faces wound inconsistently")  # fmt: skip
        raise SieveError(
            f"{path}: the plate mesh is not a closed solid ({what}), so its thickness cannot be "
            "measured; export it as a closed (watertight) mesh"
        )
    angle = tilt(v, faces)
    slab = full_slab(v, faces, solid.area(), _perimeter(solid))
    if slab is None:
        raise _no_slab(path, axis, angle)
    volume = abs(_volume(v, faces))
    return PlateReading(path, axis, holes, foot, extent, slab, angle, volume, v, faces)


def _volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """A closed mesh's signed volume (divergence theorem), scene units cubed."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    tri = tri - tri.reshape(-1, 3).mean(0)
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


@dataclass
class SieveHoles:
    """A given sieve's holes, read once, on one raster frame centred on them.

    Attributes
    ----------
    source : str
        The plate mesh's or the hole image's file.
    holes : list of Hole
        The holes on :attr:`frame`, whose centre is :attr:`centre` in the sieve's coordinates.
    frame : Frame
    centre : (2,) ndarray
        The sieve's coordinates of the frame's centre (a pose found on the frame is moved by it).
    info : list of dict
        Per hole its area (and, for a plate, its centre in the plate's coordinates).
    outlines : list of manifold3d.CrossSection or None
        A plate's exact holes, shifted by ``-centre``; None for an image (its pixels are the truth).
    plate : PlateReading or None
        The plate's slab and mesh; None for an image.
    mask : (N, N) bool ndarray or None
        An image's hole pixels on :attr:`frame`; None for a plate.
    played : list of int or None
        A plate's holes that :attr:`holes` draws, one per group of translates
        (:func:`distinct_holes`); None: every hole (an image).
    """

    source: str
    holes: list
    frame: Frame
    centre: np.ndarray
    info: list
    outlines: list | None = None
    plate: PlateReading | None = None
    mask: np.ndarray | None = None
    played: list | None = None


def frame_for_polygons(
    holes: list[manifold3d.CrossSection], resolution: int
) -> tuple[Frame, np.ndarray]:
    """A frame centred on the holes' bounding box, covering them with a margin.

    Returns
    -------
    frame : Frame
    centre : (2,) ndarray
        The bounding-box centre in the sieve's coordinates (subtracted from the outlines).
    """
    lo = np.min([h.bounds()[:2] for h in holes], axis=0)
    hi = np.max([h.bounds()[2:] for h in holes], axis=0)
    centre = 0.5 * (np.asarray(lo) + np.asarray(hi))
    radius = 0.5 * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    return Frame.covering(radius * 1.02, resolution, margin_px=4.0), centre


def read_plate_holes(path: str, axis: str, resolution: int) -> SieveHoles:
    """A plate mesh's through-holes along ``axis`` on a common frame (:func:`read_plate`, once).

    Parameters
    ----------
    path : str
        The plate mesh's file, scene units.
    axis : {"x", "y", "z"}
    resolution : int
        Pixels per side of the frame (:func:`frame_for_polygons`).

    Returns
    -------
    SieveHoles
        With the exact outlines (shifted by ``-centre``) and the plate's reading.

    Raises
    ------
    SieveError
        A plate with no through-hole, or whose thickness cannot be measured (:func:`read_plate`).
    """
    plate = read_plate(path, axis)  # the plate's holes and thickness, read once
    played = distinct_holes(plate.holes)
    frame, centre = frame_for_polygons([plate.holes[k] for k in played], resolution)
    info = []
    for o in plate.holes:
        lo, hi = np.asarray(o.bounds()[:2]), np.asarray(o.bounds()[2:])
        info.append({"area": float(o.area()), "centre": [float(c) for c in (lo + hi) / 2]})
    outlines = [o.translate([-centre[0], -centre[1]]) for o in plate.holes]
    holes = [Hole.from_outline(outlines[k], frame) for k in played]
    return SieveHoles(path, holes, frame, centre, info, outlines=outlines, plate=plate,
                      played=played)  # fmt: skip


#: Relative difference (areas, sizes, symmetric difference) within which two holes of a plate
#: count as translates of each other (:func:`distinct_holes`).
SAME_HOLE = 1e-4


def distinct_holes(holes: list) -> list[int]:
    """The index of one hole of each group of holes that are translates of one another (the
    first of each group, in the order given).

    A perforated sheet's copies of one hole are: a part of one body fits their union iff it fits
    one of them (its projection is connected; :mod:`sieve_mi.geometry.pattern`), so ``check``
    plays one per group, on a frame around those alone (finer pixels than one around the sheet).
    Two holes are translates when their areas and bounding-box sizes agree and, moved onto each
    other's bounding-box corner, their symmetric difference is at most :data:`SAME_HOLE` of the
    area (a plate file's float32 coordinates round a copy by about 1e-7 of the plate's size).

    Parameters
    ----------
    holes : list of manifold3d.CrossSection

    Returns
    -------
    list of int
    """
    kept: list[int] = []
    for k, h in enumerate(holes):
        b = np.asarray(h.bounds(), dtype=np.float64)
        if not any(_translate_of(h, b, holes[j]) for j in kept):
            kept.append(k)
    return kept


def _translate_of(
    h: manifold3d.CrossSection, b: np.ndarray, other: manifold3d.CrossSection
) -> bool:
    """Whether ``other`` is ``h`` (bounds ``b``) moved, up to :data:`SAME_HOLE`."""
    c = np.asarray(other.bounds(), dtype=np.float64)
    area = float(h.area())
    size = max(float(np.ptp(b.reshape(2, 2), axis=0).max()), 1e-300)
    if abs(area - other.area()) > SAME_HOLE * area:
        return False
    if np.abs((b[2:] - b[:2]) - (c[2:] - c[:2])).max() > SAME_HOLE * size:
        return False
    moved = other.translate([float(b[0] - c[0]), float(b[1] - c[1])])
    return (h - moved).area() + (moved - h).area() <= SAME_HOLE * area
