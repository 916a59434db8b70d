"""Time the verdict alone on the placements of a saved ``report.json``.

Run from a checkout's root (it imports that checkout's ``sieve_mi``), e.g. once in an old checkout
and once in the new one, on the same report, to compare verdicts on identical placements::

    python -m benchmarks.verdict scenes/letters.toml out/report.json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("report", help="report.json whose pass rotations/translations are used")
    parser.add_argument("--repeat", type=int, default=2, help="runs (the first compiles kernels)")
    args = parser.parse_args()

    from sieve_mi.backend import use_variant

    use_variant(None)
    from sieve_mi.game.solver import load_shapes
    from sieve_mi.game.verdict import judge
    from sieve_mi.scene import load_scene

    scene = load_scene(args.scene)
    with open(args.report) as f:
        rep = json.load(f)
    passes, blocks = load_shapes(scene)
    quats = np.array([p["rotation"] for p in rep["pass"]])
    trans = np.array([p["translation"] for p in rep["pass"]])
    times = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        v = judge(scene, passes, blocks, quats, trans, np.random.default_rng(0))
        times.append(time.perf_counter() - t0)
    print(
        f"{args.scene}: winner {v.winner}, verdict s {' '.join(f'{t:.2f}' for t in times)}, "
        f"beta {np.round(v.attack.beta[0], 4).tolist()}, "
        f"protrusion {np.round(v.attack.protrusion[0], 3).tolist()}"
    )


if __name__ == "__main__":
    main()
