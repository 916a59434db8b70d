"""Parts from catalogue dimensions, in millimetres: toy bricks and cylindrical cells.

Built like :mod:`sieve_mi.testing.shapes` (closed, watertight solids centred on their bounding
box's centre) for the makers' scenes ``scenes/bricks.toml`` and ``scenes/batteries.toml``;
``tools/make_scene_meshes.py`` writes them to ``scenes/meshes/``. Kept apart from ``shapes``,
which is near the 600-line limit of a module.

* :func:`brick`: a LEGO-compatible brick, *solid* (no hollow underside, no tubes) with its studs:
  its outside, which is all a sieve sees, is the real brick's (the hollow underside changes no
  silhouette).
* :func:`cell`: a cylindrical cell (AAA, AA) as a plain cylinder of the full length: the
  positive terminal's button and the crimped negative end lie inside that envelope.
"""

from __future__ import annotations

import manifold3d
import numpy as np
import trimesh

from sieve_mi.testing.shapes import centred, check_positive, cross_section, extrude, from_manifold

__all__ = ["BRICK", "CELLS", "brick", "cell", "hex_nut", "washer"]

#: LEGO-compatible sizes, mm: stud pitch, the play taken off each body side's length (a 1 x 2
#: brick is 2 x 8.0 - 0.2 = 15.8 long), the brick body's height, the stud's diameter and height.
BRICK = {"pitch": 8.0, "play": 0.2, "height": 9.6, "stud_diameter": 4.8, "stud_height": 1.7}

#: Cylindrical cells, (diameter, length) in mm (IEC 60086 R03 and R6, largest sizes).
CELLS = {"AAA": (10.5, 44.5), "AA": (14.5, 50.5)}


def brick(studs_x: int, studs_y: int, segments: int = 32) -> trimesh.Trimesh:
    """A solid LEGO-compatible brick with its studs on top (+z), centred.

    Parameters
    ----------
    studs_x, studs_y : int
        Studs along x and y (a 2 x 4 brick: ``brick(4, 2)`` is 31.8 x 15.8 mm).
    segments : int
        Vertices of each stud's circle (on the circle of :data:`BRICK` ``stud_diameter``).

    Returns
    -------
    trimesh.Trimesh
        Body ``(n pitch - play)`` per side by ``height`` (9.6), studs ``stud_height`` (1.7) high:
        a 1 x 2 brick is 15.8 x 7.8 x 11.3 mm overall.
    """
    if int(studs_x) != studs_x or int(studs_y) != studs_y or min(studs_x, studs_y) < 1:
        raise ValueError(f"studs must be positive integers, got {studs_x!r} x {studs_y!r}")
    pitch, h = BRICK["pitch"], BRICK["height"]
    size = (studs_x * pitch - BRICK["play"], studs_y * pitch - BRICK["play"], h)
    body = manifold3d.Manifold.cube(size, center=True)
    r, top = BRICK["stud_diameter"] / 2, BRICK["stud_height"]
    stud = manifold3d.Manifold.cylinder(top, r, r, segments)
    for i in range(int(studs_x)):
        for j in range(int(studs_y)):
            x = (i - (studs_x - 1) / 2) * pitch
            y = (j - (studs_y - 1) / 2) * pitch
            body = body + stud.translate((x, y, h / 2))
    return centred(from_manifold(body))


def cell(diameter: float, length: float, sections: int = 96) -> trimesh.Trimesh:
    """A cylindrical cell as a plain cylinder, its axis along z, centred.

    Parameters
    ----------
    diameter, length : float
        mm (:data:`CELLS`: AAA 10.5 x 44.5, AA 14.5 x 50.5, terminal included in the length).
    sections : int
        Vertices of the circle (on it: every silhouette lies within the ideal cylinder's).

    Returns
    -------
    trimesh.Trimesh
    """
    for name, value in (("diameter", diameter), ("length", length)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number (mm), got {value!r}")
    return trimesh.creation.cylinder(radius=diameter / 2.0, height=length, sections=sections)


def _ring(radius: float, sections: int, phase: float = 0.0) -> np.ndarray:
    """A regular polygon (sections, 2) with its vertices on the circle of ``radius``, mm."""
    angle = phase + 2.0 * np.pi * np.arange(sections) / sections
    return radius * np.column_stack([np.cos(angle), np.sin(angle)])


def hex_nut(
    across_flats: float, thickness: float, bore: float, sections: int = 48
) -> trimesh.Trimesh:
    """A hex nut: a regular hexagonal prism with a round bore along z, centred.

    The thread is left out (the bore is its nominal diameter) and so are the chamfers, which only
    make a nut smaller: an ISO 4032 M3 nut is ``hex_nut(5.5, 2.4, 3.0)``, M4 ``hex_nut(7.0, 3.2,
    4.0)`` (maximum across flats and thickness).

    Parameters
    ----------
    across_flats : float
        Width across the hexagon's flats, mm (two flats parallel to the y axis).
    thickness : float
        Height along z, mm.
    bore : float
        Bore diameter, mm; its polygon of ``sections`` vertices lies on the circle.
    sections : int
        Vertices of the bore's polygon.

    Returns
    -------
    trimesh.Trimesh
        Closed, volume ``(sqrt(3)/2 across_flats**2 - bore polygon's area) thickness``.
    """
    check_positive(across_flats=across_flats, thickness=thickness, bore=bore)
    if bore >= across_flats:
        raise ValueError("the bore must be narrower than the nut across its flats")
    hexagon = _ring(across_flats / np.sqrt(3.0), 6, np.pi / 6.0)
    return extrude(cross_section([hexagon, _ring(bore / 2.0, sections)]), thickness)


def washer(outer: float, inner: float, thickness: float, sections: int = 96) -> trimesh.Trimesh:
    """A flat washer: an annulus extruded along z, centred (ISO 7089 M3: ``washer(7.0, 3.2,
    0.5)``).

    Parameters
    ----------
    outer, inner : float
        Outer and inner diameters, mm; both circles are polygons of ``sections`` vertices on them.
    thickness : float
        Height along z, mm.
    sections : int

    Returns
    -------
    trimesh.Trimesh
        Closed, its silhouettes within the ideal washer's outer cylinder.
    """
    check_positive(outer=outer, inner=inner, thickness=thickness)
    if inner >= outer:
        raise ValueError("the inner diameter must be smaller than the outer one")
    rings = [_ring(outer / 2.0, sections), _ring(inner / 2.0, sections)]
    return extrude(cross_section(rings), thickness)
