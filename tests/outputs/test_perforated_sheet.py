"""A perforated sheet from a solve: the plate files hold every hole, report.json says how many,
and the default (one hole) keeps its keys. The cube's hole on a 60 x 60 hex sheet."""

from __future__ import annotations

import json
import os

import pytest
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.game.solver import solve
from sieve_mi.geometry.sieve import plate_holes
from sieve_mi.outputs.fabrication import plate_files
from sieve_mi.scene import Scene, load_scene
from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT

#: report.json's ``fabrication`` keys of a one-hole plate (before the perforated sheet).
SINGLE_KEYS = ["thickness", "required_thickness", "sheet", "border", "plate_size", "outline",
               "outline_vertices", "files", "warnings"]  # fmt: skip


@pytest.fixture(scope="module")
def result():
    scene = Scene.from_meshes(
        [trimesh.creation.box((10.0, 10.0, 10.0))],
        [trimesh.creation.icosphere(2, 8.0)],
        name="sheet",
    )
    for key, value in TINY_SOLVER.items():
        setattr(scene.solver, key, value)
    for key, value in TINY_VERDICT.items():
        setattr(scene.verdict, key, value)
    return solve(scene, seed=0, progress=False)


def test_a_pattern_writes_a_sheet_whose_holes_read_back(result, tmp_path):
    fab = result.scene.fabrication
    fab.pattern, fab.plate_size = "hex", (60.0, 60.0)
    try:
        made, _ = plate_files(result, str(tmp_path))
    finally:
        fab.pattern, fab.plate_size = "single", None
    p = made["pattern"]
    holes = plate_holes(os.path.join(tmp_path, "sieve.stl"))
    assert p["count"] == len(holes) > 4 and made["plate_size"][:2] == [60.0, 60.0]
    area = result.outline.area()
    assert sum(h.area() for h in holes) == pytest.approx(p["count"] * area, rel=1e-6)
    assert p["open_fraction"] == pytest.approx(p["count"] * area / 3600.0)
    assert p["least_gap"] >= 1.2 * (1 - 1e-9) and "sheet.svg" in made["files"]
    json.dumps(made)


def test_the_default_keeps_the_one_hole_keys(result, tmp_path):
    made, _ = plate_files(result, str(tmp_path))
    assert list(made) == SINGLE_KEYS
    assert len(plate_holes(os.path.join(tmp_path, "sieve.stl"))) == 1


def test_a_plate_too_small_for_one_hole_names_the_key(result, tmp_path):
    fab = result.scene.fabrication
    fab.pattern, fab.plate_size = "square", (12.0, 12.0)
    try:
        with pytest.raises(SieveError, match=r"^fabrication\.plate_size: 12 x 12 holds no hole"):
            plate_files(result, str(tmp_path))
    finally:
        fab.pattern, fab.plate_size = "single", None


@pytest.mark.parametrize(
    "line, expected",
    [
        ("web = -1", "fabrication.web: must be > 0, got -1"),
        (
            'pattern = "triangle"',
            "fabrication.pattern: 'triangle' is not one of: single, square, hex",
        ),
        ("plate_size = [100]", "fabrication.plate_size: expected a list of 2 numbers, got [100]"),
        (
            "turns = [30, 60]",
            "fabrication.turns: [30.0, 60.0] has no 0; one copy must be the hole itself (add 0)",
        ),
    ],
)
def test_bad_values_are_one_line_errors_naming_the_key(tmp_path, line, expected):
    # read with the scene, before any work (a plate too small is known only once H is)
    path = tmp_path / "s.toml"
    path.write_text(f'[[pass]]\nmesh = "a.stl"\n[[block]]\nmesh = "b.stl"\n[fabrication]\n{line}\n')
    with pytest.raises(SieveError) as exc:
        load_scene(str(path))
    assert str(exc.value) == f"{path}: {expected}"


def test_which_holes_each_proof_is_against():
    import manifold3d
    import numpy as np

    from sieve_mi.certify.blocks import sheet_holes
    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.geometry.pattern import lay_out

    hole = manifold3d.CrossSection.circle(4.5, 32)
    p = lay_out(hole, "hex", (60.0, 60.0), 5.0, 1.2)
    box = trimesh.creation.box((8.0, 8.0, 8.0))
    pair = trimesh.util.concatenate([box, box.copy().apply_translation((12.0, 0.0, 0.0))])
    ring = trimesh.creation.torus(10.0, 1.0)

    def count(contours) -> int:
        return 0 if contours is None else len(contours)

    one = sheet_holes(hole, shape_from_trimesh(box, name="box"), p)
    assert count(one[0]) == 1 and one[1] is None  # convex: its sections are connected
    ring_holes = sheet_holes(hole, shape_from_trimesh(ring, name="ring"), p)
    assert count(ring_holes[0]) == 1 and count(ring_holes[1]) > 7  # its sections may fall apart
    two = sheet_holes(hole, shape_from_trimesh(pair, name="pair"), p, found=5.0)
    assert count(two[0]) > count(two[1]) > 1  # two bodies: straight against the copies too (and
    # the margin bisection's grown holes: 2 x 5 mm further)
    # the section's copies come in groups that a set of the ring's diameter d can touch together:
    # within a group every two centres are at most d + 2 r apart, groups lie more than d apart,
    # and H with its six neighbours (10.2 mm away) is among them
    from sieve_mi.geometry.plate import diameter

    d = diameter(shape_from_trimesh(ring, name="r").hull)
    centres = np.array([np.mean(c, axis=0) for c in ring_holes[1]])
    groups = []
    for c in centres:
        near = [g for g in groups if min(np.linalg.norm(c - x) for x in g) <= d]
        merged = [c] + [x for g in near for x in g]
        groups = [g for g in groups if not any(g is n for n in near)] + [merged]
    for g in groups:
        assert max(np.linalg.norm(x - y) for x in g for y in g) <= d + 2 * 4.5 + 1e-6
    assert max(len(g) for g in groups) >= 7


def test_check_plays_one_hole_of_each_kind_of_copy():
    import manifold3d

    from sieve_mi.geometry.pattern import lay_out
    from sieve_mi.geometry.sieve import distinct_holes
    from sieve_mi.outputs.fabrication import sheet

    bar = manifold3d.CrossSection.square([12.0, 4.0], center=True)
    straight = sheet(lay_out(bar, "square", (60.0, 60.0), 5.0, 1.2), 2.0)
    turned = sheet(lay_out(bar, "square", (60.0, 60.0), 5.0, 1.2, turns=[0, 90]), 2.0)
    holes, turned_holes = plate_holes(straight.mesh), plate_holes(turned.mesh)
    assert len(holes) > 10 and len(distinct_holes(holes)) == 1
    assert len(turned_holes) > 10 and len(distinct_holes(turned_holes)) == 2


def test_a_b_of_two_bodies_is_named_in_a_warning():
    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.outputs.fabrication import sheet_warnings

    box = trimesh.creation.box((4.0, 4.0, 4.0))
    pair = trimesh.util.concatenate([box, box.copy().apply_translation((9.0, 0.0, 0.0))])
    shapes = [shape_from_trimesh(box, name="box"), shape_from_trimesh(pair, name="pair")]
    (line,) = sheet_warnings(shapes)
    assert (
        line.startswith("pair has 2 separate bodies: on the perforated sheet") and "\n" not in line
    )


def test_a_b_of_two_bodies_without_a_sheet_proof_is_not_covered():
    from types import SimpleNamespace

    from sieve_mi.game.sheet import not_covered
    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.motion.thin import ThinPlate

    box = trimesh.creation.box((4.0, 4.0, 4.0))
    pair = trimesh.util.concatenate([box, box.copy().apply_translation((9.0, 0.0, 0.0))])
    blocks = [shape_from_trimesh(box, name="box"), shape_from_trimesh(pair, name="pair")]
    per = [ThinPlate(b.name, 20.0, 15.0, "safe") for b in blocks]  # safe by their diameters
    scene = Scene.from_meshes([box], [box, pair], name="s")
    assert [t.status for t in not_covered(scene, blocks, per, None)] == ["safe", "safe"]
    scene.fabrication.pattern = "hex"
    got = not_covered(scene, blocks, per, None)
    assert [t.status for t in got] == ["safe", "not covered"]
    assert got[1].to_dict()["note"].startswith("pair has 2 separate bodies")
    proved = [None, SimpleNamespace(straight="proved")]  # proved against the copies in reach
    assert [t.status for t in not_covered(scene, blocks, per, proved)] == ["safe", "safe"]
