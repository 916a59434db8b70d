"""One A against many real-mesh B, each holding a ball just wider than any hole A can make.

Usage: ``python -m benchmarks.many_b [--counts 1,10,20,50] [--no-screen] [--no-prune] [--no-reuse]
[--stand-in MM] [--profile N] [--out PNG] [--json ROWS]``

A: a 20 mm ball (an icosphere of radius 10, 1,280 faces); ``[fabrication] tolerance`` at its
default. B: the closed real meshes of 5.8k-13k faces that exist here, cycled: the cow (5,804
faces) and spot (5,856; closed once its seam vertices are welded, as every loaded mesh is) from
``scenes/meshes/``, the fandisk (12,946) from ``../shared/meshes/`` (or its copy in
``benchmarks/meshes/``). There are only three, so B number ``j`` is mesh ``j % 3`` turned by a
seeded random rotation (none for the first three): scaled/rotated copies, not distinct meshes.
Each B is scaled so that its certified inscribed ball (:func:`sieve_mi.certify.bounds.inscribed_ball`
of the rotated mesh) has radius ``A radius + tolerance + 0.5`` (0.5 mm wider than the hole's
disk): every B must be blocked, and each is proved so by its ball (the issue's failing case).

Each count runs in its own process (its peak RSS is its own), at ``nice -n 10`` if asked by the
caller; the table gives report.json's ``timings`` by stage, the winner, how many B were proved
and the peak RSS, with the load average before and after. ``--no-prune`` turns player A's maximin
pruning off (:data:`sieve_mi.game.maximin.PRUNE`: every candidate attacked by every B), to
measure it; ``--no-reuse`` turns off the reuse of player B's attacks across congruent holes
(:data:`sieve_mi.game.reuse.REUSE`: every hole a full multi-start attack); each row counts player
B's work, pose x Adam steps over every descent of the solve and of player A's search alone, and
with reuse the search's classes and holes; ``--json`` appends the rows to a file, so that runs with and without the screen make
one plot. ``--profile N`` runs count N in this
process under cProfile and prints the 25 most expensive functions (cumulative).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "meshes")
#: The closed meshes of 5.8k-13k faces (file names; looked up in MESH_DIRS).
MESHES = ["cow.obj", "spot.obj", "fandisk.obj"]
MESH_DIRS = [os.path.join(ROOT, "scenes", "meshes"), SHARED, os.path.join(HERE, "meshes")]
#: Radius of A (the ball), mm; the B's balls are this + tolerance + WIDER.
RADIUS, WIDER = 10.0, 0.5


def _path(name: str) -> str:
    """The mesh file ``name`` in the first of :data:`MESH_DIRS` that holds it."""
    for folder in MESH_DIRS:
        if os.path.exists(os.path.join(folder, name)):
            return os.path.join(folder, name)
    raise FileNotFoundError(name)


def blocks(count: int, target: float) -> list[dict]:
    """``count`` B entries (mesh, name, scale), each scaled so its inscribed ball's radius is
    ``target`` (mm)."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from sieve_mi.certify.bounds import inscribed_ball
    from sieve_mi.geometry.meshes import load_trimesh, shape_from_trimesh

    out = []
    for j in range(count):
        name = MESHES[j % len(MESHES)]
        mesh = load_trimesh(_path(name))
        if j >= len(MESHES):
            turn = Rotation.random(random_state=j).as_matrix()
            mesh = trimesh.Trimesh(mesh.vertices @ turn.T, mesh.faces, process=False)
        ball = inscribed_ball(shape_from_trimesh(mesh, name="probe"))
        if ball is None:
            raise RuntimeError(f"{name}: not closed, no inscribed ball")
        stem = os.path.splitext(name)[0]
        out.append({"mesh": mesh, "name": f"{stem}_{j}", "scale": target / ball[1]})
    return out


def scene(count: int, screen: bool = True, stand_in: float = 0.0):
    """The scene with ``count`` B (``[solver] screen`` and ``stand_in`` as given)."""
    import trimesh

    import sieve_mi as sm
    from sieve_mi.scene import Fabrication

    ball = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
    target = RADIUS + Fabrication().tolerance + WIDER
    s = sm.Scene.from_meshes([{"mesh": ball, "name": "ball"}], blocks(count, target),
                             name=f"ball-vs-{count}")  # fmt: skip
    s.solver.screen = screen
    s.solver.stand_in = stand_in
    return s


def run_one(
    count: int,
    variant: str,
    screen: bool = True,
    stand_in: float = 0.0,
    prune: bool = True,
    reuse: bool = True,
) -> dict:
    """Solve the scene with ``count`` B in this process; its timings, winner, peak RSS and
    player B's pose x Adam steps (every descent)."""
    import resource

    import sieve_mi as sm
    from sieve_mi.game import maximin
    from sieve_mi.game import reuse as reusing
    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB

    maximin.PRUNE = prune
    reusing.REUSE = reuse
    work, searching, classes = [0, 0], [False], []
    descend, search = PlayerB.descend, PlayerA.search

    def counted(self, batch, steps, *args, **kw):
        work[searching[0]] += len(batch) * steps
        return descend(self, batch, steps, *args, **kw)

    def searched(self, *args, **kw):
        searching[0] = True
        try:
            return search(self, *args, **kw)
        finally:
            searching[0] = False
            if self.classes is not None:
                classes.append([len(self.classes.entries), self.classes.placed])

    PlayerB.descend, PlayerA.search = counted, searched

    t0 = time.perf_counter()
    sc = scene(count, screen, stand_in)
    setup = time.perf_counter() - t0
    c0 = time.process_time()
    t0 = time.perf_counter()
    result = sm.solve(sc, variant=variant, progress=False)
    wall = time.perf_counter() - t0
    t = result.timings
    return {
        "count": count,
        "screen": screen,
        "stand_in": stand_in,
        "prune": prune,
        "reuse": reuse,
        "pose_steps": sum(work),
        "search_pose_steps": work[1],
        "classes": classes,
        "faces": int(sum(s.face_count for s in result.block_shapes)),
        "setup_s": round(setup, 1),
        "wall_s": round(wall, 1),
        "cpu_s": round(time.process_time() - c0, 1),
        "timings": {k: round(v, 2) for k, v in t.items()},
        "winner": result.winner,
        "unblocked": sum(not b.blocked for b in result.blocks),
        "proved": sum(c is not None and c.status == "proved" for c in result.certified),
        "beta": [round(float(b), 4) for b in result.attack.beta[0]],
        "peak_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 2),
    }


def plot(rows: list[dict], out: str) -> None:
    """CPU and wall time and peak RSS against the number of B, with the screen and without (PNG):
    on a shared machine the CPU seconds are the measure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(8, 3.4))

    def kind(r):
        return r["screen"], r.get("stand_in", 0.0), r.get("prune", True), r.get("reuse", False)

    kinds = sorted({kind(r) for r in rows}, reverse=True)
    for (screen, stand, prune, reuse), mark in zip(kinds, ("o-", "^-", "s-", "v-", "d-", "p-")):
        got = [r for r in rows if kind(r) == (screen, stand, prune, reuse)]
        if got:
            row = {"stand_in": stand, "prune": prune, "reuse": reuse}
            label = ("size screen" if screen else "screen = false") + _stand(row)
            n = [r["count"] for r in got]
            line = ax.plot(n, [r["cpu_s"] for r in got], mark, label=label + ", CPU s")[0]
            ax.plot(n, [r["wall_s"] for r in got], mark[0] + ":", color=line.get_color(),
                    alpha=0.6, label=label + ", wall s")  # fmt: skip
            ax2.plot(n, [r["peak_gb"] for r in got], mark, label=label)
    ax.axhline(300, color="grey", lw=0.8, ls=":", label="5 minutes")
    ax.set_ylabel("solve time (s): CPU (solid), wall (dotted)")
    ax2.set_ylabel("peak RSS (GB)")
    for a in (ax, ax2):
        a.set_xlabel("number of B (real meshes, 5.8k-13k faces)")
        a.set_ylim(bottom=0)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("one 20 mm ball against n real meshes (2 shared CPU cores)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def _child(count: int, args) -> dict | None:
    """Run one count in a child process; its row (with the load before and after) or None."""
    cmd = [
        sys.executable,
        "-m",
        "benchmarks.many_b",
        "--one",
        str(count),
        "--variant",
        args.variant,
    ]
    cmd += ["--no-screen"] if args.no_screen else []
    cmd += ["--stand-in", str(args.stand_in)]
    cmd += ["--no-prune"] if args.no_prune else []
    cmd += ["--no-reuse"] if args.no_reuse else []
    before = os.getloadavg()[0]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        print(f"| {count} | failed: {proc.stderr.strip().splitlines()[-1:]} |", flush=True)
        return None
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row["load"] = [round(before, 2), round(os.getloadavg()[0], 2)]
    return row


def _stand(row: dict) -> str:
    """``, stand-in 0.2 mm`` for a row with a stand-in tolerance, ``, no pruning`` for one
    without maximin pruning, ``, reuse`` for one with reuse across congruent holes (rows
    without the key predate it), else ``""``."""
    out = f", stand-in {row['stand_in']:g} mm" if row.get("stand_in") else ""
    out += "" if row.get("prune", True) else ", no pruning"
    return out + (", reuse" if row.get("reuse", False) else "")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--counts", default="1,10,20,50")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--out", help="write the plot here (PNG)")
    p.add_argument("--json", help="write the rows here (JSON; appended to a file that exists)")
    p.add_argument("--no-screen", action="store_true", help="[solver] screen = false")
    p.add_argument("--stand-in", type=float, default=0.0, help="[solver] stand_in, mm")
    p.add_argument("--no-prune", action="store_true", help="no maximin pruning in the search")
    p.add_argument("--no-reuse", action="store_true", help="no reuse across congruent holes")
    p.add_argument("--profile", type=int, help="profile this count in this process")
    p.add_argument("--one", type=int, help=argparse.SUPPRESS)  # the child process's count
    args = p.parse_args(argv)
    if args.one is not None:
        print(json.dumps(run_one(args.one, args.variant, not args.no_screen, args.stand_in,
                                 not args.no_prune, not args.no_reuse)))  # fmt: skip
        return 0
    if args.profile is not None:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.enable()
        row = run_one(args.profile, args.variant, not args.no_screen, args.stand_in,
                      not args.no_prune, not args.no_reuse)  # fmt: skip
        prof.disable()
        print(json.dumps(row))
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
        return 0
    rows = json.load(open(args.json)) if args.json and os.path.exists(args.json) else []
    print("| B | screen | faces of B | wall s | CPU s | pose-steps (search) | timings s | winner | unblocked | "
          "proved | peak GB | load before → after |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for count in [int(c) for c in args.counts.split(",")]:
        r = _child(count, args)
        if r is None:
            continue
        rows.append(r)
        stages = ", ".join(
            f"{k.removesuffix('_s')} {v:g}" for k, v in r["timings"].items() if v >= 0.05
        )  # noqa: E501
        print(f"| {r['count']} | {'on' if r['screen'] else 'off'}{_stand(r)} | {r['faces']:,} | {r['wall_s']} "
              f"| {r['cpu_s']} | {r['pose_steps']:,} ({r['search_pose_steps']:,}) | {stages} | {r['winner']} | {r['unblocked']} | {r['proved']} "
              f"| {r['peak_gb']} | {r['load'][0]} → {r['load'][1]} |", flush=True)  # fmt: skip
        if args.json:
            with open(args.json, "w") as fh:
                json.dump(rows, fh, indent=1)
    if args.out and rows:
        plot(rows, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
