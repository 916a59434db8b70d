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

from sieve_mi.testing.shapes import centred, from_manifold

__all__ = ["BRICK", "CELLS", "brick", "cell"]

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
