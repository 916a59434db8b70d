"""MuJoCo and CoACD are an optional extra (``sieve-mi[shake]``): without them everything but the
shake trials works, and a command that shakes says so in one line before any work. The other way
round, shaking needs no Mitsuba: without it only shake.gif is not made (one line says so)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from helpers import REPO

from sieve_mi.cli import main

#: What a command that shakes prints without the extra (after ``sieve-mi: error: ``).
MISSING = "needs MuJoCo and CoACD: pip install 'sieve-mi[shake]'"

#: The modules that import MuJoCo (or CoACD) when they are imported: the engine's own.
ENGINE = {
    "sieve_mi.shake.model",
    "sieve_mi.shake.fidelity",
    "sieve_mi.shake.trials",
    "sieve_mi.shake.run",
    "sieve_mi.shake.clip",
    "sieve_mi.cascade.purity",
}


@pytest.fixture
def no_engine(monkeypatch):
    """MuJoCo and CoACD absent, as where the extra is not installed (an import of either raises
    ModuleNotFoundError naming it)."""
    monkeypatch.setitem(sys.modules, "mujoco", None)
    monkeypatch.setitem(sys.modules, "coacd", None)


@pytest.mark.parametrize(
    "command, args",
    [
        ("sieve-mi shake", ["shake", "FOLDER"]),
        ("sieve-mi shake", ["shake", "--sieve", "plate.stl", "part.stl", "--out", "OUT"]),
        (
            "sieve-mi solve --shake",
            ["solve", "SCENES/default.toml", "--shake", "2", "--out", "OUT"],
        ),
        (
            "sieve-mi sort --shake",
            ["sort", "SCENES/euro-coins.toml", "--shake", "2", "--out", "OUT"],
        ),
    ],
    ids=["shake-dir", "shake-sieve", "solve", "sort"],
)
def test_a_command_that_shakes_is_one_line_exit_2_without_the_extra(
    tmp_path, capsys, no_engine, command, args
):
    folder = tmp_path / "folder"
    folder.mkdir()
    (folder / "keep.txt").write_text("the user's")
    out = tmp_path / "out"
    fill = {"FOLDER": str(folder), "OUT": str(out)}
    argv = [fill.get(a, a.replace("SCENES", os.path.join(REPO, "scenes"))) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [f"sieve-mi: error: {command} {MISSING}"]
    assert not out.exists()  # nothing was written, nothing solved
    assert os.listdir(folder) == ["keep.txt"]


def test_the_shake_options_still_parse_and_need_only_the_engine_to_run(no_engine, capsys):
    with pytest.raises(SystemExit) as done:
        main(["shake", "--help"])
    assert done.value.code == 0 and "--trials TRIALS" in capsys.readouterr().out


def test_everything_but_the_engine_imports_without_mujoco_and_coacd():
    """In a fresh interpreter where both are absent, every module of sieve_mi but the engine's
    imports (so ``import sieve_mi``, ``solve``, ``check``, ``certify``, ``sort`` and the command
    line's parser do), and each engine module does need them (the blocking works)."""
    code = f"""
import importlib, pkgutil, sys
sys.modules["mujoco"] = sys.modules["coacd"] = None
import sieve_mi, sieve_mi.shake
engine = {sorted(ENGINE)!r}
names = [m.name for m in pkgutil.walk_packages(sieve_mi.__path__, "sieve_mi.")]
assert set(engine) <= set(names), set(engine) - set(names)
for name in names:
    if name not in engine and name != "sieve_mi.__main__":
        importlib.import_module(name)
from sieve_mi.cli import _parser
_parser()
assert sieve_mi.shake.ShakeSettings().trials == 200
for name in engine:
    try:
        importlib.import_module(name)
    except ModuleNotFoundError as exc:
        assert exc.name in ("mujoco", "coacd"), exc
    else:
        raise AssertionError(name + " imported without MuJoCo")
print(len(names))
"""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [REPO, os.environ.get("PYTHONPATH")])),
    }
    p = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert p.returncode == 0, p.stderr
    assert int(p.stdout) > 80  # every module was walked


def test_without_mitsuba_the_trials_are_written_and_one_line_says_the_clip_was_not(
    tmp_path, capsys, monkeypatch
):
    """A pack of the engine alone (``tools/gpu_shake.sh``: MuJoCo and CoACD, no Mitsuba nor
    Dr.Jit) shakes as usual: shake.json and shake.png are written, and one warning line (in the
    table and in shake.json's ``warnings``) says that shake.gif was not made, and why."""
    import json

    from shake_helpers import ball, plate_mesh, round_hole

    plate, part, out = tmp_path / "plate.stl", tmp_path / "ball.stl", tmp_path / "out"
    plate_mesh(round_hole(22.0), 8.0, 2.0).export(str(plate))
    ball(20.0).export(str(part))
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # an import of either raises ImportError
    monkeypatch.setitem(sys.modules, "drjit", None)
    args = ["shake", "--sieve", str(plate), str(part), "--out", str(out), "--trials", "1",
            "--duration", "0.1", "--workers", "1", "--quiet"]  # fmt: skip
    assert main(args) == 0
    std = capsys.readouterr()
    lines = [s for s in (std.out + std.err).splitlines() if "shake.gif" in s]
    assert len(lines) == 1 and "Traceback" not in std.err, std.err
    assert lines[0].startswith("warning: shake.gif not made: Mitsuba, which renders it, cannot be")
    assert sorted(os.listdir(out)) == [".sieve-mi", "report.json", "shake.json", "shake.png"]
    report = json.loads((out / "shake.json").read_text())
    assert "clip" not in report and report["shapes"][0]["trials"] == 1
    assert lines[0] == "warning: " + report["warnings"][-1]
