"""Player B's attack and player A's global search on cases with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import rng, sphere

from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.raster import Frame
from sieve_mi.optim import SwarmSettings, nlopt_maximise, particle_swarm
from sieve_mi.testing.settings import tiny_solver


def _cube_hole(cube20, resolution=128):
    f = Frame.covering(cube20.radius + 1.0, resolution)
    a = PlayerA(cube20, f, tolerance=1.0)
    return f, a, a.holes(np.array([[1.0, 0, 0, 0]]))[0]


def test_sphere_passes_or_is_blocked_by_the_inscribed_disk(cube20):
    # Face-on, the cube's hole is a 22 mm rounded square; its inscribed disk has radius 11 mm.
    f, a, hole = _cube_hole(cube20)
    h = f.pixel_size
    small, big = sphere(10.0), sphere(12.0)
    attack = PlayerB([small, big], f).attack(
        [hole], starts=10, steps=100, learning_rate=0.05, rng=rng()
    )
    assert attack.beta[0, 0] == 0.0 and attack.fits[0, 0] > 0
    assert attack.beta[0, 1] > 0
    # The 24 mm sphere sticks out by 12 - 11 = 1 mm, up to a pixel of rasterisation.
    assert attack.protrusion[0, 1] == pytest.approx(1.0, abs=1.5 * h)
    # The game value is the weakest block (eq. 10): here the small sphere's 0.
    assert attack.value()[0] == 0.0


def test_many_holes_are_attacked_independently(cube20):
    f, a, _ = _cube_hole(cube20)

    # Face-on square (blocks a 24 mm sphere) and a cube seen along its space diagonal (a hexagon
    # with inscribed radius 20/sqrt(2) = 14.1 mm, dilated by 1: admits it).
    holes = a.holes(
        np.array(
            [[1.0, 0, 0, 0], [0.8880738339771153, 0.32505758367186816, -0.32505758367186816, 0.0]]
        )
    )
    attack = PlayerB([sphere(12.0)], f).attack(
        holes, starts=8, steps=100, learning_rate=0.05, rng=rng(1)
    )
    assert attack.beta[0, 0] > 0 and attack.beta[1, 0] == 0.0


def test_particle_swarm_finds_a_known_maximum():
    target = np.array([0.3, -0.7, 0.5])

    def f(x):
        return -np.sum((x - target) ** 2, axis=1)

    x0 = np.random.default_rng(0).uniform(-1, 1, (20, 3))
    best, value, history = particle_swarm(
        f,
        x0,
        60,
        np.random.default_rng(1),
        SwarmSettings(inertia=0.5, c_personal=1.0, c_global=1.0),
    )
    assert np.allclose(best, target, atol=0.05)
    assert np.all(np.diff(history.best) >= 0) and len(history.best) == 61


@pytest.mark.parametrize("method", ["crs2", "direct", "esch", "isres"])
def test_nlopt_methods_maximise(method):
    target = np.array([0.5, -1.0, 2.0])
    x, v, history = nlopt_maximise(
        lambda x: -float(np.sum((x - target) ** 2)),
        -np.pi * np.ones(3),
        np.pi * np.ones(3),
        method,
        3000,
        np.zeros(3),
        seed=0,
    )
    assert v > -0.5 and history.evaluations <= 3000
    assert v == pytest.approx(-np.sum((x - target) ** 2))  # the value is that of the point returned


def test_player_a_search_prefers_the_face_on_cube(cube20):
    # A 24 mm sphere can only be blocked by the cube's face-on view (any tilt widens the hole's
    # inscribed disk beyond 12 mm... the hexagonal view reaches 14.1 mm): the search must find a
    # rotation with a positive game value.
    f = Frame.covering(cube20.radius + 1.0, 96)
    a = PlayerA(cube20, f, tolerance=1.0)
    b = PlayerB([sphere(12.0, 2)], f)
    solver = tiny_solver(particles=8, iterations=4, starts=6, steps=60)
    q, value, history = a.search(b, solver, rng=rng(3), seed=3)
    assert value > 0
    assert len(history.best) == 5


def test_attack_memory_replays_a_remembered_passage(cube20):
    # The face-on cube hole is a 22 mm square (rounded by the 1 mm dilation). A 21 x 21 x 40 mm
    # block passes it only standing upright and square to the hole (about 1 degree of slack in
    # plane): a random pose never fits, the remembered upright pose always does.
    import trimesh

    from sieve_mi.game.attack import Attack, AttackMemory, Starts
    from sieve_mi.geometry.meshes import shape_from_trimesh

    f, a, hole = _cube_hole(cube20)
    block = shape_from_trimesh(trimesh.creation.box(extents=(21.0, 21.0, 40.0)), name="block")
    b = PlayerB([block], f)
    cold = b.attack([hole], starts=2, steps=0, learning_rate=0.05, rng=rng(5))
    assert cold.beta[0, 0] > 0

    memory = AttackMemory(1, size=2)
    upright = np.array([[[1.0, 0.0, 0.0, 0.0]]])
    worse = np.array([[[0.0, 1.0, 0.0, 0.0]]])  # lying down: 21 x 40 does not fit
    memory.update(
        Attack(
            beta=np.array([[0.3]]),
            protrusion=np.array([[9.0]]),
            quats=worse,
            trans=np.zeros((1, 1, 2)),
            fits=np.zeros((1, 1), int),
        )
    )
    memory.update(
        Attack(
            beta=np.array([[0.0]]),
            protrusion=np.array([[0.0]]),
            quats=upright,
            trans=np.zeros((1, 1, 2)),
            fits=np.ones((1, 1), int),
        )
    )
    q, _ = memory.poses(0)
    assert q.tolist() == [[1.0, 0, 0, 0], [0.0, 1.0, 0, 0]]  # best first

    warm = b.attack([hole], Starts(2, memory=memory), steps=0, learning_rate=0.05, rng=rng(5))
    assert warm.beta[0, 0] == 0.0 and warm.fits[0, 0] == 1
    assert len(memory.poses(0)[0]) == 2 and memory.poses(0)[0][0].tolist() == [1.0, 0, 0, 0]


def test_player_b_objective_is_public_and_made_once(cube20):
    from sieve_mi.objectives.clearance import ClearanceObjective
    from sieve_mi.scene import Solver

    f, _, hole = _cube_hole(cube20, 64)
    b = PlayerB([sphere(12.0, 2)], f)
    assert b.objective_name == "clearance" and b._loss is None  # made on first use
    assert isinstance(b.objective, ClearanceObjective) and b.objective is b.objective
    b.attack([hole], starts=2, steps=2, learning_rate=0.05, rng=rng(0))
    assert b.objective is b._loss  # the descent used this one
    other = PlayerB.from_settings([sphere(12.0, 2)], f, Solver(objective="overlap", freeze=False))
    assert (other.objective_name, other.freeze) == ("overlap", False)
    assert PlayerB.from_settings([], f, Solver(), objective="clearance").freeze is True


def _two_holes(cube20):
    """The face-on cube's hole (22 mm rounded square, inscribed disk 11 mm) and the hole of the
    cube seen along its space diagonal (a hexagon, inscribed radius 20/sqrt(2) + 1 = 15.1 mm)."""
    f, a, _ = _cube_hole(cube20)
    quats = np.array(
        [[1.0, 0, 0, 0], [0.8880738339771153, 0.32505758367186816, -0.32505758367186816, 0.0]]
    )
    return f, a.holes(quats)


@pytest.mark.parametrize("settle", ["hole", "shape"])
def test_settled_starts_stop_and_the_others_descend_bit_for_bit(cube20, settle):
    # A 24 mm sphere cannot enter the square (12 > 11 mm) and fits the hexagon (12 < 15.1 mm):
    # the hexagon's starts settle as soon as one fits and leave the batch; the square's never do,
    # and with their Adam state carried over they must end exactly where they end without
    # settling (each pose's descent is its own).
    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(12.0)], f)
    calls = {None: 0, settle: 0}

    def attack(mode):
        def progress(_):
            calls[mode] += 1

        return b.attack(holes, 8, 100, 0.05, rng(3), progress=progress, settle=mode)

    plain, settled = attack(None), attack(settle)
    assert plain.beta[1, 0] == 0.0 and settled.beta[1, 0] == 0.0
    assert plain.fits[1, 0] >= 1 and settled.fits[1, 0] >= 1
    # The square's starts: same best pose and scores, bit for bit.
    assert np.array_equal(plain.quats[0], settled.quats[0])
    assert np.array_equal(plain.trans[0], settled.trans[0])
    assert plain.beta[0, 0] == settled.beta[0, 0] > 0
    assert calls[None] == calls[settle] == 100  # one call per step, the last one says "done"


def test_a_descent_whose_holes_all_settle_ends_early(cube20):
    # The 20 mm sphere fits both holes: once each hole has a fitting start the descent is over,
    # long before its 400 steps, and the value of each hole is the 0 it would have been.
    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(10.0)], f)
    done = []
    attack = b.attack(holes, 8, 400, 0.05, rng(4), progress=done.append, settle="hole")
    assert list(attack.value()) == [0.0, 0.0]
    assert done[-1] == 400 and len(done) < 100


def test_settling_needs_a_loss_that_knows_a_fit(cube20):
    # The overlap objective declares no fit_loss: settle is ignored, every start runs its steps.
    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(10.0)], f, objective="overlap")
    done = []
    b.attack(holes, 2, 20, 0.05, rng(5), progress=done.append, settle="hole")
    assert done == list(range(1, 21))


def test_a_start_that_fits_stops_and_still_counts(cube20):
    # The verdict settles each start alone: the 20 mm sphere fits both holes from every start,
    # so every start counts as fitting either way, and the descent ends once all have fitted.
    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(10.0)], f)
    plain = b.attack(holes, 8, 300, 0.05, rng(6))
    done = []
    alone = b.attack(holes, 8, 300, 0.05, rng(6), progress=done.append, settle="start")
    assert plain.fits.tolist() == alone.fits.tolist() == [[8], [8]]
    assert list(alone.beta[:, 0]) == [0.0, 0.0]
    assert done[-1] == 300 and len(done) < 100


def test_each_candidates_steps_move_the_search_bar(cube20):
    # player A's search reports player B's Adam steps on every candidate hole (candidates x
    # steps): a long first stage (the canonical views, one batch) moves the bar step by step
    f, a, _ = _cube_hole(cube20)
    b = PlayerB([sphere(12.0)], f)
    done = []
    a.on_step = done.append
    quats = np.array(
        [[1.0, 0, 0, 0], [0.8880738339771153, 0.32505758367186816, -0.325057583671868, 0]]
    )
    a.values(b, quats, 2, 7, 0.05, rng(7))
    assert sum(done) == 2 * 7 and all(n % 2 == 0 and n > 0 for n in done)


def test_a_chunked_descent_reports_the_whole_descent_once_per_step():
    from sieve_mi.game.player_b import _chunk_progress

    seen, reached = [], [0]
    for i in range(3):  # three chunks of a 4-step descent, one after another
        share = _chunk_progress(seen.append, i, 3, 4, reached)
        for n in range(1, 5):
            share(n)
    assert seen == [1, 2, 3, 4]  # steps of the whole, each once, the last one "done"
    assert _chunk_progress(None, 0, 3, 4, [0]) is None


def test_converged_starts_leave_the_descent_with_their_best_pose(cube20, monkeypatch):
    # The 24 mm sphere cannot enter the square (12 > 11 mm): every start slides to the same
    # least overhang and stays there. With attack(converged=...) (the verdict's
    # game.verdict.CONVERGED) or game.descent.CONVERGED set for every descent, starts whose best
    # loss stopped falling leave the batch; once all have, the descent ends early with the value
    # it reaches when every start runs every step, and the two ways stop the same starts.
    from sieve_mi.game import descent

    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(12.0)], f)
    runs = {}
    for everywhere, asked in ((None, None), (None, (20, 1e-4)), ((20, 1e-4), None)):
        monkeypatch.setattr(descent, "CONVERGED", everywhere)
        done = []
        attack = b.attack(holes[:1], 8, 300, 0.05, rng(7), progress=done.append, converged=asked)
        runs[everywhere, asked] = (float(attack.beta[0, 0]), done)
    (full, every), (early, stopped), same = runs.values()
    assert len(every) == 300 and stopped[-1] == 300 and len(stopped) < 300
    assert full > 0 and early == pytest.approx(full, rel=0.01)
    assert same == (early, stopped)


def test_the_placements_long_attack_stops_converged_starts_as_the_verdict(cube20, monkeypatch):
    # The placement re-ranks its finalists with the verdict's attack, and now stops its
    # converged starts as the verdict does (PlacementContext.converged): on the face-on cube's
    # square hole the 24 mm sphere is blocked (12 > 11 mm), so no start settles, every start
    # slides to the same least overhang, and the descent ends early with the same β.
    from sieve_mi.game import descent
    from sieve_mi.game.placement import PlacementContext, _PlacementGame
    from sieve_mi.game.verdict import CONVERGED
    from sieve_mi.scene import Layout

    f, a, _ = _cube_hole(cube20, resolution=64)
    steps_run, run = [], descent.Descent.run

    def counted(self, steps, progress=None, freeze=None):
        seen = []
        out = run(self, steps, seen.append, freeze)
        steps_run.append(seen)
        return out

    monkeypatch.setattr(descent.Descent, "run", counted)
    x = np.array([[1.0, 0, 0, 0, 0, 0]])  # the cube face-on at the centre
    got = []
    for converged in (None, CONVERGED):
        ctx = PlacementContext(PlayerB([sphere(12.0)], f), tiny_solver(), Layout(), rng(3))
        ctx.converged = converged
        game = _PlacementGame(a, np.zeros((64, 64), bool), f.half_extent / 2, ctx)
        got.append(game.energy(x, 8, 300, ctx.converged)[1][0])
    (full, early), (every, stopped) = got, steps_run
    # blocked either way, β within 10 % (the bound the issue sets for a lever; on the GPU Adam's
    # last steps wander by a few %: 0.0265 against 0.0283 on an H200, 2026-12-04)
    assert full > 0 and early == pytest.approx(full, rel=0.1)
    assert len(every) == 300 and stopped[-1] == 300 and len(stopped) < 300


def test_successive_halving_keeps_each_pairs_better_half(cube20, monkeypatch):
    # [solver] halving = 0.25 (issue 45's successive halving of starts): after 25, 50 and 75 of
    # 100 steps the worse half of each (hole, B)'s starts, by best loss so far, stop (10 -> 5
    # -> 3 -> 2): masked out of the step, and out of the batch once at most half of it
    # descends (at 25 and 75: 40 -> 20 -> 8 poses). The square blocks the 24 mm sphere (12 >
    # 11 mm: it sticks out by 1 mm) and the hexagon admits it (12 < 15.1 mm); the 20 mm sphere
    # fits both. A start that survives every rung descends as it does without halving, to the
    # bit; the β of every (hole, B) stays within 10 % (the bound for a lever).
    from dataclasses import replace

    from sieve_mi.game import descent
    from sieve_mi.game.attack import Starts

    f, holes = _two_holes(cube20)
    b = PlayerB([sphere(12.0), sphere(10.0)], f)
    batch = b.start_batch(holes, Starts(10), rng(5), None)
    left, shrink = [], descent.Descent.shrink

    def counted(self, live):
        left.append(int(live.sum()))
        return shrink(self, live)

    monkeypatch.setattr(descent.Descent, "shrink", counted)
    full = b.descend(batch, 100, 0.05)
    halved = b.descend(replace(batch, halving=0.25), 100, 0.05)
    assert left == [20, 8]
    same = np.all(full[0] == halved[0], axis=1) & np.all(full[1] == halved[1], axis=1)
    assert np.array_equal(np.unique(batch.pose_hole[same] * 2 + batch.pose_shape[same]), range(4))
    scores = [b._score(batch, *poses) for poses in (full, halved)]
    (beta, prot), (beta_h, prot_h) = ((s.beta, s.protrusion) for s in scores)
    assert beta[0, 0] > 0 and beta_h[0, 0] == pytest.approx(beta[0, 0], rel=0.1)
    assert prot_h[0, 0] == pytest.approx(1.0, abs=1.5 * f.pixel_size)
    assert beta[1].tolist() == beta_h[1].tolist() == [0.0, 0.0] and beta_h[0, 1] == 0.0
