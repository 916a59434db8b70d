"""From a solved hole to a printable sieve (paper Sec. 5.4 and Supplemental B).

The hole is the exact polygon of :mod:`sieve_mi.geometry.outline`. The plate is a rectangular block with
that outline cut through it by a manifold3d boolean; its thickness defaults to the largest
diameter of a B, which rules out passing by tilting and turning (when a shape's highest point
enters the top face, all of it lies within its diameter below, inside the plate's slab, so its
projection must fit H); a thinner plate's blocks rest on :mod:`sieve_mi.motion`'s search.
"""

from __future__ import annotations

import os
import time
import zipfile
from dataclasses import dataclass, field
from xml.sax.saxutils import quoteattr

import manifold3d
import numpy as np
import trimesh

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import placed_vertices, raster_agreement
from sieve_mi.geometry.pattern import Pattern, from_settings
from sieve_mi.geometry.plate import safe_thickness

__all__ = [
    "Plate",
    "UNIT_NAMES",
    "beside_plate",
    "stacked",
    "fabricate",
    "figure_args",
    "figure_file",
    "plate",
    "plate_files",
    "plate_meshes",
    "plate_thickness",
    "shape_mesh",
    "sheet",
    "sheet_warnings",
    "to_trimesh",
    "write_3mf",
    "write_objects_3mf",
    "write_svg",
]


@dataclass
class Plate:
    """A printable sieve.

    Attributes
    ----------
    mesh : trimesh.Trimesh
        The plate, scene units: z from ``-thickness`` to 0, the hole around the xy origin.
    outline : manifold3d.CrossSection
        The hole's exact outline H (scene units, xy-plane).
    thickness, border : float
        Plate thickness and minimum border width around the hole, scene units.
    warnings : list of str
        Risks the user should know about (e.g. a plate thinner than Proposition B.1 asks).
    """

    mesh: trimesh.Trimesh
    outline: manifold3d.CrossSection
    thickness: float
    border: float
    warnings: list = field(default_factory=list)


def plate_thickness(result) -> tuple[float, float]:
    """The thickness a solve's plate is written at and the safe (proved) thickness, scene units.

    The solve's :class:`~sieve_mi.game.sheet.Sheet` decides both; a result without one (made by
    hand) gets the scene's thickness, else the safe value: the largest diameter of a B (of an A
    when there is no B), rounded up to 0.1 (:func:`sieve_mi.geometry.plate.safe_thickness`).
    """
    if getattr(result, "sheet", None) is not None:
        return result.sheet.thickness, result.sheet.safe
    safe = safe_thickness([s.hull for s in (result.block_shapes or result.pass_shapes)])
    given = result.scene.fabrication.thickness
    return (safe if given in (None, "thinnest") else float(given)), safe


def plate(
    outline: manifold3d.CrossSection,
    thickness: float,
    border: float,
    *,
    required_thickness: float | None = None,
) -> Plate:
    """A rectangular plate with ``outline`` cut through it.

    Parameters
    ----------
    outline : manifold3d.CrossSection
        The hole, scene units.
    thickness : float
        Plate thickness, scene units (z from -thickness to 0).
    border : float
        Width of material between the hole's bounding box and the plate's edge, scene units.
    required_thickness : float, optional
        The thinnest proved plate (:func:`sieve_mi.game.sheet.proved_thickness`); a thinner plate
        gets a warning.

    Returns
    -------
    Plate
    """
    if outline.is_empty():
        raise ValueError("the hole outline is empty")
    if thickness <= 0 or border <= 0:
        raise ValueError("thickness and border must be positive")
    (x0, y0), (x1, y1) = _bounds(outline)
    block = manifold3d.Manifold.cube(
        [x1 - x0 + 2 * border, y1 - y0 + 2 * border, thickness]
    ).translate([x0 - border, y0 - border, -thickness])
    cut = manifold3d.Manifold.extrude(outline, thickness + 2.0).translate(
        [0.0, 0.0, -thickness - 1.0]
    )
    body = block - cut
    return Plate(
        mesh=to_trimesh(body),
        outline=outline,
        thickness=float(thickness),
        border=float(border),
        warnings=_thin_warnings(thickness, required_thickness),
    )


def _thin_warnings(thickness: float, required_thickness: float | None) -> list[str]:
    """The warning of a plate thinner than the thinnest proved one (none otherwise)."""
    if required_thickness is None or thickness >= required_thickness - 1e-9:
        return []
    return [
        f"plate thickness {thickness:g} is less than the thinnest proved plate "
        f"{required_thickness:g}: blocks on it rest on a motion search (thin_plate in "
        "report.json), not on a proof; use at least that thickness for a guaranteed block"
    ]


def sheet(pattern: Pattern, thickness: float, *, required_thickness: float | None = None) -> Plate:
    """A perforated sheet: the plate of ``pattern`` (its size) with every copy of H cut through.

    Parameters
    ----------
    pattern : Pattern
        From :func:`sieve_mi.geometry.pattern.lay_out`: the copies and the plate's corners.
    thickness : float
        Scene units (z from -thickness to 0).
    required_thickness : float, optional
        As :func:`plate`.

    Returns
    -------
    Plate
        ``outline`` is H (one copy, the one at H's own place); ``border`` the least material
        between a copy and the plate's edge.
    """
    if thickness <= 0:
        raise ValueError("thickness must be positive")
    (x0, y0), (x1, y1) = pattern.plate
    holes = pattern.holes()
    block = manifold3d.Manifold.cube([x1 - x0, y1 - y0, thickness]).translate([x0, y0, -thickness])
    cut = manifold3d.Manifold.extrude(holes, thickness + 2.0).translate(
        [0.0, 0.0, -thickness - 1.0]
    )
    (h0, g0), (h1, g1) = _bounds(holes)
    border = min(h0 - x0, g0 - y0, x1 - h1, y1 - g1)
    return Plate(to_trimesh(block - cut), pattern.outline, float(thickness), float(border),
                 _thin_warnings(thickness, required_thickness))  # fmt: skip


def sheet_warnings(shapes: list[Shape]) -> list[str]:
    """One warning per B of several bodies (:func:`sieve_mi.geometry.meshes.bodies`) on a sheet:
    its verdict is against one hole, and only a certificate against the copies within its reach
    covers the sheet (docs/fabrication.md, "A perforated sheet")."""
    from sieve_mi.geometry.meshes import bodies

    out = []
    for s in shapes:
        n = bodies(s)
        if n > 1:
            out.append(
                f"{s.name} has {n} separate bodies: on the perforated sheet they could use "
                "different holes; its verdict is against one hole, and only its certificate "
                "(against the union of the holes within its reach) covers the sheet"
            )
    return out


def _bounds(section: manifold3d.CrossSection) -> tuple[tuple[float, float], tuple[float, float]]:
    b = section.bounds()
    return (float(b[0]), float(b[1])), (float(b[2]), float(b[3]))


def to_trimesh(body: manifold3d.Manifold) -> trimesh.Trimesh:
    """A manifold3d solid as a trimesh (float64 vertices, no processing that could alter it)."""
    m = body.to_mesh()
    return trimesh.Trimesh(
        np.asarray(m.vert_properties, dtype=np.float64)[:, :3],
        np.asarray(m.tri_verts, dtype=np.int64),
        process=False,
    )


def shape_mesh(
    shape: Shape, quat: np.ndarray, trans_xy: np.ndarray, lift: float
) -> trimesh.Trimesh:
    """A shape in a pose, raised so its lowest point is ``lift`` above the plate's top (z = 0)."""
    v = placed_vertices(shape, quat, trans_xy)
    v[:, 2] += lift - v[:, 2].min()
    return trimesh.Trimesh(v, shape.faces, process=False)


def write_3mf(path: str, mesh: trimesh.Trimesh, unit: str = "millimeter") -> None:
    """Write one mesh as a 3MF package (core specification, one object, one build item).

    Parameters
    ----------
    path : str
    mesh : trimesh.Trimesh
    unit : str
        3MF unit name: micron, millimeter, centimeter, inch, foot or meter.
    """
    write_objects_3mf(path, [(None, mesh)], unit)


def write_objects_3mf(path: str, objects: list, unit: str = "millimeter") -> None:
    """Write meshes as a 3MF package: one object and one build item each.

    Parameters
    ----------
    path : str
    objects : list of (str or None, trimesh.Trimesh)
        Each object's name (shown by slicers; None: unnamed) and mesh, already placed.
    unit : str
        3MF unit name: micron, millimeter, centimeter, inch, foot or meter.

    Notes
    -----
    The bytes depend only on the meshes (fixed zip timestamps, no random UUIDs), so the same
    plates give the same file.
    """
    resources, items = [], []
    for k, (name, mesh) in enumerate(objects, start=1):
        verts = "".join(
            f'<vertex x="{x:.9g}" y="{y:.9g}" z="{z:.9g}"/>'
            for x, y, z in np.asarray(mesh.vertices)
        )
        tris = "".join(
            f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in np.asarray(mesh.faces)
        )
        label = f" name={quoteattr(name)}" if name is not None else ""
        resources.append(
            f'<object id="{k}"{label} type="model"><mesh><vertices>{verts}</vertices>'
            f"<triangles>{tris}</triangles></mesh></object>"
        )
        items.append(f'<item objectid="{k}"/>')
    model = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<model unit="{unit}" xml:lang="en-US" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        f"<resources>{''.join(resources)}</resources><build>{''.join(items)}</build></model>"
    )
    types = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
        '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
        '<Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>'
    )
    rels = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
        '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
        'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>'
    )
    parts = (("[Content_Types].xml", types), ("_rels/.rels", rels), ("3D/3dmodel.model", model))
    with zipfile.ZipFile(path, "w") as z:
        for name, text in parts:  # a fixed timestamp: the same plate gives the same bytes
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            z.writestr(info, text, compress_type=zipfile.ZIP_DEFLATED)


UNIT_NAMES = {
    "mm": "millimeter",
    "cm": "centimeter",
    "m": "meter",
    "in": "inch",
    "inch": "inch",
    "um": "micron",
    "micron": "micron",
    "ft": "foot",
}


def fabricate(result, out_dir: str, *, figure: bool = True) -> dict:
    """Write the printable sieve and the placed shapes of a solve into ``out_dir``.

    Files: ``sieve.stl``, ``sieve.3mf`` (the plate), ``hole.svg`` (the exact outline),
    ``pass_<i>.stl`` (each A in its pass orientation above the hole), ``block_<j>.stl`` (each B in its
    best attempt, above the hole at the attempt's position) and ``figure.png`` (a Mitsuba rendering).
    :func:`plate_files` then :func:`figure_file`.

    Parameters
    ----------
    result : sieve_mi.game.result.Result
    out_dir : str
        An existing folder.
    figure : bool
        Render ``figure.png``.

    Returns
    -------
    dict
        The ``fabrication`` section of ``report.json``: thickness, border, plate size, outline area,
        agreement with the raster, files and warnings; ``figure_s``, the figure's seconds.
    """
    made, meshes = plate_files(result, out_dir)
    made["figure_s"] = figure_file(result, out_dir, made, meshes) if figure else 0.0
    return made


def plate_meshes(result) -> tuple:
    """The plate and the placed shapes of :func:`plate_files`, written nowhere.

    Returns
    -------
    tuple
        ``(sieve, pattern, required, meshes)``: the :class:`Plate`, its perforation pattern (or
        None), the safe thickness (scene units) and ``(plate mesh, passes, blocks, lift)``.
    """
    scene = result.scene
    fab = scene.fabrication
    outline = result.outline
    thickness, required = plate_thickness(result)
    pattern = from_settings(outline, fab, scene.units)
    if pattern is None:
        sieve = plate(outline, thickness, fab.border, required_thickness=required)
    else:
        sieve = sheet(pattern, thickness, required_thickness=required)
        sieve.warnings += sheet_warnings(result.block_shapes)
    lift = 0.25 * thickness
    passes = [
        shape_mesh(shape, result.pass_quats[i], result.pass_trans[i], lift)
        for i, shape in enumerate(result.pass_shapes)
    ]
    blocks = [
        shape_mesh(shape, result.attack.quats[0, j], result.attack.trans[0, j], lift)
        for j, shape in enumerate(result.block_shapes)
    ]
    return sieve, pattern, required, (sieve.mesh, passes, blocks, lift)


def plate_files(result, out_dir: str, built: tuple | None = None) -> tuple[dict, tuple]:
    """The plate and placed-shape files of :func:`fabricate` (everything but the figure).

    ``built`` is :func:`plate_meshes`' answer for ``result`` where it was made already (the
    pictures' worker got them before the save); else they are built here.

    Returns
    -------
    made : dict
        The ``fabrication`` section of ``report.json`` (without ``figure_s``).
    meshes : tuple
        ``(plate, passes, blocks, lift)`` for :func:`figure_file`.
    """
    scene = result.scene
    outline = result.outline
    sieve, pattern, required, meshes = plate_meshes(result) if built is None else built
    _, passes, blocks, _ = meshes
    sieve.mesh.export(os.path.join(out_dir, "sieve.stl"))
    write_3mf(
        os.path.join(out_dir, "sieve.3mf"), sieve.mesh, UNIT_NAMES.get(scene.units, "millimeter")
    )
    write_svg(os.path.join(out_dir, "hole.svg"), outline, scene.units)
    if pattern is not None:
        write_svg(os.path.join(out_dir, "sheet.svg"), pattern.holes(), scene.units,
                  plate=pattern.plate)  # fmt: skip
    for i, m in enumerate(passes):
        m.export(os.path.join(out_dir, f"pass_{i}.stl"))
    for j, m in enumerate(blocks):
        m.export(os.path.join(out_dir, f"block_{j}.stl"))
    files = (
        ["sieve.stl", "sieve.3mf", "hole.svg"]
        + (["sheet.svg"] if pattern is not None else [])
        + [f"pass_{i}.stl" for i in range(len(passes))]
        + [f"block_{j}.stl" for j in range(len(blocks))]
    )
    (x0, y0, z0), (x1, y1, z1) = sieve.mesh.bounds
    made = {
        "thickness": sieve.thickness,
        "required_thickness": required,
        **({"sheet": result.sheet.to_dict()} if getattr(result, "sheet", None) is not None else {}),
        **({"window": result.window} if getattr(result, "window", None) else {}),
        "border": sieve.border,
        **({"pattern": pattern.to_dict()} if pattern is not None else {}),
        "plate_size": [float(x1 - x0), float(y1 - y0), float(z1 - z0)],
        "outline": raster_agreement(outline, result.hole.mask, result.hole.frame),
        "outline_vertices": int(outline.num_vert()),
        "files": files,
        "warnings": list(sieve.warnings),
    }
    return made, meshes


def figure_file(result, out_dir: str, made: dict, meshes: tuple) -> float:
    """Render ``figure.png`` of :func:`plate_files`' meshes; list it in ``made``; its seconds."""
    from sieve_mi.outputs.figure import render_figure

    t_figure = time.perf_counter()
    plate_mesh, passes, blocks, blocked, title = figure_args(result, meshes)
    render_figure(
        os.path.join(out_dir, "figure.png"), plate_mesh, passes, blocks, blocked, title=title
    )
    made["files"].append("figure.png")
    return time.perf_counter() - t_figure


def figure_args(result, meshes: tuple) -> tuple:
    """What ``figure.png`` shows, from :func:`plate_files`' meshes: ``(plate, passes, blocks,
    blocked, title)`` for :func:`sieve_mi.outputs.figure.render_figure` (the A stacked over the
    hole, the B beside the plate, each B's colour from its verdict, the title)."""
    sieve, passes, blocks, lift = meshes
    return (
        sieve,
        stacked(passes, lift),
        beside_plate(sieve, blocks),
        [b.blocked for b in result.blocks],  # a thin-plate or certified passage passes
        f"{result.scene.name}: winner {result.winner}",
    )


def stacked(meshes: list[trimesh.Trimesh], gap: float) -> list[trimesh.Trimesh]:
    """Copies of the A meshes over their hole, each lifted above the one before by ``gap``
    (several A pass one at a time through a merged hole; drawn at one height they overlap).

    Parameters
    ----------
    meshes : list of trimesh.Trimesh
        Each A placed over the hole (as ``pass_<i>.stl``), the first one kept where it is.
    gap : float
        Clearance between consecutive copies, scene units.
    """
    out, top = [], None
    for m in meshes:
        c = m.copy()
        if top is not None:
            c.apply_translation([0.0, 0.0, top + gap - float(c.bounds[0, 2])])
        out.append(c)
        top = float(c.bounds[1, 2])
    return out


def beside_plate(
    plate_mesh: trimesh.Trimesh, meshes: list[trimesh.Trimesh], gap: float | None = None
) -> list[trimesh.Trimesh]:
    """Copies of ``meshes`` standing in a row on the ground beside the plate (for the figure).

    Parameters
    ----------
    plate_mesh : trimesh.Trimesh
        The sieve plate; its bounding box fixes the row's start and the ground height (its bottom).
    meshes : list of trimesh.Trimesh
        Shapes in their poses; only translated.
    gap : float, optional
        Spacing between neighbours, scene units (default: 10 % of the plate's larger side).

    Returns
    -------
    list of trimesh.Trimesh
        The moved copies, in the order given.
    """
    (x0, y0, z0), (x1, y1, _) = plate_mesh.bounds
    gap = 0.1 * max(x1 - x0, y1 - y0) if gap is None else gap
    x = x1 + gap
    out = []
    for m in meshes:
        (a0, b0, c0), (a1, b1, _) = m.bounds
        shift = np.array([x - a0, 0.5 * (y0 + y1) - 0.5 * (b0 + b1), z0 - c0])
        out.append(trimesh.Trimesh(np.asarray(m.vertices) + shift, m.faces, process=False))
        x += (a1 - a0) + gap
    return out


def write_svg(
    path: str, outline: manifold3d.CrossSection, units: str = "mm", *, plate=None
) -> None:
    """The outline as an SVG path (even-odd fill), 1 user unit = 1 scene unit, +y up.

    ``plate`` (corners ``[[x0, y0], [x1, y1]]``, scene units), if given, is drawn as a second
    path, its outline unfilled (a sheet's cutting file: the plate's edge and its holes).
    """
    (x0, y0), (x1, y1) = _bounds(outline) if plate is None else np.asarray(plate, float)
    pad = 0.05 * max(x1 - x0, y1 - y0)
    w, h = x1 - x0 + 2 * pad, y1 - y0 + 2 * pad
    edge = "" if plate is None else (
        f'<path fill="none" stroke="black" stroke-width="{0.002 * max(w, h):.6g}" '
        f'd="M {x0:.6g} {-y0:.6g} L {x1:.6g} {-y0:.6g} L {x1:.6g} {-y1:.6g} L {x0:.6g} {-y1:.6g} Z"/>\n'
    )  # fmt: skip
    d = []
    for c in outline.to_polygons():
        pts = " L ".join(f"{x:.6g} {-y:.6g}" for x, y in np.asarray(c))
        d.append(f"M {pts} Z")
    svg_units = units if units in ("mm", "cm", "in") else ""
    with open(path, "w") as fh:
        fh.write(
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.6g}{svg_units}" height="{h:.6g}{svg_units}" '
            f'viewBox="{x0 - pad:.6g} {-(y1 + pad):.6g} {w:.6g} {h:.6g}">\n'
            f'<path fill="black" fill-rule="evenodd" d="{" ".join(d)}"/>\n{edge}</svg>\n'
        )
