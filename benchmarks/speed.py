"""Frozen vs traced Adam steps, and the objectives end to end: ratios measured in one run.

Usage: ``python -m benchmarks.speed [--variant V] [--scene PATH] [--repeat R] [--objectives LIST]``

1. **Frozen vs traced** (``[solver] freeze``): solves the scene (default ``scenes/default.toml``,
   cube vs sphere, the paper's settings) with ``freeze = true`` and ``freeze = false``,
   alternating, ``R`` times each after one warm-up solve of each, and prints the median search,
   verdict and total times, their ratios, and whether both gave the same winner, β, protrusion
   and A rotation (they must: the frozen step is the traced one, replayed).
2. **Objectives end to end**: the same scene with each of ``--objectives`` (default
   ``clearance,overlap``; ``overlap-mitsuba`` takes about an hour on a 2-core CPU), once each after
   the runs above, with their search time relative to ``clearance``. The verdict always attacks
   with ``clearance``.
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
    from sieve_mi.solver import solve

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


def main(argv=None) -> int:
    import sieve_mi  # noqa: F401
    from sieve_mi.scene import load_scene

    p = argparse.ArgumentParser(description="frozen vs traced steps; objectives end to end")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--scene", default=os.path.join(ROOT, "scenes", "default.toml"))
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--objectives", default="clearance,overlap")
    args = p.parse_args(argv)
    scene = load_scene(args.scene)
    from benchmarks.run import machine

    print(f"Machine: {machine()}; variant {args.variant}; scene {os.path.basename(args.scene)}")
    rows = {True: [], False: []}
    outcome = {}
    for freeze in (True, False):  # warm-up: compile kernels, record the frozen steps
        solve_once(scene, args.variant, freeze=freeze)
    for _ in range(args.repeat):
        for freeze in (True, False):
            result, total = solve_once(scene, args.variant, freeze=freeze)
            rows[freeze].append(times(result, total))
            outcome.setdefault(freeze, set()).add(summary(result))
    med = {f: np.median(np.array(r), axis=0) for f, r in rows.items()}
    print(f"{'steps':8s} {'search s':>9s} {'verdict s':>10s} {'total s':>8s}")
    for freeze in (False, True):
        s, v, t = med[freeze]
        print(f"{'frozen' if freeze else 'traced':8s} {s:9.2f} {v:10.2f} {t:8.2f}")
    ratio = med[False] / med[True]
    print(f"{'ratio':8s} {ratio[0]:8.2f}x {ratio[1]:9.2f}x {ratio[2]:7.2f}x  (traced / frozen)")
    same = len(outcome[True] | outcome[False]) == 1
    print(f"same results frozen and traced, every run: {same}")
    base = None
    print(f"{'objective':16s} {'search s':>9s} {'verdict s':>10s} {'ratio':>7s} winner  β")
    for name in args.objectives.split(","):
        result, total = solve_once(scene, args.variant, objective=name)
        s, v, _ = times(result, total)
        base = s if base is None else base
        beta = ", ".join(f"{b:.3f}" for b in result.attack.beta.ravel())
        print(f"{name:16s} {s:9.2f} {v:10.2f} {s / base:6.2f}x {result.winner:6s}  {beta}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
