"""The widest tolerance of a solved hole (:mod:`sieve_mi.game.tolerance`), on the default scene.

The 20 mm cube (A), face on, makes a square hole of side 20 + 2t with round corners: the largest
disk it holds has radius 10 + t. The 24 mm sphere mesh (B) holds a certified ball of radius
ρ = 11.95 and lies within 12 of its centre, so it is blocked while the grown hole (10 + t, plus
the offset's bounded excess) holds no disk of radius ρ, and passes once 10 + t >= 12. At the
scene's tolerance t0 = 1 the sphere overhangs the 22 mm square by 12 - 11 = 1 at best; the
bisection from [1, 2] must end within one step (1 / 2^STEPS) below the ball's bound, at most 2.
"""

from __future__ import annotations

import os

import numpy as np
from helpers import REPO

import sieve_mi
from sieve_mi.certify.bounds import inscribed_ball
from sieve_mi.game import tolerance
from sieve_mi.game.solver import load_shapes
from sieve_mi.geometry.outline import ARC_ERROR, SIMPLIFY
from sieve_mi.testing.settings import TINY_VERDICT


def test_the_tolerance_grows_until_the_sphere_would_fit(monkeypatch):
    monkeypatch.setattr(tolerance, "STEPS", 3)  # 3 verdicts (4 CPU s): the bracket shrinks to 1/8
    scene = sieve_mi.load_scene(os.path.join(REPO, "scenes", "default.toml"))
    for key, value in TINY_VERDICT.items():
        setattr(scene.verdict, key, value)
    scene.verdict.certify = False  # the attack alone decides each try
    passes, blocks = load_shapes(scene)
    quats, trans = np.array([[1.0, 0.0, 0.0, 0.0]]), np.zeros((1, 2))
    got, tries = tolerance.widest_tolerance(scene, passes, blocks, quats, trans, 1.0, seed=0)
    rho = inscribed_ball(blocks[0])[1]
    ball_bound = (rho - 10.0) / (1.0 + ARC_ERROR + SIMPLIFY)  # 1.95: below it no disk of rho fits
    assert ball_bound - 1.0 / 2**3 <= got < 2.0
    assert [t["tolerance"] for t in tries][:2] == [1.5, 1.75]  # blocked: the bracket moves up
    assert all(t["blocked"] == (t["tolerance"] <= got) for t in tries)
    assert scene.fabrication.tolerance == 1.0  # the scene itself is left as it was
    assert tolerance.widest_tolerance(scene, passes, blocks, quats, trans, 0.0, 0) == (1.0, [])
