"""The command line: outputs of a run, and one-line errors with exit code 2 on bad input."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from helpers import REPO, cli_run, exr_bitmap

from sieve_mi.errors import SieveError
from sieve_mi.testing.settings import TINY

SCENES = os.path.join(REPO, "scenes")


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
def test_solve_writes_every_output(write_scene, tmp_path, capsys):
    import time

    scene = _good_scene(write_scene)
    out = tmp_path / "result"
    t0 = time.perf_counter()
    p = run_cli("solve", scene, "--out", str(out), "--quiet")
    wall = time.perf_counter() - t0
    assert "winner" in p.stdout
    report = json.loads((out / "report.json").read_text())
    # the times count from the process's start (Python and the imports are "startup"): the
    # stages add up to the total, which is this wall time less writing report.json and exiting
    t = report["timings"]
    if sys.platform.startswith("linux"):
        assert 0.0 < t["startup_s"] < t["total_s"]
        assert list(t)[0] == "startup_s" and "time: " in p.stdout and " = startup " in p.stdout
    stages = sum(v for k, v in t.items() if k != "total_s")
    assert stages == pytest.approx(t["total_s"], rel=0.05)
    assert 0.8 * wall <= t["total_s"] <= wall
    assert p.returncode == (0 if report["winner"] == "A" else 3), p.stderr  # docs/cli.md
    for key in ("winner", "pass", "block", "settings", "timings", "pixel_size"):
        assert key in report
    b = report["block"][0]
    for key in ("mesh", "beta", "loss", "blocked", "protrusion", "rotation", "translation"):
        assert key in b
    if b["blocked"]:
        # the margin, bracketed: the icosphere holds a certified ball of radius ~11.9 (its faces'
        # distance from the centre) and the face-on cube's hole holds at most a disk of radius
        # 11 (22 mm across), so every pose sticks out by more than ~0.9 mm; the best pose found
        # sticks out by about 1 mm (the sphere's 12 mm radius against 11)
        m = b["margin"]
        assert 0.8 < m["proved_at_least"] <= m["found_at_most"] == b["protrusion"] < 1.2
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
    hole = np.array(exr_bitmap(out / "hole.exr"))  # the exact hole's pixel centres
    area = float(hole.sum()) * report["pixel_size"] ** 2
    assert abs(area - report["hole"]["area"]) < 0.05 * report["hole"]["area"]
    # check reads hole.png's pixel size from its pHYs: no --pixel-size; A (cube) passes: exit 0
    # (in this process: the solve above is this test's process)
    fits = cli_run(capsys, "check", os.path.join(SCENES, "meshes", "cube.stl"), "--hole",
                   str(out / "hole.png"), "--starts", "8", "--steps", "60", "--no-fit", "--json")  # fmt: skip
    assert fits.returncode == 0, fits.stderr
    assert json.loads(fits.stdout)["pixel_size"] == report["pixel_size"]
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
    # the blocked 24 mm sphere (scenes/meshes/sphere.stl) holds a certified ball wider than any
    # disk in the hole: proved on any plate, so the plate is the printable minimum, 1.2 mm
    assert fab["required_thickness"] == 0.0 and fab["thickness"] == pytest.approx(1.2)
    assert report["block"][0]["thin_plate"]["by"] == "ball"
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
def test_a_given_thin_plate_needs_no_warning_where_a_ball_proves_the_block(write_scene, tmp_path):
    scene = _good_scene(write_scene, "[fabrication]\nthickness = 5.0\n")
    out = tmp_path / "thin"
    p = run_cli("solve", scene, "--out", str(out), "--quiet", "--no-figure")
    assert p.returncode == 0, p.stderr
    assert "warning" not in p.stderr  # 5 mm is below the sphere's 24 mm, but a ball proves it
    # the sphere holds a certified ball wider than the hole: safe on any plate, no search
    report = json.loads((out / "report.json").read_text())
    assert report["block"][0]["thin_plate"]["by"] == "ball"
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


def _assert_clean_main_error(capsys, argv, *needles, out=None):
    """:func:`_assert_clean_error` of ``sieve-mi ARGV`` run in this process
    (``sieve_mi.cli.main``): exit code 2, one stderr line holding every needle, nothing on stdout,
    ``out`` not made; any other exception fails the test as a traceback would. One process
    fewer per case: the subprocess of ``test_missing_scene_file`` checks the same path end to
    end, from ``python -m sieve_mi`` to the exit status."""
    from sieve_mi.cli import main

    code = main([str(a) for a in argv])
    err = capsys.readouterr()
    lines = [ln for ln in err.err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1, (err.out, err.err)
    assert err.out == ""
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
            ["scene.toml: name:", "control characters"],
        ),
    ],
)
def test_bad_scenes_fail_with_one_line(write_scene, tmp_path, capsys, text, needles):
    mesh = os.path.abspath(os.path.join(SCENES, "meshes", "cube.stl"))
    scene = write_scene(text.replace("MESH", mesh))
    argv = ["solve", scene, "--out", tmp_path / "o"]
    _assert_clean_main_error(capsys, argv, *needles, out=tmp_path / "o")


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
def test_bad_meshes_fail_with_one_line(write_scene, tmp_path, capsys, name):
    _bad_meshes(tmp_path)
    cube = os.path.abspath(os.path.join(SCENES, "meshes", "cube.stl"))
    scene = write_scene(
        f'name = "x"\n[[pass]]\nmesh = "{cube}"\n[[block]]\nmesh = "{tmp_path / name}"\n'
    )
    argv = ["solve", scene, "--out", tmp_path / "o"]
    _assert_clean_main_error(capsys, argv, name, out=tmp_path / "o")


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


def test_unknown_variant_and_bad_out(write_scene, tmp_path, capsys):
    scene = _good_scene(write_scene)
    argv = ["solve", scene, "--variant", "scalar_rgb", "--out", tmp_path / "o"]
    _assert_clean_main_error(capsys, argv, "scalar_rgb", out=tmp_path / "o")
    f = tmp_path / "file"
    f.write_text("x")
    _assert_clean_main_error(capsys, ["solve", scene, "--out", f], "--out")


@pytest.mark.parametrize("name", ["suzanne.obj", "alligator.obj", "spot.obj"])
def test_awkward_but_valid_meshes_are_accepted(name):
    # Open, non-manifold and flat (zero-thickness) meshes are valid input.
    from sieve_mi.geometry.meshes import load_shape

    s = load_shape(os.path.join(SCENES, "meshes", name))
    assert s.face_count > 0 and s.radius > 0


# --- check's and certify's settings options: built by sieve_mi.settings, checked like scene keys ---

#: (command, option, bad value, words of the message after "sieve-mi: error: COMMAND: OPTION: ").
BAD_OPTIONS = [
    *[
        ("check", "--learning-rate", v, w)
        for v, w in [
            ("0", "must be > 0"),
            ("-1", "must be > 0"),
            ("nan", "finite number"),
            ("inf", "finite number"),
            ("1e300", "must be <= 1.0"),
            ("fast", "expected a number, got 'fast'"),
        ]
    ],
    ("check", "--resolution", "8", "must be >= 16"),
    ("check", "--resolution", "5000", "must be <= 4096"),
    ("check", "--resolution", "1.5", "expected a whole number"),
    ("check", "--seed", "-1", "must be >= 0"),
    ("check", "--seed", "1e-3", "expected a whole number, got 0.001"),
    ("check", "--starts", "0", "must be >= 1"),
    ("check", "--steps", "0", "must be >= 1"),
    ("check", "--fit-tolerance", "0", "must be >= 1e-06"),
    ("check", "--fit-tolerance", "1e-300", "must be >= 1e-06"),  # endless before
    ("check", "--fit-tolerance", "1", "must be < 1"),
    ("check", "--fit-tolerance", "nan", "finite number"),
    ("check", "--scale", "0", "must be > 0"),
    ("check", "--scale", "inf", "finite number"),
    ("check", "--scale", "1e300", "must be <="),
    ("check", "--pixel-size", "-1", "must be > 0"),
    ("check", "--pixel-size", "nan", "finite number"),
    ("check", "--pixel-size", "1e300", "must be <="),
    ("check", "--axis", "w", "'w' is not one of: x, y, z"),
    ("check", "--units", "", "non-empty string"),
    ("certify", "--budget", "0", "must be > 0"),
    ("certify", "--budget", "-1", "must be > 0"),
    ("certify", "--budget", "nan", "finite number"),
    ("certify", "--budget", "inf", "finite number"),
    ("certify", "--scale", "-2", "must be > 0"),
    ("certify", "--axis", "q", "is not one of"),
]


def _command_line(tmp_path, command: str, option: str, value: str) -> tuple[list[str], str]:
    """A command line with one bad option, and the output it must not write."""
    from PIL import Image

    trimesh.creation.box((10, 10, 10)).export(str(tmp_path / "cube.stl"))
    img = np.zeros((40, 40), np.uint8)
    img[5:35, 5:35] = 255
    Image.fromarray(img).save(tmp_path / "h.png")
    (tmp_path / "h.svg").write_text("<svg/>")
    cube = str(tmp_path / "cube.stl")
    if command == "check":
        out = str(tmp_path / "o")
        head = ["check", cube, "--hole", str(tmp_path / "h.png"), "--pixel-size", "0.5"]
        return [*head, "--steps", "5", "--out", out, option, value], out
    out = str(tmp_path / "cert.json")
    return [
        "certify",
        cube,
        "--hole",
        str(tmp_path / "h.svg"),
        "--certificate",
        out,
        option,
        value,
    ], out


@pytest.mark.parametrize("command, option, value, words", BAD_OPTIONS)
def test_bad_setting_options_fail_with_one_line(tmp_path, capsys, command, option, value, words):
    from sieve_mi.cli import main

    argv, out = _command_line(tmp_path, command, option, value)
    assert main(argv) == 2
    err = capsys.readouterr()
    lines = [ln for ln in err.err.splitlines() if ln.strip()]
    assert len(lines) == 1, err.err
    assert lines[0].startswith(f"sieve-mi: error: {command}: {option}: "), lines[0]
    assert words in lines[0] and err.out == ""
    assert not os.path.exists(out)


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "1e300"])
def test_check_refuses_a_bad_learning_rate_in_one_line(tmp_path, capsys, value):
    # Before: 0 reported a passing cube as blocked (Adam never moved); the others crashed.
    argv, out = _command_line(tmp_path, "check", "--learning-rate", value)
    _assert_clean_main_error(capsys, argv, "check: --learning-rate: ", out=out)


def test_a_bad_option_gets_the_message_of_a_bad_scene_key(tmp_path, capsys):
    from sieve_mi.game.check_settings import CheckSettings
    from sieve_mi.settings import read_value

    scene = tmp_path / "s.toml"
    scene.write_text('[[pass]]\nmesh = "a.stl"\n[[block]]\nmesh = "a.stl"\n[solver]\nsteps = -2\n')
    argv = ["solve", scene, "--out", tmp_path / "o"]
    _assert_clean_main_error(capsys, argv, f"{scene}: solver.steps: must be >= 0, got -2")
    argv, _ = _command_line(tmp_path, "check", "--steps", "-2")
    _assert_clean_main_error(capsys, argv, "check: --steps: must be >= 1, got -2")
    with pytest.raises(SieveError, match=r"^check: --steps: must be >= 1, got -2$"):
        read_value(CheckSettings, "steps", -2, "check", "--steps")


def test_check_and_certify_options_keep_their_defaults(capsys):
    from dataclasses import asdict

    from sieve_mi.cli import main
    from sieve_mi.game.check import CheckSettings
    from sieve_mi.scene import Verdict

    # The options' defaults are the declarations' (and what they were before).
    assert asdict(CheckSettings()) == {
        "starts": 100, "steps": 500, "learning_rate": 0.05, "resolution": 256, "seed": 0,
        "thin_budget": 10.0, "fit": True, "fit_tolerance": 0.01,
    }  # fmt: skip
    assert Verdict().certify_budget == 30.0
    helps = {
        "check": [
            "random starts of the fitting search (int 1–100000, default 100)",
            "Adam steps per start (int 1–1000000, default 500)",
            "Adam's learning rate (number > 0, ≤ 1.0, default 0.05)",
            "(int 16–4096, default 256)",
            "random seed (int 0–18446744073709551615, default 0)",
            "--no-fit turn off the fit-scale search",
            "seconds of motion search through a plate (--sieve) thinner than the part "
            "(number > 0, ≤ 86400, default 10.0)",
            "(number ≥ 1e-06, < 1, default 0.01)",
            "one of x, y, z (default z)",
            "(number > 0, ≤ 1000000, default 1.0)",
            "(default mm)",
        ],
        "certify": ["time budget of each proof, seconds (number > 0, ≤ 86400, default 30.0)"],
    }
    for command, defaults in helps.items():
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert all(d in text for d in defaults), (command, text)


def test_check_options_make_the_check_settings():
    from dataclasses import asdict

    from sieve_mi.cli import _parser
    from sieve_mi.game.check_settings import CheckSettings
    from sieve_mi.options import check_options

    args = _parser().parse_args(["check", "a.stl", "--sieve", "p.stl"])
    check_options(args)
    assert {k: getattr(args, k) for k in asdict(CheckSettings())} == asdict(CheckSettings())
    assert (args.scale, args.axis, args.pixel_size, args.units) == (1.0, "z", None, "mm")
    argv = ["check", "a.stl", "--sieve", "p.stl", "--no-fit", "--learning-rate", "0.1"]
    args = _parser().parse_args([*argv, "--starts", "7", "--axis", "x"])
    check_options(args)
    assert (args.fit, args.learning_rate, args.starts, args.axis) == (False, 0.1, 7, "x")
    assert type(args.learning_rate) is float and type(args.starts) is int
    args = _parser().parse_args(["certify", "a.stl", "--hole", "h.svg", "--budget", "5"])
    check_options(args)
    assert args.certify_budget == 5.0


def test_version():
    from sieve_mi import __version__

    run = run_cli("--version")
    assert run.returncode == 0 and run.stdout.strip() == f"sieve-mi {__version__}"


def test_progress_into_a_log_is_plain_lines(tmp_path):
    # stderr is a pipe here, as in a log file: one line per stage, no tqdm '\r' frames.
    run = run_cli(
        "solve",
        os.path.join(SCENES, "rupert.toml"),
        "--out",
        str(tmp_path / "o"),
        "--no-figure",
        "--no-animation",
    )
    assert run.returncode == 3, run.stderr  # B wins: the design failed
    assert "\r" not in run.stderr
    assert "verdict: done in " in run.stderr


@pytest.mark.parametrize("command", ["solve", "check", "certify", "sort", "sweep"])
def test_every_working_subcommand_takes_quiet(command):
    from sieve_mi.cli import _parser

    assert "--quiet" in _parser()._subparsers._group_actions[0].choices[command].format_help()


def test_check_says_each_scale_it_tries(capsys):
    from sieve_mi.cli import _say_fit
    from sieve_mi.game.check import ShapeCheck

    _say_fit(ShapeCheck(1.0, True, 0.0, 0.0, [1, 0, 0, 0], [0, 0], 0, 3))
    _say_fit(ShapeCheck(1.25, False, 0.0312, 0.5, [1, 0, 0, 0], [0, 0], 0, 0))
    err = capsys.readouterr().err.splitlines()
    assert err == ["check: scale 1.0000: passes",
                   "check: scale 1.2500: blocked (beta 0.0312, sticks out 0.500)"]  # fmt: skip


def test_every_option_of_every_subcommand_has_help():
    from sieve_mi.cli import _parser

    commands = _parser()._subparsers._group_actions[0].choices
    missing = [
        (name, a.option_strings or a.dest)
        for name, sub in commands.items()
        for a in sub._actions
        if not a.help and "-h" not in a.option_strings
    ]
    assert missing == []
    assert "-sweep" not in commands["sort"].format_help()  # sort's --out is not sweep's


# ------------------------------------------------------------------------------------------------
# exit codes (docs/cli.md) and --threads
# ------------------------------------------------------------------------------------------------


def test_every_subcommand_takes_threads():
    from sieve_mi.cli import _parser

    for command, sub in _parser()._subparsers._group_actions[0].choices.items():
        assert "--threads N" in sub.format_help(), command
        if command in ("solve", "check", "certify", "sort", "sweep"):
            assert "--json" in sub.format_help() and "--quiet" in sub.format_help(), command


def test_exit_code_constants_are_the_documented_ones():
    from sieve_mi import errors

    assert (errors.EXIT_OK, errors.EXIT_BAD_INPUT, errors.EXIT_NO, errors.EXIT_UNDECIDED) == (
        0,
        2,
        3,
        4,
    )
    with open(os.path.join(REPO, "docs", "cli.md")) as fh:
        doc = fh.read()
    for code in ("| 0 |", "| 1 |", "| 2 |", "| 3 |", "| 4 |", "| 130, 143, 129 |"):
        assert code in doc, code


@pytest.mark.parametrize("count", ["0", "-2"])
def test_threads_below_one_is_one_line(count, tmp_path, capsys):
    argv = [
        "solve",
        os.path.join(SCENES, "rupert.toml"),
        "--threads",
        count,
        "--out",
        tmp_path / "o",
    ]
    needle = f"--threads {count}: must be a whole number from 1 to "
    _assert_clean_main_error(capsys, argv, needle, out=tmp_path / "o")


def test_solve_json_prints_report_json_on_stdout_and_one_thread_writes_every_exr(tmp_path):
    # One run for two tests that solved the same scene with the same flags (but --threads 1):
    # --json prints report.json's content on stdout and nothing else; one Dr.Jit thread:
    # Mitsuba's OpenEXR reader and writer would wait forever on the pool (backend.bitmap_threads
    # gives them two); the report records the count.
    out = tmp_path / "o"
    run = run_cli("solve", os.path.join(SCENES, "rupert.toml"), "--threads", "1", "--out",
                  str(out), "--no-figure", "--no-animation", "--quiet", "--json")  # fmt: skip
    assert run.returncode == 3, run.stderr  # Rupert's cube gets through: the design failed
    report = json.loads(run.stdout)  # nothing else on stdout
    with open(out / "report.json") as fh:
        assert report == json.load(fh)
    assert report["winner"] == "B" and "outputs:" in run.stderr
    assert report["provenance"]["machine"]["threads"] == 1
    assert np.array(exr_bitmap(out / "hole.exr")).shape[:2] == (report["hole"]["resolution"],) * 2


@pytest.mark.slow
def test_check_exit_code_says_passes_or_blocked(tmp_path, capsys):
    # A 10 mm cube and a 16 mm square hole (1 mm pixels, recorded in the PNG as solve writes
    # it): 0 when it passes, 3 when blocked; --pixel-size overrides what the PNG records. The
    # first check runs in a process of its own, the other two in this one (sieve_mi.cli.main).
    from sieve_mi.cli import main
    from sieve_mi.outputs.images import write_png

    def in_process(*argv):
        code = main(list(argv))
        return code, json.loads(capsys.readouterr().out)

    trimesh.creation.box((10.0, 10.0, 10.0)).export(str(tmp_path / "cube.stl"))
    img = np.zeros((24, 24), bool)
    img[4:20, 4:20] = True
    write_png(str(tmp_path / "hole.png"), img, 1.0, "mm")
    args = ["check", str(tmp_path / "cube.stl"), "--hole", str(tmp_path / "hole.png"),
            "--starts", "4", "--steps", "40", "--no-fit", "--json"]  # fmt: skip
    passes = run_cli(*args)
    assert passes.returncode == 0, passes.stderr
    assert json.loads(passes.stdout)["passes"] is True
    assert json.loads(passes.stdout)["pixel_size"] == 1.0
    code, blocked = in_process(*args, "--scale", "2")  # a 20 mm cube
    assert code == 3 and blocked["passes"] is False
    code, smaller = in_process(*args, "--pixel-size", "0.5")  # the flag wins: an 8 mm hole
    assert code == 3 and smaller["pixel_size"] == 0.5


@pytest.mark.parametrize("inner, code", [("term", 143), ("int", 130)])
def test_a_signal_wrapped_by_a_library_still_gives_its_exit_code(monkeypatch, capsys, inner, code):
    # Mitsuba's render wraps an exception raised in its Python callbacks (RuntimeError from
    # ...); a SIGTERM or Ctrl-C landing there must still end the run as that signal does.
    from sieve_mi import cli

    def boom(args):
        cause = cli.Terminated(15) if inner == "term" else KeyboardInterrupt()
        raise RuntimeError("render failed") from cause

    monkeypatch.setattr(cli, "cmd_solve", boom)
    assert cli.main(["solve", "scenes/default.toml"]) == code
    assert capsys.readouterr().err.strip().startswith("sieve-mi: ")


@pytest.mark.parametrize("signum, code", [(15, 143), (2, 130)])
def test_a_signal_a_frozen_step_swallowed_as_text_still_ends_the_run(monkeypatch, capsys, signum,
                                                                     code):  # fmt: skip
    # Dr.Jit may report an exception raised while it recorded a frozen step as a RuntimeError
    # carrying the interrupt only as text. Player B used to read that as "freezing failed" and
    # trace on: a SIGTERM was lost (seen on a letters run that ran on for minutes after a kill).
    # Once the handler has run, the error stands for the signal: the players raise a
    # KeyboardInterrupt and the command line ends with the signal's code.
    from sieve_mi import cli
    from sieve_mi.errors import clear_signals, interruption, note_signal

    text_only = RuntimeError("drjit.freeze(): KeyboardInterrupt")
    clear_signals()
    assert interruption(text_only) is None  # a real failure of freezing: trace instead
    note_signal(signum)
    assert isinstance(interruption(text_only), KeyboardInterrupt)

    def lost(args):
        note_signal(signum)
        raise interruption(text_only)

    monkeypatch.setattr(cli, "cmd_solve", lost)
    assert cli.main(["solve", "scenes/default.toml"]) == code
    word = "terminated" if signum == 15 else "interrupted"
    assert capsys.readouterr().err.strip() == f"sieve-mi: {word}"
    clear_signals()


def test_every_subcommand_runs_from_the_one_command_table():
    import importlib

    from sieve_mi import cli

    sub = next(a for a in cli._parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert list(sub.choices) == list(cli.COMMANDS)
    for module, function in cli.COMMANDS.values():
        assert callable(getattr(importlib.import_module(module), function))
