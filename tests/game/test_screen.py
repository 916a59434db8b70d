"""Blocks proved before the game by size (sieve_mi.game.screen): a ball inside B larger than any
hole A can make. Known answers: a 20 mm ball (radius 10) with a 1 mm tolerance makes holes
within radius 10 + 1.003; a cube of side s holds a ball of radius s / 2 at its centre."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import sieve_mi as sm
from sieve_mi.game.screen import largest_hole_radius, proved_by_size
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.testing.settings import tiny_solver


def _ball():
    return trimesh.creation.icosphere(subdivisions=3, radius=10.0)


def _cube(side: float):
    return trimesh.creation.box((side, side, side))


def _scene(blocks, **fab):
    scene = sm.Scene.from_meshes([_ball()], blocks, name="screen")
    scene.fabrication.tolerance = fab.get("tolerance", 1.0)
    scene.fabrication.block_margin = fab.get("block_margin", 0.0)
    scene.solver = tiny_solver()
    scene.verdict.starts, scene.verdict.steps = 4, 20
    return scene


def test_the_bound_and_which_blocks_it_proves():
    open_cube = _cube(30.0)
    open_cube.update_faces(np.arange(len(open_cube.faces)) != 0)  # one triangle missing
    blocks = [_cube(30.0), _cube(21.0), open_cube, _cube(22.2)]
    scene = _scene([{"mesh": m, "name": f"b{j}"} for j, m in enumerate(blocks)])
    passes = [shape_from_trimesh(_ball(), name="ball")]
    shapes = [shape_from_trimesh(m, name=f"b{j}") for j, m in enumerate(blocks)]
    bound = largest_hole_radius(scene, passes)
    assert bound == pytest.approx(10.0 + 1.003, rel=1e-6)  # icosphere vertices lie on r = 10
    proved = proved_by_size(scene, passes, shapes)
    # the 30 mm cube (ball 15) and the 22.2 mm cube (ball 11.1 > 11.003) are proved; the 21 mm
    # cube (ball 10.5) is left to the game; an open mesh has no certified inside
    assert sorted(proved) == [0, 3]
    assert proved[0] == pytest.approx(15.0, rel=1e-6) and proved[3] == pytest.approx(11.1, rel=1e-6)
    scene.fabrication.block_margin = 0.2  # blocking is decided against H grown by 0.2
    assert sorted(proved_by_size(scene, passes, shapes)) == [0]


def test_merged_holes_of_several_a_are_not_screened():
    scene = sm.Scene.from_meshes([_ball(), _ball()], [_cube(30.0)], name="m")
    passes = [shape_from_trimesh(_ball(), name="a")] * 2
    assert largest_hole_radius(scene, passes) is None
    assert proved_by_size(scene, passes, [shape_from_trimesh(_cube(30.0), name="b")]) == {}


@pytest.mark.slow
def test_a_screened_block_is_proved_and_the_game_plays_the_others(tmp_path):
    scene = _scene([{"mesh": _cube(30.0), "name": "big"}, {"mesh": _cube(21.0), "name": "small"}])
    result = sm.solve(scene, progress=False)
    assert result.winner == "A"
    big, small = result.blocks
    assert big.blocked and small.blocked
    assert result.certified[0].status == "proved" and result.certified[0].method == "ball"
    # certified by default ([verdict] certify = true): the 21 mm cube's narrowest shadow, a
    # face-on 21 mm square (diagonal 29.7 mm), cannot fit the ~22 mm disk, but its inscribed ball
    # (10.5 mm) is smaller than the disk, so the proof needs rotation cells (cube symmetry)
    assert result.certified[1].status == "proved" and result.certified[1].method == "cells"
    assert result.certified[1].symmetry == "octahedral"
    # the unrotated 30 mm cube, centred: its square silhouette (900 mm²) minus the hole disk
    # (radius 11, a little less inside the square's rounded outline) sticks out
    assert big.beta == pytest.approx(1 - math.pi * 11.0**2 / 900.0, abs=0.01)
    assert any("proved blocked before the game" in w and "big" in w for w in result.warnings)
    assert len(result.history.best) > 0  # A searched against the 21 mm cube
    rep = result.save(str(tmp_path / "o"), figure=False, animation=False)
    assert rep["block"][0]["certified"] == "proved" and rep["winner"] == "A"


@pytest.mark.slow
def test_when_every_block_is_proved_a_is_not_searched(tmp_path):
    scene = _scene([{"mesh": _cube(30.0), "name": "big"}])
    result = sm.solve(scene, progress=False)
    assert result.winner == "A" and result.blocks[0].blocked
    assert math.isnan(result.search_value) and len(result.history.best) == 0
    assert result.timings["search_s"] < 1.0
    assert result.outline.area() == pytest.approx(math.pi * 11.0**2, rel=0.01)
    rep = result.save(str(tmp_path / "o"), figure=False, animation=False)
    assert rep["block"][0]["certified"] == "proved"


def test_screen_false_plays_every_block():
    scene = _scene([{"mesh": _cube(30.0), "name": "big"}])
    passes = [shape_from_trimesh(_ball(), name="ball")]
    shapes = [shape_from_trimesh(_cube(30.0), name="big")]
    assert sorted(proved_by_size(scene, passes, shapes)) == [0]
    scene.solver.screen = False
    assert proved_by_size(scene, passes, shapes) == {}


@pytest.mark.slow
def test_a_block_kilometres_across_is_proved_without_running_out_of_memory():
    # A 24 mm ball scaled 1e5 (2.4 km) against a 20 mm ball's hole: it used to fill the memory
    # (the protrusion's outline samples every 1/2000 of the hole along a 7.5 km outline).
    scene = _scene([{"mesh": trimesh.creation.icosphere(3, 12.0), "name": "huge", "scale": 1e5}])
    result = sm.solve(scene, progress=False)
    assert result.winner == "A" and result.certified[0].status == "proved"
    assert result.blocks[0].protrusion > 1e6  # metres out, in mm
