"""Clearance versus overlap: cost of one Adam step of player B, measured in one run.

Usage: ``python -m benchmarks.objectives [--variant V] [--poses K] [--resolution N]``

Times one batched Adam step (forward + backward + update) for K poses of each B shape against the
hole of scene's A, for both objectives, and prints the ratio. The overlap objective renders one
pose at a time, so its cost grows linearly with K.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
MESHES = os.path.join(os.path.dirname(HERE), "scenes", "meshes")
PAIRS = [("cube.stl", 1.0, "sphere.stl", 1.0), ("spot.obj", 23.0, "cow.obj", 4.2)]


def step_time(player_b, hole, poses: int, steps: int, rng) -> float:
    """Seconds per Adam step (median over ``steps`` steps after one warm-up step)."""
    k = poses
    q0 = np.tile([1.0, 0, 0, 0], (k, 1)) + rng.normal(0, 0.3, (k, 4))
    t0 = rng.uniform(-0.1, 0.1, (k, 2)) * hole.frame.half_extent
    zeros = np.zeros(k, int)
    player_b.descend([hole], zeros, zeros, q0, t0, 1, 0.05)  # compile
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        player_b.descend([hole], zeros, zeros, q0, t0, 1, 0.05)
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main(argv=None) -> int:
    import sieve_mi  # noqa: F401
    from sieve_mi.backend import use_variant

    p = argparse.ArgumentParser(description="clearance vs overlap step cost")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--poses", type=int, default=10)
    p.add_argument("--resolution", type=int, default=256)
    p.add_argument("--steps", type=int, default=3)
    args = p.parse_args(argv)
    use_variant(args.variant)
    from sieve_mi.layout import hole_frame
    from sieve_mi.meshes import load_shape
    from sieve_mi.players import PlayerA, PlayerB

    rng = np.random.default_rng(0)
    print(f"variant {args.variant}, {args.poses} poses per step, {args.resolution}^2 raster")
    print(f"{'pair':22s} {'clearance s/step':>17s} {'overlap s/step':>15s} {'ratio':>8s}")
    for a_name, a_scale, b_name, b_scale in PAIRS:
        a = load_shape(os.path.join(MESHES, a_name), scale=a_scale)
        b = load_shape(os.path.join(MESHES, b_name), scale=b_scale)
        frame = hole_frame(a, 1.0, args.resolution)
        hole = PlayerA(a, frame, 1.0).holes(np.array([[1.0, 0, 0, 0]]))[0]
        tc = step_time(PlayerB([b], frame, "clearance"), hole, args.poses, args.steps, rng)
        to = step_time(PlayerB([b], frame, "overlap"), hole, args.poses, args.steps, rng)
        print(f"{a.name + ' / ' + b.name:22s} {tc:17.4f} {to:15.3f} {to / tc:8.0f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
