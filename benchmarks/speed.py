"""Frozen vs traced Adam steps, and the objectives end to end: ratios measured in one run.

Usage: ``python -m benchmarks.speed [--variant V] [--scenes A.toml,B.toml] [--repeat R] [--objectives LIST]``

First the cost of one Adam step, traced and frozen, at 10, 100 and 1,000 poses. Then for each
scene (default ``scenes/default.toml``, cube vs sphere, and ``scenes/spot-vs-cow.toml``;
the paper's settings):

1. **Frozen vs traced** (``[solver] freeze``): solves it with ``freeze = false`` and ``true``,
   interleaved, ``R`` times each after one warm-up solve of each, and prints the minimum search,
   verdict and total times (the least disturbed run on a shared machine), their ratios, and
   whether every run gave the same winner, β, protrusion and A rotation (they must: the frozen
   step is the traced one, replayed).
2. **Objectives end to end**: the same with each of ``--objectives`` (default
   ``clearance,overlap``; ``overlap-mitsuba`` takes about an hour per run on a 2-core CPU; ``""``
   skips this part), times relative to the first. The verdict always attacks with ``clearance``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def solve_once(scene, variant: str, **solver):
    """Solve ``scene`` with ``[solver]`` keys replaced by ``solver``; (result, seconds)."""
    from sieve_mi.api import solve

    changed = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, **solver))
    t = time.perf_counter()
    result = solve(changed, variant=variant, progress=False)
    return result, time.perf_counter() - t


def summary(result) -> tuple:
    """What must agree between runs: winner, β, protrusion, A's rotation."""
    return (
        result.winner,
        tuple(np.round(result.attack.beta.ravel(), 9)),
        tuple(np.round(result.attack.protrusion.ravel(), 9)),
        tuple(np.round(np.asarray(result.pass_quats).ravel(), 9)),
    )


def times(result, total: float) -> tuple[float, float, float]:
    return result.timings.get("search_s", 0.0), result.timings.get("verdict_s", 0.0), total


def compare(scene, variant: str, key: str, values: list, repeat: int) -> dict:
    """Solve ``scene`` with ``[solver] key`` at each of ``values``, interleaved, ``repeat`` times.

    Returns ``{value: (min times (search, verdict, total), set of outcomes)}``; the minimum is the
    least disturbed run on a shared machine (all noise is added time).
    """
    runs = {v: [] for v in values}
    outcomes = {v: set() for v in values}
    for v in values:  # warm-up: compile kernels (and record frozen steps)
        solve_once(scene, variant, **{key: v})
    for _ in range(repeat):
        for v in values:
            result, total = solve_once(scene, variant, **{key: v})
            runs[v].append(times(result, total))
            outcomes[v].add(summary(result))
    return {v: (np.min(np.array(runs[v]), axis=0), outcomes[v]) for v in values}


def step_times(variant: str, poses=(10, 100, 1000), steps: int = 100) -> None:
    """Print ms per Adam step, traced and frozen, for K cube-hole/sphere poses (one run).

    Each is :func:`benchmarks.objectives.step_time` with ``skip = 2``: (time of ``2 + steps``
    steps - time of 2 steps) / ``steps``, the minimum of 3, after a warm-up descent that compiles
    the kernels and records the frozen step; a descent's set-up and its two traced first steps are
    left out.
    """
    from benchmarks.objectives import step_time
    from sieve_mi.game.frames import hole_frame
    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB
    from sieve_mi.geometry.meshes import load_shape

    def rng():
        return np.random.default_rng(0)

    meshes = os.path.join(ROOT, "scenes", "meshes")
    a, b = (load_shape(os.path.join(meshes, n)) for n in ("cube.stl", "sphere.stl"))
    frame = hole_frame(a, 1.0, 256)
    hole = PlayerA(a, frame, 1.0).holes(np.array([[1.0, 0, 0, 0]]))[0]
    print(f"\nms per Adam step, cube hole vs sphere (clearance, {steps} steps)")
    print(f"{'poses':>6s} {'traced':>8s} {'frozen':>8s} {'traced / frozen':>16s}")
    for k in poses:
        ms = {
            f: 1e3 * step_time(PlayerB([b], frame, "clearance", freeze=f), hole, k, steps, rng(), 2)
            for f in (0, 1)
        }
        print(f"{k:6d} {ms[0]:8.2f} {ms[1]:8.2f} {ms[0] / ms[1]:15.2f}x")


def table(name: str, rows: dict, base) -> None:
    """Print one comparison: min times per setting and ratios to ``base``."""
    print(f"{name:16s} {'search s':>9s} {'verdict s':>10s} {'total s':>8s}  ratios to {base}")
    ref = rows[base][0]
    for value, (t, outcomes) in rows.items():
        r = t / ref
        winner = ", ".join(sorted({o[0] for o in outcomes}))
        print(
            f"{str(value):16s} {t[0]:9.2f} {t[1]:10.2f} {t[2]:8.2f}  "
            f"{r[0]:.2f}x {r[1]:.2f}x {r[2]:.2f}x  winner {winner}"
        )


def main(argv=None) -> int:
    import sieve_mi  # noqa: F401
    from sieve_mi.scene import load_scene

    p = argparse.ArgumentParser(description="frozen vs traced steps; objectives end to end")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument(
        "--scenes",
        default=",".join(
            os.path.join(ROOT, "scenes", s) for s in ("default.toml", "spot-vs-cow.toml")
        ),
    )
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--objectives", default="clearance,overlap")
    args = p.parse_args(argv)
    from benchmarks.run import machine

    print(
        f"Machine: {machine()}; variant {args.variant}; minimum of {args.repeat} interleaved runs"
    )
    from sieve_mi.backend import use_variant

    use_variant(args.variant)
    step_times(args.variant)
    same = True
    for path in args.scenes.split(","):
        scene = load_scene(path)
        print(f"\n{os.path.basename(path)}")
        rows = compare(scene, args.variant, "freeze", [False, True], args.repeat)
        table("freeze", rows, False)
        agree = len(rows[False][1] | rows[True][1]) == 1
        print(f"same results frozen and traced, every run: {agree}")
        same = same and agree
        names = [n for n in args.objectives.split(",") if n]
        if names:  # --objectives "" measures frozen vs traced only
            rows = compare(scene, args.variant, "objective", names, args.repeat)
            table("objective", rows, names[0])
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
