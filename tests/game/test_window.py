"""The turning window of a solve (``[fabrication] window``), on the default scene.

The 20 mm cube (A) makes a 22 mm square hole; turned within ±δ the hole holds the disk of radius
(11 + g) / cos δ about its centre (tests/geometry/test_window.py; g the chord bound). The 24 mm
sphere mesh (B) holds a certified ball of radius ρ = 11.95 and lies within 12 of its centre. So
B is proved blocked by its ball while (11 + g) / cos δ < ρ (δ < 22.3°), and passes once
11 / cos δ >= 12 (δ >= 23.6°): the widest window found must lie in between, within one
bisection step (90° / 2^6) below the ball's bound.
"""

from __future__ import annotations

import json
import math
import os

import pytest
from helpers import REPO

import sieve_mi
from sieve_mi.certify.bounds import inscribed_ball
from sieve_mi.game.window import WIDEST
from sieve_mi.geometry.outline import ARC_ERROR, SIMPLIFY
from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT

pytestmark = pytest.mark.slow


def _scene(window):
    scene = sieve_mi.load_scene(os.path.join(REPO, "scenes", "default.toml"))
    for key, value in TINY_SOLVER.items():
        setattr(scene.solver, key, value)
    for key, value in TINY_VERDICT.items():
        setattr(scene.verdict, key, value)
    scene.verdict.certify_budget = 5.0  # certify looks for passages the short attack misses
    scene.fabrication.window = window
    return scene


def test_auto_finds_the_widest_window_the_sphere_allows(tmp_path, monkeypatch):
    from sieve_mi.game import window

    monkeypatch.setattr(window, "STEPS", 4)  # 5 verdicts: the bracket is 90° / 16 = 5.6°
    result = sieve_mi.solve(_scene("auto"), progress=False)
    w = result.window
    rho = inscribed_ball(result.block_shapes[0])[1]
    grown = 11.0 + w["chord_bound"] + (ARC_ERROR + SIMPLIFY) * (1.0 + w["chord_bound"])
    ball_bound = math.degrees(math.acos(grown / rho))  # 22.3°
    assert result.winner == "A" and result.certified[0].method == "ball"
    assert result.certified[0].status == "proved"
    assert ball_bound - WIDEST / 2**4 <= w["degrees"] <= ball_bound < 23.56
    assert w["mode"] == "auto" and w["bisection"][0] == {"degrees": 90.0, "blocked": False}
    assert [t["degrees"] for t in w["bisection"] if t["blocked"]][-1] == w["degrees"]
    report = result.save(str(tmp_path / "out"), figure=False, animation=False)
    assert report["fabrication"]["window"] == json.loads(json.dumps(w))
    assert report["settings"]["fabrication"]["window"] == "auto"  # what ran, as written


def test_a_given_window_wider_than_the_sphere_allows_lets_it_through():
    scene = _scene(30.0)
    scene.verdict.certify = False  # B's attack finds its way through: nothing to prove
    result = sieve_mi.solve(scene, progress=False)  # 11 / cos 30° = 12.7 > 12
    assert result.winner == "B" and result.window["degrees"] == 30.0
    assert result.window["mode"] == "given" and "bisection" not in result.window
