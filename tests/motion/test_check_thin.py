"""``sieve-mi check PART --sieve PLATE``: the plate's measured thickness and the thin-plate answer."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import manifold3d
import pytest
import trimesh

from sieve_mi.game.check import plate_thickness
from sieve_mi.testing import shapes


def _plate(path, thickness: float, radius: float = 4.5) -> str:
    block = manifold3d.Manifold.cube([60, 60, thickness]).translate([-30, -30, -thickness])
    hole = manifold3d.Manifold.cylinder(thickness + 2, radius, radius, 64).translate(
        [3.0, -2.0, -thickness - 1]
    )
    m = (block - hole).to_mesh()
    trimesh.Trimesh(m.vert_properties[:, :3], m.tri_verts).export(str(path))
    return str(path)


def _check(*args):
    cmd = [sys.executable, "-m", "sieve_mi", "check", *args, "--no-fit", "--json", "--quiet"]
    cmd += ["--starts", "16", "--steps", "60"]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600)


def test_plate_thickness_is_its_extent_along_the_axis(tmp_path):
    assert plate_thickness(_plate(tmp_path / "p.stl", 1.5)) == pytest.approx(1.5)
    assert plate_thickness(_plate(tmp_path / "q.stl", 1.5), "x") == pytest.approx(60.0)


@pytest.mark.slow
def test_check_finds_the_rod_threading_a_thin_plate_and_not_a_thick_one(tmp_path):
    """The L-rod (two 20 mm arms, 2 x 2 mm) against a 9 mm round hole off the plate's centre:
    blocked straight down (each arm projects >= 14.1 mm); through a 1 mm plate it threads, and
    the motion's poses are in the plate's own coordinates (they start over the hole at (3, -2));
    on a 30 mm plate (more than its 28.35 mm diameter) the block is safe."""
    rod = tmp_path / "rod.stl"
    shapes.l_rod(20.0, 2.0).export(str(rod))
    p = _check(str(rod), "--sieve", _plate(tmp_path / "thin.stl", 1.0), "--thin-budget", "60")
    report = json.loads(p.stdout)
    thin = report["thin_plate"]
    assert report["result"]["passes"] is False and thin["status"] == "passage", p.stderr
    assert report["passes"] is True  # through the real plate, by a verified motion
    assert thin["thickness"] == pytest.approx(1.0) and thin["diameter"] == pytest.approx(
        math.sqrt(804)
    )
    first = thin["poses"][0]
    assert math.hypot(first[4] - 3.0, first[5] + 2.0) < 25.0  # the hole's box grown by the radius
    p = _check(str(rod), "--sieve", _plate(tmp_path / "thick.stl", 30.0))
    report = json.loads(p.stdout)
    assert report["thin_plate"]["status"] == "safe" and report["passes"] is False
