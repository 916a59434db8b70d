"""A blocked B's overhang in a maker's words: the least overhang over poses, found and scored on
the exact polygon, and its proved lower bound, never a bare 0 under "proved"."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sieve_mi.game.exact import ExactAttempt, score
from sieve_mi.game.overhang import _proof, least_overhang, overhang, overhang_text
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import Boundary, hole_outline
from sieve_mi.geometry.rotations import from_axis_angle
from sieve_mi.outputs.console import margin_lines
from sieve_mi.testing.shapes import box

TOL = 0.1
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def brick():
    """A 9 x 17 x 20 box against the hole of an 8 x 16 x 10 box seen along z (grown by TOL):
    its body is 0.5 mm wider on each side than the hole (less the tolerance: 0.4 mm)."""
    a = shape_from_trimesh(box(8.0, 16.0, 10.0), name="a")
    b = shape_from_trimesh(box(9.0, 17.0, 20.0), name="b")
    hole = hole_outline([a], IDENTITY[None], np.zeros((1, 2)), TOL, "never", [True])
    return b, hole, Boundary(hole)


def test_the_least_overhang_is_found_from_a_tilted_start(brick):
    b, hole, boundary = brick
    tilted = from_axis_angle(np.array([1.0, 0.3, 0.0]), 0.5)
    start = ExactAttempt(tilted, np.zeros(2), score(b, tilted, np.zeros(2), hole, boundary, True))
    assert start.score.protrusion > 3.0  # the pose with a corner far out
    best = least_overhang(b, hole, start)
    # standing straight and centred: the corners stick out by |(0.5, 0.5)| - TOL
    straight = score(b, IDENTITY, np.zeros(2), hole, boundary, True).protrusion
    assert straight == pytest.approx(np.hypot(0.5, 0.5) - TOL, abs=1e-3)
    assert best.score.protrusion <= straight + 1e-9
    # B's narrowest width is 9 and the hole's widest slot 8.2: no pose sticks out by less than 0.4
    assert best.score.protrusion >= 0.4 - 1e-9
    # the number is the exact polygon's at the pose reported, not a raster's
    again = score(b, best.quat, best.trans, hole, boundary, True)
    assert again.protrusion == pytest.approx(best.score.protrusion, rel=1e-12)


def test_the_search_stops_at_a_pose_close_to_the_proved_bound(brick):
    b, hole, boundary = brick
    start = ExactAttempt(
        IDENTITY, np.zeros(2), score(b, IDENTITY, np.zeros(2), hole, boundary, True)
    )
    got = overhang(b, hole, start, {"proved_at_least": 0.59, "found_at_most": 0.61})
    # 0.607 is within 5 % of the bound: no start is polished, the verdict's pose stays
    assert got.at_best_pose == start.score.protrusion
    assert got.proved_at_least == 0.59 and got.proof == "ball"  # no certification: a ball's
    entry = got.to_dict("mm")
    assert (
        entry["text"] == "overhangs the hole by ≥ 0.59 mm in every pose, 0.61 mm at its best pose"
    )


@pytest.mark.parametrize(
    ("status", "margin", "steps", "proof"),
    [("proved", 0.3, 2, "bisection"), ("proved", 0.0, 0, "not bisected"),
     ("proved", 0.0, 5, "bisection failed"), ("undecided", None, 0, "ball")],
)  # fmt: skip
def test_a_proved_line_says_why_its_bound_is_zero(status, margin, steps, proof):
    c = SimpleNamespace(status=status, margin=margin, margin_steps=steps)
    low = margin if status == "proved" else 0.2
    assert _proof(c, low) == proof
    entry = {"at_best_pose": 1.25, "proved_at_least": low, "proof": proof}
    entry["text"] = overhang_text(entry, "mm")
    row = {"name": "letter_R", "certified": status, "overhang": entry}
    (line,) = margin_lines({"block": [row, {"name": "passes", "certified": "-"}]})
    assert line.startswith("letter_R: blocked (") and "1.25 mm at its best pose" in line
    if low:
        assert f"by ≥ {low:.2f} mm in every pose" in line
    else:  # proved, but no margin: never a bare "≥ 0.00"
        assert "≥" not in line and "blocked (proved)" in line
        assert line.endswith("was not bisected" if steps == 0 else "within the budget")


def test_a_b_proved_by_size_is_not_searched_and_says_so(brick):
    b, hole, boundary = brick
    tilted = from_axis_angle(np.array([1.0, 0.3, 0.0]), 0.5)
    start = ExactAttempt(tilted, np.zeros(2), score(b, tilted, np.zeros(2), hole, boundary, True))
    got = overhang(b, hole, start, {"proved_at_least": 0.4}, search=False).to_dict("mm")
    assert got["at_best_pose"] == start.score.protrusion and got["searched"] is False
    assert got["text"].endswith(f"{start.score.protrusion:.2f} mm at the one pose tried")
