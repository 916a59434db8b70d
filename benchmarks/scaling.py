"""How the search time grows with the number of shapes to block (paper Fig. 16).

Usage: ``python -m benchmarks.scaling [--variant V] [--max-b 8] [--out docs/img/scaling_b.png]``

A 20 mm cube must pass; 1..max-b shapes must be blocked (spheres, prisms, letters, arch, bowtie,
cycled). Paper settings for the search; the verdict is skipped (it scales the same way).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
MESHES = os.path.join(os.path.dirname(HERE), "scenes", "meshes")
POOL = [
    "sphere.stl",
    "prism.stl",
    "letter_R.stl",
    "arch.stl",
    "bowtie.stl",
    "letter_A.stl",
    "small_sphere.stl",
    "letter_H.stl",
]


def main(argv=None) -> int:
    import sieve_mi  # noqa: F401
    from sieve_mi.backend import use_variant

    p = argparse.ArgumentParser(description="search time against the number of B shapes")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--max-b", type=int, default=8)
    p.add_argument(
        "--out", default=os.path.join(os.path.dirname(HERE), "docs", "img", "scaling_b.png")
    )
    args = p.parse_args(argv)
    use_variant(args.variant)
    from sieve_mi.game.frames import hole_frame
    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB
    from sieve_mi.geometry.meshes import load_shape
    from sieve_mi.scene import Solver

    search = Solver(canonical=0, polish=0)  # the [solver] defaults: the swarm alone

    a = load_shape(os.path.join(MESHES, "cube.stl"))
    frame = hole_frame(a, 1.0, 256)
    rows = []
    print(
        f"variant {args.variant}; search {search.particles} particles x "
        f"{search.iterations + 1} evaluations, {search.starts} starts x {search.steps} steps"
    )
    print(f"{'B shapes':>8s} {'faces':>7s} {'search s':>9s} {'s per B':>8s}")
    for n in range(1, args.max_b + 1):
        blocks = [load_shape(os.path.join(MESHES, POOL[i % len(POOL)])) for i in range(n)]
        pa, pb = PlayerA(a, frame, 1.0), PlayerB(blocks, frame)
        t = time.perf_counter()
        pa.search(pb, search, rng=np.random.default_rng(0), seed=0)
        dt = time.perf_counter() - t
        rows.append((n, sum(b.face_count for b in blocks), dt))
        print(f"{n:8d} {rows[-1][1]:7d} {dt:9.1f} {dt / n:8.1f}", flush=True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 3.2), dpi=120)
    ax.plot([r[0] for r in rows], [r[2] for r in rows], marker="o")
    ax.set_xlabel("number of shapes to block")
    ax.set_ylabel("search time (s)")
    ax.set_title(f"Search time vs |B| ({args.variant})")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"plot: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
