"""Feasibility before the search (sieve_mi.game.feasible): a B that the tolerance makes
impossible to block, proved, with the largest tolerance that could work.

Grow semantics (sieve_mi.geometry.outline.hole_outline): every hole contains proj_q(A) +
disk(tolerance), so in 3D B passes whenever it fits inside A + ball(tolerance + block_margin).
Every threshold below is argued on paper in its comment.
"""

from __future__ import annotations

import math
import os
import tomllib

import numpy as np
import pytest
import trimesh

import sieve_mi as sm
from sieve_mi.game.feasible import feasibility, round_up
from sieve_mi.game.solver import load_shapes
from sieve_mi.geometry.bodies import SAFETY, hull_edges_on_surface
from sieve_mi.geometry.containment import distance_to_hull, least_growth
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.outputs.report import report_dict
from sieve_mi.scene import load_scene
from sieve_mi.testing import catalogue, shapes
from sieve_mi.testing.settings import tiny_solver

SCENES = os.path.join(os.path.dirname(__file__), "..", "..", "scenes")
#: M4 nut over an M3 nut, corner over corner (ISO 4032 across flats 7 and 5.5, thicknesses 3.2
#: and 2.4): the M4 corner is (7 - 5.5) / sqrt(3) further out and 0.4 higher than the M3 corner.
M3_M4 = math.hypot(1.5 / math.sqrt(3.0), 0.4)  # 0.9539 mm


def _m3_m4(tolerance: float, **fab) -> tuple:
    scene = load_scene(os.path.join(SCENES, "m3-vs-m4.toml"))
    scene.fabrication.tolerance = tolerance
    for key, value in fab.items():
        setattr(scene.fabrication, key, value)
    return scene, *load_shapes(scene)


def _pair(a, b, tolerance: float, **fab):
    scene = sm.Scene.from_meshes([{"mesh": a, "name": "A"}], [{"mesh": b, "name": "B"}])
    scene.fabrication.tolerance = tolerance
    for key, value in fab.items():
        setattr(scene.fabrication, key, value)
    return feasibility(scene, *load_shapes(scene)).blocks[0]


def test_m3_nut_at_1mm_makes_the_m4_nut_impossible_to_block():
    scene, passes, blocks = _m3_m4(1.0)
    feas = feasibility(scene, passes, blocks)
    assert feas.impossible == [0] and feas.solid == ["filled", "filled"]  # bores filled
    m4 = feas.blocks[0]
    assert (m4.rule, m4.passing) == ("fits-inside", "M3 nut")
    # the certificate's growth is an upper bound on the true least growth, found within 1e-3
    assert M3_M4 <= m4.grow <= M3_M4 + SAFETY * passes[0].radius + 1e-3
    assert m4.max_tolerance == m4.grow
    assert "M4 nut cannot be blocked at tolerance 1 mm" in m4.reason
    assert "the largest tolerance that could work is below 0.955 mm" in m4.reason
    # the certificate, checked again: every hull vertex of the turned, moved M4 nut lies within
    # the growth of the M3 nut's hull
    rot = trimesh.transformations.quaternion_matrix(m4.certificate["rotation"])[:3, :3]
    placed = blocks[0].hull @ rot.T + np.array(m4.certificate["translation"])
    hull = trimesh.convex.convex_hull(passes[0].hull)
    assert distance_to_hull(placed, hull).max() <= m4.grow
    entry = feas.as_dict()
    assert entry["feasible"] is False and entry["block"][0]["status"] == "impossible"
    assert entry["max_tolerance"] == pytest.approx(m4.grow, abs=1e-6)


def test_at_0_2mm_nothing_is_ruled_out():
    # the M4 nut is 3.2 mm thick, the M3 nut grown by 0.2 mm 2.8 mm: it cannot fit inside
    feas = feasibility(*_m3_m4(0.2))
    assert feas.impossible == [] and feas.blocks[0].status == "not ruled out"
    assert feas.as_dict()["feasible"] is True and feas.lines() == []


def test_the_block_margin_counts_and_unfilled_holes_prove_nothing():
    # 0.9 mm + 0.1 mm block margin: as 1.0 mm of tolerance; 0.9 alone is not enough
    assert feasibility(*_m3_m4(0.9)).impossible == []
    feas = feasibility(*_m3_m4(0.9, block_margin=0.1))
    assert feas.impossible == [0]
    assert feas.blocks[0].max_tolerance == pytest.approx(feas.blocks[0].grow - 0.1)
    assert "plus block_margin 0.1 mm" in feas.blocks[0].reason
    # without fill_holes the hole keeps the nut's bore: its hull does not stand for it
    feas = feasibility(*_m3_m4(1.0, fill_holes=False))
    assert feas.impossible == [] and feas.solid == [None, None]


def test_cubes_10_and_10_5mm():
    # B = a 10.5 mm cube inside A = a 10 mm cube grown by g (a ball): the faces need g >= 0.25,
    # the corners (0.25, 0.25, 0.25) from A's corner, g >= 0.25 sqrt(3) = 0.4330; no turn does
    # better (B is wider than A along each of A's face normals). The argument holds from 0.4330
    # plus SAFETY times A's radius (5 sqrt(3)): impossible at 0.44, not at 0.43.
    a, b = shapes.cube(10.0), shapes.cube(10.5)
    threshold = 0.25 * math.sqrt(3.0) + SAFETY * 5.0 * math.sqrt(3.0)
    rec = _pair(a, b, 0.44)
    assert rec.status == "impossible" and rec.rule == "fits-inside"
    assert rec.max_tolerance == pytest.approx(threshold, abs=1e-4)
    assert _pair(a, b, 0.43).status == "not ruled out"


def test_end_first_a_square_rod_through_a_cube():
    # A = a 10 mm cube holds a ball of radius 5; B = a 7.5 x 7.5 x 40 mm rod, seen end first, a
    # square in a disk of radius 7.5 / sqrt(2) = 5.303: every hole holds a disk of radius 5 + g,
    # so from g = 0.303 on the rod passes (it fits inside no grown cube: 40 mm long)
    a, b = shapes.cube(10.0), shapes.box(7.5, 7.5, 40.0)
    threshold = 7.5 / math.sqrt(2.0) - 5.0 + SAFETY * 5.0 * math.sqrt(3.0)
    rec = _pair(a, b, 0.31)
    assert rec.status == "impossible" and rec.rule == "end-first"
    assert rec.max_tolerance == pytest.approx(threshold, abs=1e-6)
    assert _pair(a, b, 0.30).status == "not ruled out"
    # a thin rod passes at any tolerance: no tolerance can work
    rec = _pair(a, shapes.box(2.0, 2.0, 40.0), 0.0)
    assert rec.status == "impossible" and rec.max_tolerance == 0.0
    assert "no tolerance can work (it passes with no tolerance at all)" in rec.reason


def test_only_a_solid_hull_stands_for_a():
    nut = shape_from_trimesh(catalogue.hex_nut(5.5, 2.4, 3.0), name="nut")
    washer = shape_from_trimesh(catalogue.washer(7.0, 3.2, 0.5), name="washer")
    rod = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="L")  # the hull edge across the L
    assert hull_edges_on_surface(nut) and hull_edges_on_surface(washer)
    assert not hull_edges_on_surface(rod)
    # an L rod A proves nothing, even over a much smaller B
    assert _pair(shapes.l_rod(20.0, 2.0), shapes.cube(1.0), 1.0).status == "not ruled out"


def test_least_growth_of_a_shape_in_itself_is_zero():
    nut = catalogue.hex_nut(7.0, 3.2, 4.0)
    pts = np.asarray(trimesh.convex.convex_hull(nut.vertices).vertices)
    frames = [np.eye(3)]
    assert least_growth(pts, pts, frames, frames).grow == pytest.approx(0.0, abs=1e-6)


def test_round_up_never_prints_a_tighter_bound():
    assert round_up(0.95428) == 0.955 and round_up(0.4338) == 0.434 and round_up(2.0) == 2.0


@pytest.mark.parametrize("name", ["default.toml", "letters.toml"])
def test_bundled_games_are_not_ruled_out(name):
    scene = load_scene(os.path.join(SCENES, name))
    assert feasibility(scene, *load_shapes(scene)).impossible == []


def test_the_coin_sorter_holds_are_not_ruled_out():
    # scenes/euro-coins.toml's cascade holds the 2 euro coin over the 50, 10 and 1 cent coins,
    # the 50 cent over the 10 and 1 cent, the 10 cent over the 1 cent (its tolerance, 0.2 mm)
    with open(os.path.join(SCENES, "euro-coins.toml"), "rb") as f:
        sorter = tomllib.load(f)
    coins = {e["name"]: os.path.join(SCENES, e["mesh"]) for e in sorter["shape"]}
    order = ["2eur", "50c", "10c", "1c"]
    assert sorted(coins) == sorted(order)
    for k, held in enumerate(order[:-1]):
        scene = sm.Scene.from_meshes([{"mesh": coins[c], "name": c} for c in order[k + 1 :]],
                                     [{"mesh": coins[held], "name": held}])  # fmt: skip
        scene.fabrication.tolerance = sorter["fabrication"]["tolerance"]
        assert feasibility(scene, *load_shapes(scene)).impossible == [], held
    # the other way round the 1 cent coin fits inside the 2 euro coin: impossible to hold
    scene = sm.Scene.from_meshes([{"mesh": coins["2eur"]}], [{"mesh": coins["1c"]}])
    assert feasibility(scene, *load_shapes(scene)).impossible == [0]


def test_the_solve_stops_before_the_search(capsys):
    scene, _, _ = _m3_m4(1.0)
    scene.solver = tiny_solver()
    scene.verdict.starts, scene.verdict.steps, scene.verdict.resolution = 4, 20, 96
    result = sm.solve(scene, progress=True)
    err = capsys.readouterr().err
    assert "feasibility: M4 nut cannot be blocked at tolerance 1 mm" in err
    assert "search:" not in err  # no search stage ran
    assert result.winner == "B" and not result.blocks[0].blocked
    assert result.blocks[0].beta == 0.0  # the certificate's pose passes the exact hole
    assert result.stages == [] and len(result.history.best) == 0
    assert any(w.startswith("B wins whatever A does: M4 nut") for w in result.warnings)
    rep = report_dict(result)
    assert rep["winner"] == "B" and rep["feasibility"]["max_tolerance"] < 0.955


@pytest.mark.slow
def test_at_0_2mm_the_solve_finds_a_hole_that_blocks_the_m4_nut():
    # the M4 nut is 0.4 mm thicker than the M3 nut's edge-on slot (3.2 > 2.4 + 2 x 0.2)
    scene, _, _ = _m3_m4(0.2)
    scene.solver = tiny_solver()
    scene.verdict.starts, scene.verdict.steps, scene.verdict.resolution = 8, 40, 128
    scene.verdict.certify = False
    result = sm.solve(scene, progress=False)
    assert result.feasibility.impossible == [] and len(result.history.best) > 0
    assert result.winner == "A" and result.blocks[0].protrusion > 0.1


def test_exact_distances_to_a_hole_of_two_pieces():
    # separate holes make an outline of several rings of different lengths (it used to fail)
    import manifold3d

    from sieve_mi.geometry.outline import Boundary

    square = manifold3d.CrossSection.square((2.0, 2.0), center=True)
    disk = manifold3d.CrossSection.circle(1.0, 40).translate((10.0, 0.0))
    d = Boundary(square + disk).distance(np.array([[0.0, 0.0], [10.0, 0.0]]))
    assert d == pytest.approx([1.0, np.cos(np.pi / 40)], abs=1e-6)
