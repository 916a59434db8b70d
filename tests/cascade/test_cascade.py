"""Sorting cascades and sweeps (sieve_mi.cascade): order, trays, inseparable pairs, Ray, resume."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from sieve_mi.cascade import games as games_mod
from sieve_mi.cascade.games import EngineSettings
from sieve_mi.cascade.mixture import load_mixture
from sieve_mi.cascade.sort import sort_mixture
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.size import inscribed_radius, passage_radius
from sieve_mi.testing.settings import CASCADE_SOLVER, TINY_LAYOUT, settings_toml

SMALL = settings_toml(
    fabrication={"tolerance": 0.5},
    solver=CASCADE_SOLVER,
    verdict={"starts": 16, "steps": 100, "resolution": 96},
    layout=TINY_LAYOUT,
)


def _mixture(tmp_path, meshes: dict, name="mix", extra="") -> str:
    os.makedirs(tmp_path / "meshes", exist_ok=True)
    text = f'name = "{name}"\n'
    for label, mesh in meshes.items():
        mesh.export(str(tmp_path / "meshes" / f"{label}.stl"))
        text += f'[[shape]]\nmesh = "meshes/{label}.stl"\n'
    path = tmp_path / f"{name}.toml"
    path.write_text(text + extra + SMALL)
    return str(path)


def _four(tmp_path) -> str:
    # Listed out of order on purpose. Passage radii: cube28 14, ball20 10, cube14 7, ball10 5.
    return _mixture(
        tmp_path,
        {
            "ball10": trimesh.creation.icosphere(3, 5.0),
            "cube28": trimesh.creation.box((28.0, 28.0, 28.0)),
            "cube14": trimesh.creation.box((14.0, 14.0, 14.0)),
            "ball20": trimesh.creation.icosphere(3, 10.0),
        },
        name="four",
    )


def test_inscribed_radius_and_passage_radius_known_answers():
    assert inscribed_radius(np.array([[0, 0], [4, 0], [4, 2], [0, 2.0]])) == pytest.approx(1.0)
    assert inscribed_radius(np.array([[0, 0], [1, 0], [2, 0.0]])) == 0.0  # a segment
    cases = [
        (trimesh.creation.box((20.0, 20.0, 20.0)), 10.0, 1e-6),  # the face-on square
        (trimesh.creation.box((30.0, 10.0, 4.0)), 2.0, 1e-6),  # half the thinnest side
        (trimesh.creation.cylinder(10.0, 1.5, sections=64), 0.75, 1e-6),  # a coin edge-on
        (trimesh.creation.icosphere(4, 10.0), 10.0, 0.02),  # a ball: its radius
    ]
    for mesh, expected, rel in cases:
        r, view = passage_radius(shape_from_trimesh(mesh, name="x"))
        assert r == pytest.approx(expected, rel=rel) and np.linalg.norm(view) == pytest.approx(1)


@pytest.fixture(scope="module")
def four_sorted(tmp_path_factory):
    """The four shapes sorted serially, the user stopping the first sort after its first game
    and sorting again (so the second sort reuses that game and plays two): the mixture's path,
    the output folder, the names of the games stored before the stop, whether the first sort
    left the output folder alone, and the resumed sort's report. One sort for the tests of the
    serial cascade and of Ray, which must give the same: under ``pytest -n`` the first worker
    to need it sorts (under a lock, in the run's shared temporary folder) and the other reads
    its record (about 26 s of sorting saved)."""
    import fcntl

    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    with open(root / "four-sorted.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        record = root / "four-sorted.json"
        if not record.exists():
            record.write_text(json.dumps(_sort_four(root / "four-sorted")))
        return tuple(json.loads(record.read_text()))


def _sort_four(tmp_path) -> list:
    """:func:`four_sorted`'s sorts, in ``tmp_path``; its record as JSON-ready lists."""
    os.makedirs(tmp_path, exist_ok=True)
    mixture = load_mixture(_four(tmp_path))
    out = str(tmp_path / "out" / "four")
    stored, original = [], games_mod.GameCache.store

    def store_then_stop(self, spec, outcome):
        original(self, spec, outcome)
        stored.append(spec.key)
        raise KeyboardInterrupt  # the user stops the sort after its first game

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(games_mod.GameCache, "store", store_then_stop)
        with pytest.raises(KeyboardInterrupt):
            sort_mixture(mixture, out, engine=EngineSettings(use_ray=False, progress=False))
        waiting = [os.path.exists(out), sorted(os.listdir(out + ".games"))]
    report = sort_mixture(
        load_mixture(mixture.path), out, engine=EngineSettings(use_ray=False, progress=False)
    )
    return [mixture.path, out, stored, waiting, report]


@pytest.mark.slow
def test_four_shapes_sort_into_four_trays_and_an_interrupted_sort_resumes(four_sorted):
    # Coarsest on top: a hole that passes the 20 mm ball and the 14 mm cube cannot pass the
    # 28 mm cube (its every projection holds a 28 mm square); a 14 mm cube's hole (+0.5 mm)
    # cannot pass a 20 mm ball; a 10 mm ball's hole cannot pass the 14 mm cube.
    path, out, stored, (out_existed, waiting), report = four_sorted
    assert not out_existed and len(stored) == 1
    assert waiting == stored  # the finished game waits
    assert report["trays"] == [["cube28"], ["ball20"], ["cube14"], ["ball10"]]
    assert report["runner"]["reused"] == 1 and report["runner"]["played"] == 2
    assert not os.path.exists(out + ".games")  # the waiting games moved into the output
    on_disk = json.loads(open(os.path.join(out, "cascade.json")).read())
    assert on_disk["trays"] == report["trays"]
    for k, s in enumerate(on_disk["sieves"]):
        assert (
            s["winner"] == "A" and s["margins"]["beta"] > 0.1 and s["holds"] == report["trays"][k]
        )
        game = json.loads(open(os.path.join(out, s["folder"], "report.json")).read())
        assert game["winner"] == "A" and [p["name"] for p in game["pass"]] == s["passes"]
    plates = trimesh.load(os.path.join(out, "cascade.stl"), force="mesh")
    assert len(plates.split(only_watertight=False)) >= 3  # three plates, stacked
    bed = trimesh.load(os.path.join(out, "cascade.3mf"))  # one named object per plate
    assert list(bed.geometry) == [
        f"sieve_{k + 1}_holds_{'+'.join(s['holds'])}" for k, s in enumerate(report["sieves"])
    ]
    # the STL stores float32 coordinates: on thin (1.2 mm) plates that is ~1e-6 of the volume
    assert sum(g.volume for g in bed.geometry.values()) == pytest.approx(plates.volume, rel=1e-5)
    assert os.path.getsize(os.path.join(out, "cascade.png")) > 10_000
    # a second sort of the same mixture plays nothing: every game is in the output
    again = sort_mixture(
        load_mixture(path), out, engine=EngineSettings(use_ray=False, progress=False)
    )
    assert again["runner"] == {**report["runner"], "played": 0, "reused": 3}
    assert again["sieves"] == report["sieves"]


@pytest.mark.slow
def test_ray_with_two_workers_gives_the_serial_cascade_and_retries_a_dead_worker(
    tmp_path, monkeypatch, four_sorted
):
    # The serial cascade is four_sorted's: its games, resumed or not, are the same games.
    pytest.importorskip("ray")
    serial = four_sorted[-1]
    flag = tmp_path / "killed-once"
    monkeypatch.setenv(games_mod.FAULT_ENV, str(flag))  # the first game's worker dies
    ray = sort_mixture(
        load_mixture(_four(tmp_path)),
        str(tmp_path / "ray"),
        engine=EngineSettings(use_ray=True, workers=2, progress=False),
    )
    assert flag.exists()  # a worker did die, and Ray played its game again
    assert ray["runner"]["mode"] == "ray" and ray["runner"]["played"] == 3
    assert ray["trays"] == serial["trays"]
    for a, b in zip(ray["sieves"], serial["sieves"]):
        assert a["margins"] == pytest.approx(b["margins"], rel=1e-6)


@pytest.mark.slow
def test_a_pair_that_no_sieve_splits_shares_a_tray_with_the_reason(tmp_path):
    # Balls of 20 and 20.2 mm with a 0.5 mm tolerance: each one's hole (its disk grown by
    # 0.5 mm) lets the other through, so no sieve can split them; the 28 mm cube is held above.
    path = _mixture(
        tmp_path,
        {
            "cube28": trimesh.creation.box((28.0, 28.0, 28.0)),
            "ball20": trimesh.creation.icosphere(3, 10.0),
            "ball20_2": trimesh.creation.icosphere(3, 10.1),
        },
        name="twins",
    )
    proc = _cli("sort", path, "--serial", "--quiet", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 3, proc.stderr  # two shapes share a tray (docs/cli.md)
    assert "trays (top to bottom): cube28 | ball20_2+ball20" in proc.stdout
    assert "cannot split ball20_2 and ball20" in proc.stdout
    report = json.loads((tmp_path / "out" / "cascade.json").read_text())
    assert report["trays"] == [["cube28"], ["ball20_2", "ball20"]]
    (pair,) = report["inseparable"]
    assert sorted(pair["pair"]) == ["ball20", "ball20_2"]
    assert "ball20 passes" in pair["reason"] and "ball20_2 passes" in pair["reason"]


@pytest.mark.slow
def test_sort_shake_reports_the_trays_each_ball_ends_in(tmp_path, monkeypatch, capsys):
    # Balls of 24, 20 and 14 mm: sieve 1's hole is about a 21 mm disc (the falling balls grown
    # by the 0.5 mm tolerance), which no pose of the 24 mm ball fits, so no trial gets it through
    # and it never reaches sieve 2; sieve 2's hole (about 15 mm) never passes the 20 mm ball, so
    # it cannot reach the bottom tray. 4 parts per shape, 1 s of shaking per sieve. The command
    # runs in this process (the test above runs sort in its own).
    from sieve_mi.cli import main

    balls = {f"ball{d}": trimesh.creation.icosphere(3, d / 2) for d in (14, 24, 20)}
    path = _mixture(tmp_path, balls, name="balls", extra="[shake]\nduration = 1.0\nworkers = 1\n")
    monkeypatch.chdir(tmp_path)
    code = main(["sort", path, "--serial", "--quiet", "--out", "out", "--shake", "4"])
    stdout, stderr = capsys.readouterr()
    assert code == 0, stderr
    report = json.loads((tmp_path / "out" / "cascade.json").read_text())
    assert report["trays"] == [["ball24"], ["ball20"], ["ball14"]]
    shake = report["shake"]
    assert shake["trials"] == 4 and shake["settings"]["duration"] == 1.0
    counts = {s["name"]: [t["count"] for t in s["trays"]] for s in shake["shapes"]}
    assert counts["ball24"] == [4, 0, 0] and counts["ball20"][2] == 0
    assert all(sum(c) == 4 for c in counts.values())
    top = shake["sieves"][0]
    assert [r["name"] for r in top["shapes"]] == ["ball24", "ball20", "ball14"]
    assert top["shapes"][0]["passed"] == 0 and top["plate"]["file"].endswith("/sieve.stl")
    assert "ball24" not in [r["name"] for r in shake["sieves"][1]["shapes"]]
    assert "shake trials: 4 parts of each shape" in stdout
    assert "ball24          * 1.000 [0.510, 1.000]" in stdout


def test_bad_shake_settings_of_sort_are_one_line_before_any_game(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    two = _mixture(
        tmp_path,
        {"a": trimesh.creation.box((1.0, 1.0, 1.0)), "b": trimesh.creation.box((2.0, 2.0, 2.0))},
        name="two",
    )
    for value, words in (("many", "expected a whole number, got 'many'"), ("0", "must be >= 1")):
        _one_error_line(
            capsys, f"sort: --shake: {words}", "sort", two, "--serial", "--shake", value
        )
    cases = [
        ("duration = 0", "shake.duration: must be >= 0.01, got 0"),
        ("timestep = 1.0", "shake.timestep: must be <= 0.5, got 1.0"),
        ("trials = 5", "shake.trials: give the number of trials as sort --shake N"),
        ("speed = 3", "shake.speed: unknown key"),
    ]
    for line, words in cases:
        bad = _mixture(
            tmp_path,
            {
                "a": trimesh.creation.box((1.0, 1.0, 1.0)),
                "b": trimesh.creation.box((2.0, 2.0, 2.0)),
            },
            name="bad",
            extra=f"[shake]\n{line}\n",
        )
        _one_error_line(capsys, words, "sort", bad, "--serial", "--shake", "2")
    assert not (tmp_path / "out").exists()


def test_sweep_keeps_the_run_with_the_largest_margin(tmp_path):
    from sieve_mi.cascade.sweep import sweep_scene
    from sieve_mi.scene import load_scene

    os.makedirs(tmp_path / "meshes")
    trimesh.creation.box((14.0, 14.0, 14.0)).export(str(tmp_path / "meshes" / "cube.stl"))
    trimesh.creation.icosphere(3, 10.0).export(str(tmp_path / "meshes" / "ball.stl"))
    (tmp_path / "pair.toml").write_text(
        '[[pass]]\nmesh = "meshes/cube.stl"\n[[block]]\nmesh = "meshes/ball.stl"\n'
        + SMALL.replace("tolerance = 0.5", "")
    )
    scene = load_scene(str(tmp_path / "pair.toml"))
    out = tmp_path / "sweep"
    report = sweep_scene(
        scene,
        str(out),
        seeds=[0, 1],
        tolerances=[0.5, 2.0],
        engine=EngineSettings(use_ray=False, progress=False),
    )
    assert len(report["runs"]) == 4 and all(r["winner"] == "A" for r in report["runs"])
    # a wider tolerance makes a wider hole: the ball sticks out less; the smaller one wins
    assert report["best"]["tolerance"] == 0.5
    assert report["best"]["beta"] == max(r["beta"] for r in report["runs"])
    best = json.loads((out / "best" / "report.json").read_text())
    kept = json.loads((out / report["best"]["folder"] / "report.json").read_text())
    assert best == kept and best["settings"]["fabrication"]["tolerance"] == 0.5


def _cli(*args, cwd):
    env = {**os.environ, "SIEVE_MI_VARIANT": "llvm_ad_mono"}
    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", *args], capture_output=True, text=True, cwd=cwd, env=env
    )


def _one_error_line(capsys, needle, *argv):
    """``sieve-mi ARGV`` (in this process: ``sieve_mi.cli.main``) exits with 2 and one stderr
    line holding ``needle``; any other exception fails the test as a traceback would."""
    from sieve_mi.cli import main

    code = main(list(argv))
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("sieve-mi: error: ") and needle in lines[0], lines[0]


def test_bad_mixtures_and_addresses_are_one_line_errors(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    one = _mixture(tmp_path, {"a": trimesh.creation.box((1.0, 1.0, 1.0))}, name="one")
    _one_error_line(capsys, "a mixture needs at least two", "sort", one)
    dup = tmp_path / "dup.toml"
    dup.write_text(
        '[[shape]]\nmesh = "meshes/a.stl"\nname = "x"\n[[shape]]\nmesh = "meshes/a.stl"\nname = "x"\n'
    )
    _one_error_line(capsys, "shape[1].name: 'x'", "sort", str(dup))
    old = tmp_path / "old.toml"
    old.write_text('[[pass]]\nmesh = "meshes/a.stl"\n[[block]]\nmesh = "meshes/a.stl"\n')
    _one_error_line(capsys, "[[shape]]", "sort", str(old))
    with socket.socket() as s:  # a port with nothing listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    two = _mixture(
        tmp_path,
        {"a": trimesh.creation.box((1.0, 1.0, 1.0)), "b": trimesh.creation.box((2.0, 2.0, 2.0))},
        name="two",
    )
    if games_mod.ray_module() is not None:
        _one_error_line(
            capsys, "nothing is listening", "sort", two, "--address", f"127.0.0.1:{port}"
        )
    _one_error_line(capsys, "--seeds 3-x", "sweep", two, "--seeds", "3-x")
    with pytest.raises(SieveError, match="expected host:port"):
        games_mod.check_address("nowhere")


def test_a_file_where_the_games_wait_is_refused_before_any_game(tmp_path, monkeypatch, capsys):
    from sieve_mi.cli import main

    two = _mixture(
        tmp_path,
        {"a": trimesh.creation.box((1.0, 1.0, 1.0)), "b": trimesh.creation.box((2.0, 2.0, 2.0))},
        name="two",
    )
    mine = tmp_path / "out.games"
    mine.write_text("my notes")

    def no_game(self, specs):
        raise AssertionError("no game may be played")

    monkeypatch.setattr(games_mod.Engine, "play", no_game)
    monkeypatch.chdir(tmp_path)
    code = main(["sort", two, "--out", str(tmp_path / "out"), "--serial"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert (
        lines[0].startswith("sieve-mi: error: ")
        and "out.games: exists and is not a folder" in lines[0]
    )
    assert mine.read_text() == "my notes" and not (tmp_path / "out").exists()


def test_progress_lines_name_what_each_game_is():
    # sort's games hold and pass shapes; sweep's games are a seed and a tolerance (no "hold -").
    from sieve_mi.cascade.games import label_text

    assert label_text({"holds": ["a"], "passes": ["b", "c"]}).split() == [
        "hold",
        "a",
        "pass",
        "b+c",
    ]
    assert label_text({"seed": 3, "tolerance": 0.5}).split() == ["seed", "3", "tolerance", "0.5"]


def test_cascade_3mf_has_one_named_object_per_plate_side_by_side(tmp_path):
    from sieve_mi.cascade.outputs import side_by_side
    from sieve_mi.outputs.fabrication import write_objects_3mf

    plates = [trimesh.creation.box((30.0, 20.0, 4.0)), trimesh.creation.cylinder(8.0, 6.0)]
    plates[1].apply_translation([0.0, 0.0, -20.0])  # stacked below the first, as in the cascade
    bed = side_by_side(plates, 5.0)
    names = ["sieve_1_holds_cube28", "sieve_2_holds_ball20"]
    for path in (tmp_path / "a.3mf", tmp_path / "b.3mf"):
        write_objects_3mf(str(path), list(zip(names, bed)))
    assert (tmp_path / "a.3mf").read_bytes() == (tmp_path / "b.3mf").read_bytes()
    scene = trimesh.load(str(tmp_path / "a.3mf"))
    assert isinstance(scene, trimesh.Scene) and list(scene.geometry) == names
    assert scene.units == "millimeter"
    boxes = [scene.geometry[n].bounds for n in names]
    assert [b[0, 2] for b in boxes] == pytest.approx([0.0, 0.0])  # both on the bed
    assert boxes[1][0, 0] == pytest.approx(boxes[0][1, 0] + 5.0)  # side by side, 5 apart
    for got, plate in zip(scene.geometry.values(), plates):
        assert got.volume == pytest.approx(plate.volume, rel=1e-6) and got.is_watertight
