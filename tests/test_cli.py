"""The command line: outputs of a run, and one-line errors with exit code 2 on bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from helpers import TINY

SCENES = os.path.join(os.path.dirname(__file__), "..", "scenes")


def run_cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def _good_scene(write_scene, extra=""):
    mesh = os.path.abspath(os.path.join(SCENES, "meshes"))
    return write_scene(
        f'name = "tiny"\n[[pass]]\nmesh = "{mesh}/cube.stl"\n[[block]]\nmesh = "{mesh}/sphere.stl"\n'
        + extra
        + TINY
    )


@pytest.mark.slow
def test_solve_writes_every_output(write_scene, tmp_path):
    import mitsuba as mi

    scene = _good_scene(write_scene)
    out = tmp_path / "result"
    p = run_cli("solve", scene, "--out", str(out), "--quiet")
    assert p.returncode == 0, p.stderr
    assert "winner" in p.stdout
    report = json.loads((out / "report.json").read_text())
    for key in ("winner", "pass", "block", "settings", "timings", "pixel_size"):
        assert key in report
    b = report["block"][0]
    for key in ("mesh", "beta", "loss", "blocked", "protrusion", "rotation", "translation"):
        assert key in b
    # the winner follows from the blocks: A iff every B is blocked (β > 0 and no fitting start)
    assert report["winner"] == ("A" if all(x["blocked"] for x in report["block"]) else "B")
    assert b["blocked"] == (b["beta"] > 0) and b["beta"] == b["loss"]
    assert len(report["pass"][0]["rotation"]) == 4 and len(b["translation"]) == 2
    assert set(report["timings"]) >= {"search_s", "verdict_s"}
    for f in (
        "hole.png",
        "hole.exr",
        "convergence.png",
        "overlay.png",
        "masks/a_silhouette.exr",
        "masks/block_0_sphere.exr",
    ):
        assert (out / f).is_file(), f
    hole = np.array(mi.Bitmap(str(out / "hole.exr")))
    area = float(hole.sum()) * report["pixel_size"] ** 2
    assert area == pytest.approx(report["hole"]["raster_area"])
    # the conservative raster covers every pixel that touches the exact hole
    assert report["hole"]["area"] <= report["hole"]["raster_area"]
    assert not [
        f for f in os.listdir(tmp_path) if f.startswith(".sieve-mi-")
    ]  # no temporary leftovers
    # the printable sieve and the placed shapes
    for f in ("sieve.stl", "sieve.3mf", "hole.svg", "pass_0.stl", "block_0.stl", "figure.png"):
        assert (out / f).is_file(), f
    fab = report["fabrication"]
    plate = trimesh.load(str(out / "sieve.stl"))
    assert plate.is_watertight and plate.is_volume and len(plate.split(only_watertight=False)) == 1
    # cube of side 20 (scenes/meshes/cube.stl): circumsphere diameter 20 sqrt(3) = 34.64
    assert (
        fab["required_thickness"] == pytest.approx(34.7)
        and fab["thickness"] == fab["required_thickness"]
    )
    assert plate.extents[2] == pytest.approx(fab["thickness"], rel=1e-6)
    # exact outline vs the coarse 96 px raster, which is conservative (it covers every pixel
    # within half a pixel diagonal of H): never smaller, at most a thin ring larger
    assert -0.1 < fab["outline"]["area_difference"] <= 0
    assert fab["warnings"] == [] and "warning" not in p.stderr
    cube = trimesh.load(str(out / "pass_0.stl"))
    assert (
        cube.volume == pytest.approx(8000.0, rel=1e-6) and cube.bounds[0, 2] > 0
    )  # above the plate


@pytest.mark.slow
def test_thin_plate_gets_a_warning(write_scene, tmp_path):
    scene = _good_scene(write_scene, "[fabrication]\nthickness = 5.0\n")
    out = tmp_path / "thin"
    p = run_cli("solve", scene, "--out", str(out), "--quiet", "--no-figure")
    assert p.returncode == 0, p.stderr
    assert "warning" in p.stderr and "34.7" in p.stderr and "B.1" in p.stderr
    assert trimesh.load(str(out / "sieve.stl")).extents[2] == pytest.approx(5.0)
    assert not (out / "figure.png").exists()


def _assert_clean_error(p, *needles, out=None):
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = [ln for ln in p.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr
    for n in needles:
        assert n in lines[0], lines[0]
    if out is not None:
        assert not os.path.exists(out)


def test_missing_scene_file(tmp_path):
    _assert_clean_error(
        run_cli("solve", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")),
        "nope.toml",
        "not found",
        out=tmp_path / "o",
    )


@pytest.mark.parametrize(
    "text, needles",
    [
        ("name = \n", ["not valid TOML"]),
        ('name = "x"\n[[block]]\nmesh = "a.stl"\n', ["pass", "missing"]),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[solver]\npartciles = 3\n',
            ["solver.partciles", "unknown key"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[solver]\nparticles = -3\n',
            ["solver.particles", ">= 1"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[solver]\nobjective = "area"\n',
            ["solver.objective", "clearance"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\nrotation = [1, 1, 0, 0]\n[[block]]\nmesh = "MESH"\n',
            ["pass[0].rotation", "unit quaternion"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\nscale = 0\n[[block]]\nmesh = "MESH"\n',
            ["pass[0].scale", "> 0"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "missing.stl"\n[[block]]\nmesh = "MESH"\n',
            ["missing.stl", "not found"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[fabrication]\ntolerance = "1mm"\n',
            ["fabrication.tolerance", "number"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[layout]\nrounds = 0\n',
            ["layout.rounds", ">= 1"],
        ),
        (
            'name = "x"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n[layout]\nalternatives = 1.5\n',
            ["layout.alternatives", "whole number"],
        ),
        (
            'name = "a\\u0000b"\n[[pass]]\nmesh = "MESH"\n[[block]]\nmesh = "MESH"\n',
            ["scene.toml: name:", "folder name"],
        ),
    ],
)
def test_bad_scenes_fail_with_one_line(write_scene, tmp_path, text, needles):
    mesh = os.path.abspath(os.path.join(SCENES, "meshes", "cube.stl"))
    scene = write_scene(text.replace("MESH", mesh))
    _assert_clean_error(
        run_cli("solve", scene, "--out", str(tmp_path / "o")), *needles, out=tmp_path / "o"
    )


def _bad_meshes(tmp_path):
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    (tmp_path / "cloud.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
    )
    (tmp_path / "empty.stl").write_bytes(b"")
    (tmp_path / "garbage.obj").write_bytes(b"\x00\x01\x02 not a mesh \xff" * 10)
    (tmp_path / "flat0.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"
    )  # zero-area triangle only
    return ["nan.obj", "cloud.ply", "empty.stl", "garbage.obj", "flat0.obj"]


@pytest.mark.parametrize("name", ["nan.obj", "cloud.ply", "empty.stl", "garbage.obj", "flat0.obj"])
def test_bad_meshes_fail_with_one_line(write_scene, tmp_path, name):
    _bad_meshes(tmp_path)
    cube = os.path.abspath(os.path.join(SCENES, "meshes", "cube.stl"))
    scene = write_scene(
        f'name = "x"\n[[pass]]\nmesh = "{cube}"\n[[block]]\nmesh = "{tmp_path / name}"\n'
    )
    _assert_clean_error(
        run_cli("solve", scene, "--out", str(tmp_path / "o")), name, out=tmp_path / "o"
    )


def test_bad_variant_in_environment(write_scene, tmp_path):
    scene = _good_scene(write_scene)
    env = {**os.environ, "SIEVE_MI_VARIANT": "scalar_rgb"}
    p = subprocess.run(
        [sys.executable, "-m", "sieve_mi", "solve", scene, "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    _assert_clean_error(p, "SIEVE_MI_VARIANT=scalar_rgb", out=tmp_path / "o")


def test_unknown_variant_and_bad_out(write_scene, tmp_path):
    scene = _good_scene(write_scene)
    _assert_clean_error(
        run_cli("solve", scene, "--variant", "scalar_rgb", "--out", str(tmp_path / "o")),
        "scalar_rgb",
        out=tmp_path / "o",
    )
    f = tmp_path / "file"
    f.write_text("x")
    _assert_clean_error(run_cli("solve", scene, "--out", str(f)), "--out")


@pytest.mark.parametrize("name", ["suzanne.obj", "alligator.obj", "spot.obj"])
def test_awkward_but_valid_meshes_are_accepted(name):
    # Open, non-manifold and flat (zero-thickness) meshes are valid input.
    from sieve_mi.geometry.meshes import load_shape

    s = load_shape(os.path.join(SCENES, "meshes", name))
    assert s.face_count > 0 and s.radius > 0
