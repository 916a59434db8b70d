"""The cost of deterministic reductions and of drjit.opt.Adam: before and after, in one run.

Usage: ``python -m benchmarks.determinism [--variant V] [--poses K] [--steps N] [--repeat R]``

"Before" is sieve-mi's player B up to issue 17, kept here only as a reference: per-pose losses
summed with ``dr.scatter_reduce(Add)`` and gradients from AD, whose backward pass turns each
per-sample gather of a pose's rotation and translation into an atomic scatter-add (summation order
set by thread scheduling), and a hand-written Adam. "After" is the package: per-pose sums in a
fixed order (:meth:`sieve_mi.objectives.clearance.ClearanceObjective._pose_sums`) and ``drjit.opt.Adam``.

For each B shape (K poses against ten 22 mm cube holes, as in one PSO iteration of the default scene) it prints the median
time of one loss + gradient evaluation, of a whole descent of N Adam steps, the median best loss
per start after the descent, and how many distinct results R repeated descents gave.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHAPES = [
    ("sphere 1,280 faces", os.path.join(ROOT, "scenes", "meshes", "sphere.stl"), 1.0),
    ("cow 5,804 faces", os.path.join(ROOT, "scenes", "meshes", "cow.obj"), 4.2),
    ("bunny 69,451 faces", os.path.join(HERE, "meshes", "stanford-bunny.obj"), 250.0),
]


def atomic_loss(obj, q, t, holes, pose_hole):
    """The clearance loss as it was: AD through per-sample gathers, atomic per-pose sums."""
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.geometry.rotations import quat_rows

    pair_pose, pair_seg = obj.pairs
    rows = quat_rows(*q)
    active = obj.active_pairs(q)
    if dr.width(active) == 0:
        zero = dr.zeros(mi.Float, obj.pose_count)
        return dr.sum(zero), zero
    idx = dr.arange(mi.UInt32, dr.width(active) * obj.samples)
    pair = dr.gather(mi.UInt32, active, idx // obj.samples)
    frac = (mi.Float(idx % obj.samples) + 0.5) / obj.samples
    pose = dr.gather(mi.UInt32, pair_pose, pair)
    seg = dr.gather(mi.UInt32, pair_seg, pair)
    p = dr.gather(mi.Vector3f, obj.a, seg) + dr.gather(mi.Vector3f, obj.d, seg) * frac
    g = [dr.gather(mi.Float, r, pose) for r in rows[:6]]
    x = g[0] * p.x + g[1] * p.y + g[2] * p.z + dr.gather(mi.Float, t[0], pose)
    y = g[3] * p.x + g[4] * p.y + g[5] * p.z + dr.gather(mi.Float, t[1], pose)
    dist = obj.hole_distance(x, y, holes, dr.gather(mi.UInt32, pose_hole, pose))[0]
    value = dist * dist
    per_pose = dr.zeros(mi.Float, obj.pose_count)
    dr.scatter_reduce(dr.ReduceOp.Add, per_pose, dr.detach(value), pose)
    return dr.sum(value), per_pose


def hand_adam_descend(player, holes, pose_hole, q0, t0, steps, lr, loss_fn=atomic_loss):
    """Player B's descent as it was (hand-written Adam); best pose per start, (K, 6) scene units."""
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.geometry.hole import HoleStack
    from sieve_mi.geometry.rotations import normalize

    obj, stack, scale = player.objective, HoleStack(holes), player.frame.half_extent
    x0 = np.concatenate([q0, np.asarray(t0) / scale], axis=1).astype(np.float32)
    params = [mi.Float(x0[:, i]) for i in range(6)]
    m = [dr.zeros(mi.Float, len(q0)) for _ in params]
    v = [dr.zeros(mi.Float, len(q0)) for _ in params]
    hole_idx = mi.UInt32(np.asarray(pose_hole).astype(np.uint32))
    best, best_loss = [dr.detach(p) for p in params], dr.full(mi.Float, np.inf, len(q0))
    for step in range(1, steps + 1):
        for p in params:
            dr.enable_grad(p)
        q, t = tuple(params[:4]), (params[4] * scale, params[5] * scale)
        total, per_pose = loss_fn(obj, q, t, stack, hole_idx)
        dr.backward(total)
        improved = per_pose < best_loss
        best = [dr.select(improved, dr.detach(p), b) for p, b in zip(params, best)]
        best_loss = dr.select(improved, per_pose, best_loss)
        lr_t = dr.opaque(mi.Float, lr * np.sqrt(1 - 0.999**step) / (1 - 0.9**step))
        for i, p in enumerate(params):
            g = dr.grad(p)
            m[i] = 0.9 * m[i] + 0.1 * g
            v[i] = 0.999 * v[i] + 0.001 * dr.square(g)
            params[i] = dr.detach(p) - lr_t * m[i] / (dr.sqrt(v[i]) + 1e-8)
        norm = dr.rsqrt(sum(dr.square(p) for p in params[:4]))
        params[:4] = [p * norm for p in params[:4]]
        dr.eval(params, best, best_loss, m, v)
    x = np.stack([np.asarray(b, dtype=np.float64) for b in best], axis=1)
    return np.concatenate([normalize(x[:, :4]), x[:, 4:] * scale], axis=1)


def setup(path, scale, poses, rng):
    """Ten holes (a 20 mm cube + 1 mm, random rotations), a player B for one shape, K poses.

    Like one PSO iteration of the default scene: pose k is tested against hole k % 10.
    """
    import trimesh

    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB
    from sieve_mi.game.solver import hole_frame
    from sieve_mi.geometry.meshes import load_shape, shape_from_trimesh
    from sieve_mi.geometry.rotations import random_uniform

    cube = shape_from_trimesh(trimesh.creation.box((20.0, 20.0, 20.0)), name="cube")
    frame = hole_frame(cube, 1.0, 256)
    holes = PlayerA(cube, frame, 1.0).holes(random_uniform(10, rng))
    player = PlayerB([load_shape(path, scale=scale)], frame)
    q0 = random_uniform(poses, rng)
    t0 = rng.uniform(-0.1, 0.1, (poses, 2)) * frame.half_extent
    return player, holes, q0, t0


def time_loss(player, holes, q0, t0, loss_fn, repeat):
    """Median seconds of one loss + backward over the K poses."""
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.geometry.hole import HoleStack

    obj, stack = player.objective, HoleStack(holes)
    obj.bind(np.zeros(len(q0), int))
    pose_hole = mi.UInt32(np.arange(len(q0), dtype=np.uint32) % len(holes))
    times = []
    for _ in range(repeat + 1):
        q = [mi.Float(q0[:, i].astype(np.float32)) for i in range(4)]
        t = [mi.Float(t0[:, i].astype(np.float32)) for i in range(2)]
        dr.enable_grad(q, t)
        start = time.perf_counter()
        total, per_pose = loss_fn(obj, tuple(q), tuple(t), stack, pose_hole)
        dr.backward(total)
        dr.eval(per_pose, [dr.grad(x) for x in q + t])
        times.append(time.perf_counter() - start)
    return float(np.median(times[1:]))


def descents(player, holes, q0, t0, steps, repeat, config: str):
    """Median seconds per descent, best losses per start, number of distinct results.

    ``config``: "before" (atomic loss, hand-written Adam), "fixed order + hand Adam", or
    "after" (the package's :meth:`~sieve_mi.game.player_b.PlayerB.descend`).
    """
    import drjit as dr
    import mitsuba as mi

    from sieve_mi.game.descent import Batch
    from sieve_mi.geometry.hole import HoleStack
    from sieve_mi.objectives.clearance import ClearanceObjective

    zeros = np.zeros(len(q0), int)
    pose_hole = np.arange(len(q0)) % len(holes)
    times, results = [], set()
    for _ in range(repeat):
        start = time.perf_counter()
        if config == "after":
            qs, ts = player.descend(Batch(holes, pose_hole, zeros, q0, t0), steps, 0.05)
            x = np.concatenate([qs, ts], axis=1)
        else:
            player.objective.bind(zeros)
            fn = atomic_loss if config == "before" else ClearanceObjective.loss
            x = hand_adam_descend(player, holes, pose_hole, q0, t0, steps, 0.05, fn)
        times.append(time.perf_counter() - start)
        results.add(x.tobytes())
    obj = player.objective
    qs = [mi.Float(x[:, i].astype(np.float32)) for i in range(4)]
    ts = (mi.Float(x[:, 4].astype(np.float32)), mi.Float(x[:, 5].astype(np.float32)))
    ph = mi.UInt32(pose_hole.astype(np.uint32))
    losses = obj.loss(tuple(qs), ts, HoleStack(holes), ph)[1].numpy()
    dr.eval()
    return float(np.median(times)), losses, len(results)


def main(argv=None) -> int:
    import sieve_mi  # noqa: F401
    from sieve_mi.backend import use_variant

    p = argparse.ArgumentParser(description="deterministic reductions and drjit.opt.Adam: cost")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--poses", type=int, default=100)
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    use_variant(args.variant)
    from sieve_mi.objectives.clearance import ClearanceObjective

    print(f"variant {args.variant}, {args.poses} poses, {args.steps} Adam steps, x{args.repeat}")
    print(
        "| B shape | configuration | loss + gradient ms | descent s | starts that fit "
        "| median loss of the others (px²) | distinct results |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    configs = {"before": atomic_loss, "fixed order + hand Adam": None, "after": None}
    for name, path, scale in SHAPES:
        player, holes, q0, t0 = setup(path, scale, args.poses, np.random.default_rng(0))
        for config, fn in configs.items():
            if fn is None and config != "after":
                loss_ms = "="
            else:
                fn = fn or ClearanceObjective.loss
                loss_ms = f"{time_loss(player, holes, q0, t0, fn, args.repeat) * 1e3:.1f}"
            sec, losses, distinct = descents(player, holes, q0, t0, args.steps, args.repeat, config)
            rest = losses[losses > 0]
            print(
                f"| {name} | {config} | {loss_ms} | {sec:.2f} | {int((losses == 0).sum())} "
                f"| {np.median(rest) if len(rest) else 0:.4g} | {distinct} of {args.repeat} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
