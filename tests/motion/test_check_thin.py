"""``sieve-mi check PART --sieve PLATE``: the plate's measured thickness and the thin-plate answer.

The thickness is measured where the holes are (:mod:`sieve_mi.geometry.sieve`): a post elsewhere
on the plate must not make a thin sheet look thick (issue 40 row 3, a false "safe"), and a motion
found through the slab must also clear the plate's own mesh before it counts.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.game.check import CheckSettings, check
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.sieve import read_plate
from sieve_mi.motion import thin_plate
from sieve_mi.outputs.console import check_summary
from sieve_mi.testing import shapes


def _plate(path, thickness: float, radius: float = 4.5) -> str:
    block = manifold3d.Manifold.cube([60, 60, thickness]).translate([-30, -30, -thickness])
    hole = manifold3d.Manifold.cylinder(thickness + 2, radius, radius, 64).translate(
        [3.0, -2.0, -thickness - 1]
    )
    m = (block - hole).to_mesh()
    trimesh.Trimesh(m.vert_properties[:, :3], m.tri_verts).export(str(path))
    return str(path)


#: The check's options in these tests: no fit, JSON, 16 starts of 60 steps.
CHECK_ARGS = ("--no-fit", "--json", "--quiet", "--starts", "16", "--steps", "60")


def _check(*args):
    cmd = [sys.executable, "-m", "sieve_mi", "check", *args, *CHECK_ARGS]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600)


def test_plate_thickness_is_measured_along_the_axis_where_the_holes_are(tmp_path):
    assert read_plate(_plate(tmp_path / "p.stl", 1.5)).thickness == pytest.approx(1.5)
    with pytest.raises(SieveError, match="no through-hole along x"):  # not its 60 mm width
        read_plate(_plate(tmp_path / "q.stl", 1.5), "x")


def _with_post(path) -> str:
    """Issue 40 row 3: a 2 mm sheet with a 10 mm hole and one 60 mm post beside it."""
    sheet = manifold3d.Manifold.cube([60, 60, 2]).translate([-30, -30, -2])
    sheet -= manifold3d.Manifold.cylinder(6, 5, 5, 64).translate([0, 0, -3])
    sheet += manifold3d.Manifold.cylinder(60, 2, 2, 16).translate([20, 20, 0])
    m = sheet.to_mesh()
    trimesh.Trimesh(m.vert_properties[:, :3], m.tri_verts).export(str(path))
    return str(path)


def test_a_post_does_not_make_a_thin_sheet_safe(tmp_path):
    """The L-rod (diameter 28.35 mm) against the sheet with a post: measured 2 mm (not the
    62 mm extent), so the block is not "safe by diameter"; the summary and the JSON say the
    plate is not a uniform slab; a passage, if the short search finds one, was re-checked
    against the plate's own mesh."""
    rod = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="rod")
    settings = CheckSettings(starts=8, steps=30, fit=False, thin_budget=0.5)
    rep = check(rod, sieve=_with_post(tmp_path / "post.stl"), settings=settings)
    thin = rep.to_dict()["thin_plate"]
    assert thin["thickness"] == pytest.approx(2.0) and thin["status"] != "safe"
    note = "plate is not a uniform slab: 2 mm where the holes are, 62 mm overall; proofs use 2 mm"
    assert thin["plate"]["note"] == note
    assert thin["plate"]["overall"] == pytest.approx(62.0) and not thin["plate"]["uniform"]
    assert note in check_summary(rep).splitlines()
    assert rep.result.passes is False and rep.passes == (thin["status"] == "passage")
    if thin["status"] == "passage":
        assert thin["verified_on"] == "plate mesh"


CUBE = shape_from_trimesh(trimesh.creation.box((8.0, 8.0, 8.0)), name="cube")
SQUARE = manifold3d.CrossSection.square([10.0, 10.0], center=True)


def _slab_and(extra: manifold3d.Manifold) -> tuple:
    """The 2 mm slab (top at z = 0) with the 10 mm square hole, plus ``extra``: (V, F)."""
    slab = manifold3d.Manifold.cube([60, 60, 2]).translate([-30, -30, -2])
    slab -= manifold3d.Manifold.cube([10, 10, 4]).translate([-5, -5, -3])
    m = (slab + extra).to_mesh()
    return np.asarray(m.vert_properties[:, :3], float), np.asarray(m.tri_verts, np.int64)


def test_a_motion_through_the_slab_counts_only_once_it_clears_the_plate_mesh():
    """The 8 mm cube drops straight through the 10 mm square hole of a 2 mm slab. With a post
    beside the hole the motion is lengthened to start above the post and is verified; with a
    bar over the hole (material the slab model lacks) it is dropped, and the answer says why."""
    post = manifold3d.Manifold.cylinder(60, 2, 2, 16).translate([20, 20, 0])
    found = thin_plate(CUBE, SQUARE, 2.0, budget_s=2.0, plate=_slab_and(post))
    assert found.status == "passage" and found.verified_on == "plate mesh"
    assert found.poses[0, 6] >= 60.0 + CUBE.radius and found.poses[-1, 6] <= -2.0 - CUBE.radius
    bar = manifold3d.Manifold.cube([60, 4, 2]).translate([-30, -2, 10])
    found = thin_plate(CUBE, SQUARE, 2.0, budget_s=2.0, plate=_slab_and(bar))
    assert found.status == "no passage found"
    assert "met the plate's other material" in found.to_dict()["note"]


@pytest.mark.parametrize("thickness", [0.0, -1.0, math.nan, math.inf, 1e-9])
def test_the_search_never_gets_a_degenerate_plate(monkeypatch, thickness):
    """Issue 40 row 8: a flat plate crashed the worker (a zero-height prism); now a one-line
    SieveError before any worker starts."""
    import sieve_mi.motion.thin as thin

    def no_pool(*args, **kwargs):
        raise AssertionError("no worker may start")

    monkeypatch.setattr(thin, "worker_pool", no_pool, raising=False)
    with pytest.raises(SieveError, match="thickness .*must be a positive number"):
        thin_plate(CUBE, SQUARE, thickness, budget_s=1.0)


@pytest.mark.slow
def test_check_finds_the_rod_threading_a_thin_plate_and_not_a_thick_one(tmp_path, capsys):
    """The L-rod (two 20 mm arms, 2 x 2 mm) against a 9 mm round hole off the plate's centre:
    blocked straight down (each arm projects >= 14.1 mm); through a 1 mm plate it threads, and
    the motion's poses are in the plate's own coordinates (they start over the hole at (3, -2));
    on a 30 mm plate (more than its 28.35 mm diameter) the block is safe.

    16 s: the rod's slab-section proof gets half and fails (it threads), then the motion search,
    seeded with the check's pose, finds the passage (in 2 s on a loaded machine; 2026-12-04)."""
    rod = tmp_path / "rod.stl"
    shapes.l_rod(20.0, 2.0).export(str(rod))
    p = _check(str(rod), "--sieve", _plate(tmp_path / "thin.stl", 1.0), "--thin-budget", "16")
    report = json.loads(p.stdout)
    thin = report["thin_plate"]
    assert report["result"]["passes"] is False and thin["status"] == "passage", p.stderr
    assert report["passes"] is True  # through the real plate, by a verified motion
    assert thin["thickness"] == pytest.approx(1.0) and thin["diameter"] == pytest.approx(
        math.sqrt(804)
    )
    first = thin["poses"][0]
    assert math.hypot(first[4] - 3.0, first[5] + 2.0) < 25.0  # the hole's box grown by the radius
    # the same command in this process (the thin plate's run above is the real one)
    from sieve_mi.cli import main

    args = [str(rod), "--sieve", _plate(tmp_path / "thick.stl", 30.0), *CHECK_ARGS]
    assert main(["check", *args]) == 3  # blocked (docs/cli.md)
    report = json.loads(capsys.readouterr().out)
    assert report["thin_plate"]["status"] == "safe" and report["passes"] is False
