"""The one progress bar (sieve_mi.progress): a tqdm bar on a terminal, plain lines in a log,
nothing when quiet; and what solve, shake and sort print through it."""

from __future__ import annotations

import sys
from types import SimpleNamespace

from sieve_mi.progress import Progress


def _terminal(monkeypatch) -> None:
    """The captured stderr claims to be a terminal (called in the test: capsys swaps sys.stderr
    after the fixtures are set up)."""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)


def _stages(bar: Progress) -> None:
    bar.update(0, stage="cube: nlopt")
    for i in range(3):
        bar.update(1, best=f"{i / 10:.4f}", stage="cube: nlopt")
    bar.update(2, best="0.5", stage="merge")
    bar.write("a note")
    bar.write("only in a log", terminal=False)
    bar.close()


def test_a_log_gets_a_line_per_stage_the_notes_and_the_time(capsys):
    _stages(Progress(True, 4, "search"))
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert out == "" and "\r" not in err
    assert lines[:4] == ["search: cube: nlopt", "search: merge", "a note", "only in a log"]
    assert len(lines) == 5 and lines[4].startswith("search: done in ") and lines[4].endswith(" s")


def test_done_line_is_optional_and_quiet_is_silent(capsys):
    _stages(Progress(True, 4, "shake", done_line=False))
    assert capsys.readouterr().err.splitlines()[-1] == "only in a log"
    _stages(Progress(False, 4, "search"))
    assert capsys.readouterr() == ("", "")


def test_a_terminal_gets_the_bar_and_no_plain_lines(capsys, monkeypatch):
    _terminal(monkeypatch)
    bar = Progress(True, 2, "search", unit="trial", grow_by=3)
    _stages(bar)
    out, err = capsys.readouterr()
    assert "\r" in err and "search:" in err and "trial" in err
    assert "stage=merge" in err and "best=0.5" in err
    assert "search: cube: nlopt\n" not in err and "done in" not in err
    assert bar.bar.total == 5  # 5 steps of 2 planned: grown once by 3
    assert "a note" in out + err and "only in a log" not in out + err


def test_grow_and_describe_show_on_the_bar(capsys, monkeypatch):
    _terminal(monkeypatch)
    bar = Progress(True, 0, "games", unit="game", done_line=False)
    bar.grow(3)
    bar.describe("ball")
    bar.update(1)
    bar.close()
    err = capsys.readouterr().err
    assert "games ball:" in err and "1/3" in err


def test_shake_writes_a_line_per_shape_in_a_log(capsys, monkeypatch):
    from sieve_mi.shake import run

    monkeypatch.setattr(run, "check_plate", lambda *a, **k: None)
    monkeypatch.setattr(run, "measure_sink", lambda *a, **k: {})
    monkeypatch.setattr(run, "judge", lambda name, fidelity, outcomes: (fidelity, []))
    monkeypatch.setattr(run, "summarize", lambda o: {"passed": 3, "trials": 4, "fraction": 0.75})
    steps = []

    def trials(plate, part, settings, unit_m, step, indices=None):
        for i in range(4):
            step(i)
            steps.append(i)
        return steps

    monkeypatch.setattr(run, "run_trials", trials)
    bar = run.trial_bar(True, 4, desc="shake sieve 2")
    part = SimpleNamespace(name="ball", to_dict=dict, warnings=[])
    run.shape_entry(part, "A", None, None, None, 1e-3, bar)
    bar.close()
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("shake sieve 2: ball: 3 of 4 passed (75.0 %) in ") and line.endswith(
        " s"
    )


def test_sort_writes_a_line_per_game(tmp_path, capsys):
    from sieve_mi.cascade.games import Engine, EngineSettings

    block = [{"name": "ball", "blocked": True, "beta": 0.25, "protrusion": 1.0}]
    label = {"holds": ["cube"], "passes": ["ball"], "stage": "screen"}
    record = {"summary": {"winner": "A", "block": block, "game_s": 1.5}, "label": label}
    with Engine(str(tmp_path / "out"), EngineSettings(use_ray=False, progress=True)) as engine:
        engine.runner.on_done(record, False)
        engine.runner.on_done(record, True)
    lines = capsys.readouterr().err.splitlines()
    head = "  screen hold cube                 pass ball                         winner A  "
    assert lines == [
        head + "weakest ball beta 0.2500  1.5 s",
        head + "weakest ball beta 0.2500  reused",
    ]


def test_a_log_gets_the_share_done_and_the_time_left(capsys, monkeypatch):
    import sieve_mi.progress as progress

    now = [0.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    bar = Progress(True, 4, "verdict", every=0)  # starts at t = 0
    now[0] = 2.0
    bar.update(1)  # 1 of 4 in 2 s: 3 more steps take about 6 s
    assert bar.left() == "about 6 s left"
    now[0] = 5.0
    bar.update(3)
    assert bar.left() == ""  # all done
    bar.close()
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["verdict: 25 % (1/4 it), about 6 s left", "verdict: 100 % (4/4 it)",
                     "verdict: done in 5.0 s"]  # fmt: skip
    quiet = Progress(False, 4, "verdict", every=0)
    quiet.update(2)
    assert quiet.left() == "" and capsys.readouterr() == ("", "")


def test_a_certify_run_says_each_b_and_quiet_says_nothing(tmp_path, capsys):
    # the solve's certify stage on two blocked B: its bound first, then a line per B with the
    # share of rotations excluded (and the time left while some are still running); stdout stays
    # clean; with progress off (--quiet) nothing at all
    import numpy as np
    from helpers import REPO

    from sieve_mi.game.attack import Attack
    from sieve_mi.game.solver import _certify, load_shapes
    from sieve_mi.scene import load_scene
    from sieve_mi.testing.settings import TINY_VERDICT, settings_toml

    meshes = f"{REPO}/scenes/meshes"
    path = tmp_path / "scene.toml"
    path.write_text(
        f'name = "certify progress"\n[[pass]]\nmesh = "{meshes}/cube.stl"\n'
        f'[[block]]\nmesh = "{meshes}/sphere.stl"\n[[block]]\nmesh = "{meshes}/sphere.stl"\n'
        'scale = 1.03\nname = "big"\n' + settings_toml(verdict=TINY_VERDICT)
    )
    scene = load_scene(str(path))
    passes, blocks = load_shapes(scene)
    identity = np.array([1.0, 0.0, 0.0, 0.0])

    def certify(progress: bool) -> list:
        attack = Attack(np.ones((1, 2)), np.ones((1, 2)), np.tile(identity, (1, 2, 1)),
                        np.zeros((1, 2, 2)), fits=np.zeros((1, 2), int))  # fmt: skip
        v = SimpleNamespace(attack=attack, trans=np.zeros((1, 2)), warnings=[], outline=None)
        return _certify(scene, passes, blocks, identity[None], v, progress)

    proofs = certify(True)
    out, err = capsys.readouterr()
    assert out == "" and [c.status for c in proofs] == ["proved", "proved"]
    lines = err.splitlines()
    assert lines[0].startswith("certify: 2 B, up to 4 s each (") and "at most about" in lines[0]
    assert sorted(x.split(":")[0] for x in lines[1:]) == ["certify big", "certify sphere"]
    assert all("proved (" in x and "100.0 % of rotations excluded" in x for x in lines[1:])
    assert len(lines) == 3 and lines[1].endswith(" s left")  # one B still to come
    assert lines[2].endswith("excluded)")  # nothing left after the last
    assert certify(False) and capsys.readouterr() == ("", "")


def test_the_thin_plate_search_says_each_b_only_when_it_searches(capsys, monkeypatch):
    from sieve_mi.game import sheet
    from sieve_mi.motion import ThinPlate

    def answers(shapes, outline, thickness, **kw):
        for j, s in enumerate(shapes):
            yield j, ThinPlate(s.name, thickness, 30.0, "no passage found", seconds=2.0 + j)

    monkeypatch.setattr(sheet, "each_thin_plate", answers)
    blocks = [SimpleNamespace(name="R"), SimpleNamespace(name="A")]
    import numpy as np

    attack = SimpleNamespace(quats=np.zeros((1, 2, 4)), trans=np.zeros((1, 2, 2)))
    scene = SimpleNamespace(verdict=SimpleNamespace(thin_budget=5.0))
    searches = sheet._Searches(scene, blocks, [0, 1], None, attack, 0, [None, None], True)
    got = searches.at(2.0)
    assert [t.name for t in got] == ["R", "A"]
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith("thin plate 2: R: no passage found (2.0 s); about ")
    assert lines[1] == "thin plate 2: A: no passage found (3.0 s)"
    searches.at(2.0, search=False)  # the proved plate: every B safe at once, nothing to say
    assert capsys.readouterr() == ("", "")
    searches._replace(progress=False).at(2.0)
    assert capsys.readouterr() == ("", "")
