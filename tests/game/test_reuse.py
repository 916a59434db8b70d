"""Player B's attacks reused across congruent holes (sieve_mi.game.reuse).

Known answer: every view of a ball makes the same disk, so the search's holes form one class;
its reference alone gets a full attack (the search's steps from random starts), every other
hole a short descent from B's best poses there, and each such hole's value is the reference's
up to the raster's noise. On the plate, a 20 mm ball's hole (radius 11 with the 1 mm tolerance)
leaves 1 - (11 / 11.8)^2 = 0.131 of a 23.6 mm ball's shadow outside (β).
"""

from __future__ import annotations

import numpy as np
from helpers import rng, sphere

from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.game.reuse import Entry, Incumbent, Member
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.testing import shapes
from sieve_mi.testing.settings import tiny_solver


def test_a_balls_holes_get_one_full_attack():
    box = shape_from_trimesh(shapes.box(24.0, 25.0, 26.0), name="box")
    frame = Frame.covering(11.0, 64)
    player_a, player_b = PlayerA(sphere(10.0), frame, 1.0), PlayerB([sphere(11.8), box], frame)
    solver = tiny_solver(particles=3, iterations=1, starts=4, steps=30, canonical=4, polish=1)
    full, descend = [], player_b.descend

    def counted(batch, steps, *args, **kw):
        if steps == solver.steps:
            full.append(len(batch))
        return descend(batch, steps, *args, **kw)

    player_b.descend = counted
    _, value, _ = player_a.search(player_b, solver, rng=rng(1), seed=1)
    classes = player_a.classes
    assert len(classes.entries) == 1 and classes.reused == classes.placed - 1 > 5
    assert player_a.incumbent.confirmed == 1  # the one class, confirmed by a fresh attack once
    assert sum(full) == 2 * solver.starts * 2  # the reference's starts of both B, and those
    ref = classes.entries[0].beta
    assert abs(ref[0] - 0.131) < 0.02 and ref[1] > ref[0]  # the ball decides
    assert abs(value - ref[0]) < 0.01


def test_a_class_that_would_be_best_is_confirmed_once_by_a_fresh_attack():
    # Holes 0 and 1 are one class (X), hole 2 another (Y); reused attacks gave 0.1, 0.5, 0.3,
    # fresh attacks find 0.05 on X and 0.2 on Y. The 0.5 would be the best: X is confirmed and
    # capped at 0.05, hole 0 with it; then the 0.3: Y capped at 0.2, the best now.
    x, y, z = (Entry(None, None, None) for _ in range(3))
    found = {1: 0.05, 2: 0.2, 3: 0.9}
    asked = []

    def fresh(quats, k):
        asked.append((int(quats[0, 0]), k))
        return np.array([found[int(quats[0, 0])]])

    def members(*entries):
        return [Member(e, None, False) for e in entries]

    incumbent = Incumbent(fresh)
    quats = np.array([[0.0, 0, 0, 1], [1.0, 0, 0, 0], [2.0, 0, 0, 0]])  # tagged in w
    got = incumbent(quats, [0.1, 0.5, 0.3], members(x, x, y))
    np.testing.assert_array_equal(got, [0.05, 0.05, 0.2])
    assert asked == [(1, 0), (2, 1)] and incumbent.best == 0.2
    assert (incumbent.confirmed, incumbent.lowered) == (2, 2)
    # later holes of confirmed classes are capped, and no class is attacked again
    got = incumbent(quats, [0.15, 0.4, 0.25], members(x, x, y))
    np.testing.assert_array_equal(got, [0.05, 0.05, 0.2])
    assert incumbent.confirmed == 2 and incumbent.best == 0.2
    # a new class's fresh attack that finds no lower value leaves its value as it was
    got = incumbent(np.array([[3.0, 0, 0, 0]]), [0.3], members(z))
    np.testing.assert_array_equal(got, [0.3])
    assert (incumbent.confirmed, incumbent.lowered, incumbent.best) == (3, 2, 0.3)
