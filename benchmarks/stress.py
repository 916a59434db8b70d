"""One A against many real-mesh B (the paper's largest case: one A against 50 random B).

Usage: ``python -m benchmarks.stress [--counts 1,10,20,50] [--variant V] [--out PNG]``

A: a 20 mm ball (an icosphere, 1,280 faces). B: ``n`` closed real meshes of 5.8k-13k faces (the
cow, 5,804 faces, and the fandisk, 12,946 faces, alternating), each scaled so that its thinnest
part holds a ball much larger than any hole the 20 mm ball can make (every B must be blocked).
Each count runs in its own process, so its peak RSS is its own; the table gives search, verdict
and total seconds, the winner, and the peak RSS; ``--out`` plots time and peak against the count.

The authors' code on this case: 6,625 s on one A40 GPU for 50 B (their results.json), 16 of 50 B
left unblocked at their settings; their meshes are Thingi10K downloads, so the correspondence is
by counts and face counts, not by shapes.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
#: (file, scale): the cow is 10.4 x 6.4 x 3.4 units, the fandisk 4.8 x 5.2 x 2.7.
MESHES = [
    (os.path.join(ROOT, "scenes", "meshes", "cow.obj"), 16.0),
    (os.path.join(HERE, "meshes", "fandisk.obj"), 24.0),
]


def scene(count: int, screen: bool = True):
    """The scene with ``count`` B shapes (scales vary by a few percent, so no two are equal)."""
    import trimesh

    import sieve_mi as sm

    ball = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    blocks = []
    for j in range(count):
        path, scale = MESHES[j % len(MESHES)]
        mesh = trimesh.load(path, force="mesh")
        name = f"{os.path.splitext(os.path.basename(path))[0]}_{j}"
        blocks.append({"mesh": mesh, "name": name, "scale": scale * (1.0 + 0.01 * j)})
    s = sm.Scene.from_meshes([ball], blocks, name=f"ball-vs-{count}")
    s.fabrication.tolerance = 0.5
    s.solver.screen = screen
    return s


def run_one(count: int, variant: str, screen: bool = True) -> dict:
    """Solve the scene with ``count`` B in this process; its times, winner and peak RSS."""
    import resource

    import sieve_mi as sm

    result = sm.solve(scene(count, screen), variant=variant, progress=False)
    t = result.timings
    return {
        "count": count,
        "faces": int(sum(s.face_count for s in result.block_shapes)),
        "search_s": round(t["search_s"], 1),
        "verdict_s": round(t["verdict_s"], 1),
        "total_s": round(sum(t.values()), 1),
        "winner": result.winner,
        "unblocked": sum(not b.blocked for b in result.blocks),
        "proved": sum(c is not None and c.status == "proved" for c in result.certified),
        "peak_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 2),
    }


def plot(rows: list[dict], out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r["count"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(n, [r["search_s"] + r["verdict_s"] for r in rows], "o-", label="search + verdict (s)")
    ax.set_xlabel("number of B shapes (5.8k-13k faces each)")
    ax.set_ylabel("seconds")
    ax2 = ax.twinx()
    ax2.plot(n, [r["peak_gb"] for r in rows], "s--", color="tab:red", label="peak RSS (GB)")
    ax2.set_ylabel("peak RSS (GB)")
    ax.legend(loc="upper left")
    ax2.legend(loc="lower right")
    ax.set_title("one 20 mm ball against n real meshes (2 CPU cores)")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--counts", default="1,10,20,50")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--out", help="write the plot here (PNG)")
    p.add_argument(
        "--no-screen", action="store_true", help="[solver] screen = false: every B plays the game"
    )
    p.add_argument("--one", type=int, help=argparse.SUPPRESS)  # the child process's count
    args = p.parse_args(argv)
    if args.one is not None:
        print(json.dumps(run_one(args.one, args.variant, not args.no_screen)))
        return 0
    rows = []
    print(
        "| B | faces of B | search s | verdict s | total s | winner | unblocked | proved | peak GB |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for count in [int(c) for c in args.counts.split(",")]:
        cmd = [sys.executable, "-m", "benchmarks.stress", "--one", str(count)]
        cmd += ["--no-screen"] if args.no_screen else []
        proc = subprocess.run(
            cmd + ["--variant", args.variant], capture_output=True, text=True, cwd=ROOT
        )
        if proc.returncode != 0:
            print(f"| {count} | failed: {proc.stderr.strip().splitlines()[-1:]} |")
            continue
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(r)
        print(
            f"| {r['count']} | {r['faces']:,} | {r['search_s']} | {r['verdict_s']} | {r['total_s']} "
            f"| {r['winner']} | {r['unblocked']} | {r['proved']} | {r['peak_gb']} |",
            flush=True,
        )
    if args.out and rows:
        plot(rows, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
