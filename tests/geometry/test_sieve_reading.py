"""Reading a given plate mesh (sieve_mi.geometry.sieve): holes, the slab around them, refusals.

Known answers: every plate is built here with manifold3d, so its slab is known by construction.
A post, a raised rim or a boss adds no thickness; a chamfer takes its depth off; a tilted, flat or
open plate is refused in one line, by ``check`` and by ``shake`` alike, before any work.
"""

from __future__ import annotations

import hashlib
import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.geometry.sieve import plate_holes, read_plate, section_areas
from sieve_mi.shake.geometry import plate_from_mesh

HOLE = manifold3d.CrossSection.circle(5.0, 64)  # the 10 mm hole, a 64-gon on the circle


def _mesh(solid: manifold3d.Manifold) -> trimesh.Trimesh:
    m = solid.to_mesh()
    return trimesh.Trimesh(np.asarray(m.vert_properties[:, :3], float), np.asarray(m.tri_verts),
                           process=False)  # fmt: skip


def _sheet(thickness: float = 2.0) -> manifold3d.Manifold:
    """A 60 x 60 sheet, top at z = 0, with the 10 mm hole through it at the origin."""
    block = manifold3d.Manifold.cube([60, 60, thickness]).translate([-30, -30, -thickness])
    return block - manifold3d.Manifold.extrude(HOLE, thickness + 2).translate(
        [0, 0, -thickness - 1]
    )


def _post() -> manifold3d.Manifold:
    """The issue's plate: a 2 mm sheet with a 10 mm hole and one 60 mm post beside it."""
    return _sheet() + manifold3d.Manifold.cylinder(60, 2, 2, 16).translate([20, 20, 0])


def _rim() -> manifold3d.Manifold:
    """A raised rim 1.5 mm wide and 3 mm tall around the hole."""
    ring = manifold3d.Manifold.cylinder(3, 6.5, 6.5, 64) - manifold3d.Manifold.cylinder(3, 5, 5, 64)
    return _sheet() + ring


def _chamfer() -> manifold3d.Manifold:
    """The hole counter-sunk 1 mm deep (radius 7 at the top)."""
    return _sheet() - manifold3d.Manifold.cylinder(1, 5, 7, 64).translate([0, 0, -1])


def _tilted(degrees: float = 30.0) -> trimesh.Trimesh:
    """The issue's 22 mm plate with a 22 mm hole, turned ``degrees`` about x."""
    plate = manifold3d.Manifold.cube([60, 60, 22]).translate([-30, -30, -22])
    plate -= manifold3d.Manifold.cylinder(30, 11, 11, 64).translate([0, 0, -25])
    mesh = _mesh(plate)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(degrees), [1, 0, 0]))
    return mesh


def _flat_annulus() -> trimesh.Trimesh:
    ring = trimesh.creation.annulus(5.0, 20.0, height=1.0)
    return trimesh.Trimesh(ring.vertices * [1, 1, 0], ring.faces)


def _open() -> trimesh.Trimesh:
    mesh = _mesh(_sheet())
    return trimesh.Trimesh(mesh.vertices, mesh.faces[:-3], process=False)


@pytest.mark.parametrize(
    "solid, thickness, overall",
    [
        (_sheet(), 2.0, 2.0),
        (_post(), 2.0, 62.0),  # issue 40 row 3: the post adds nothing
        (_rim(), 2.0, 5.0),  # the sheet under the rim
        (_chamfer(), 1.0, 2.0),  # the straight part of the hole
        (_sheet(22.0), 22.0, 22.0),
    ],
    ids=["sheet", "post", "rim", "chamfer", "thick"],
)
def test_thickness_is_the_full_slab_around_the_holes(solid, thickness, overall):
    plate = read_plate(_mesh(solid), path="p.stl")
    assert plate.thickness == pytest.approx(thickness, abs=1e-9)
    assert plate.overall == pytest.approx(overall, abs=1e-9)
    assert plate.uniform == (thickness == overall)
    assert plate.slab[1] - plate.slab[0] == pytest.approx(thickness, abs=1e-9)
    assert [h.area() for h in plate.holes] == pytest.approx(
        [HOLE.area()], rel=1e-7
    )  # float32 corners
    assert plate.holes[0].area() == pytest.approx(math.pi * 25.0, rel=3e-3)  # a 64-gon
    said = plate.describe("mm")
    if thickness == overall:
        assert said == ""
    else:
        assert said == (
            f"plate is not a uniform slab: {thickness:g} mm where the holes are, "
            f"{overall:g} mm overall"
        )


def test_an_inside_out_plate_and_one_turned_to_x_read_the_same():
    inverted = _mesh(_post())
    inverted.invert()
    assert read_plate(inverted).thickness == pytest.approx(2.0, abs=1e-9)
    turned = _mesh(_post())
    turned.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    plate = read_plate(turned, "x")
    assert plate.thickness == pytest.approx(2.0, abs=1e-9) and plate.overall == pytest.approx(62)
    assert plate.holes[0].area() == pytest.approx(HOLE.area(), rel=1e-7)


def test_section_areas_of_a_plate_with_a_post():
    """Below the top: the sheet minus the hole; above it: the post's 16-gon."""
    mesh = _mesh(_post())
    got = section_areas(mesh.vertices, mesh.faces, np.array([-1.0, 30.0]))
    post = manifold3d.CrossSection.circle(2.0, 16).area()
    assert got == pytest.approx([3600.0 - HOLE.area(), post], rel=1e-6)  # float32 corners


@pytest.mark.parametrize(
    "mesh, words",
    [
        (_tilted(30.0), "p.stl: the plate is tilted 30.0° from the z axis"),
        (_tilted(3.0), "p.stl: the plate is tilted 3.0° from the z axis"),
        (_flat_annulus(), "p.stl: the plate is flat (no thickness along z)"),
        (_open(), "p.stl: the plate mesh is not a closed solid (9 edges not shared by two faces)"),
    ],
    ids=["tilted-30", "tilted-3", "flat", "open"],
)
def test_a_plate_that_cannot_be_measured_is_refused(mesh, words):
    with pytest.raises(SieveError) as err:
        read_plate(mesh, path="p.stl")
    assert str(err.value).startswith(words) and "\n" not in str(err.value)
    assert plate_holes(mesh, path="p.stl")  # its holes are still found (certify needs only them)


def test_shake_reads_the_slab_of_a_plate_with_a_post():
    """Issue 40 row 14: the post no longer hides the hole (the mid-height section was inside
    it); the plate is shaken as its 2 mm slab, named, with the post in volume_error."""
    plate = plate_from_mesh(_mesh(_post()), "post.stl", "mm")
    assert plate.thickness == pytest.approx(2.0, abs=1e-9)
    assert plate.hole_area == pytest.approx(HOLE.area(), rel=1e-7)
    slab = _sheet().volume()
    post = _post().volume() - slab
    assert plate.volume_error == pytest.approx(post / slab, rel=1e-6)
    assert plate.offset == pytest.approx([0.0, 0.0, 0.0])
    assert plate.to_dict()["warnings"] == [
        "post.stl: plate is not a uniform slab: 2 mm where the holes are, 62 mm overall; "
        "shaken as its slab"
    ]
    uniform = plate_from_mesh(_mesh(_sheet(22.0)), "thick.stl")
    assert uniform.volume_error < 1e-9 and uniform.warnings == []


def _digest(paths) -> list[str]:
    return [hashlib.sha256(open(p, "rb").read()).hexdigest() for p in paths]


@pytest.mark.parametrize("command", ["check", "shake"])
@pytest.mark.parametrize(
    "plate, words",
    [
        (_tilted(30.0), "the plate is tilted 30.0° from the z axis"),  # row 5
        (_flat_annulus(), "the plate is flat (no thickness along z)"),  # row 8
    ],
    ids=["tilted", "flat"],
)
def test_check_and_shake_refuse_it_in_one_line(tmp_path, capsys, command, plate, words):
    """Exit 2, one line naming the file, nothing written, the inputs byte-identical; no worker
    (issue 40 row 8 crashed the thin-plate worker on the flat plate)."""
    from sieve_mi.cli import main

    sieve, part = tmp_path / "plate.stl", tmp_path / "cube.stl"
    plate.export(str(sieve))
    trimesh.creation.box((8.0, 8.0, 8.0)).export(str(part))
    before = _digest([sieve, part])
    if command == "check":
        argv = ["check", str(part), "--sieve", str(sieve), "--no-fit", "--quiet"]
    else:
        argv = ["shake", "--sieve", str(sieve), str(part), "--trials", "2", "--quiet"]
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1
    assert out.err.startswith(f"sieve-mi: error: {sieve}: {words}")
    assert _digest([sieve, part]) == before and sorted(p.name for p in tmp_path.iterdir()) == [
        "cube.stl",
        "plate.stl",
    ]
