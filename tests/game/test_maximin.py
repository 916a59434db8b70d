"""Maximin pruning of player A's candidates (sieve_mi.game.maximin).

Argument: a candidate's value is the least β over B, and further attacks only lower each B's β;
so a candidate at or below the value it must beat cannot change the search, and a candidate
above it gets every B's attack. Since every start is drawn up front and each start descends on
its own, the pruned search must take exactly the steps of the unpruned one, with fewer poses.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import rng, sphere

from sieve_mi.game import maximin, reuse
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.testing import shapes
from sieve_mi.testing.settings import tiny_solver


def _players(cube20, blocks):
    frame = Frame.covering(cube20.radius + 1.0, 64)
    return PlayerA(cube20, frame, tolerance=1.0), PlayerB(blocks, frame)


def _blocks():
    box = shape_from_trimesh(shapes.box(24.0, 25.0, 26.0), name="box")
    coin = shape_from_trimesh(shapes.coin(30.0, 3.0), name="coin")
    return [sphere(13.0), box, sphere(12.5), coin]


def test_rounds_of_b_equal_one_attack_of_every_b(cube20):
    # Two B, the second "more dangerous": attacked first, in a round of its own; each B's β on
    # each hole is the one attack of both gives (the same starts, descended apart).
    blocks = _blocks()[:2]
    player_a, player_b = _players(cube20, blocks)
    q = np.random.default_rng(3).normal(size=(3, 4))
    holes = player_a.holes(q / np.linalg.norm(q, axis=1)[:, None])
    whole = PlayerB(blocks, player_b.frame).attack(holes, 6, 30, 0.05, rng(7))
    player_b.danger = np.array([1.0, 0.0])
    pruned = maximin.Pruned(player_b, holes, 6, 30, 0.05, rng(7), None)
    assert [list(g) for g in pruned.rounds] == [[1], [0]]
    values = pruned.advance()
    np.testing.assert_allclose(pruned.low, whole.beta, atol=1e-6)
    np.testing.assert_allclose(values, whole.value(), atol=1e-6)
    # the lowest β of each B is remembered as its danger
    np.testing.assert_allclose(player_b.danger, whole.beta.min(axis=0), atol=1e-6)


def test_a_candidate_at_its_floor_meets_no_more_b(cube20):
    player_a, player_b = _players(cube20, _blocks())
    q = np.random.default_rng(5).normal(size=(4, 4))
    holes = player_a.holes(q / np.linalg.norm(q, axis=1)[:, None])
    pruned = maximin.Pruned(player_b, holes, 4, 20, 0.05, rng(2), None)
    # β <= 1: a floor of 2 stops a candidate after its first round, -inf never
    values = pruned.advance(floor=np.array([2.0, -np.inf, 2.0, -np.inf]))
    assert list(pruned.reached) == [1, len(pruned.rounds), 1, len(pruned.rounds)]
    assert np.isinf(pruned.low[0]).sum() == 4 - len(pruned.rounds[0])  # B never attacked
    assert np.all(values[[1, 3]] == pruned.low[[1, 3]].min(axis=1))  # complete: every B's


@pytest.mark.parametrize("reusing", [False, True])
def test_pruning_never_changes_the_search(cube20, monkeypatch, reusing):
    # Canonical views (ranked), the swarm (personal bests) and the polish (gain) all prune; the
    # rotation, value and history are those of the unpruned search, for fewer descended poses;
    # with reuse across congruent holes too (the cube's face views are congruent squares, and
    # every pair of hole and B gets its β from its class alone, whatever else is attacked).
    got = {}
    monkeypatch.setattr(maximin, "FAR", np.inf)  # every B gets every start: pruning alone
    monkeypatch.setattr(reuse, "REUSE", reusing)
    for prune in (False, True):
        monkeypatch.setattr(maximin, "PRUNE", prune)
        player_a, player_b = _players(cube20, _blocks())
        poses, descend = [0], player_b.descend

        def counted(batch, *args, descend=descend, poses=poses, **kw):
            poses[0] += len(batch)
            return descend(batch, *args, **kw)

        player_b.descend = counted
        solver = tiny_solver(particles=4, iterations=3, starts=4, steps=30, canonical=6, polish=3)
        q, value, history = player_a.search(player_b, solver, rng=rng(1), seed=1)
        got[prune] = (q, value, history.best, history.polish, poses[0])
        assert (player_a.classes is not None) == reusing
        if reusing:
            assert player_a.classes.reused > 0
    (q0, v0, b0, p0, n0), (q1, v1, b1, p1, n1) = got[False], got[True]
    np.testing.assert_array_equal(q0, q1)
    assert v0 == v1 and b0 == b1 and p0 == p1
    assert n1 < n0


def test_a_b_far_from_fitting_gets_fewer_starts(cube20):
    # B 1's last β is more than (1 + FAR) times B 0's: a pruned evaluation gives it FEW of its
    # starts (2 of 6), B 0 all of them; without a known danger every B gets every start.
    blocks = _blocks()[:2]
    player_a, player_b = _players(cube20, blocks)
    holes = player_a.holes(np.array([[1.0, 0.0, 0.0, 0.0]]))
    for danger, want in ((None, [6, 6]), (np.array([0.1, 0.2]), [6, 2])):
        player_b.danger = danger
        pruned = maximin.Pruned(player_b, holes, 6, 5, 0.05, rng(0), None)
        shapes, descend = [], player_b.descend

        def counted(batch, *args, shapes=shapes, descend=descend, **kw):
            shapes.append(batch.pose_shape)
            return descend(batch, *args, **kw)

        player_b.descend = counted
        pruned.advance()
        player_b.descend = descend
        got = np.bincount(np.concatenate(shapes), minlength=2)
        assert list(got) == want
