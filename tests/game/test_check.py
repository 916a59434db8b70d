"""``sieve-mi check`` on sieves made by hand (not by sieve-mi), with known answers.

* A cube of side a passes a square hole of side w iff a <= w: face-on it fits when a <= w, and
  every projection of a cube has width >= a in every direction, so it cannot fit when a > w. Its
  fit scale through the hole is therefore w / a.
* A ball of radius r passes a round hole of radius R iff r <= R; fit scale R / r (an icosphere's
  silhouette is a polygon inscribed in the great circle, so its fit scale is slightly above).
* A long thin rod passes a slot end-on whatever its length.
"""

from __future__ import annotations

import json
import math

import manifold3d
import numpy as np
import pytest
import trimesh
from helpers import cli_run
from PIL import Image

from sieve_mi.errors import SieveError
from sieve_mi.game.check import CheckSettings, ShapeCheck, check, fit_scale
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.sieve import plate_holes
from sieve_mi.outputs.fabrication import to_trimesh

FAST = CheckSettings(starts=24, steps=150, resolution=192, fit_tolerance=0.01)


def square_plate(
    path: str, w: float, *, offset=(3.0, -2.0), thickness: float = 20.0, axis: str = "z"
) -> str:
    """A 50 x 50 plate with a w x w square hole centred at ``offset``, written as STL."""
    plate = manifold3d.Manifold.cube([50, 50, thickness]).translate([-25, -25, -thickness / 2])
    hole = manifold3d.Manifold.cube([w, w, thickness + 10]).translate(
        [offset[0] - w / 2, offset[1] - w / 2, -thickness / 2 - 5]
    )
    mesh = to_trimesh(plate - hole)
    if axis == "x":  # turn the plate so its hole runs along x
        mesh.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    mesh.export(path)
    return path


def cube(a: float):
    return shape_from_trimesh(trimesh.creation.box((a, a, a)), name="cube")


def test_holes_of_a_plate_are_found_exactly(tmp_path):
    path = square_plate(str(tmp_path / "p.stl"), 12.0)
    holes = plate_holes(path)
    assert len(holes) == 1
    assert holes[0].area() == pytest.approx(144.0, rel=1e-9)
    b = holes[0].bounds()
    assert (b[0] + b[2]) / 2 == pytest.approx(3.0) and (b[1] + b[3]) / 2 == pytest.approx(-2.0)
    # a plate with two holes
    plate = (
        manifold3d.Manifold.cube([60, 30, 10])
        - manifold3d.Manifold.cube([10, 10, 20]).translate([5, 5, -5])
        - manifold3d.Manifold.cylinder(20, 6.0, 6.0, 64).translate([40, 15, -5])
    )
    to_trimesh(plate).export(str(tmp_path / "two.stl"))
    two = plate_holes(str(tmp_path / "two.stl"))
    assert [h.area() for h in two] == pytest.approx(
        [manifold3d.CrossSection.circle(6.0, 64).area(), 100.0], rel=1e-6
    )


def test_a_plate_without_a_through_hole_is_a_clear_error(tmp_path):
    path = str(tmp_path / "solid.stl")
    trimesh.creation.box((20, 20, 5)).export(path)
    with pytest.raises(SieveError, match="no through-hole"):
        plate_holes(path)
    # a blind hole (a pocket) is no through-hole either
    pocket = manifold3d.Manifold.cube([20, 20, 5]) - manifold3d.Manifold.cube([5, 5, 10]).translate(
        [7, 7, 2]
    )
    to_trimesh(pocket).export(path)
    with pytest.raises(SieveError, match="no through-hole"):
        plate_holes(path)


@pytest.mark.slow
def test_cube_through_square_hole_fit_scale(tmp_path):
    w, a = 15.0, 10.0
    path = square_plate(str(tmp_path / "p.stl"), w)
    rep = check(cube(a), sieve=path, settings=FAST)
    assert rep.result.passes and rep.result.beta == 0
    assert rep.result.exact_outside_area == pytest.approx(
        0.0, abs=0.05 * a
    )  # at most a sliver at the pixel scale
    # the pose is reported in the plate's coordinates: near the hole's centre (3, -2)
    assert (
        np.hypot(rep.result.translation[0] - 3.0, rep.result.translation[1] + 2.0)
        < (w - a) / 2 + 0.5
    )
    lo, hi = rep.fit_bracket
    assert hi / lo - 1 <= 0.011
    h = rep.pixel_size
    assert w / a - 2 * h / a <= rep.fit_scale <= w / a + 2 * h / a


@pytest.mark.slow
def test_cube_too_big_for_the_hole_is_blocked_with_its_margin(tmp_path):
    w, a = 9.0, 10.0
    path = square_plate(str(tmp_path / "p.stl"), w, axis="x")
    rep = check(cube(a), sieve=path, axis="x", settings=FAST)
    assert not rep.result.passes
    # every projection of the cube is at least a wide along the hole's sides: it sticks out by (a - w) / 2 or more
    assert rep.result.protrusion >= (a - w) / 2 - 2 * rep.pixel_size
    h = rep.pixel_size
    assert w / a - 2 * h / a <= rep.fit_scale <= w / a + 2 * h / a


@pytest.mark.slow
def test_ball_through_a_round_hole_in_an_image(tmp_path):
    R, r, px = 8.0, 6.0, 0.1
    n = 200
    yy, xx = np.mgrid[0:n, 0:n]
    c = (n - 1) / 2
    disk = np.hypot(xx - c, yy - c) * px <= R
    Image.fromarray(disk.astype(np.uint8) * 255).save(tmp_path / "hole.png")
    ball = shape_from_trimesh(trimesh.creation.icosphere(3, r), name="ball")
    rep = check(ball, image=str(tmp_path / "hole.png"), pixel_size=px, settings=FAST)
    assert rep.result.passes
    assert rep.pixel_size == pytest.approx(px)
    assert rep.holes[0]["area"] == pytest.approx(math.pi * R * R, rel=0.02)
    # the icosphere's silhouette is inscribed in the great circle: at least R / r, a little above
    assert R / r - 2 * px / r <= rep.fit_scale <= R / r * 1.03


@pytest.mark.slow
def test_a_long_rod_passes_a_slot_end_on(tmp_path):
    """Length does not matter when the rod can go end-on: a 4 x 4 x 60 rod through a 5 x 30 slot."""
    plate = manifold3d.Manifold.cube([80, 80, 10]) - manifold3d.Manifold.cube(
        [30, 5, 20]
    ).translate([25, 37.5, -5])
    to_trimesh(plate).export(str(tmp_path / "slot.stl"))
    rod = shape_from_trimesh(trimesh.creation.box((4, 4, 60)), name="rod")
    rep = check(
        rod,
        sieve=str(tmp_path / "slot.stl"),
        settings=CheckSettings(starts=48, steps=300, fit=False),
    )
    assert rep.result.passes
    assert rep.fit_scale is None


def test_fit_scale_bisection_on_a_known_threshold():
    calls = []

    def evaluate(s):
        calls.append(s)
        return ShapeCheck(
            scale=s,
            passes=s <= 1.37,
            beta=0.0,
            protrusion=0.0,
            rotation=[1, 0, 0, 0],
            translation=[0, 0],
            hole=0,
            fitting_starts=0,
        )

    s, (lo, hi) = fit_scale(evaluate, evaluate(1.0), 0.001)
    assert lo <= 1.37 < hi and hi / lo - 1 <= 0.001 and s == lo
    calls.clear()
    s, (lo, hi) = fit_scale(
        lambda x: ShapeCheck(x, x <= 0.3, 0, 0, [], [], 0, 0),
        ShapeCheck(1.0, False, 0.1, 1, [], [], 0, 0),
        0.01,
    )
    assert lo <= 0.3 < hi and s == lo
    s, (lo, hi) = fit_scale(
        lambda x: ShapeCheck(x, False, 0.1, 1, [], [], 0, 0),
        ShapeCheck(1.0, False, 0.1, 1, [], [], 0, 0),
        0.01,
    )
    assert s == 0.0


# ------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_check_command_json(tmp_path, capsys):
    path = square_plate(str(tmp_path / "p.stl"), 15.0)
    trimesh.creation.box((10, 10, 10)).export(str(tmp_path / "cube.stl"))
    p = cli_run(
        capsys,
        "check",
        str(tmp_path / "cube.stl"),
        "--sieve",
        path,
        "--starts",
        "24",
        "--steps",
        "150",
        "--json",
    )
    assert p.returncode == 0, p.stderr
    rep = json.loads(p.stdout)
    assert rep["passes"] is True
    assert rep["fit_scale"] == pytest.approx(1.5, abs=0.03)
    # --scale applies before the test: the 10 mm cube at scale 1.6 is blocked
    p = cli_run(
        capsys,
        "check",
        str(tmp_path / "cube.stl"),
        "--sieve",
        path,
        "--scale",
        "1.6",
        "--starts",
        "24",
        "--steps",
        "150",
        "--no-fit",
    )
    assert p.returncode == 3, p.stderr  # blocked: docs/cli.md's exit codes
    assert "blocked" in p.stdout


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--sieve", "{tmp}/missing.stl"], "missing.stl"),
        (["--hole", "{tmp}/h.png"], "--pixel-size"),
        (["--hole", "{tmp}/black.png", "--pixel-size", "0.1"], "no hole pixels"),
        (["--hole", "{tmp}/h.png", "--pixel-size", "-1"], "--pixel-size"),
        (["--sieve", "{tmp}/solid.stl"], "no through-hole"),
        (["--sieve", "{tmp}/solid.stl", "--scale", "0"], "--scale"),
    ],
)
def test_check_bad_input_is_one_line(tmp_path, capsys, args, needle):
    trimesh.creation.box((10, 10, 10)).export(str(tmp_path / "cube.stl"))
    trimesh.creation.box((20, 20, 5)).export(str(tmp_path / "solid.stl"))
    Image.fromarray(np.zeros((10, 10), np.uint8)).save(tmp_path / "black.png")
    img = np.zeros((10, 10), np.uint8)
    img[3:7, 3:7] = 255
    Image.fromarray(img).save(tmp_path / "h.png")
    p = cli_run(
        capsys, "check", str(tmp_path / "cube.stl"), *[a.format(tmp=tmp_path) for a in args]
    )
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in p.stderr
    assert needle in lines[0]
