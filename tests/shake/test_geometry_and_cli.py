"""Plates recovered from meshes, parts decomposed, and the ``sieve-mi shake`` command."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from helpers import REPO
from shake_helpers import ball, plate_mesh, round_hole, square_hole

from sieve_mi.errors import SieveError
from sieve_mi.shake import decompose
from sieve_mi.shake.geometry import (
    collision_hull,
    collision_pieces,
    part_from_mesh,
    plate_from_mesh,
    plate_from_outline,
)
from sieve_mi.testing.shapes import letter


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", *args], capture_output=True, text=True, timeout=300
    )


def test_plate_from_mesh_recovers_holes_and_thickness():
    """Slicing a plate mesh at mid-thickness gives back its hole(s); z gives its thickness; the
    convex prisms tile the plate exactly (volume error ~0)."""
    plate = plate_from_mesh(plate_mesh(round_hole(22.0), 10.0, 3.0))
    assert plate.thickness == pytest.approx(3.0)
    assert plate.hole_area == pytest.approx(round_hole(22.0).area(), rel=1e-9)
    assert plate.volume_error < 1e-9
    assert np.allclose(plate.half_size, 21.0)

    def area(p):
        q = np.roll(p, -1, axis=0)
        return 0.5 * abs(float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])))

    total = sum(area(p) for p in plate.pieces)
    assert total == pytest.approx(42.0 * 42.0 - plate.hole_area, rel=1e-9)


def test_collision_pieces_merge_a_256_gon_hole_within_the_tolerance():
    """A 22 mm hole cut as a 256-gon needs one convex piece per segment (256). A chord over k
    segments of radius 11 leaves its skipped vertices at most 11 (cos(pi / 256) - cos(7 pi /
    256)) = 0.040 mm away for k = 7, and 11 (1 - cos(8 pi / 256)) = 0.053 mm for k = 8, so the
    greedy chords at 0.05 mm span 7 segments: 36 of them and one over the last 4, 37 pieces; the
    outer square kept, the hole only shrunk (chords lie inside a convex hole) and by less than its
    perimeter times the tolerance."""
    import manifold3d

    plate = plate_from_outline(manifold3d.CrossSection.circle(11.0, 256), 14.0, 2.0)
    merged = collision_pieces(plate.pieces, 0.05)
    assert len(plate.pieces) == 256 and len(merged) == 37

    def area(p):
        q = np.roll(p, -1, axis=0)
        return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]))

    pts = np.concatenate(merged)
    r = np.linalg.norm(pts, axis=1)
    inner = r[r < 12.0]
    assert len(inner) == 2 * 37 and np.allclose(inner, 11.0, atol=1e-6)  # kept corners, 2 each
    assert np.abs(pts).max() == pytest.approx(25.0)
    grown = sum(area(p) for p in merged) - sum(area(p) for p in plate.pieces)
    assert 0.0 < grown < 2 * math.pi * 11.0 * 0.05
    assert all(area(p) > 0 for p in merged)
    assert len(collision_pieces(plate.loops, 0.0)) == 256  # 0: the exact pieces
    assert len(collision_pieces(plate.loops, 0.05)) == 37  # from the face's loops alike


def test_collision_hull_keeps_every_third_vertex_of_a_coin():
    """A coin of radius 9.875 cut as a 96-gon prism: dropping the two vertices between two kept
    ones leaves them 9.875 (cos(pi / 96) - cos(3 pi / 96)) = 0.042 mm inside the chord, three
    would leave the middle one 9.875 (1 - cos(8 pi / 96)) = 0.085 mm: at 0.05 mm the engine's
    coin is a 32-gon prism (64 of 192 vertices), each dropped vertex within 0.05 mm of it."""
    coin = trimesh.creation.cylinder(radius=9.875, height=1.93, sections=96)
    full = np.asarray(coin.convex_hull.vertices)
    kept = collision_hull(full, 0.05)
    assert len(full) == 192 and len(kept) == 64
    hull = trimesh.convex.convex_hull(kept)
    p, t = np.repeat(full, len(hull.triangles), axis=0), np.tile(hull.triangles, (len(full), 1, 1))
    d = np.linalg.norm(trimesh.triangles.closest_point(t, p) - p, axis=1)
    assert d.reshape(len(full), -1).min(axis=1).max() == pytest.approx(0.0423, abs=1e-3)
    assert len(collision_hull(full, 0.0)) == 192  # 0: every vertex


def test_plate_mesh_without_a_hole_is_one_line_error():
    with pytest.raises(SieveError, match="no through-hole"):
        plate_from_mesh(trimesh.creation.box((40.0, 40.0, 2.0)))


def test_flat_part_is_one_line_error():
    flat = trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 0]], [[0, 1, 2], [1, 3, 2]])
    with pytest.raises(SieveError, match="flat"):
        part_from_mesh(flat, "sheet", None, 0.05)


def test_convex_part_goes_in_whole_and_a_letter_through_coacd(coacd_cache, monkeypatch):
    """A cube is one convex piece (Hausdorff 0); an L is decomposed by CoACD into a few pieces
    whose union is within a millimetre of it (reported with the sample spacing). The
    decomposition is kept in the cache folder under the mesh's hash: the same L again reads it
    (CoACD is not called) and gets the same bits; a damaged file is a miss."""
    cube = part_from_mesh(trimesh.creation.box((20.0, 20.0, 20.0)), "cube", "A", 0.05)
    assert cube.convex and len(cube.hulls) == 1 and cube.hausdorff == 0.0
    assert cube.volume == pytest.approx(8000.0) and cube.radius == pytest.approx(math.sqrt(300))
    ell = part_from_mesh(letter("L", height=30.0, depth=6.0), "L", "B", 0.05)
    assert not ell.convex and len(ell.hulls) >= 2
    assert ell.hausdorff < 1.0 + ell.hausdorff_resolution
    (stored,) = coacd_cache.glob("*.npz")
    import coacd

    monkeypatch.setattr(coacd, "run_coacd", lambda *a, **k: pytest.fail("not from the cache"))
    again = part_from_mesh(letter("L", height=30.0, depth=6.0), "L", "B", 0.05)
    assert all(np.array_equal(a, b) for a, b in zip(again.hulls, ell.hulls, strict=True))
    assert again.hausdorff == ell.hausdorff
    stored.write_bytes(b"damaged")
    assert decompose._load(stored) is None  # a miss: decomposed again and stored anew


def _solve_like_folder(tmp_path):
    """A folder laid out as solve writes it: marker, report.json, sieve.stl, pass_0, block_0."""
    folder = tmp_path / "out"
    folder.mkdir()
    plate_mesh(square_hole(22.0), 5.0, 2.0).export(str(folder / "sieve.stl"))
    ball(20.0).export(str(folder / "pass_0.stl"))
    ball(24.0).export(str(folder / "block_0.stl"))
    report = {"pass": [{"name": "small"}], "block": [{"name": "big"}], "units": "mm"}
    (folder / "report.json").write_text(json.dumps(report))
    files = ["block_0.stl", "pass_0.stl", "report.json", "sieve.stl"]
    marker = {"sieve_mi": "0", "command": "solve", "files": files, "folders": []}
    (folder / ".sieve-mi").write_text(json.dumps(marker))
    return folder


def test_shake_dir_writes_json_png_and_clip_and_lists_them(tmp_path, capsys):
    from sieve_mi.cli import main

    folder = _solve_like_folder(tmp_path)
    code = main(["shake", str(folder), "--trials", "3", "--duration", "0.5", "--workers", "1"])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "small" in out.out and "big" in out.out and "0.02 mm" in out.out
    report = json.loads((folder / "shake.json").read_text())
    assert [(s["name"], s["role"]) for s in report["shapes"]] == [("small", "A"), ("big", "B")]
    assert report["settings"]["trials"] == 3 and report["settings"]["seed"] == 0
    assert report["shapes"][1]["passed"] == 0 and report["fidelity_ok"]
    assert (folder / "shake.png").stat().st_size > 1000
    assert (folder / "shake.gif").read_bytes()[:6] == b"GIF89a"
    assert report["clip"]["frames"] == 2 * 16 and len(report["clip"]["trials"]) == 2
    marker = json.loads((folder / ".sieve-mi").read_text())
    assert {"shake.json", "shake.png", "shake.gif"} <= set(marker["files"])
    assert not [f for f in os.listdir(folder) if ".tmp-" in f]


def test_only_shakes_the_named_shapes(tmp_path, capsys):
    """``--only`` picks shapes by name: the folder's shake.json then lists the big ball alone
    (and it stays on top of the 22 mm hole, as a 24 mm ball must)."""
    from sieve_mi.cli import main

    folder = _solve_like_folder(tmp_path)
    quick = ("--trials", "2", "--duration", "0.3", "--workers", "1", "--no-clip", "--quiet")
    assert main(["shake", str(folder), "--only", " big ", *quick]) == 0, capsys.readouterr().err
    report = json.loads((folder / "shake.json").read_text())
    assert [(s["name"], s["role"], s["passed"]) for s in report["shapes"]] == [("big", "B", 0)]


def test_only_names_and_select():
    """Names are split at commas, kept in the input's order; a name that is no shape's is one
    SieveError line (exit code 2 on the command line) naming the shapes there are."""
    from sieve_mi.shake.inputs import ShakeInput, only_names, select

    inp = ShakeInput("p.stl", None, [("S", "A", "a", None), ("I", "A", "b", None),
                                     ("G", "A", "c", None)])  # fmt: skip
    assert only_names(None) is None and select(inp, None) is inp
    assert [p[0] for p in select(inp, only_names("G, S")).parts] == ["S", "G"]  # file order
    with pytest.raises(SieveError, match=r"^shake: --only: no shape named 'R'; the shapes are "
                                         r"S, I, G$"):  # fmt: skip
        select(inp, only_names("S,R"))
    with pytest.raises(SieveError, match=r"^shake: --only: expected shape names"):
        only_names(" , ")


def test_shake_sieve_json_same_seed_same_numbers(tmp_path):
    plate, part = tmp_path / "plate.stl", tmp_path / "ball.stl"
    plate_mesh(round_hole(22.0), 8.0, 2.0).export(str(plate))
    ball(20.0).export(str(part))
    args = (
        "shake",
        "--sieve",
        str(plate),
        str(part),
        "--trials",
        "2",
        "--duration",
        "0.3",
        "--workers",
        "1",
    )  # fmt: skip  (the same numbers whatever the workers: test_fidelity_and_stats)
    a, b = run_cli(*args, "--json", "--quiet"), run_cli(*args, "--json", "--quiet")
    assert a.returncode == 0 and b.returncode == 0, a.stderr
    ra, rb = json.loads(a.stdout), json.loads(b.stdout)
    ra.pop("timings"), rb.pop("timings")
    assert ra == rb and ra["shapes"][0]["name"] == "ball" and ra["shapes"][0]["role"] is None


@pytest.mark.parametrize(
    "args, message",
    [
        (("shake",), "one solve output folder"),
        (("shake", "/no/such/folder"), "no such folder"),
        (
            ("shake", ".", "--trials", "many"),
            "shake: --trials: expected a whole number, got 'many'",
        ),
        (("shake", ".", "--frequency", "-5"), "shake: --frequency: must be >= 0.0, got -5"),
        (("shake", ".", "--timestep", "1"), "shake: --timestep: must be <= 0.5, got 1"),
        (("shake", "--sieve", "/no/plate.stl", "/no/part.stl"), "not found"),
    ],
)
def test_bad_input_is_one_line_exit_2(args, message, capsys):
    # In this process (sieve_mi.cli.main): an exception other than the one-line error would fail
    # the test as a traceback would; test_shake_sieve_json_same_seed_same_numbers runs the
    # command end to end.
    from sieve_mi.cli import main

    assert main(list(args)) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_solve_shake_bad_value_stops_before_the_solve(tmp_path, monkeypatch, capsys):
    from sieve_mi import api
    from sieve_mi.cli import main

    monkeypatch.setattr(api, "solve", lambda *a, **k: pytest.fail("the solve started"))
    scene, out = os.path.join(REPO, "scenes", "default.toml"), tmp_path / "o"
    assert main(["solve", scene, "--out", str(out), "--shake", "lots"]) == 2
    err = capsys.readouterr().err
    assert "solve: --shake: expected a whole number, got 'lots'" in err and not out.exists()


def test_shake_settings_are_checked_as_scene_keys_are():
    """The options, the values given in code and a mixture's [shake] table are checked by one
    declaration (sieve_mi.settings.read_value), with the one-line error a bad scene key gets: it
    names the setting (as given), the bound to keep and the value."""
    import argparse
    from dataclasses import replace

    from sieve_mi.options import add_options
    from sieve_mi.settings import read_value
    from sieve_mi.shake.commands import settings_from_args, trials_option
    from sieve_mi.shake.settings import ShakeSettings

    with pytest.raises(SieveError, match=r"^shake: trials: must be >= 1, got 0$"):
        ShakeSettings(trials=0)
    with pytest.raises(SieveError, match=r"^shake: --trials: must be >= 1, got 0$"):
        settings_from_args(argparse.Namespace(trials="0"))
    with pytest.raises(SieveError, match=r"^shake: --seed: expected a whole number, got 1.5$"):
        settings_from_args(argparse.Namespace(seed="1.5"))
    with pytest.raises(SieveError, match=r"^shake: duration: expected a number, got 'long'$"):
        ShakeSettings(duration="long")
    with pytest.raises(SieveError, match=r"^sort: --shake: must be >= 1, got -3$"):
        trials_option("-3", "sort")
    # The rotary part of a throw-action shaker has no published size: off unless set.
    assert ShakeSettings().twist == 0.0 and ShakeSettings(twist=0.5).twist == 0.5
    with pytest.raises(SieveError, match=r"^shake: --twist: must be <= 45.0, got 90$"):
        read_value(ShakeSettings, "twist", 90, "shake", "--twist")
    given = settings_from_args(argparse.Namespace(trials="7", duration="2", coacd_threshold="0.1"))
    assert given == ShakeSettings(trials=7, duration=2.0, coacd_threshold=0.1)
    assert type(given.duration) is float and type(given.trials) is int
    assert trials_option("3", "sort", base=given) == replace(given, trials=3)
    parser = argparse.ArgumentParser()
    add_options(parser, ShakeSettings)
    text = " ".join(parser.format_help().split())
    assert "integration step (at most half the contact time constant) (number 0.01–0.5, ms" in text
    assert "--coacd-threshold COACD_THRESHOLD" in text and "(int 1–1000000, default 200)" in text


@pytest.mark.slow
def test_solve_shake_adds_shake_outputs(tmp_path, monkeypatch, capsys):
    """``solve --shake N --json`` shakes the fresh folder: shake.json, shake.png, a report.html
    card, report.json's ``shake`` entry and one line per shape (on stderr), and prints the
    folder's report.json after the trials, with that entry.
    In-process (``sieve_mi.cli.main``), with the shaking cut to 0.3 s on one worker and no
    shake.gif (the default 10 s on every core and the rendered clip, which
    test_shake_dir_writes_json_png_and_clip_and_lists_them checks, would only make the same
    files slower): N trials reach shake.json."""
    from dataclasses import replace

    from sieve_mi.cli import main
    from sieve_mi.shake import commands
    from sieve_mi.testing.settings import TINY

    shaken = []
    real = commands.shake_folder

    def shorter(folder, settings, **kw):
        shaken.append(settings)
        return real(folder, replace(settings, duration=0.3, workers=1), **{**kw, "clip": False})

    monkeypatch.setattr(commands, "shake_folder", shorter)
    mesh = os.path.join(REPO, "scenes", "meshes")
    scene = tmp_path / "s.toml"
    scene.write_text(
        f'name = "t"\n[[pass]]\nmesh = "{mesh}/cube.stl"\n[[block]]\nmesh = "{mesh}/sphere.stl"\n'
        + TINY
    )
    out = tmp_path / "out"
    argv = ["solve", str(scene), "--out", str(out), "--quiet", "--no-figure", "--no-animation"]
    assert main([*argv, "--shake", "2", "--json"]) == 0, capsys.readouterr().err
    assert [s.trials for s in shaken] == [2]  # --shake N: N trials, the rest the defaults
    report = json.loads((out / "shake.json").read_text())
    assert [s["role"] for s in report["shapes"]] == ["A", "B"] and report["settings"]["trials"] == 2
    assert 'id="shake"' in (out / "report.html").read_text()
    assert "shake.json" in json.loads((out / ".sieve-mi").read_text())["files"]
    captured = capsys.readouterr()
    printed = captured.err  # --json: the table and the lines on stderr, report.json on stdout
    assert "fidelity: resting sink under" in printed  # the shake table printed
    entry = json.loads((out / "report.json").read_text())["shake"]  # and report.json's entry
    assert json.loads(captured.out)["shake"] == entry  # the report after the trials is printed
    a, b = entry["shapes"]
    assert (a["role"], a["trials"], b["role"], b["trials"], entry["duration_s"]) == (
        "A", 2, "B", 2, 0.3)  # fmt: skip
    assert "proof" in b and "proof" not in a and b["passed"] == 0  # the sphere never passes
    assert f"shake: {b['name']} (B): 0 of 2 passed" in printed  # one line per shape


def test_solve_shaken_honours_the_scenes_shake_table(tmp_path, monkeypatch):
    """In Python, ``sieve_mi.shake.solve_shaken`` solves, saves and runs the scene's ``[shake]``
    trials as ``sieve-mi solve`` does (``sieve_mi.solve`` plays the game alone): the returned
    report.json has the ``shake`` entry with the table's trials and duration, and the 24 mm
    sphere never passes (shaking cut to one worker and no clip, as above)."""
    from dataclasses import replace

    import sieve_mi as sm
    from sieve_mi.shake import commands, solve_shaken
    from sieve_mi.testing.settings import TINY

    real = commands.shake_folder
    monkeypatch.setattr(commands, "shake_folder", lambda folder, settings, **kw: real(
        folder, replace(settings, workers=1), **{**kw, "clip": False}))  # fmt: skip
    mesh = os.path.join(REPO, "scenes", "meshes")
    path = tmp_path / "s.toml"
    path.write_text(
        f'name = "t"\n[[pass]]\nmesh = "{mesh}/cube.stl"\n[[block]]\nmesh = "{mesh}/sphere.stl"\n'
        + TINY
        + "\n[shake]\ntrials = 2\nduration = 0.3\n"
    )
    report = solve_shaken(sm.load_scene(str(path)), str(tmp_path / "out"), progress=False,
                          figure=False, animation=False)  # fmt: skip
    entry = report["shake"]
    assert (entry["trials"], entry["duration_s"]) == (2, 0.3)
    assert [(s["role"], s["trials"]) for s in entry["shapes"]] == [("A", 2), ("B", 2)]
    assert entry["shapes"][1]["passed"] == 0
    assert json.loads((tmp_path / "out" / "report.json").read_text())["shake"] == entry


def test_the_letters_g_decomposes_within_a_millimetre():
    """The G of scenes/letters.toml: CoACD cut in the part's principal frame (pca) keeps every
    piece out of the G's opening, so the pieces' union is within 1 mm of the letter (sampled,
    give or take the sample spacing). Without it a piece bridged the opening (3.3 mm) and the G
    in the engine was fatter than the real one, which can only lower its pass fraction."""
    g = trimesh.load(os.path.join(REPO, "scenes", "meshes", "letter_G.stl"))
    part = part_from_mesh(g, "G", "A", 0.05)
    assert not part.convex and 2 <= len(part.hulls) <= 20
    assert part.hausdorff < 1.0 + part.hausdorff_resolution
