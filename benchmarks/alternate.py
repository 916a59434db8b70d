"""Search and verdict CPU seconds of scenes, two or more source trees (or settings) alternating.

Usage::

    python -m benchmarks.alternate [--scenes scenes/letters.toml,...] [--seeds 0] [--rounds 2]
        --run LABEL=TREE[:TABLE.KEY=VALUE,...] --run LABEL=TREE[:...] ... [--json ROWS.json]

Every (round, scene, seed, run) solves in a child process of its own, ``PYTHONPATH`` = the run's
``TREE`` (a checkout: ``/work/main``, ``.``), with ``[verdict] certify = false``, the run's
settings on top, no figure, no animation, no progress. The runs alternate within every round, so
a machine whose load changes shifts them alike. The child measures the CPU seconds of the whole
process (every Dr.Jit thread) around player A's search (``game.solver.search``) and the verdict
(``game.solver._verdict``), with ``time.process_time``; wall seconds too, but on a shared machine
only the CPU seconds compare. The table prints per run and scene the medians over rounds, the
winner and each B's β of the last round (the βs of one tree and seed repeat to the bit), and the
load average before and after.

Issue 45's letters target (seed 0, search + verdict ≤ 20 s on 2 quiet cores) and its guard
(the authors' quick rows keep their winner, each β within 10 %)::

    python -m benchmarks.alternate --rounds 2 --run main=/work/main --run new=. \\
        --scenes scenes/letters.toml,benchmarks/authors/arch-vs-rect-prism.toml,\\
    benchmarks/authors/bowtie-vs-sphere.toml,benchmarks/authors/fig2-beetle-vs-beetle-front.toml
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

#: The child: solve one scene with timers around the search and the verdict; prints one JSON line.
CHILD = r"""
import json, sys, time
from sieve_mi import api
from sieve_mi.game import solver
from sieve_mi.settings import read_value
spent = {}
def timed(name, f):
    def g(*a, **k):
        c, w = time.process_time(), time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            spent[name + "_cpu"] = spent.get(name + "_cpu", 0) + time.process_time() - c
            spent[name + "_wall"] = spent.get(name + "_wall", 0) + time.perf_counter() - w
    return g
solver.search = timed("search", solver.search)
solver._verdict = timed("verdict", solver._verdict)
scene_path, seed, sets = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
scene = api.load_scene(scene_path)
for key, value in [("verdict.certify", False), *sets]:
    table, name = key.split(".")
    setattr(getattr(scene, table), name, value)
c = time.process_time()
r = api.solve(scene, seed=seed, progress=False)
spent["total_cpu"] = time.process_time() - c
spent["winner"] = r.winner
spent["beta"] = [float(x) for x in r.attack.beta[0]]
print(json.dumps(spent))
"""


def parse_run(text: str) -> tuple[str, str, list]:
    """``LABEL=TREE[:TABLE.KEY=VALUE,...]`` as (label, absolute tree, [(key, value)]); values
    are TOML (``0.25``, ``true``, ``"auto"``)."""
    import tomllib

    label, _, rest = text.partition("=")
    tree, _, sets = rest.partition(":")
    pairs = []
    for item in filter(None, sets.split(",")):
        key, _, value = item.partition("=")
        pairs.append((key, tomllib.loads(f"v = {value}")["v"]))
    return label, os.path.abspath(tree or "."), pairs


def solve_in(tree: str, scene: str, seed: int, sets: list) -> dict:
    """One child solve of ``scene`` with the sieve-mi of ``tree``; its JSON, with the load."""
    env = {**os.environ, "PYTHONPATH": tree}
    load = os.getloadavg()[0]
    cmd = [sys.executable, "-c", CHILD, os.path.abspath(scene), str(seed), json.dumps(sets)]
    done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=False)
    if done.returncode not in (0, 3):
        raise RuntimeError(f"{tree} {scene}: {done.stderr.strip().splitlines()[-1:]}")
    row = json.loads(done.stdout.strip().splitlines()[-1])
    row["load"] = [load, os.getloadavg()[0]]
    return row


def table(rows: list[dict]) -> str:
    """Markdown: per scene, seed and run the medians of the rounds."""
    out = [
        "| scene | seed | run | search CPU s | verdict CPU s | search + verdict wall s | winner, β "
        "| load |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    keys = dict.fromkeys((r["scene"], r["seed"], r["run"]) for r in rows)
    for scene, seed, run in keys:
        got = [r for r in rows if (r["scene"], r["seed"], r["run"]) == (scene, seed, run)]
        med = {k: float(np.median([g[k] for g in got])) for k in ("search_cpu", "verdict_cpu")}
        wall = float(np.median([g["search_wall"] + g["verdict_wall"] for g in got]))
        each = " / ".join(f"{g['search_cpu']:.1f}" for g in got)
        beta = ", ".join(f"{b:.4f}" for b in got[-1]["beta"])
        loads = [x for g in got for x in g["load"]]
        out.append(
            f"| {os.path.basename(scene)} | {seed} | {run} | {med['search_cpu']:.1f} ({each}) | "
            f"{med['verdict_cpu']:.1f} | {wall:.1f} | {got[-1]['winner']}, {beta} | "
            f"{min(loads):.1f}–{max(loads):.1f} |"
        )
    return "\n".join(out)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scenes", default="scenes/letters.toml")
    p.add_argument("--seeds", default="0")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--run", action="append", required=True, help="LABEL=TREE[:TABLE.KEY=VALUE,...]")
    p.add_argument("--json", help="write every row here as well")
    args = p.parse_args(argv)
    runs = [parse_run(r) for r in args.run]
    rows = []
    for rnd in range(args.rounds):
        for scene in args.scenes.split(","):
            for seed in (int(s) for s in args.seeds.split(",")):
                for label, tree, sets in runs:
                    t = time.strftime("%H:%M:%S", time.gmtime())
                    row = solve_in(tree, scene, seed, sets)
                    row.update(scene=scene, seed=seed, run=label, round=rnd, utc=t)
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                    if args.json:
                        with open(args.json, "w") as f:
                            json.dump(rows, f, indent=1)
    print(table(rows))


if __name__ == "__main__":
    main()
