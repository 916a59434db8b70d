"""Separate holes, each its own (:mod:`sieve_mi.game.holes`): a tolerance per A and mirrored holes.

A 20 x 10 mm bar lying flat (4 mm thick) makes a hole that is its rectangle grown by the
tolerance t: width 20 + 2t, height 10 + 2t, area 200 + 2t (20 + 10) + πt² (the round offset,
within the arc's chord error). An L of arms 20 and 12 mm (4 mm wide) is not its own mirror image
(a J, turned however, is not an L); the bar, a square and a disk are.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sieve_mi.errors import SieveError
from sieve_mi.game.holes import hole_tolerances, is_chiral, separate_holes
from sieve_mi.game.tolerance import one_hole
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import ARC_ERROR, SIMPLIFY
from sieve_mi.scene import Scene
from sieve_mi.testing.shapes import box, extrude_polygon, sphere

L_POLY = np.array([[0, 0], [12, 0], [12, 4], [4, 4], [4, 20], [0, 20]], dtype=float)
FLAT = np.array([1.0, 0.0, 0.0, 0.0])


def _scene(mirrored: bool = False, bar_tolerance: float | None = 2.0) -> tuple[Scene, list]:
    passes = [{"mesh": box(20, 10, 4), "name": "bar", "rotation": list(FLAT)},
              {"mesh": extrude_polygon(L_POLY, 4.0), "name": "ell", "rotation": list(FLAT)}]  # fmt: skip
    if bar_tolerance is not None:
        passes[0]["tolerance"] = bar_tolerance
    scene = Scene.from_meshes(passes, [sphere(12.0, 2)])
    scene.fabrication.tolerance = 0.5
    scene.layout.mode = "separate"
    scene.layout.mirrored = mirrored
    shapes = [shape_from_trimesh(e.data, name=e.name) for e in scene.passes]
    return scene, shapes


def _width(outline) -> tuple[float, float]:
    lo_x, lo_y, hi_x, hi_y = outline.bounds()
    return hi_x - lo_x, hi_y - lo_y


def test_each_hole_is_its_silhouette_grown_by_its_own_tolerance():
    scene, shapes = _scene()
    assert list(hole_tolerances(scene)) == [2.0, 0.5]  # the bar's own, the scene's for the L
    got = separate_holes(scene, shapes, np.array([FLAT, FLAT]), 64)
    assert len(got.outlines) == 2 and got.mirrored == []
    for o, t, (w, h, area) in zip(got.outlines, (2.0, 0.5), ((20, 10, 200.0), (12, 20, 112.0))):
        width, height = _width(o)  # never less than the offset, at most its bounded excess
        assert w + 2 * t - 1e-9 <= width <= w + 2 * t * (1 + ARC_ERROR + SIMPLIFY) + 1e-9
        assert h + 2 * t - 1e-9 <= height <= h + 2 * t * (1 + ARC_ERROR + SIMPLIFY) + 1e-9
        # the round offset by r: area + perimeter r + the corners' arcs (the L's five convex
        # corners, a quarter disk each, less the square its reflex corner overlaps)
        corners = math.pi if w == 20 else 5 * math.pi / 4 - 1

        def offset(r, a=area, p=2 * (w + h), c=corners):
            return a + p * r + c * r**2

        assert offset(t) - 1e-6 <= o.area() <= offset(t * (1 + ARC_ERROR + SIMPLIFY)) + 1e-6
    gap = got.outlines[1].bounds()[0] - got.outlines[0].bounds()[2]  # the row: bar, then L
    assert gap >= scene.fabrication.border - 1e-6


def test_a_chiral_hole_gets_its_mirror_image_and_an_achiral_one_does_not():
    scene, shapes = _scene(mirrored=True)
    ell = separate_holes(one_hole(scene, 1), shapes[1:], FLAT[None], 64).outlines[0]
    assert is_chiral(ell)
    assert not is_chiral(separate_holes(one_hole(scene, 0), shapes[:1], FLAT[None], 64).outlines[0])
    got = separate_holes(scene, shapes, np.array([FLAT, FLAT]), 64)
    assert [m["of"] for m in got.mirrored] == [1] and len(got.outlines) == 3
    mine, mirror = got.outlines[1], got.outlines[2]
    assert mirror.area() == pytest.approx(mine.area(), rel=1e-6)
    # the mirrored hole is the L's, mirrored and moved: not a turn of it, but its mirror is
    back = mirror.translate((-got.places[2]).tolist()).mirror([1.0, 0.0])
    here = mine.translate((-got.places[1]).tolist())
    assert (back ^ here).area() == pytest.approx(here.area(), rel=1e-6)  # the same polygon
    assert np.allclose(got.places[2], got.mirrored[0]["translation"])
    assert got.groups == [[0], [1], [2]]


def test_bad_tolerances_are_one_line_errors(tmp_path):
    with pytest.raises(SieveError, match=r"pass\[0\]: tolerance: must be >= 0"):
        Scene.from_meshes([{"mesh": box(5, 5, 5), "tolerance": -1.0}], [sphere(12.0, 2)])
    with pytest.raises(SieveError, match=r"block\[0\]\.tolerance: a shape to block has no hole"):
        Scene.from_meshes([box(5, 5, 5)], [{"mesh": sphere(12.0, 2), "tolerance": 1.0}])
    scene, _ = _scene()
    scene.layout.mode = "merged"
    with pytest.raises(SieveError, match=r"pass\[0\]\.tolerance: a tolerance per A needs") as e:
        hole_tolerances(scene)
    assert "\n" not in str(e.value)
    path = tmp_path / "s.toml"
    path.write_text('[[pass]]\nmesh = "a.stl"\ntolerance = "wide"\n[[block]]\nmesh = "b.stl"\n')
    from sieve_mi.scene import load_scene

    with pytest.raises(SieveError, match=r"pass\[0\]\.tolerance: expected a number") as e:
        load_scene(str(path))
    assert "\n" not in str(e.value)
