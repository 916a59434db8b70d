"""Simple solid test shapes for sieve scenes, in millimetres.

Every function returns a ``trimesh.Trimesh`` whose axis-aligned bounding box is centred at the
origin. The solids (everything here) are closed, watertight, consistently oriented 2-manifolds
with positive volume. Extruded shapes are built with manifold3d: a 2D
:class:`manifold3d.CrossSection` is extruded along +z and converted to trimesh.

The shapes mirror the simple inputs of the shape-aware-sieve paper (cube, sphere, bowtie, arch,
rectangular prism, thick capital letters); ``tools/make_scene_meshes.py`` writes them to
``scenes/meshes/``.
"""

from __future__ import annotations

from collections.abc import Sequence

import manifold3d
import numpy as np
import trimesh

__all__ = [
    "arch",
    "arch_polygon",
    "bowtie",
    "bowtie_polygon",
    "box",
    "centred",
    "check_positive",
    "cross_section",
    "cube",
    "extrude",
    "extrude_polygon",
    "from_manifold",
    "glyph_contours",
    "l_rod",
    "letter",
    "sphere",
    "to_manifold",
]


# --------------------------------------------------------------------------------------------
# manifold3d <-> trimesh
# --------------------------------------------------------------------------------------------


def from_manifold(m: manifold3d.Manifold) -> trimesh.Trimesh:
    """Convert a manifold3d solid to a trimesh mesh (double precision, no re-centring).

    Parameters
    ----------
    m : manifold3d.Manifold
        A non-empty solid.

    Returns
    -------
    trimesh.Trimesh
        Same vertices (first three vertex properties) and triangles, in the same units.

    Raises
    ------
    ValueError
        If ``m`` is empty or in an error state.
    """
    if m.status() != manifold3d.Error.NoError:
        raise ValueError(f"manifold is invalid: {m.status()}")
    if m.is_empty():
        raise ValueError("manifold is empty")
    mesh = m.to_mesh64()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=True)


def to_manifold(mesh: trimesh.Trimesh) -> manifold3d.Manifold:
    """Convert a closed, oriented trimesh mesh to a manifold3d solid.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        A watertight mesh with consistent winding (vertex coordinates in any unit).

    Returns
    -------
    manifold3d.Manifold
        The same solid.

    Raises
    ------
    ValueError
        If manifold3d rejects the mesh (open, non-manifold or inconsistently wound).
    """
    mesh64 = manifold3d.Mesh64(
        vert_properties=np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        tri_verts=np.ascontiguousarray(mesh.faces, dtype=np.uint64),
    )
    m = manifold3d.Manifold(mesh64)
    if m.status() != manifold3d.Error.NoError:
        raise ValueError(f"mesh is not a closed oriented 2-manifold: {m.status()}")
    return m


def centred(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Translate a mesh in place so its axis-aligned bounding-box centre is the origin.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Any mesh.

    Returns
    -------
    trimesh.Trimesh
        ``mesh`` itself, translated.
    """
    lo, hi = mesh.bounds
    mesh.apply_translation(-0.5 * (lo + hi))
    return mesh


def check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number (mm), got {value!r}")


# --------------------------------------------------------------------------------------------
# Extrusion
# --------------------------------------------------------------------------------------------


def cross_section(
    contours: Sequence[np.ndarray], fill_rule: manifold3d.FillRule = manifold3d.FillRule.EvenOdd
) -> manifold3d.CrossSection:
    """Build a 2D region from closed contours.

    Parameters
    ----------
    contours : sequence of (N, 2) array_like
        Closed polygons (the last point need not repeat the first), in mm.
    fill_rule : manifold3d.FillRule
        How overlapping/nested contours combine. ``EvenOdd`` (the default) makes every nested
        contour a hole regardless of its winding, which is what font outlines need.

    Returns
    -------
    manifold3d.CrossSection
        The region, free of self-intersections.
    """
    polys = [np.ascontiguousarray(np.asarray(c, dtype=np.float64)[:, :2]) for c in contours]
    return manifold3d.CrossSection(polys, fillrule=fill_rule)


def extrude(section: manifold3d.CrossSection, depth: float) -> trimesh.Trimesh:
    """Extrude a 2D region along z and centre the resulting solid.

    Parameters
    ----------
    section : manifold3d.CrossSection
        Region in the xy-plane, mm.
    depth : float
        Extrusion length along z, mm.

    Returns
    -------
    trimesh.Trimesh
        Watertight prism over ``section`` of z-extent ``depth``, bounding-box centred.

    Raises
    ------
    ValueError
        If ``depth`` is not positive or the region is empty.
    """
    check_positive(depth=depth)
    if section.is_empty() or section.area() <= 0:
        raise ValueError("cross-section is empty (degenerate or cancelling contours)")
    return centred(from_manifold(manifold3d.Manifold.extrude(section, depth)))


def extrude_polygon(points_xy: np.ndarray, depth: float) -> trimesh.Trimesh:
    """Extrude one simple polygon along z.

    Parameters
    ----------
    points_xy : (N, 2) array_like
        Polygon vertices in mm, either winding, not repeating the first point.
    depth : float
        Extrusion length along z, mm.

    Returns
    -------
    trimesh.Trimesh
        Watertight prism with volume ``area(polygon) * depth``, bounding-box centred.
    """
    return extrude(cross_section([points_xy]), depth)


# --------------------------------------------------------------------------------------------
# Primitive solids
# --------------------------------------------------------------------------------------------


def box(x: float, y: float, z: float) -> trimesh.Trimesh:
    """A rectangular prism (cuboid) with 8 vertices and 12 triangles.

    Parameters
    ----------
    x, y, z : float
        Edge lengths along each axis, mm.

    Returns
    -------
    trimesh.Trimesh
        The box spanning ``[-x/2, x/2] x [-y/2, y/2] x [-z/2, z/2]``.
    """
    check_positive(x=x, y=y, z=z)
    return centred(from_manifold(manifold3d.Manifold.cube((x, y, z), center=True)))


def cube(side: float = 20.0) -> trimesh.Trimesh:
    """A cube centred at the origin.

    Parameters
    ----------
    side : float
        Edge length, mm.

    Returns
    -------
    trimesh.Trimesh
        12-triangle cube of volume ``side**3``.
    """
    return box(side, side, side)


def l_rod(arm: float = 20.0, side: float = 2.0) -> trimesh.Trimesh:
    """An L-shaped rod: two arms of square section meeting at a right angle, centred.

    Parameters
    ----------
    arm : float
        Each arm's outer length, mm (along x and along y from the shared corner).
    side : float
        The square section's side, mm.

    Returns
    -------
    trimesh.Trimesh
        A closed solid of volume ``(2 arm - side) side²`` (the corner cube counted once).
    """
    check_positive(arm=arm, side=side)
    if side >= arm:
        raise ValueError("the arms must be longer than the section's side")
    cube = manifold3d.Manifold.cube
    rod = cube((arm, side, side)) + cube((side, arm, side))
    return centred(from_manifold(rod))


def coin(diameter: float, thickness: float, sections: int = 96) -> trimesh.Trimesh:
    """A coin: a cylinder with its axis along z, centred at the origin.

    Parameters
    ----------
    diameter, thickness : float
        mm. The rim is a regular polygon of ``sections`` vertices on the circle of the diameter.

    Returns
    -------
    trimesh.Trimesh
        Closed, with vertices on the circle (so its silhouettes lie within the ideal coin's).
    """
    check_positive(diameter=diameter, thickness=thickness)
    return trimesh.creation.cylinder(radius=diameter / 2.0, height=thickness, sections=sections)


def sphere(radius: float = 12.0, subdivisions: int = 3) -> trimesh.Trimesh:
    """An icosphere (subdivided icosahedron) approximating a ball.

    All vertices lie exactly on the sphere of the given radius, so the flat faces lie inside it:
    the mesh is inscribed in the ball, its volume is slightly *below* ``4/3 pi radius**3`` and
    every silhouette lies within the disk of radius ``radius``.

    Parameters
    ----------
    radius : float
        Radius of the circumscribed sphere (where the vertices lie), mm.
    subdivisions : int
        Loop subdivisions of the icosahedron: ``20 * 4**subdivisions`` faces
        (3 gives 1280 faces and 642 vertices).

    Returns
    -------
    trimesh.Trimesh
        Watertight icosphere centred at the origin.
    """
    check_positive(radius=radius)
    if int(subdivisions) != subdivisions or subdivisions < 0:
        raise ValueError(f"subdivisions must be a non-negative integer, got {subdivisions!r}")
    mesh = trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=radius)
    # Re-project onto the sphere in double precision (subdivision midpoints are normalised
    # by trimesh already; this makes |v| == radius to rounding for every vertex).
    v = mesh.vertices
    mesh.vertices = v * (radius / np.linalg.norm(v, axis=1))[:, None]
    return centred(mesh)


# --------------------------------------------------------------------------------------------
# Hardware from catalogue dimensions: hex nuts (ISO 4032) and flat washers (ISO 7089)
# --------------------------------------------------------------------------------------------


# --------------------------------------------------------------------------------------------
# Extruded outlines: bowtie and arch
# --------------------------------------------------------------------------------------------


def bowtie_polygon(width: float, height: float, waist: float) -> np.ndarray:
    """Outline of a bowtie: two trapezoids meeting at a narrow vertical waist.

    Parameters
    ----------
    width : float
        Overall x-extent, mm.
    height : float
        y-extent of the two outer (vertical) edges, mm.
    waist : float
        y-extent at ``x = 0`` where the two halves meet, mm; ``0 < waist < height``.

    Returns
    -------
    (6, 2) ndarray
        Counter-clockwise vertices; area ``width * (height + waist) / 2``.
    """
    check_positive(width=width, height=height, waist=waist)
    if waist >= height:
        raise ValueError(f"waist ({waist}) must be smaller than height ({height})")
    w, h, s = width / 2, height / 2, waist / 2
    return np.array([[-w, -h], [0.0, -s], [w, -h], [w, h], [0.0, s], [-w, h]])


def bowtie(
    width: float = 30.0, height: float = 20.0, thickness: float = 6.0, waist: float = 6.0
) -> trimesh.Trimesh:
    """A bowtie plate: :func:`bowtie_polygon` extruded along z.

    Parameters
    ----------
    width : float
        x-extent, mm.
    height : float
        y-extent at the two ends, mm.
    thickness : float
        z-extent (extrusion depth), mm.
    waist : float
        y-extent of the narrow middle, mm.

    Returns
    -------
    trimesh.Trimesh
        Watertight bowtie of volume ``width * (height + waist) / 2 * thickness`` (28 faces).
    """
    return extrude_polygon(bowtie_polygon(width, height, waist), thickness)


def arch_polygon(width: float, height: float, thickness: float, segments: int = 16) -> np.ndarray:
    """Outline of a bridge arch: a rectangle with a semicircular opening cut from its bottom edge.

    The opening is centred on the bottom edge with radius ``width / 2 - thickness``, so each leg
    is ``thickness`` wide at the bottom and the crown above the opening is
    ``height - (width / 2 - thickness)`` tall. The semicircle is approximated by ``segments``
    chords whose end points lie on the circle (so slightly *less* than a half disk is removed).

    Parameters
    ----------
    width : float
        x-extent of the rectangle, mm.
    height : float
        y-extent of the rectangle, mm; must exceed the opening radius.
    thickness : float
        Width of each leg, mm; ``0 < thickness < width / 2``.
    segments : int
        Number of chords on the semicircle (>= 2).

    Returns
    -------
    (segments + 5, 2) ndarray
        Counter-clockwise vertices, bottom edge at ``y = 0``.
    """
    check_positive(width=width, height=height, thickness=thickness)
    r = width / 2 - thickness
    if r <= 0:
        raise ValueError(
            f"thickness ({thickness}) must be below width / 2 ({width / 2}) to leave an opening"
        )
    if height <= r:
        raise ValueError(
            f"height ({height}) must exceed the opening radius width/2 - thickness ({r})"
        )
    if int(segments) != segments or segments < 2:
        raise ValueError(f"segments must be an integer >= 2, got {segments!r}")
    w = width / 2
    theta = np.linspace(np.pi, 0.0, int(segments) + 1)
    arc = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    arc[0], arc[-1] = (-r, 0.0), (r, 0.0)  # exact feet, no cos(pi) rounding
    return np.vstack([[[-w, 0.0]], arc, [[w, 0.0], [w, height], [-w, height]]])


def arch(
    width: float = 30.0,
    height: float = 20.0,
    thickness: float = 6.0,
    depth: float = 10.0,
    segments: int = 16,
) -> trimesh.Trimesh:
    """A bridge-like arch: :func:`arch_polygon` extruded along z.

    Parameters
    ----------
    width : float
        x-extent, mm.
    height : float
        y-extent, mm.
    thickness : float
        Leg width, mm; the opening radius is ``width / 2 - thickness``.
    depth : float
        z-extent (extrusion depth), mm.
    segments : int
        Chords approximating the semicircular opening.

    Returns
    -------
    trimesh.Trimesh
        Watertight arch (genus 0) of volume ``area(arch_polygon) * depth``.
    """
    return extrude_polygon(arch_polygon(width, height, thickness, segments), depth)


# --------------------------------------------------------------------------------------------
# Thick capital letters
# --------------------------------------------------------------------------------------------


def _flatten_path(vertices: np.ndarray, codes: np.ndarray, curve_segments: int) -> list[np.ndarray]:
    """Split a matplotlib path into closed polylines, sampling each Bezier curve uniformly."""
    from matplotlib.path import Path

    contours: list[np.ndarray] = []
    current: list[np.ndarray] = []
    t = np.linspace(0.0, 1.0, curve_segments + 1)[1:, None]
    i = 0
    while i < len(codes):
        code = codes[i]
        if code == Path.MOVETO:
            if len(current) >= 3:
                contours.append(np.array(current))
            current = [vertices[i]]
            i += 1
        elif code == Path.LINETO:
            current.append(vertices[i])
            i += 1
        elif code == Path.CURVE3:
            p0, p1, p2 = current[-1], vertices[i], vertices[i + 1]
            current.extend((1 - t) ** 2 * p0 + 2 * (1 - t) * t * p1 + t**2 * p2)
            i += 2
        elif code == Path.CURVE4:
            p0, p1, p2, p3 = current[-1], vertices[i], vertices[i + 1], vertices[i + 2]
            current.extend(
                (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3
            )
            i += 3
        elif code == Path.CLOSEPOLY:
            if len(current) >= 3:
                contours.append(np.array(current))
            current = []
            i += 1
        else:  # STOP
            i += 1
    if len(current) >= 3:
        contours.append(np.array(current))
    return [_drop_repeats(c) for c in contours]


def _drop_repeats(contour: np.ndarray) -> np.ndarray:
    """Remove consecutive duplicate points, including a closing point equal to the first."""
    keep = np.ones(len(contour), dtype=bool)
    keep[1:] = np.any(np.diff(contour, axis=0) != 0, axis=1)
    contour = contour[keep]
    if len(contour) > 1 and np.all(contour[0] == contour[-1]):
        contour = contour[:-1]
    return contour


def glyph_contours(
    char: str, font: str = "DejaVu Sans", weight: str = "bold", curve_segments: int = 6
) -> list[np.ndarray]:
    """Outline contours of one glyph, in font units (matplotlib ``TextPath`` at size 100).

    Parameters
    ----------
    char : str
        A single character.
    font : str
        Font family name, resolved by matplotlib's font manager (an error if not found,
        no silent fallback).
    weight : str
        Font weight, e.g. ``"bold"`` or ``"normal"``.
    curve_segments : int
        Straight segments per Bezier curve of the outline.

    Returns
    -------
    list of (N, 2) ndarray
        Closed contours (outer boundaries and holes, in the font's winding).
    """
    from matplotlib.font_manager import FontProperties, findfont
    from matplotlib.textpath import TextPath

    if not isinstance(char, str) or len(char) != 1 or char.isspace():
        raise ValueError(f"char must be a single visible character, got {char!r}")
    if int(curve_segments) != curve_segments or curve_segments < 1:
        raise ValueError(f"curve_segments must be a positive integer, got {curve_segments!r}")
    prop = FontProperties(family=font, weight=weight)
    prop.set_file(findfont(prop, fallback_to_default=False))
    path = TextPath((0.0, 0.0), char, size=100.0, prop=prop)
    contours = _flatten_path(
        np.asarray(path.vertices, dtype=np.float64), np.asarray(path.codes), int(curve_segments)
    )
    if not contours:
        raise ValueError(f"character {char!r} has no outline in font {font!r}")
    return contours


def letter(
    char: str,
    height: float = 30.0,
    depth: float = 8.0,
    font: str = "DejaVu Sans",
    weight: str = "bold",
    curve_segments: int = 6,
) -> trimesh.Trimesh:
    """A thick extruded letter (one glyph of a TrueType font).

    The glyph outline (with its holes, e.g. the counters of "A", "P", "R") is filled with the
    even-odd rule, scaled uniformly so the outline's own y-extent is ``height`` (for round letters
    such as "S" and "G" this includes the overshoot above the cap height and below the
    baseline), and extruded along z by ``depth``.

    Parameters
    ----------
    char : str
        A single character, typically a capital letter.
    height : float
        y-extent of the glyph, mm.
    depth : float
        z-extent (extrusion depth), mm.
    font : str
        Font family name for matplotlib's font manager.
    weight : str
        Font weight (``"bold"`` gives thick strokes).
    curve_segments : int
        Straight segments per Bezier curve of the outline.

    Returns
    -------
    trimesh.Trimesh
        Watertight solid, bounding-box centred; its genus equals the number of holes of the glyph.
    """
    check_positive(height=height, depth=depth)
    contours = glyph_contours(char, font=font, weight=weight, curve_segments=curve_segments)
    lo = min(c[:, 1].min() for c in contours)
    hi = max(c[:, 1].max() for c in contours)
    scale = height / (hi - lo)
    return extrude(cross_section([c * scale for c in contours]), depth)
