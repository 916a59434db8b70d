"""The Python API refuses bad arguments with the CLI's one-line SieveError, before any work."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from helpers import REPO

import sieve_mi as sm
from sieve_mi.cascade.commands import parse_seeds

DEFAULT = os.path.join(REPO, "scenes", "default.toml")


@pytest.fixture(scope="module")
def scene():
    return sm.load_scene(DEFAULT)


def _one_line(exc: pytest.ExceptionInfo, needle: str) -> None:
    text = str(exc.value)
    assert "\n" not in text and needle in text, text


@pytest.mark.parametrize("bad", [None, 123, b"x", ""])
def test_load_scene_and_load_shape_want_a_path(bad):
    with pytest.raises(sm.SieveError) as e:
        sm.load_scene(bad)
    _one_line(e, "load_scene: expected a file path")
    with pytest.raises(sm.SieveError) as e:
        sm.load_shape(bad)
    _one_line(e, "load_shape: expected a file path")


@pytest.mark.parametrize(
    "bad, needle",
    [(None, "expected a Scene"), ("t.toml", "sieve_mi.load_scene(path)"), (3, "expected a Scene")],
)
def test_solve_wants_a_scene(bad, needle):
    with pytest.raises(sm.SieveError) as e:
        sm.solve(bad)
    _one_line(e, needle)


@pytest.mark.parametrize("seed", [-1, "3", 1.5, True, 2**64, float("nan")])
def test_solve_refuses_bad_seeds_at_once(scene, seed):
    t0 = time.perf_counter()
    with pytest.raises(sm.SieveError) as e:
        sm.solve(scene, seed=seed, progress=False)
    _one_line(e, "seed")
    assert time.perf_counter() - t0 < 1.0  # refused before any work


@pytest.mark.parametrize("bad", [None, 123, b"x", ""])
def test_result_save_wants_a_folder_path(bad):
    with pytest.raises(sm.SieveError) as e:
        sm.Result.save(object(), bad)  # refused before the result is looked at
    _one_line(e, "Result.save: expected a file path")


@pytest.mark.parametrize(
    "args, kwargs, needle",
    [
        ((None,), {"sieve": "plate.stl"}, "check: expected a mesh"),
        (("part.stl",), {}, "give sieve=PLATE"),
        (("part.stl",), {"image": "hole.png"}, "needs pixel_size"),
    ],
)
def test_check_refuses_missing_pieces_in_words_of_the_api(args, kwargs, needle):
    with pytest.raises(sm.SieveError) as e:
        sm.check(*args, **kwargs)
    _one_line(e, needle)
    assert "--" not in str(e.value)  # not the CLI's option names


@pytest.mark.parametrize("text", ["0-1000000000", "0-100000", f"{2**64}", "5-2", "-3", "x"])
def test_sweep_seeds_are_bounded_before_any_list_is_built(text):
    t0 = time.perf_counter()
    with pytest.raises(sm.SieveError) as e:
        parse_seeds(text)
    _one_line(e, "--seeds")
    assert time.perf_counter() - t0 < 0.5


def test_seed_two_to_the_64_is_one_line_from_the_cli(tmp_path):
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "sieve_mi",
            "solve",
            DEFAULT,
            "--seed",
            str(2**64),
            "--out",
            str(tmp_path / "o"),
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "--seed" in lines[0] and "2**64" in lines[0], run.stderr
    assert not (tmp_path / "o").exists()


def test_report_settings_record_the_seed_that_ran():
    # --seed 7 (or solve(seed=7)) overrides [solver] seed: report.json's settings say 7, as its
    # provenance does, so the settings replay the run.
    from sieve_mi.outputs.report import report_dict

    rupert = os.path.join(os.path.dirname(DEFAULT), "rupert.toml")
    scene = sm.load_scene(rupert)
    assert scene.solver.seed != 7
    rep = report_dict(sm.solve(scene, seed=7, progress=False))
    assert rep["settings"]["solver"]["seed"] == 7 == rep["provenance"]["seed"]
    assert scene.solver.seed != 7  # the scene itself is not changed
