"""Inputs no command should trust (the hostile pass after issue 40, rows F4-F14): a solve
folder's report.json and shape files (shake DIR), sizes that would make the raster absurd, a
decompression-bomb image, the API's check in a fresh process and with a wrong part, --workers,
unknown units, an overflowing rotation.

Each refusal is one stderr line naming the file or value, exit 2, before any work, nothing of
the user's touched (every input hashed before and after). In-process (``sieve_mi.cli.main``)
except where the row is about a fresh process.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import warnings
import zlib

import manifold3d
import pytest
import trimesh
from helpers import REPO, tree

import sieve_mi as sm
from sieve_mi.backend import max_threads
from sieve_mi.cli import main
from sieve_mi.game.check import EDGE_SAMPLES_MAX, check_part_size
from sieve_mi.geometry.hole_image import IMAGE_PIXELS_MAX
from sieve_mi.geometry.meshes import edge_length, shape_from_trimesh
from sieve_mi.shake.inputs import from_folder
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.testing.shapes import from_manifold

SHAKE_QUICK = ("--trials", "1", "--duration", "0.1", "--workers", "1", "--no-clip", "--quiet")
CHECK_QUICK = ("--starts", "2", "--steps", "2", "--no-fit", "--thin-budget", "0.5", "--quiet")
UNITS = "mm, cm, m, in, um"


def refused(capsys, args) -> str:
    """Run ``sieve-mi args`` with every warning recorded; assert exit code 2, one stderr line
    and no warning; return the line without its ``sieve-mi: error:`` prefix."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main([str(a) for a in args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("sieve-mi: error: "), err
    assert not caught, [str(w.message) for w in caught]
    return err.strip().removeprefix("sieve-mi: error: ")


def plate(hole: float = 22.0, thickness: float = 2.0) -> trimesh.Trimesh:
    """A 60 x 60 mm plate of ``thickness`` with a round hole of diameter ``hole`` along z."""
    slab = manifold3d.Manifold.cube([60.0, 60.0, thickness], center=True)
    cut = manifold3d.Manifold.cylinder(4 * thickness, hole / 2, hole / 2, 64, center=True)
    return from_manifold(slab - cut)


@pytest.fixture
def files(tmp_path):
    """``plate.stl`` (22 mm hole, 2 mm thick) and ``ball.stl`` (20 mm) in tmp_path."""
    plate().export(str(tmp_path / "plate.stl"))
    trimesh.creation.icosphere(2, 10.0).export(str(tmp_path / "ball.stl"))
    return tmp_path


@pytest.fixture
def no_search(monkeypatch):
    """Make any search (check's attempt, shake's trials) fail the test: refusals come first."""

    def fail(*args, **kwargs):
        raise AssertionError("the work started")

    for target in (
        "sieve_mi.game.check.attempt",
        "sieve_mi.shake.run.run_trials",
        "sieve_mi.shake.run.measure_sink",
    ):
        monkeypatch.setattr(target, fail)


# --- shake DIR: report.json read with every field it uses checked; a missing shape file --------


def solve_folder(tmp_path) -> str:
    """A folder as solve writes it: marker, report.json, sieve.stl, pass_0.stl, block_0.stl."""
    folder = tmp_path / "out"
    folder.mkdir()
    plate().export(str(folder / "sieve.stl"))
    trimesh.creation.box((8.0, 8.0, 8.0)).export(str(folder / "pass_0.stl"))
    trimesh.creation.box((30.0, 30.0, 30.0)).export(str(folder / "block_0.stl"))
    report = {"pass": [{"name": "small"}], "block": [{"name": "big"}], "units": "mm"}
    (folder / "report.json").write_text(json.dumps(report))
    names = ["block_0.stl", "pass_0.stl", "report.json", "sieve.stl"]
    marker = {"sieve_mi": "0", "command": "solve", "files": names, "folders": []}
    (folder / ".sieve-mi").write_text(json.dumps(marker))
    return str(folder)


REPORTS = [
    # (report.json's text, how the line goes on after "<DIR>/report.json: ")
    ("[" * 100_000, "(top level) (line 1): arrays or objects nested too deeply"),
    ('{"pass": [], "settings": [1]}', "settings: expected an object (the solve's settings), got [1]"),
    ('{"pass": [{"name": "small"}], "units": "parsec"}', f'units: "parsec" is not one of: {UNITS}'),
    ('{"pass": [{"name": "small"}], "settings": {"units": null}}', f"settings.units: null is not one of: {UNITS}"),
    ('{"pass": {"name": "small"}}', "is not a solve's report (no 'pass' list)"),
    ('{"pass": [], "block": 5}', "block: expected a list of shapes, got 5"),
    ('{"pass": [1]}', "pass[0]: expected an object (a shape's entry), got 1"),
    ('{"pass": [{"name": null}]}', "pass[0].name: expected a non-empty string, got null"),
    ('{"pass": [], "block": []}', "lists no shape (pass or block) to shake"),
    ("[]", "expected a solve's report (a JSON object), got []"),
    ('{"pass": [], "pass": []}', "pass: given twice in one object; keep one"),
    ('{"pass": [', "not valid JSON"),
]  # fmt: skip


@pytest.mark.parametrize("text, words", REPORTS, ids=range(len(REPORTS)))
def test_shake_dir_checks_every_field_of_report_json(tmp_path, capsys, no_search, text, words):
    # Were a RecursionError (deep nesting) and an AttributeError ("settings": [1]) traceback;
    # a units or name of the wrong type was taken as it came.
    folder = solve_folder(tmp_path)
    with open(os.path.join(folder, "report.json"), "w", encoding="utf-8") as fh:
        fh.write(text)
    before = tree(tmp_path)
    line = refused(capsys, ["shake", folder, *SHAKE_QUICK])
    assert line.startswith(f"{os.path.join(folder, 'report.json')}: {words}"), line
    assert tree(tmp_path) == before


def test_shake_dir_refuses_a_shape_whose_file_is_gone(tmp_path, capsys, no_search):
    # Was: the shape silently left out, exit 0.
    folder = solve_folder(tmp_path)
    os.remove(os.path.join(folder, "block_0.stl"))
    before = tree(tmp_path)
    line = refused(capsys, ["shake", folder, *SHAKE_QUICK])
    assert line == (
        f"{folder}: has no block_0.stl (the shape 'big' of report.json); restore it, or shake "
        "the others with --only small"
    )
    assert tree(tmp_path) == before
    # The others are still there to shake: --only picks them, the missing one is not needed.
    inp = from_folder(folder, ["small"])
    assert [(name, role) for name, role, _, _ in inp.parts] == [("small", "A")]


# --- --workers bounded as --threads is; unknown units refused where --units exists ---------------


def test_shake_workers_are_bounded_by_the_cores(files, capsys, no_search):
    # Was: up to 1024 worker processes whatever the machine (about 77 MB each).
    top = max_threads()
    before = tree(files)
    line = refused(capsys, ["shake", "--sieve", files / "plate.stl", files / "ball.stl",
                            *SHAKE_QUICK, "--workers", top + 1])  # fmt: skip
    cores = os.cpu_count() or 1
    assert line == (
        f"shake: --workers {top + 1}: must be a whole number from 0 to {top} (0: every core; "
        f"four per core on this machine's {cores} cores)"
    )
    with pytest.raises(sm.SieveError, match=rf"^shake: workers {top + 1}: must be a whole"):
        ShakeSettings(workers=top + 1)
    assert ShakeSettings(workers=top).workers == top
    assert tree(files) == before


@pytest.mark.parametrize("source", ["--sieve", "--hole"])
def test_check_refuses_unknown_units(files, capsys, no_search, source):
    # Was: with --hole "the image records no pixel size", with --sieve accepted silently.
    from PIL import Image

    Image.new("L", (40, 40), 255).save(files / "hole.png", dpi=(254, 254))
    given = files / ("plate.stl" if source == "--sieve" else "hole.png")
    before = tree(files)
    line = refused(capsys, ["check", files / "ball.stl", source, given, "--units", "parsec"])
    assert line == f"check: --units: 'parsec' is not one of: {UNITS}"
    with pytest.raises(sm.SieveError, match=rf"^check: units: 'parsec' is not one of: {UNITS}$"):
        sm.check(str(files / "ball.stl"), sieve=str(files / "plate.stl"), units="parsec")
    assert tree(files) == before


def test_shake_refuses_unknown_units_before_reading_a_mesh(tmp_path, capsys, no_search):
    line = refused(capsys, ["shake", "--sieve", tmp_path / "no-plate.stl", tmp_path / "no.stl",
                            "--units", "parsec", *SHAKE_QUICK])  # fmt: skip
    assert line == f"shake: unknown units 'parsec'; use one of {UNITS}"


# --- check: a part too large for the raster, a decompression-bomb image --------------------------


def test_check_refuses_a_part_too_large_for_the_raster(files, capsys, no_search):
    # Was: numpy's _ArrayMemoryError (2 TiB) after the plate was read.
    trimesh.creation.icosphere(1, 1e9).export(str(files / "huge.stl"))
    before = tree(files)
    line = refused(capsys, ["check", files / "huge.stl", "--sieve", files / "plate.stl"])
    assert line.startswith(f"{files / 'huge.stl'}: the part is 2e+09 mm across, ")
    assert "raster (0.1" in line and f"check takes at most {EDGE_SAMPLES_MAX:,}; " in line
    assert tree(files) == before


def test_the_part_bound_is_on_the_samples_along_its_edges():
    ball = shape_from_trimesh(trimesh.creation.icosphere(1, 10.0), name="ball")
    pixel = edge_length(ball) / EDGE_SAMPLES_MAX  # exactly the bound: accepted
    check_part_size(ball, pixel, "plate.stl")
    with pytest.raises(sm.SieveError, match=r"^ball: the part is 20 mm across, .* samples, "):
        check_part_size(ball, pixel * 0.99, "plate.stl")
    # A metre-long part against a 22 mm hole at the default resolution (256) is far inside it.
    rod = shape_from_trimesh(trimesh.creation.box((1000.0, 20.0, 20.0)), name="rod")
    check_part_size(rod, 22.0 / 256, "plate.stl")


def png_header(width: int, height: int) -> bytes:
    """A PNG of ``width`` x ``height`` 1-bit pixels that stops after its header: what a reader
    sees before it decodes anything (a decompression bomb's 48 KB hold the rest)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


def exr_header(width: int, height: int) -> bytes:
    """An OpenEXR file's header of ``width`` x ``height`` pixels (its ``dataWindow``), no more."""
    window = b"dataWindow\0box2i\0" + struct.pack("<i4i", 16, 0, 0, width - 1, height - 1)
    return b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + window + b"\0"


IMAGES = [  # (file, its bytes, its size): Pillow refuses the first, warns in two lines on the next
    ("bomb.png", png_header(20_000, 20_000), (20_000, 20_000)),
    ("big.png", png_header(13_000, 13_000), (13_000, 13_000)),
    ("bomb.exr", exr_header(20_000, 15_000), (20_000, 15_000)),
]


@pytest.mark.parametrize("name, data, size", IMAGES, ids=[i[0] for i in IMAGES])
@pytest.mark.parametrize("pixel_size", [("--pixel-size", "0.05"), ()], ids=["given", "read"])
def test_check_refuses_an_image_of_too_many_pixels(files, capsys, no_search, name, data, size,
                                                   pixel_size):  # fmt: skip
    # Was: PIL's DecompressionBombError traceback; a 13000 x 13000 image passed with Pillow's
    # two-line warning.
    (files / name).write_bytes(data)
    before = tree(files)
    line = refused(capsys, ["check", files / "ball.stl", "--hole", files / name, *pixel_size])
    dims = f" ({size[0]} x {size[1]})" if name.endswith(".exr") else ""
    assert line == (
        f"{files / name}: the image has {size[0] * size[1]:,} pixels{dims}; hole images may "
        f"have at most {IMAGE_PIXELS_MAX:,} (Pillow's bound against decompression bombs): crop "
        "it to the holes or scale it down (and its pixel size up)"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(sm.SieveError, match=rf"{name}: the image has "):
            sm.check(str(files / "ball.stl"), image=str(files / name), pixel_size=0.05)
    assert not caught
    assert tree(files) == before


# --- the API's check -------------------------------------------------------------------------


@pytest.mark.parametrize("part", [[1, 2, 3], {"mesh": "ball.stl"}, 1.5, trimesh.Scene()])
def test_api_check_refuses_what_is_no_mesh_in_one_line(part):
    # Was: AttributeError 'list' object has no attribute 'vertices'.
    with pytest.raises(sm.SieveError) as e:
        sm.check(part, sieve="plate.stl")
    assert str(e.value).startswith(
        "check: expected a mesh file path, a trimesh.Trimesh or a Shape, got "
    ) and "\n" not in str(e.value)


def test_api_check_selects_the_variant_itself_in_a_fresh_process(tmp_path):
    # Was: Mitsuba's AttributeError "Cannot access 'Mesh' before setting a variant" unless a
    # solve had run first in the process (docs/api.md's example).
    plate(22.0, 25.0).export(str(tmp_path / "plate.stl"))
    trimesh.creation.icosphere(2, 10.0).export(str(tmp_path / "ball.stl"))
    code = (
        "import sieve_mi as sm\n"
        "from sieve_mi.game.check import CheckSettings\n"
        "s = CheckSettings(starts=2, steps=2, fit=False, thin_budget=0.5)\n"
        "print(sm.check('ball.stl', sieve='plate.stl', settings=s).passes)\n"
    )
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [REPO, os.environ.get("PYTHONPATH")])),
    }
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0 and run.stdout.strip() == "True", run.stderr[-2000:]


# --- a scene's rotation that overflows: the one line only ---------------------------------------


def test_an_overflowing_rotation_is_one_line_without_numpy_warnings(tmp_path, capsys):
    cube = os.path.join(REPO, "scenes", "meshes", "cube.stl")
    scene = tmp_path / "scene.toml"
    scene.write_text(
        f'[[pass]]\nmesh = "{cube}"\nrotation = [1e308, 1e308, 0, 0]\n\n'
        f'[[block]]\nmesh = "{cube}"\n'
    )
    before = tree(tmp_path)
    line = refused(capsys, ["solve", scene, "--out", tmp_path / "o"])
    assert line == (
        f"{scene}: pass[0].rotation: quaternion [1e+308, 1e+308, 0, 0] is not a unit "
        "quaternion (norm inf); divide it by its norm"
    )
    assert tree(tmp_path) == before
