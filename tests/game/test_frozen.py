"""Frozen Adam steps (``[solver] freeze``): the same results as traced ones."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from helpers import REPO, rng, sphere

from sieve_mi.game.descent import Batch
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import random_uniform

FRAME = Frame(64, 1.0)


def _holes():
    xc, yc = FRAME.centres()
    xx, yy = np.meshgrid(xc, yc)
    return [
        Hole.from_mask((np.abs(xx) < 0.45) & (np.abs(yy) < 0.3), FRAME),
        Hole.from_mask(xx**2 + yy**2 < 0.4**2, FRAME),
    ]


def _descend(player, steps=12):
    shapes = len(player.shapes)
    k = 2 * shapes * 3  # 2 holes x shapes x 3 starts
    pose_hole = np.repeat(np.arange(2), shapes * 3)
    pose_shape = np.tile(np.repeat(np.arange(shapes), 3), 2)
    q0 = random_uniform(k, rng(4))
    t0 = rng(5).uniform(-0.1, 0.1, (k, 2))
    return player.descend(Batch(_holes(), pose_hole, pose_shape, q0, t0), steps, 0.05)


@pytest.fixture(scope="module")
def shapes():
    box = shape_from_trimesh(trimesh.creation.box((0.7, 0.4, 0.3)), name="box")
    return [sphere(0.35, 2), box]


def test_frozen_steps_give_the_same_poses_as_traced_ones(mi, shapes):
    traced = _descend(PlayerB(shapes, FRAME, freeze=False))
    frozen_player = PlayerB(shapes, FRAME, freeze=True)
    frozen = _descend(frozen_player)
    # every step frozen, the first too: one recording, replayed by the same-sized descent after
    assert frozen_player._frozen is not None and frozen_player._frozen.n_recordings == 1
    again = _descend(frozen_player)  # replayed, not recorded
    assert frozen_player._frozen.n_recordings == 1
    for out in (frozen, again):
        np.testing.assert_array_equal(out[0], traced[0])
        np.testing.assert_array_equal(out[1], traced[1])
    assert not np.allclose(traced[0], _descend(PlayerB(shapes, FRAME), steps=0)[0])  # moved


def test_an_overflowing_buffer_falls_back_to_traced_steps(mi, shapes, monkeypatch):
    from sieve_mi.objectives.clearance import ClearanceObjective

    traced = _descend(PlayerB(shapes, FRAME, freeze=False))
    monkeypatch.setattr(ClearanceObjective, "capacity", lambda self, q: 16)  # far too small
    player = PlayerB(shapes, FRAME, freeze=True)
    out = _descend(player)
    np.testing.assert_array_equal(out[0], traced[0])
    np.testing.assert_array_equal(out[1], traced[1])
    assert player.freeze  # switched back on after the fallback


def test_a_failing_frozen_step_warns_and_traces(mi, shapes, monkeypatch):
    """If Dr.Jit cannot record or replay the step, player B warns once and traces: same poses."""
    import sieve_mi.game.frozen

    traced = _descend(PlayerB(shapes, FRAME, freeze=False))

    def broken():
        def step(*args):
            raise RuntimeError("record(): unsupported operation")

        return step

    monkeypatch.setattr(sieve_mi.game.frozen, "frozen_step", broken)
    player = PlayerB(shapes, FRAME, freeze=True)
    with pytest.warns(RuntimeWarning, match="drjit.freeze failed.*unsupported operation"):
        out = _descend(player)
    np.testing.assert_array_equal(out[0], traced[0])
    np.testing.assert_array_equal(out[1], traced[1])
    assert not player.freeze  # later descents trace without trying again


def test_no_garbage_collection_runs_while_a_step_is_recorded(mi, shapes, monkeypatch):
    """Dr.Jit runs the step's Python code only while it records it: the cyclic collector is off
    there, and afterwards as it was before (on, or off where the caller had turned it off)."""
    import sieve_mi.game.frozen

    log, step = SimpleNamespace(seen=[]), sieve_mi.game.frozen._step

    def spy(*args, **kw):  # (a list in its closure would be part of the recording's key)
        log.seen.append(gc.isenabled())
        return step(*args, **kw)

    monkeypatch.setattr(sieve_mi.game.frozen, "_step", spy)
    _descend(PlayerB(shapes, FRAME, freeze=True))
    assert log.seen == [False] and gc.isenabled()  # one recording, replayed for the later steps
    gc.disable()
    try:
        _descend(PlayerB(shapes, FRAME, freeze=True))
        assert log.seen == [False, False] and not gc.isenabled()
    finally:
        gc.enable()


# A Mitsuba scene that has traced rays, left in a reference cycle (an earlier solve's renderer),
# and a collection that lands while a step is recorded: the scene's release queues a host function
# that the recording refuses from a destructor, and the process aborts (exit -6, "this function
# cannot be recorded!"). The collection is forced inside the recording by the step's spy.
_COLLECTED_WHILE_RECORDING = """
import gc, sys
sys.path[:0] = [{tests!r}, {here!r}]
import drjit as dr, mitsuba as mi
import sieve_mi.game.frozen as frozen
from sieve_mi.backend import default_variant, use_variant
use_variant(default_variant())
from test_frozen import FRAME, PlayerB, _descend, shape_from_trimesh, sphere, trimesh

step = frozen._step
def collecting(*args, **kw):
    gc.set_threshold(1)
    junk = [[i] for i in range(5000)]  # allocations: a collection would run here
    gc.set_threshold(700)
    return step(*args, **kw)
frozen._step = collecting
shapes = [sphere(0.35, 2), shape_from_trimesh(trimesh.creation.box((0.7, 0.4, 0.3)), name="box")]
player = PlayerB(shapes, FRAME, freeze=True)
gc.collect()
gc.set_threshold(10**9)
scene = mi.load_dict({{"type": "scene", "ball": {{"type": "sphere"}}}})
dr.eval(scene.ray_intersect(mi.Ray3f(mi.Point3f(0, 0, -5), mi.Vector3f(0, 0, 1))).t)
cycle = [scene]
cycle.append(cycle)
del scene, cycle
_descend(player)
print("descended")
"""


def test_a_scene_collected_during_a_recording_does_not_abort_the_process():
    here = os.path.dirname(os.path.abspath(__file__))
    code = _COLLECTED_WHILE_RECORDING.format(tests=os.path.dirname(here), here=here)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [REPO, os.environ.get("PYTHONPATH")])),
    }
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300)  # fmt: skip
    assert run.returncode == 0 and run.stdout.strip() == "descended", run.stderr[-2000:]


def test_large_cpu_steps_are_traced(mi, shapes, monkeypatch):
    """On the CPU a descent with more pairs than CPU_FREEZE_PAIRS is traced: same poses."""
    import sieve_mi.game.frozen

    if not mi.variant().startswith("llvm"):
        pytest.skip("a rule of the CPU backend; a GPU freezes steps of every size")

    traced = _descend(PlayerB(shapes, FRAME, freeze=False))
    monkeypatch.setattr(sieve_mi.game.frozen, "CPU_FREEZE_PAIRS", 10)
    player = PlayerB(shapes, FRAME, freeze=True)
    out = _descend(player)
    assert player._frozen is None and player.freeze  # not recorded, still on for smaller ones
    np.testing.assert_array_equal(out[0], traced[0])
    np.testing.assert_array_equal(out[1], traced[1])


@pytest.mark.parametrize("per_edge", [True, False], ids=["per-edge", "per-segment"])
def test_the_fixed_size_loss_equals_the_loss(mi, shapes, per_edge):
    """loss_fixed's active-pair buffer holds the same pairs in the same order: same bits.

    Both layouts of the buffer: expanded from active (pose, edge) pairs, and written per
    (pose, segment) pair (meshes whose edges are about one segment long).
    """
    import drjit as dr

    from sieve_mi.geometry.hole import HoleStack
    from sieve_mi.objectives import make_objective

    obj = make_objective("clearance", shapes, FRAME)
    obj.per_edge = per_edge
    k = 8
    obj.bind(np.arange(k) % 2)
    q = random_uniform(k, rng(9))
    qa = tuple(mi.Float(q[:, i].astype(np.float32)) for i in range(4))
    ta = tuple(mi.Float(rng(10).uniform(-0.3, 0.3, k).astype(np.float32)) for _ in range(2))
    stack, ph = HoleStack(_holes()), mi.UInt32(np.arange(k, dtype=np.uint32) % 2)
    capacity = obj.capacity(qa)
    want = obj.active_pairs(qa).numpy()
    buffer, count, overflow = obj.active_fixed(qa, capacity)
    assert not bool(overflow[0]) and 0 < len(want) < capacity
    np.testing.assert_array_equal(buffer.numpy()[: len(want)], want)
    assert not buffer.numpy()[len(want) :].any()
    poses = obj.pairs[0].numpy()[want]
    np.testing.assert_array_equal(count.numpy(), np.bincount(poses, minlength=k))
    total, per = obj.loss(qa, ta, stack, ph)
    total_f, per_f, overflow = obj.loss_fixed(qa, ta, stack, ph, capacity)
    assert not bool(overflow[0])
    np.testing.assert_array_equal(per_f.numpy(), per.numpy())
    assert float(dr.sum(per)[0]) > 0
    _, _, small = obj.loss_fixed(qa, ta, stack, ph, 8)
    assert bool(small[0])


@pytest.mark.slow
def test_a_frozen_solve_gives_the_same_result(write_scene):
    """Search and verdict with ``[solver] freeze = true``: the traced solve's result, exactly."""
    import os

    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene

    meshes = os.path.abspath(os.path.join(REPO, "scenes", "meshes"))
    body = (
        f'name = "t"\n[[pass]]\nmesh = "{meshes}/cube.stl"\n[[block]]\nmesh = "{meshes}/sphere.stl"\n'
        "[solver]\nresolution = 96\nparticles = 4\niterations = 2\nstarts = 6\nsteps = 40\n"
        "canonical = 4\npolish = 2\n[verdict]\nstarts = 20\nsteps = 120\nresolution = 128\n"
    )
    results = []
    for freeze in ("false", "true"):
        scene = load_scene(
            write_scene(body.replace("steps = 40\n", f"steps = 40\nfreeze = {freeze}\n"))
        )
        results.append(solve(scene, progress=False))
    traced, frozen = results
    assert frozen.winner == traced.winner == "A"
    np.testing.assert_array_equal(frozen.pass_quats, traced.pass_quats)
    np.testing.assert_array_equal(frozen.attack.beta, traced.attack.beta)
    np.testing.assert_array_equal(frozen.attack.protrusion, traced.attack.protrusion)


@pytest.mark.parametrize("interrupt", ["ctrl-c", "sigterm"])
def test_an_interrupt_while_recording_stops_the_run(mi, shapes, monkeypatch, interrupt):
    """Ctrl-C or SIGTERM inside a frozen step's recording: Dr.Jit wraps it in a RuntimeError,
    which must not turn into the trace-instead fallback (the run would go on for minutes)."""
    import drjit as dr

    import sieve_mi.game.frozen
    from sieve_mi.cli import Terminated

    raised = KeyboardInterrupt() if interrupt == "ctrl-c" else Terminated(15)

    def interrupted():
        @dr.freeze
        def step(opt, best, best_loss, *rest):
            raise raised

        return step

    monkeypatch.setattr(sieve_mi.game.frozen, "frozen_step", interrupted)
    player = PlayerB(shapes, FRAME, freeze=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "drjit.freeze failed" warning either
        with pytest.raises(KeyboardInterrupt) as caught:
            _descend(player)
    assert caught.value is raised
    assert player.freeze  # not mistaken for a Dr.Jit failure


@pytest.mark.parametrize("freeze", [False, True])
def test_a_descent_in_chunks_gives_the_same_poses(mi, shapes, freeze):
    """Poses over the memory budget descend in chunks of consecutive poses: same bits."""
    whole = PlayerB(shapes, FRAME, freeze=freeze)
    expected = _descend(whole)
    chunked = PlayerB(shapes, FRAME, freeze=freeze)
    per_pose = chunked.objective.counts
    chunked.max_pairs = int(2.5 * per_pose.max())  # two or three poses per chunk
    k = 2 * len(shapes) * 3
    parts = chunked.chunks(np.tile(np.repeat(np.arange(len(shapes)), 3), 2))
    assert len(parts) >= k // 3 and parts[0].start == 0 and parts[-1].stop == k
    assert all(a.stop == b.start for a, b in zip(parts[:-1], parts[1:]))  # consecutive, no gaps
    got = _descend(chunked)
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_array_equal(got[1], expected[1])


def test_a_pose_larger_than_the_budget_is_refused_in_one_line(mi, shapes):
    from sieve_mi.backend import BYTES_PER_PAIR, pair_budget
    from sieve_mi.errors import SieveError

    player = PlayerB(shapes, FRAME)
    player.memory = (
        (int(player.objective.counts.max()) - 1) * BYTES_PER_PAIR / 2**30
    )  # an explicit GB
    player.max_pairs = pair_budget(player.memory)
    with pytest.raises(SieveError, match=r"\[solver\] memory: one pose of .* needs"):
        _descend(player)


def test_the_default_cap_only_sizes_chunks(mi, shapes):
    """With ``memory = 0`` the CPU cap is no limit: a pose bigger than it gets a chunk alone."""
    player = PlayerB(shapes, FRAME)
    assert player.memory == 0
    player.max_pairs = int(player.objective.counts.max()) - 1
    poses = np.arange(len(shapes)).repeat(3)
    chunks = player.chunks(poses)
    assert [c.start for c in chunks][0] == 0 and chunks[-1].stop == len(poses)
    assert all(a.stop == b.start for a, b in zip(chunks, chunks[1:]))  # consecutive, all covered
    counts = np.asarray(player.objective.counts)[poses]
    for c in chunks:  # over the cap only when one pose alone is
        assert counts[c].sum() <= player.max_pairs or c.stop - c.start == 1


def test_the_default_budget_is_a_share_of_available_memory_capped_on_the_cpu():
    from sieve_mi.backend import (
        BYTES_PER_PAIR,
        CPU_MEMORY_CAP_GB,
        MEMORY_SHARE,
        available_memory,
        pair_budget,
        use_variant,
    )

    use_variant("llvm_ad_mono")
    assert pair_budget(2.0) == 2 * 2**30 // BYTES_PER_PAIR  # an explicit budget is not capped
    free = available_memory()
    assert 0 < free < 1 << 50  # bytes, a real machine's
    share = min(MEMORY_SHARE * free, CPU_MEMORY_CAP_GB * 2**30)
    assert pair_budget(0.0) == pytest.approx(share / BYTES_PER_PAIR, rel=0.2)
    assert pair_budget(0.0) <= CPU_MEMORY_CAP_GB * 2**30 // BYTES_PER_PAIR  # 4M pairs
