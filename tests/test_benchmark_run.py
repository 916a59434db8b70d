"""``benchmarks.run``'s scene files: the bundled settings, ``--quick`` and ``--set`` overrides."""

from __future__ import annotations

import os
import sys

import pytest

import sieve_mi as sm

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import run  # noqa: E402


def _scene(tmp_path, text: str):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return sm.load_scene(str(path))


def test_letters_keep_their_tolerance_and_take_overrides(tmp_path):
    text = run.scene_text(
        "letters", "clearance", False, ["solver.settle=false", 'layout.mode="separate"']
    )
    scene = _scene(tmp_path, text)
    assert scene.fabrication.tolerance == 0.5
    assert scene.solver.settle is False and scene.layout.mode == "separate"
    assert [len(scene.passes), len(scene.blocks)] == [3, 4]
    # one [solver] table, whatever is added to it (TOML forbids a table twice)
    assert text.count("[solver]") == 1


def test_quick_settings_and_a_later_override_of_them(tmp_path):
    scene = _scene(tmp_path, run.scene_text("cube-sphere", "clearance", True, ["solver.steps=7"]))
    assert (scene.solver.particles, scene.solver.starts, scene.solver.steps) == (4, 4, 7)
    assert (scene.verdict.starts, scene.verdict.steps) == (20, 100)


@pytest.mark.parametrize("bad", ["settle=false", "solver.settle", "solver.=1", ".steps=3"])
def test_a_malformed_override_is_refused_in_one_line(bad, capsys):
    assert run.main(["--only", "cube-sphere", "--set", bad]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "TABLE.KEY=VALUE" in err and bad in err
