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
