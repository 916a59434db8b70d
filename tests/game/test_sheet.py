"""The plate's thickness in a solve: the thinnest proved, a thin sheet that leaks, and "thinnest".

scenes/thin-sheet.toml: a 9 mm ball (A, hole: a 10 mm disk), an L-shaped rod and a 12 mm cube
(B). Default plate: the game's verdict (A wins) is proved by the rod's slab section, thinner than
its diameter. 2 mm sheet: the
rod threads through (found and verified), so B wins; the cube is safe on any plate by its
inscribed 12 mm ball (wider than the 10 mm hole; its centre must cross the sheet).
"""

from __future__ import annotations

import json
import math
import os

import pytest
import trimesh
from helpers import REPO

import sieve_mi
from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT

pytestmark = pytest.mark.slow


def _scene(thickness, budget: float):
    scene = sieve_mi.load_scene(os.path.join(REPO, "scenes", "thin-sheet.toml"))
    for key, value in TINY_SOLVER.items():
        setattr(scene.solver, key, value)
    for key, value in TINY_VERDICT.items():
        setattr(scene.verdict, key, value)
    # the rod's proofs get room enough on a loaded machine (the L-rod's straight proof takes
    # about a second alone; its section proofs a few)
    scene.verdict.certify_budget, scene.verdict.section_budget = 20.0, 12.0
    scene.fabrication.thickness = thickness
    scene.verdict.thin_budget = budget
    return scene


def test_default_plate_is_the_thinnest_proved(tmp_path):
    result = sieve_mi.solve(_scene(None, 1.0), progress=False)
    assert result.winner == "A"
    sheet = result.sheet
    # the rod's diameter is sqrt(20² + 20² + 2²) = 28.35 (the thick-plate argument's 28.4 mm);
    # its slab-section proof, bisected above the 2 mm sheet it threads (next test), is thinner
    rod, cube = sheet.per_block
    proof = result.certified[0].section
    assert proof["status"] == "proved" and 2.0 < proof["thickness"] < 28.35
    assert sheet.thickness == pytest.approx(proof["thickness"]) and sheet.proved
    assert sheet.mode == "safe" and sheet.safe == pytest.approx(proof["thickness"])
    assert rod.status == "safe" and rod.to_dict()["by"] == "section"
    assert cube.status == "safe" and cube.to_dict()["by"] == "ball"
    assert result.certified[0].status == "proved"  # on this plate, by its section
    result.save(str(tmp_path / "out"), figure=False, animation=False)  # report.json, sieve.stl
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["fabrication"]["thickness"] == pytest.approx(proof["thickness"])
    assert report["fabrication"]["sheet"]["proved"] is True
    assert [b["thin_plate"]["status"] for b in report["block"]] == ["safe", "safe"]
    plate = trimesh.load(str(tmp_path / "out" / "sieve.stl"))
    assert plate.extents[2] == pytest.approx(proof["thickness"], rel=1e-6)
    # the bracket's other side: motion searches below the rod's proof, at its unproved thickness,
    # then at the printable minimum (1.2 mm), then halfway up when only the minimum passed
    (gap,) = sheet.bracket
    assert gap["name"] == "rod" and gap["proved"] == pytest.approx(proof["thickness"])
    assert gap["unproved"] == proof["bracket"]["unproved"] and gap["unproved"] < gap["proved"]
    left = proof["bracket"]["unproved_left"]  # why: the failed try's caps left open
    assert left["open"] > 0 and left["seconds"] > 0
    tried = gap["no_passage_found"] + ([gap["passage"]] if gap["passage"] is not None else [])
    assert gap["unproved"] in tried and 1 <= len(tried) <= 3
    if gap["passage"] is not None:  # the thickest passage lies below every plate without one
        assert all(t > gap["passage"] for t in gap["no_passage_found"])
    assert report["fabrication"]["sheet"]["bracket"] == [gap]


def test_a_2_mm_sheet_leaks_the_rod(tmp_path):
    scene = _scene(2.0, 60.0)
    scene.verdict.section_budget = 1.0  # the rod threads a 2 mm sheet: no section proof there
    result = sieve_mi.solve(scene, progress=False)
    rod, cube = result.sheet.per_block
    assert rod.status == "passage" and rod.min_clearance > 0
    assert cube.status == "safe" and "ball" in cube.argument
    assert result.winner == "B" and not result.sheet.proved
    assert [b.blocked for b in result.blocks] == [False, True]
    assert any("rod passes a 2 mm plate" in w for w in result.warnings)
    result.save(str(tmp_path / "out"))
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    row = report["block"][0]
    assert row["blocked"] is False and row["thin_plate"]["status"] == "passage"
    assert len(row["thin_plate"]["poses"][0]) == 7 and row["thin_plate"]["min_clearance"] > 0
    assert trimesh.load(str(tmp_path / "out" / "sieve.stl")).extents[2] == pytest.approx(2.0)
    # the one end-to-end figure and passage.gif of a B that threads through (the other tests
    # of this file skip them)
    assert {"figure.png", "passage.gif"} <= set(os.listdir(tmp_path / "out"))


def test_thinnest_bisects_and_says_it_is_not_proved(tmp_path):
    # 0.75 s per motion search and step (6 steps): what the bisection does with what the
    # searches find is checked here, not how much they find (test_a_2_mm_sheet_leaks_the_rod).
    scene = _scene("thinnest", 0.75)
    scene.verdict.section_budget = 2.0  # the section proofs are the previous test's subject
    result = sieve_mi.solve(scene, progress=False)
    sheet = result.sheet
    assert sheet.mode == "thinnest" and 2.0 < sheet.safe <= 28.4  # proved, or its diameter
    steps = sheet.bisection
    assert 1 <= len(steps) <= 6
    # a bracket: every thickness where some B passed is below every one where none did
    passed = [s["thickness"] for s in steps if s["passage"]]
    held = [s["thickness"] for s in steps if not s["passage"]]
    assert not passed or not held or max(passed) < min(held)
    assert sheet.thickness == pytest.approx(min(held + [sheet.safe]))
    assert sheet.proved == (sheet.thickness >= sheet.safe)
    # the first step is halfway from the printable minimum to the proved value, and no step
    # goes below that minimum
    low = result.scene.fabrication.min_thickness
    assert steps[0]["thickness"] == pytest.approx(round(0.5 * (low + sheet.safe), 3))
    assert all(s["thickness"] > low for s in steps) and sheet.thickness > low
    # no B passes the plate that is written
    assert all(t.status != "passage" for t in sheet.per_block if t is not None)
    assert result.winner == "A"
    result.save(str(tmp_path / "out"), figure=False, animation=False)  # report.json, sieve.stl
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["fabrication"]["sheet"]["bisection"] == steps
    plate = trimesh.load(str(tmp_path / "out" / "sieve.stl"))
    assert math.isclose(plate.extents[2], sheet.thickness, rel_tol=1e-6)
