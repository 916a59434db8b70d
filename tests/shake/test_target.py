"""A pass-rate target (``[shake] target``): the scene's keys, and the loop's decisions on stubbed
trial outcomes (no MuJoCo, no solve)."""

from __future__ import annotations

import pytest

from sieve_mi.errors import SieveError
from sieve_mi.scene import load_scene
from sieve_mi.shake import commands, target
from sieve_mi.shake.outputs import report_entry, shape_lines, target_card
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.target import best_try, next_step, sheet_turns, try_row
from sieve_mi.shaker import Shake

SCENE = '[[pass]]\nmesh = "a.stl"\n[[block]]\nmesh = "b.stl"\n'


def _scene(tmp_path, shake: str = ""):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE + (f"[shake]\n{shake}\n" if shake else ""))
    return load_scene(str(path))


@pytest.mark.parametrize(
    "key, expected",
    [
        ("target = 1.5", "shake.target: must be <= 1, got 1.5"),
        ("target = 0", "shake.target: must be > 0, got 0"),
        ("trials = 0", "shake.trials: must be >= 1, got 0"),
        ('duration = "long"', "shake.duration: expected a number, got 'long'"),
        (
            "amplitude = 2",
            "shake.amplitude: unknown key; known keys here: duration, seed, target, trials",
        ),  # fmt: skip
    ],
)
def test_a_bad_shake_key_is_one_line_naming_it(tmp_path, key, expected):
    with pytest.raises(SieveError) as e:
        _scene(tmp_path, key)
    assert str(e.value) == f"{tmp_path / 'scene.toml'}: {expected}"


def test_the_shake_table_is_read_and_recorded_only_when_given(tmp_path):
    s = _scene(tmp_path, "target = 0.9\nduration = 10\nseed = 3")
    assert s.shake == Shake(trials=None, duration=10.0, seed=3, target=0.9)
    assert s.settings()["shake"] == {"trials": None, "duration": 10.0, "seed": 3, "target": 0.9}
    assert "shake" not in _scene(tmp_path).settings()  # the bundled scenes' report.json as before


def test_solve_takes_its_trials_from_the_scene_or_shake_n(tmp_path, monkeypatch):
    monkeypatch.setattr(commands, "need_engine", lambda command: None)
    target = _scene(tmp_path, "target = 0.9\nduration = 4\nseed = 7")
    got = commands.solve_shake_settings(None, target)
    assert (got.trials, got.duration, got.seed) == (200, 4.0, 7)  # a target alone: 200 trials
    assert commands.solve_shake_settings("12", target).trials == 12
    assert commands.solve_shake_settings(None, _scene(tmp_path, "duration = 4")) is None
    assert commands.solve_shake_settings(None, _scene(tmp_path)) is None
    assert commands.solve_shake_settings("5", _scene(tmp_path)) == ShakeSettings(trials=5)


def _try(step: str, *passed: int, trials: int = 20, blocked: bool = True, margin=0.5) -> dict:
    """A stubbed try: each A's pass count of ``trials``."""
    a = [{"name": f"a{i}", "passed": p, "trials": trials, "fraction": p / trials,
          "ci95": [0.0, 1.0], "median_time_s": None} for i, p in enumerate(passed)]  # fmt: skip
    return {"step": step, "blocked": blocked, "pass": a, "b_margin": margin,
            "window_deg": 0.0, "holes": 1, "b_proved": True}  # fmt: skip


def test_the_loop_grows_then_widens_then_adds_copies_then_mirrors_them_then_stops():
    tries = [_try("solved", 20, 10)]  # the second A is under 90 %
    assert next_step(tries, 0.9) == "tolerance"
    assert next_step(tries, 0.9, skip=("tolerance",)) == "window"  # no wider tolerance holds
    tries.append(_try("tolerance", 20, 12))
    assert next_step(tries, 0.9) == "window"
    tries.append(_try("window", 20, 15))
    assert next_step(tries, 0.9) == "sheet"
    tries.append(_try("sheet", 20, 17))
    assert next_step(tries, 0.9) == "mirror"
    assert next_step(tries, 0.9, skip=("mirror",)) == "stop"  # the scene's sheet mirrors already
    tries.append(_try("mirror", 20, 16))
    assert next_step(tries, 0.9) == "stop"
    assert best_try(tries) == 3  # the least A pass fraction is highest there


def test_the_mirror_step_lays_the_sheet_with_mirrored_copies(tmp_path):
    scene = _scene(tmp_path, "target = 0.9")
    sheet = target._scene_for(scene, "sheet", [[1.0, 0.0, 0.0, 0.0]], 30.0).fabrication
    mirror = target._scene_for(scene, "mirror", [[1.0, 0.0, 0.0, 0.0]], 30.0).fabrication
    assert (sheet.pattern, sheet.mirror, mirror.pattern, mirror.mirror) == (
        "hex",
        False,
        "hex",
        True,
    )
    assert mirror.turns == sheet.turns == sheet_turns(30.0) and mirror.window == 30.0
    assert scene.fabrication.mirror is False  # the scene itself is left as it was
    grown = target._scene_for(scene, "tolerance", [[1.0, 0.0, 0.0, 0.0]], 5.0, 2.125)
    assert (grown.fabrication.tolerance, grown.fabrication.window) == (2.125, 5.0)
    assert grown.fabrication.pattern == "single" and grown.passes[0].rotation == [1, 0, 0, 0]
    assert scene.fabrication.tolerance == 1.0
    # separate holes: each A's own tolerance (the scene's [fabrication] tolerance kept)
    own = target._scene_for(scene, "tolerance", [[1.0, 0.0, 0.0, 0.0]], 5.0, [3.25])
    assert (own.passes[0].tolerance, own.fabrication.tolerance) == (3.25, 1.0)
    assert scene.passes[0].tolerance is None


def test_the_loop_stops_at_the_target_and_skips_a_window_already_auto():
    assert next_step([_try("solved", 18)], 0.9) == "met"  # 18 of 20 is 90 %
    assert next_step([_try("solved", 17)], 0.9) == "tolerance"
    assert next_step([_try("solved", 17)], 0.9, skip=("tolerance", "window")) == "sheet"
    assert next_step([_try("solved", 17), _try("window", 19)], 0.9) == "met"


def test_a_try_that_lets_b_through_never_meets_the_target_nor_is_chosen():
    assert next_step([_try("solved", 20, blocked=False)], 0.9) == "stop"  # B wins from the start
    tries = [_try("solved", 5), _try("window", 9), _try("sheet", 20, blocked=False)]
    assert next_step(tries, 0.9, skip=("tolerance",)) == "stop"
    assert best_try(tries) == 1
    # equal pass rates: the wider B margin is the better trade-off
    assert best_try([_try("solved", 9, margin=0.8), _try("window", 9, margin=0.2)]) == 0


@pytest.mark.parametrize(
    "degrees, turns",
    [
        (90.0, (0.0, 180.0)),
        (30.0, tuple(60.0 * i for i in range(6))),
        (180.0, None),
        (0.0, tuple(15.0 * i for i in range(24))),
    ],  # fmt: skip
)
def test_a_sheet_turns_its_copies_so_every_turn_is_within_the_window_of_one(degrees, turns):
    assert sheet_turns(degrees) == turns


def _report(certified: str | None = "proved") -> dict:
    block = {"name": "b", "margin": {"found_at_most": 0.75, "proved_at_least": None}}
    if certified:
        block["certified"] = certified
    return {"winner": "A", "pass": [{"name": "a"}], "block": [block],
            "fabrication": {"window": {"degrees": 21.1},
                            "pattern": {"count": 16, "turns": [0.0, 180.0], "open_fraction": 0.5,
                                        "plate_size": [104.8, 104.8]},
                            "plate_size": [30.0, 30.0, 2.0]}}  # fmt: skip


def _shape(name: str, role: str, passed: int, trials: int = 200, median=None) -> dict:
    return {"name": name, "role": role, "trials": trials, "passed": passed,
            "fraction": passed / trials, "ci95": [0.845, 0.930] if passed else [0.0, 0.0188],
            "median_time_s": median}  # fmt: skip


def _run(*shapes) -> dict:
    return {"shapes": list(shapes), "fidelity_ok": True,
            "settings": {"trials": 200, "duration": 10.0, "seed": 0}}  # fmt: skip


def test_a_try_row_holds_the_pass_counts_and_b_margin():
    row = try_row("sheet", _report(), _run(_shape("a", "A", 179, median=1.234)))
    assert row["pass"] == [{"name": "a", "passed": 179, "trials": 200, "fraction": 0.895,
                            "ci95": [0.845, 0.930], "median_time_s": 1.234}]  # fmt: skip
    assert (row["window_deg"], row["holes"], row["turns"]) == (21.1, 16, [0.0, 180.0])
    assert row["plate_size"] == [104.8, 104.8]  # the sheet's, not the one hole's plate
    one = _report()
    del one["fabrication"]["pattern"]
    assert try_row("solved", one, _run(_shape("a", "A", 1)))["plate_size"] == [30.0, 30.0]
    assert (row["blocked"], row["b_margin"], row["b_margin_proved"], row["b_proved"]) == (
        True, 0.75, None, True)  # fmt: skip


def test_the_b_margin_is_the_least_overhang_found_not_the_verdict_poses_protrusion():
    """The letters at tolerance 0.5 mm (docs/shake.md): the verdict keeps the P's pose of least
    area outside H, which sticks out 3.33 mm; lying on its side over the I's hole the P sticks
    out 1.63 mm, the R at best 2.93 mm: the margin the tolerance can spend is 1.63 mm."""
    report = _report()
    report["settings"] = {"fabrication": {"tolerance": 0.5}}
    report["block"] = [
        {"name": name, "margin": {"found_at_most": found, "proved_at_least": 0.0},
         "overhang": {"at_best_pose": over, "proved_at_least": 0.0}, "certified": "proved"}
        for name, found, over in (("R", 2.93, 2.93), ("P", 3.33, 1.63))
    ]  # fmt: skip
    row = try_row("solved", report, _run(_shape("a", "A", 1)))
    assert (row["b_margin"], row["b_margin_proved"], row["tolerance"]) == (1.63, 0.0, 0.5)


def test_each_shape_is_one_line_a_b_with_its_proof():
    run = _run(_shape("a", "A", 179, median=1.234))
    entry = report_entry(run, _report())  # b proved: not shaken
    assert [s["evidence"] for s in entry["shapes"]] == ["trials", "proof"]
    assert shape_lines(entry) == [
        "shake: a (A): 179 of 200 passed (89.5 %, 95 % interval 84.5–93.0 %), median 1.23 s "
        "to pass",
        "shake: b (B): 0 passed: proved blocked (certify), not shaken",
    ]
    entry = report_entry(_run(*run["shapes"], _shape("b", "B", 0)), _report("undecided"))
    assert shape_lines(entry)[1] == (
        "shake: b (B): 0 of 200 passed (0.0 %, 95 % interval 0.0–1.9 %); certify: undecided"
    )


def test_the_target_card_lists_every_try():
    tries = [try_row("solved", _report(), _run(_shape("a", "A", 150))),
             try_row("window", _report(), _run(_shape("a", "A", 179)))]  # fmt: skip
    card = target_card({"fraction": 0.9, "met": False, "chosen": 1, "tries": tries}, "mm")
    assert card.count("<tr><td>") == 2 and "1 (in this folder)" in card
    assert "not met: the best trade-off is kept" in card and "data:image/png;base64," in card
    mirrored = dict(tries[1], step="mirror", holes=16, mirror=True)
    card = target_card({"fraction": 0.9, "met": False, "chosen": 0, "tries": [mirrored]}, "mm")
    held = ("<td>mirror</td><td>-</td><td>±21.1°</td><td>16, every other class mirrored on 104.8 "
            "x 104.8</td>")  # fmt: skip
    assert held in card


def test_the_trade_off_plots_labels_of_nearly_equal_tries_do_not_overlap():
    """The letters' loop (docs/shake.md): a window, its sheet and its mirrored sheet at margins
    1.57, 1.55 and 1.55 mm, all at 0 of 20, beside a try at 2.93 mm: four labels, no two boxes
    overlapping, none cut off at the figure's edge, each moved label joined to its point."""
    from matplotlib.text import Text

    from sieve_mi.shake.outputs import tradeoff_figure

    tries = [_try(step, 0, margin=m) for step, m in
             (("solved", 2.93), ("window", 1.57), ("sheet", 1.55), ("mirror", 1.55))]  # fmt: skip
    fig = tradeoff_figure(tries, 0.5, "mm")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = [t for t in fig.axes[0].texts if t.get_text()[:1].isdigit()]
    assert sorted(t.get_text() for t in labels) == ["0: solved", "1: window", "2: sheet",
                                                    "3: mirror"]  # fmt: skip
    boxes = [Text.get_window_extent(t, renderer) for t in labels]
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :])
    assert all(fig.bbox.x0 <= b.x0 and b.x1 <= fig.bbox.x1 for b in boxes)  # none cut off
    moved = [t for t in labels if t.arrow_patch is not None]
    assert len(moved) == 2 and all(abs(t.xyann[1]) > 4 for t in moved)


def test_the_nut_scene_holds_the_m5_in_a_hole_turned_any_way():
    """scenes/nuts-shaken.toml (issue 43): an M4 nut lying flat, corners 4.04 mm from its axis,
    in a hole grown by the 0.3 mm tolerance and turned every way (a window of ±90°) makes a disc
    of 4.34 mm; the M5 needs 4.62 mm lying flat (its corners) and 4.64 mm on its side (half the
    diagonal of 8 × 4.7 mm), so even the widest window holds it: the target loop may widen it."""
    import os

    import numpy as np
    import trimesh
    from helpers import REPO

    scene = load_scene(os.path.join(REPO, "scenes", "nuts-shaken.toml"))
    assert (scene.shake.target, scene.shake.trials, scene.fabrication.tolerance) == (0.9, 200, 0.3)
    mesh = os.path.join(REPO, "scenes", "meshes")
    m4, m5 = (trimesh.load(os.path.join(mesh, f"nut_{n}.stl")) for n in ("m4", "m5"))
    disc = np.linalg.norm(m4.vertices[:, :2], axis=1).max() + scene.fabrication.tolerance
    assert disc == pytest.approx(4.341, abs=1e-3)
    flat = np.linalg.norm(m5.vertices[:, :2], axis=1).max()
    side = np.hypot(m5.extents[0] / 2, m5.extents[2] / 2)  # on a flat: 8 x 4.7
    assert flat == pytest.approx(4.619, abs=1e-3) and side == pytest.approx(4.639, abs=1e-3)
    assert min(flat, side) > disc
