"""Optimisers: Adam over poses (drjit.opt.Adam), nlopt's global methods with a hard budget."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.optim import (
    NLOPT_METHODS,
    POSE_KEYS,
    QUAT_KEYS,
    nlopt_maximise,
    pose_adam,
    renormalise_quaternions,
)

TARGET = np.array([0.5, -1.0, 2.0])


def _quadratic(calls):
    def f(x):
        calls.append(np.array(x))
        return -float(np.sum((x - TARGET) ** 2))

    return f


@pytest.mark.parametrize("method", sorted(NLOPT_METHODS))
def test_nlopt_method_finds_a_known_maximum_within_its_budget(method):
    # -|x - target|^2 has its maximum 0 at target; 600 evaluations get every method within
    # 0.5 of it (value > -0.5). The budget is exact: nlopt never calls past it.
    calls = []
    x, v, history = nlopt_maximise(
        _quadratic(calls), -np.pi * np.ones(3), np.pi * np.ones(3), method, 600, np.zeros(3), seed=0
    )
    assert v > -0.5
    assert v == pytest.approx(-np.sum((x - TARGET) ** 2))
    assert history.evaluations == len(calls) <= 600
    assert history.best == sorted(history.best)  # best so far never decreases


@pytest.mark.parametrize("method", sorted(NLOPT_METHODS))
def test_nlopt_stops_at_a_small_budget_without_crashing(method):
    # A budget smaller than some methods' first population: they are stopped by force_stop,
    # which must end the run normally (it used to surface as SystemError with nlopt 2.11).
    calls = []
    x, v, history = nlopt_maximise(
        _quadratic(calls), -np.pi * np.ones(3), np.pi * np.ones(3), method, 5, np.zeros(3), seed=1
    )
    assert history.evaluations == len(calls) == 5
    assert v == max(-float(np.sum((c - TARGET) ** 2)) for c in calls)


@pytest.mark.parametrize("method", sorted(NLOPT_METHODS))
def test_nlopt_reraises_the_objectives_own_error(method):
    def bad(x):
        raise SieveError("mesh exploded")

    with pytest.raises(SieveError, match="mesh exploded"):
        nlopt_maximise(bad, -np.ones(3), np.ones(3), method, 50, np.zeros(3), seed=0)


def test_adam_steps_by_the_learning_rate_under_a_constant_gradient(mi):
    # With a constant gradient g, Adam's bias-corrected moments are exactly g and g^2, so every
    # step moves each parameter by lr * sign(g): after 3 steps of lr 0.1 on L = sum(2 tx - 3 ty),
    # tx = 1 - 0.3 and ty = -1 + 0.3.
    import drjit as dr

    opt = pose_adam(np.tile([1.0, 0, 0, 0], (4, 1)), np.tile([1.0, -1.0], (4, 1)), 0.1)
    for _ in range(3):
        dr.backward(dr.sum(2 * opt["tx"] - 3 * opt["ty"]))
        opt.step()
    assert np.allclose(opt["tx"].numpy(), 0.7, atol=1e-5)
    assert np.allclose(opt["ty"].numpy(), -0.7, atol=1e-5)


def test_renormalised_quaternions_are_unit_and_keep_adams_moments(mi):
    import drjit as dr

    q0 = np.array([[2.0, 0, 0, 0], [1.0, 1.0, 1.0, 1.0]])
    opt = pose_adam(q0, np.zeros((2, 2)), 0.05)
    renormalise_quaternions(opt)
    q = np.stack([opt[k].numpy() for k in QUAT_KEYS], axis=1)
    assert np.allclose(q, [[1, 0, 0, 0], [0.5, 0.5, 0.5, 0.5]], atol=1e-6)
    # A step with a gradient on qx only, then a renormalisation: if qx's first moment survived
    # it, a second step without gradient still moves qx down (a reset moment would not move it).
    dr.backward(dr.sum(opt["qx"]))
    opt.step(eval=False)
    renormalise_quaternions(opt)
    before = opt["qx"].numpy().copy()
    opt.step()
    assert np.all(opt["qx"].numpy() < before)
    assert set(opt.keys()) == set(POSE_KEYS)


@pytest.mark.parametrize("freeze", [False, True], ids=["traced", "frozen"])
def test_descend_compiles_no_kernel_after_its_first_steps(mi, cube20, freeze):
    # Per-step scalars (learning rate, bias correction) are opaque: the kernels of step 3 are
    # reused by every later step instead of being compiled again. Frozen, step 3 is recorded
    # (with Adam's step counter made opaque first) and every later step replays it.
    import drjit as dr
    from helpers import sphere

    from sieve_mi.game.descent import Batch
    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB
    from sieve_mi.geometry.raster import Frame

    f = Frame.covering(cube20.radius + 1.0, 64)
    hole = PlayerA(cube20, f, 1.0).holes(np.array([[1.0, 0, 0, 0]]))[0]
    rng = np.random.default_rng(0)
    k = 6
    q0 = rng.normal(size=(k, 4))
    t0 = rng.uniform(-3, 3, (k, 2))
    seen = []
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        player = PlayerB([sphere(12.0, 2)], f, freeze=freeze)
        player.descend(
            Batch([hole], np.zeros(k, int), np.zeros(k, int), q0, t0),
            8,
            0.05,
            progress=lambda s: seen.append({e["hash"] for e in dr.kernel_history() if "hash" in e}),
        )
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    later = seen[3:]
    assert len(later) == 5 and all(later)  # every step launched kernels
    assert set().union(*later) <= set().union(*seen[:3])
    if freeze:
        assert player._frozen.n_recordings == 1


@pytest.mark.slow
@pytest.mark.parametrize("outer", ["pso", *sorted(NLOPT_METHODS)])
def test_every_outer_method_solves_end_to_end(write_scene, outer):
    # The hole's plane contains a direction u with a zero component in the cube's frame (two
    # planes through the origin share a line); along u the 20 mm cube is 20 (|u1| + |u2|) <=
    # 20 sqrt(2) = 28.3 mm wide, the hole (1 mm tolerance per side) at most 30.3 mm. A 32 mm
    # sphere is blocked whatever rotation the search picks: A wins with every method, after
    # exactly its budget of particles x (iterations + 1) = 3 x 2 evaluations plus the cube's
    # three canonical (face-on) views; the search's value is the polish's final one.
    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene
    from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT, settings_toml

    ball = trimesh.creation.icosphere(2, 16.0)
    cube = trimesh.creation.box((20.0, 20.0, 20.0))
    path = write_scene(
        'name = "t"\n[[pass]]\nmesh = "meshes/cube.stl"\n[[block]]\nmesh = "meshes/ball.stl"\n'
        + settings_toml(
            solver={"outer": outer, **TINY_SOLVER}, verdict={**TINY_VERDICT, "resolution": 64}
        ),
        {"cube.stl": cube, "ball.stl": ball},
    )
    r = solve(load_scene(path), progress=False)
    assert r.winner == "A" and r.attack.beta[0, 0] > 0
    assert r.history.evaluations == 6 + 3
    assert r.search_value == r.polish[0]["after"] >= r.polish[0]["before"] > 0


def test_patience_stops_a_swarm_whose_best_stalls_and_not_one_that_climbs():
    """The swarm's best is a count of evaluations: +1 each iteration, always more than 1 %
    above the last best while below 100, so patience 2 never stops it in 10 iterations; the same
    swarm on values that grow by 1e-4 per iteration (under the 1e-3 floor) stops after exactly
    2 idle iterations, with 3 entries in its history (the start and 2 iterations)."""
    from sieve_mi.optim import SwarmSettings, particle_swarm

    def counting(step):
        calls = [0]

        def evaluate(x):
            calls[0] += 1
            return np.full(len(x), step * calls[0])

        return evaluate

    rng = np.random.default_rng(0)
    x0 = rng.normal(size=(3, 2))
    _, best, h = particle_swarm(counting(1.0), x0, 10, rng, SwarmSettings(patience=2))
    assert h.stopped is None and len(h.best) == 11 and best == 11.0
    _, best, h = particle_swarm(counting(1e-4), x0, 10, rng, SwarmSettings(patience=2))
    assert h.stopped == 2 and len(h.best) == 3 and best == pytest.approx(3e-4)
    _, _, h = particle_swarm(counting(1e-4), x0, 10, rng, SwarmSettings(patience=0))
    assert h.stopped is None and len(h.best) == 11
