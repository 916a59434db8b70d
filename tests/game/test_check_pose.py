"""``check`` names the pose a part passes in, and its fit scale gallops (known answers).

* A 1 x 2 toy brick (15.8 x 7.8 x 11.3 mm with its studs) through the hole its own end-on view
  makes (grown by 0.4 mm) passes only end on: every other view is at least 11.3 x 15.8 mm.
* A 2 x 2 brick (15.8 x 15.8 x 11.3) does not pass that hole: its smallest view is 15.8 wide.
* A 10 mm cube held face-on in a 15 mm square hole fits up to scale 1.5 exactly.
* ``solve`` with the 1 x 2 brick's rotation fixed end on names its pass pose as ``check`` does:
  in report.json (``pass[0].pose``), on the console and on the page's hole view.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from sieve_mi.game.check import CheckSettings, ShapeCheck, check, fit_scale, grown_scale
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import hole_outline
from sieve_mi.geometry.rotations import from_axis_angle
from sieve_mi.outputs.console import check_summary
from sieve_mi.outputs.fabrication import plate
from sieve_mi.testing.catalogue import brick

FAST = CheckSettings(starts=24, steps=150, resolution=128, fit=False)
END_ON = from_axis_angle(np.array([0.0, 1.0, 0.0]), math.pi / 2)  # brick's x (15.8) along z


@pytest.fixture(scope="module")
def end_on_plate(tmp_path_factory):
    """A 25 mm plate (thicker than either brick is across) with the 1 x 2 brick's end-on hole."""
    one = shape_from_trimesh(brick(2, 1), name="1x2")
    hole = hole_outline([one], END_ON[None], np.zeros((1, 2)), 0.4, closed=[True])
    folder = tmp_path_factory.mktemp("bricks")
    plate(hole, 25.0, 5.0).mesh.export(str(folder / "plate.stl"))
    brick(2, 1).export(str(folder / "brick_1x2.stl"))
    brick(2, 2).export(str(folder / "brick_2x2.stl"))
    return folder


@pytest.fixture(scope="module")
def end_on_check(end_on_plate):
    return check(str(end_on_plate / "brick_1x2.stl"), sieve=str(end_on_plate / "plate.stl"),
                 settings=FAST)  # fmt: skip


def test_the_1x2_brick_passes_end_on_and_check_says_so(end_on_check):
    rep = end_on_check
    assert rep.result.passes
    pose = rep.pose
    assert pose["of"] == "pass" and pose["position"] == "end on"
    assert pose["upright"] == pytest.approx(15.8, abs=1e-4)
    # the hole leaves 0.4 mm a side: the brick can lean only a few degrees
    assert pose["tilt_deg"] < 8.0 and pose["rest_position"] == "end on"
    assert np.linalg.norm(pose["quaternion"]) == pytest.approx(1.0)
    text = check_summary(rep)
    assert "pass pose: end on (standing on its short end): its 15.8 mm extent upright" in text
    assert "from resting end on" in text and "rotation: " in text
    assert json.loads(json.dumps(rep.to_dict()))["pose"]["words"].startswith("end on")
    from sieve_mi.outputs.viewer import check_table

    assert "<td>pass pose</td><td>end on (standing on its short end)" in check_table(rep.to_dict())


def test_check_json_has_the_pose_and_a_blocked_part_names_its_best_attempt(end_on_plate, capsys):
    from sieve_mi.cli import main

    code = main(["check", str(end_on_plate / "brick_2x2.stl"), "--sieve",
                 str(end_on_plate / "plate.stl"), "--starts", "24", "--steps", "150",
                 "--resolution", "128", "--no-fit", "--json", "--quiet"])  # fmt: skip
    assert code == 3  # blocked
    rep = json.loads(capsys.readouterr().out)
    assert rep["passes"] is False
    pose = rep["pose"]
    assert pose["of"] == "best attempt"
    assert pose["position"] in ("on its side", "end on")  # a 15.8 extent upright
    assert pose["upright"] == pytest.approx(15.8, abs=1e-4)
    assert set(pose) >= {"words", "tilt_deg", "rest_deg", "quaternion", "euler_xyz_deg",
                         "turn_deg", "turn_axis", "rest_share"}  # fmt: skip


def test_solve_names_the_pass_pose_as_check_does(end_on_plate, end_on_check):
    """The 1 x 2 brick fixed end on (no search), the 2 x 2 blocked on a plate thicker than it is
    across (no proof, no thin-plate search): the A's pose in report.json, console and page."""
    from sieve_mi.api import solve
    from sieve_mi.outputs.console import summary_table
    from sieve_mi.outputs.report import report_dict
    from sieve_mi.outputs.svg import hole_svg
    from sieve_mi.outputs.viewer import pose_caption
    from sieve_mi.scene import load_scene
    from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT, settings_toml

    q = ", ".join(repr(float(x)) for x in END_ON)
    text = (f'name = "end on"\n[[pass]]\nmesh = "brick_1x2.stl"\nname = "1x2"\nrotation = [{q}]\n'
            '[[block]]\nmesh = "brick_2x2.stl"\nname = "2x2"\n'
            + settings_toml(solver=TINY_SOLVER, verdict={**TINY_VERDICT, "certify": False},
                            fabrication={"tolerance": 0.4, "thickness": 25.0}))  # fmt: skip
    (end_on_plate / "end_on.toml").write_text(text)
    result = solve(load_scene(str(end_on_plate / "end_on.toml")), progress=False)
    report = report_dict(result)
    assert report["winner"] == "A"  # every view of the 2 x 2 is at least 15.8 wide
    pose = json.loads(json.dumps(report["pass"][0]["pose"]))
    want = end_on_check.pose
    assert pose["of"] == "pass" and pose["words"] == want["words"]
    assert pose["words"] == "end on (standing on its short end)"
    assert pose["position"] == want["position"] and pose["rest_position"] == want["rest_position"]
    assert set(pose) == set(want)  # the same shape of dict as check --json
    # fixed exactly end on: upright 15.8 mm, untilted, on a resting face
    assert pose["upright"] == pytest.approx(15.8, abs=1e-4)
    assert pose["tilt_deg"] < 1e-4 and pose["rest_deg"] < 1e-4
    line = "1x2: passes end on (standing on its short end): its 15.8 mm extent upright; 0.0° "
    assert line + "from resting end on" in summary_table(report)
    titles, caption = pose_caption(report)
    assert titles[0].startswith(line) and "<li>1x2: passes end on (standing" in caption
    svg = hole_svg(result, [True], titles)
    assert "<title>1x2: passes end on (standing on its short end)" in svg


def test_grown_scale_of_a_face_on_cube_in_a_square_hole():
    cube = shape_from_trimesh(trimesh.creation.box((10, 10, 10)), name="cube")
    import manifold3d

    hole = manifold3d.CrossSection.square((15.0, 15.0), center=True).translate((2.0, -1.0))
    q, t = [1.0, 0, 0, 0], [2.0, -1.0]
    assert grown_scale(cube, q, t, hole, 1.0, 1e-4) == pytest.approx(1.5, rel=1e-4)
    assert grown_scale(cube, q, t, hole, 2.0, 1e-4) == pytest.approx(1.5, rel=1e-4)  # shrinks
    # off the hole's centre by 2 mm it fits only up to (7.5 - 2) / 5
    assert grown_scale(cube, q, [4.0, -1.0], hole, 1.0, 1e-4) == pytest.approx(1.1, rel=1e-4)
    # centre outside the hole: no scale fits
    assert grown_scale(cube, q, [30.0, 0.0], hole, 1.0, 1e-4) == 0.0


def _probe(threshold):
    def evaluate(s):
        calls.append(s)
        return ShapeCheck(s, s <= threshold, 0.0, 0.0, [1, 0, 0, 0], [0, 0], 0, 0)

    calls = []
    return evaluate, calls


@pytest.mark.parametrize("threshold, first_grow", [(0.6555, 0.566), (1.37, 1.0), (3.0, 1.2)])
def test_fit_scale_gallops_from_the_grown_pose(threshold, first_grow):
    """Each pose grows to just under the threshold (its pose is a good one): the search ends at
    the first probe a tolerance above, a handful of attacks where bisection took nine."""
    evaluate, calls = _probe(threshold)

    def grow(v):  # a passing pose fits up to 0.999 of the threshold; the first grows less
        if v.scale == 1.0:
            return first_grow if first_grow <= threshold else 0.0
        return 0.999 * threshold if v.passes else 0.0

    first = evaluate(1.0)
    s, (lo, hi) = fit_scale(evaluate, first, 0.01, grow=grow)
    assert lo <= threshold < hi and hi / lo - 1 <= 0.01 + 1e-12 and s == lo
    assert len(calls) <= 4
    # without grow: the bisection of before, more attacks
    evaluate, slow = _probe(threshold)
    s2, (lo2, hi2) = fit_scale(evaluate, evaluate(1.0), 0.01)
    assert lo2 <= threshold < hi2 and len(slow) > len(calls)


def test_fit_scale_gallop_when_nothing_fits_or_everything_does():
    evaluate, calls = _probe(0.0)
    s, (lo, hi) = fit_scale(evaluate, evaluate(1.0), 0.01, limit=5, grow=lambda v: 0.0)
    assert s == 0.0 and lo == 0.0 and hi == 2.0**-5 and len(calls) == 1 + 5  # as bisection
    evaluate, calls = _probe(math.inf)
    s, (lo, hi) = fit_scale(evaluate, evaluate(1.0), 0.01, limit=3, grow=lambda v: v.scale)
    assert math.isinf(hi) and s == lo > 1.0 and len(calls) <= 3 + 7 + 2
