"""Issue 40's shake rows: nothing of the user's touched, every refusal before the trials, and a
fidelity check that covers the motion (acceleration, penetration while shaken, the engine's own
warnings).

In-process (``sieve_mi.cli.main``) with one or two short trials; a refusal must come before any
trial, which ``no_trials`` holds by making the trials fail the test.
"""

from __future__ import annotations

import json
import math
import os

import mujoco
import pytest
import trimesh
from helpers import tree
from shake_helpers import ball, plate_mesh, quick, round_hole, square_hole

from sieve_mi.cli import main
from sieve_mi.outputs.viewer import with_card
from sieve_mi.shake.fidelity import judge
from sieve_mi.shake.geometry import part_from_mesh, plate_from_outline
from sieve_mi.shake.model import build_model
from sieve_mi.shake.outputs import CARD
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.trials import Outcome, run_trial

QUICK = ("--trials", "1", "--duration", "0.1", "--workers", "1", "--no-clip", "--quiet")


def solve_folder(tmp_path, html=True, listed=()):
    """A folder as solve writes it (marker, report.json, sieve.stl, pass_0, block_0 and, with
    ``html``, report.html), its marker listing also ``listed``."""
    folder = tmp_path / "out"
    folder.mkdir()
    plate_mesh(square_hole(22.0), 5.0, 2.0).export(str(folder / "sieve.stl"))
    ball(20.0).export(str(folder / "pass_0.stl"))
    ball(24.0).export(str(folder / "block_0.stl"))
    report = {"pass": [{"name": "small"}], "block": [{"name": "big"}], "units": "mm"}
    (folder / "report.json").write_text(json.dumps(report))
    files = ["block_0.stl", "pass_0.stl", "report.json", "sieve.stl", *listed]
    if html:
        page = '<html><body>\n  <section class="card" id="details">d</section>\n</body></html>\n'
        (folder / "report.html").write_text(page)
        files.append("report.html")
    marker = {"sieve_mi": "0", "command": "solve", "files": sorted(files), "folders": []}
    (folder / ".sieve-mi").write_text(json.dumps(marker))
    return folder


@pytest.fixture
def no_trials(monkeypatch):
    """Make any trial (or fidelity drop) fail the test: a refusal must come before them."""

    def fail(*args, **kwargs):
        raise AssertionError("the trials started")

    monkeypatch.setattr("sieve_mi.shake.run.run_trials", fail)
    monkeypatch.setattr("sieve_mi.shake.run.measure_sink", fail)


def refused(capsys, args) -> str:
    """Run ``sieve-mi args``; assert exit code 2 and one stderr line; return that line."""
    assert main([str(a) for a in args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sieve-mi: error: "), err
    return err.strip()


# ------------------------------------------------------------------------------------------------
# Rows 2 and 18d: shake DIR writes only through the marker-checked path, and refuses first
# ------------------------------------------------------------------------------------------------


def _own_outputs(folder):
    (folder / "shake.json").write_text('{"mine": 1}\n')
    (folder / "shake.png").write_bytes(b"my picture")


def _own_notes(folder):
    (folder / "notes.txt").write_text("my notes\n")


def _own_folder(folder):
    (folder / "shake.gif").mkdir()
    (folder / "shake.gif" / "keep.txt").write_text("mine\n")


def _no_marker(folder):
    (folder / ".sieve-mi").unlink()


def _bad_marker(folder):
    (folder / ".sieve-mi").write_text("not json")


@pytest.mark.parametrize(
    "spoil, message",
    [
        (_own_outputs, r"holds shake\.json \(and 1 more\), which its \.sieve-mi marker does not"),
        (_own_notes, r"holds notes\.txt, which its \.sieve-mi marker does not list"),
        (_own_folder, r"holds shake\.gif \(and 1 more\), which its \.sieve-mi marker"),
        (_no_marker, r"has no readable \.sieve-mi marker, so sieve-mi did not write it; use "),
        (_bad_marker, r"has no readable \.sieve-mi marker"),
    ],
)
def test_a_folder_with_files_its_marker_does_not_list_is_refused_before_the_trials(
    tmp_path, capsys, no_trials, spoil, message
):
    """Row 2: the user's own shake.json and shake.png in a sieve-mi folder whose marker does not
    list them were overwritten; row 18d: a folder without a marker was refused only after the
    trials. Now: one line, exit 2, before any trial, every file byte-identical."""
    import re

    folder = solve_folder(tmp_path)
    spoil(folder)
    before = tree(folder)
    line = refused(capsys, ["shake", folder, *QUICK])
    assert re.search(message, line), line
    assert tree(folder) == before


def test_a_missing_report_html_writes_the_files_and_says_the_page_got_no_card(tmp_path, capsys):
    """Row 10: with report.html gone the run ended in a traceback after the trials and the marker
    was not updated. Now the files are written and listed, one warning line says no page got the
    card, and the solve's files are untouched."""
    folder = solve_folder(tmp_path, html=True)
    (folder / "report.html").unlink()  # listed in the marker, gone
    before = tree(folder)
    assert main(["shake", str(folder), "--only", "big", *QUICK]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == f"sieve-mi: warning: {folder} has no report.html, so no page got shake's card"
    after = tree(folder)
    assert {k: after[k] for k in before if k != ".sieve-mi"} == {
        k: v for k, v in before.items() if k != ".sieve-mi"
    }
    marker = json.loads((folder / ".sieve-mi").read_text())
    assert {"shake.json", "shake.png"} <= set(marker["files"])
    assert set(after) - {".sieve-mi"} <= set(marker["files"])  # no stray temporary file
    assert json.loads((folder / "shake.json").read_text())["shapes"][0]["name"] == "big"


def test_the_card_replaces_an_earlier_one_and_a_cut_card_is_left_alone():
    """The viewer places shake's card in report.html: a new card goes before the details section
    (or </body>), replaces an earlier card (between its markers), and a page whose card lost its
    end marker, or that has no place for one, is not edited (None)."""
    begin, end = f"<!--{CARD}-->", f"<!--/{CARD}-->"
    page = '<body>\n  <section class="card" id="details">d</section>\n</body>'
    once = with_card(page, CARD, "one")
    twice = with_card(once, CARD, "two")
    assert twice.count(begin) == 1 and "two" in twice and "one" not in twice
    assert twice.index("two") < twice.index('id="details"')
    assert with_card(f"{end} x {begin} cut", CARD, "c") is None
    assert with_card("<p>no body</p>", CARD, "c") is None
    assert with_card(f"<body>{end}</body>", CARD, "c").count(begin) == 1


# ------------------------------------------------------------------------------------------------
# Row 6: a motion no sieve shaker makes is refused before the trials
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def plate_and_ball(tmp_path):
    plate, part = tmp_path / "plate.stl", tmp_path / "ball.stl"
    plate_mesh(round_hole(22.0), 8.0, 2.0).export(str(plate))
    ball(20.0).export(str(part))
    return plate, part


@pytest.mark.parametrize(
    "options, message",
    [
        (
            ("--amplitude", "50", "--frequency", "1000", "--twist", "45"),
            "shake: amplitude 50 mm at frequency 1000 Hz is a peak acceleration of 201,215 g; "
            "sieve shakers give at most 50 g (3 mm at 60 Hz is 43 g): lower the amplitude or "
            "the frequency",
        ),
        (
            ("--amplitude", "0.01", "--frequency", "1000"),
            "shake: timestep 0.25 ms is more than 1/20 of the shaker's period at 1000 Hz; use a "
            "timestep of at most 0.05 ms or a lower frequency",
        ),
        (
            ("--amplitude", "3", "--frequency", "60", "--twist", "10"),
            "plate.stl: a twist of 10 degrees at 60 Hz shakes the plate's corners (26.9 mm from "
            "its centre) at 81 g; sieve shakers give at most 50 g: lower the twist, the "
            "amplitude or the frequency",
        ),
    ],
)
def test_a_motion_beyond_a_sieve_shaker_is_refused_before_the_trials(
    tmp_path, capsys, no_trials, plate_and_ball, options, message
):
    """Row 6: 50 mm at 1000 Hz with a 45 degree twist ran at 201,000 g with fidelity_ok true.
    Now the peak acceleration (of the lift, and of the plate's corners with the twist) is held to
    50 g and the step to a twentieth of the period: one line, exit 2, nothing written."""
    plate, part = plate_and_ball
    before = tree(tmp_path)
    out = tmp_path / "o"
    line = refused(capsys, ["shake", "--sieve", plate, part, *options, *QUICK, "--out", out])
    assert line.endswith(message), line
    assert tree(tmp_path) == before and not out.exists()


def test_the_default_and_the_strongest_lab_motion_are_accepted():
    """The bound refuses nothing a lab shaker does: 1 mm at 50 Hz is 10 g, 3 mm at 60 Hz 43 g."""
    assert ShakeSettings().peak_acceleration_g() == pytest.approx(10.06, abs=0.01)
    assert ShakeSettings(amplitude=3, frequency=60).peak_acceleration_g() < 50.0


# ------------------------------------------------------------------------------------------------
# Rows 6 and 22: penetration while shaken and the engine's warnings make fidelity_ok false
# ------------------------------------------------------------------------------------------------


def test_deep_penetration_and_engine_warnings_fail_the_fidelity_check():
    """Row 22: a 1.12 mm penetration while shaken and MuJoCo's "unstable simulation" left
    fidelity_ok true and no warning. Each now fails the shape's fidelity with one warning line."""
    rest = {
        "sink_mm": 0.002,
        "shaken_penetration_mm": 0.2,
        "bound_mm": 0.02,
        "shaken_bound_mm": 0.5,
        "orientations": 3,
        "engine_warnings": {},
    }
    ok, lines = judge("ball", rest, [Outcome(True, 0.4, penetration=0.3e-3)])
    assert ok["within_bound"] and lines == [] and ok["trial_penetration_mm"] == pytest.approx(0.3)
    deep, lines = judge("ball", rest, [Outcome(False, math.nan, penetration=1.12e-3)])
    assert not deep["within_bound"]
    assert lines == [
        "ball: penetration while shaken 1.12 mm is over the bound 0.5 mm (the soft contacts let "
        "the part into the plate: its fractions are not to be trusted; shake more gently or use "
        "a thicker plate)"
    ]
    unstable = Outcome(False, math.nan, warnings=("mjWARN_BADQACC",))
    warned, lines = judge("ball", rest, [unstable, Outcome(True, 0.5)])
    assert not warned["within_bound"] and warned["unstable_trials"] == 1
    assert warned["engine_warnings"] == {"mjWARN_BADQACC": 1}
    assert len(lines) == 1 and "mjWARN_BADQACC, unstable simulation" in lines[0]
    assert "1 of 2 trial(s) ended there, counted as not passed" in lines[0]


def test_a_trial_the_engine_resets_ends_there_and_says_so(capfd, tmp_path, monkeypatch):
    """An unstable step makes MuJoCo reset the simulation (the part back at its start) and print
    a warning (and write MUJOCO_LOG.TXT into the working folder). The trial now ends there, not
    passed, with the warning in its outcome; nothing is printed, no file written."""
    monkeypatch.chdir(tmp_path)
    plate = plate_from_outline(round_hole(22.0), 14.0, 2.0)
    part = part_from_mesh(ball(20.0), "ball", None, 0.05)
    settings = quick(duration=0.2)
    model = build_model(plate, part, settings, 1e-3)
    data = mujoco.MjData(model)

    def blow_up(k, data, lift):
        if k == 5:
            data.qvel[2] = 1e30  # the part's speed: a bad velocity for the next step

    out = run_trial(model, data, 0, plate, part, settings, 1e-3, observe=blow_up)
    assert out.warnings == ("mjWARN_BADQVEL",) and not out.passed
    assert data.time < 0.01  # ended at the reset, not run on from the start
    assert capfd.readouterr() == ("", "") and os.listdir(tmp_path) == []
    calm = run_trial(model, data, 0, plate, part, settings, 1e-3)
    assert calm.warnings == () and 0 < calm.penetration < 0.5e-3


def test_a_rod_shaken_at_43_g_is_not_called_faithful(tmp_path, capsys):
    """A 30 x 1 x 1 mm rod on a 2 mm plate at 3 mm and 60 Hz (43 g, the strongest lab motion)
    goes deeper into the plate than the 0.5 mm bound (0.8 mm in these two trials, 1.6 mm in
    eight; 4.0 mm, with one trial MuJoCo found unstable, against the plate's 96 exact pieces
    before they were merged): shake.json says fidelity_ok false, with the reasons in
    ``warnings``; the table says so too."""
    plate, rod = tmp_path / "plate.stl", tmp_path / "rod.stl"
    plate_mesh(round_hole(22.0), 14.0, 2.0).export(str(plate))
    trimesh.creation.box((30.0, 1.0, 1.0)).export(str(rod))
    args = ["shake", "--sieve", plate, rod, "--amplitude", "3", "--frequency", "60"]
    quick_ = ("--trials", "2", "--duration", "0.4", "--workers", "1", "--quiet", "--json")
    assert main([str(a) for a in args] + list(quick_) + ["--no-clip"]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)
    fidelity = report["shapes"][0]["fidelity"]
    assert report["fidelity_ok"] is False and not fidelity["within_bound"]
    assert max(fidelity["shaken_penetration_mm"], fidelity["trial_penetration_mm"]) > 0.5
    assert any("penetration while shaken" in w for w in report["warnings"])
    assert fidelity["unstable_trials"] == sum("mjWARN" in w for w in report["warnings"]) <= 2
    assert report["warnings"] == report["shapes"][0]["warnings"] and "WARNING" not in err


# ------------------------------------------------------------------------------------------------
# Row 9: a part too small (or too large) for the engine is refused before the trials
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "scale, units, message",
    [
        (1e-5, "mm", "the part is 0.0002 mm across; shake simulates parts 0.5 to 1000 mm across: "
                     "check the mesh's scale and units"),
        (1.0, "m", "the part is 20,000 mm (20 m) across; shake simulates parts 0.5 to 1000 mm "
                   "across: check the mesh's scale and units"),
    ],
)  # fmt: skip
def test_a_part_too_small_or_too_large_is_refused_before_the_trials(
    tmp_path, capsys, no_trials, plate_and_ball, scale, units, message
):
    """Row 9: a 0.1 um part ended in MuJoCo's ValueError traceback. Now a part is 0.5 mm to 1 m
    across or refused in one line naming the file, its size and what to check."""
    plate, _ = plate_and_ball
    part = tmp_path / "part.stl"
    mesh = ball(20.0)
    mesh.apply_scale(scale)
    mesh.export(str(part))
    before = tree(tmp_path)
    line = refused(capsys, ["shake", "--sieve", plate, part, "--units", units, *QUICK])
    assert line == f"sieve-mi: error: {part}: {message}"
    assert tree(tmp_path) == before


def test_a_part_mujoco_refuses_is_one_line_naming_it(tmp_path, capsys, no_trials, plate_and_ball):
    """A part within the size bounds that MuJoCo still refuses (0.6 mm at 1 kg/m^3: its inertia
    is under MuJoCo's least) is found by compiling its model before the trials."""
    plate, _ = plate_and_ball
    part = tmp_path / "speck.stl"
    ball(0.6).export(str(part))
    line = refused(capsys, ["shake", "--sieve", plate, part, "--density", "1", *QUICK])
    assert line.startswith(f"sieve-mi: error: {part}: MuJoCo cannot simulate it (Error: ")
    assert line.endswith("the part is 0.6 mm across at 1 kg/m^3: check the mesh's units and "
                         "scale, or the density")  # fmt: skip


def test_a_misspelt_shake_setting_is_refused_naming_the_known_ones():
    from sieve_mi.scene import UnknownSettingError
    from sieve_mi.shake.settings import ShakeSettings

    with pytest.raises(
        UnknownSettingError, match=r"shake: trails: unknown setting; known: .*trials"
    ):
        ShakeSettings(trails=3)
    assert ShakeSettings(trials=3).trials == 3
