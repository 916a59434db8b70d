"""The default solve with every output, two checkouts alternating: wall and CPU seconds.

Usage: ``python -m benchmarks.default_solve BEFORE AFTER [--runs 3] [--scene scenes/default.toml]
[--label before,after] [--extra "--no-animation"]``

BEFORE and AFTER are sieve-mi checkouts (folders holding ``sieve_mi/``; e.g. ``/work/main`` and
a worktree). Each run is ``python -m sieve_mi solve SCENE --out TMP --quiet`` in a process of its
own, in the checkout's folder and with ``PYTHONPATH`` set to it (``python -m`` puts the working
folder first on ``sys.path``; the header prints which package each checkout imports), the two
alternating (before, after, before, ...), so
a machine's load falls on both alike. Per run: wall seconds, CPU seconds (user + system of the
command and every process it waited for: the pictures' worker included), the load average
before it, report.json's stage timings, the winner and each B's β. Then the medians per
checkout, and whether every run gave the same winner and the same β to 4 digits (a change of
the outputs' pictures must not change the game).

On 2 shared cores the wall time says little: compare the CPU seconds, and re-measure the wall
time on a quiet machine (docs/performance.md, "Current timings: the default scene"). Dr.Jit's
threads wait for work spinning, so on an overloaded machine CPU seconds grow too; ``--extra
"--threads 1"`` measures the work with one kernel thread per process.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

#: report.json's timings shown per run (seconds; ``figure``, ``gif``: the save's wait for them).
STAGES = ("startup", "search", "verdict", "margins", "images", "figure", "animation", "total")


def _commit(tree: str) -> str:
    """The short commit of ``tree`` (with ``+`` when its work tree has changes), or ``?``."""
    try:
        head = subprocess.run(["git", "-C", tree, "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=10).stdout.strip()  # fmt: skip
        dirty = subprocess.run(["git", "-C", tree, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return "?"
    return (head or "?") + ("+" if dirty else "")


def _package(tree: str) -> str:
    """Where ``import sieve_mi`` finds the package when run as the solves are (``python -m``
    puts the working folder first on ``sys.path``: each solve runs in its checkout)."""
    env = {**os.environ, "PYTHONPATH": tree}
    got = subprocess.run([sys.executable, "-c", "import sieve_mi; print(sieve_mi.__file__)"],
                         env=env, cwd=tree, capture_output=True, text=True, timeout=60)  # fmt: skip
    return os.path.dirname(got.stdout.strip()) or "?"


def _children_cpu() -> float:
    """User + system CPU seconds of every child process waited for so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_once(tree: str, scene: str, extra: list[str]) -> dict:
    """One solve of ``scene`` with the checkout ``tree``: its wall and CPU seconds, load,
    report.json's timings, winner and β."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out")
        env = {**os.environ, "PYTHONPATH": tree}
        cmd = [sys.executable, "-m", "sieve_mi", "solve", scene, "--out", out, "--quiet", *extra]
        load = os.getloadavg()[0]
        cpu0, t0 = _children_cpu(), time.perf_counter()
        done = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
        if done.returncode not in (0, 1):
            raise SystemExit(f"{tree}: exit {done.returncode}\n{done.stderr[-2000:]}")
        with open(os.path.join(out, "report.json")) as fh:
            report = json.load(fh)
    t = report["timings"]
    return {
        "wall": wall,
        "cpu": cpu,
        "load": load,
        "timings": {k: t.get(f"{k}_s", 0.0) for k in STAGES},
        "winner": report["winner"],
        "beta": [round(b["beta"], 4) for b in report["block"]],
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("trees", nargs="+", help="checkouts to compare (each a folder with sieve_mi/)")
    p.add_argument("--runs", type=int, default=3, help="runs per checkout (default 3)")
    p.add_argument("--scene", default="scenes/default.toml")
    p.add_argument("--label", default=None, help="comma-separated names (default: before,after)")
    p.add_argument("--extra", default="", help="more options for `sieve-mi solve`")
    args = p.parse_args(argv)
    trees = [os.path.abspath(t) for t in args.trees]
    labels = args.label.split(",") if args.label else ["before", "after", "third", "fourth"]
    scene = os.path.abspath(args.scene)
    print(f"{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}")  # fmt: skip
    for lab, tree in zip(labels, trees):
        print(f"  {lab}: {tree} at {_commit(tree)} (imports {_package(tree)})")
    rows: dict[str, list] = {lab: [] for lab in labels[: len(trees)]}
    head = " ".join(f"{s[:7]:>7}" for s in STAGES)
    print(f"{'tree':8} {'wall':>6} {'CPU':>6} {'load':>5} {head}  winner β")
    for _ in range(args.runs):
        for lab, tree in zip(labels, trees):
            r = run_once(tree, scene, args.extra.split())
            rows[lab].append(r)
            cells = " ".join(f"{r['timings'][s]:7.2f}" for s in STAGES)
            print(f"{lab:8} {r['wall']:6.2f} {r['cpu']:6.2f} {r['load']:5.1f} {cells}  "
                  f"{r['winner']} {r['beta']}", flush=True)  # fmt: skip
    print("medians:")
    for lab, rs in rows.items():
        med = {s: statistics.median(r["timings"][s] for r in rs) for s in STAGES}
        cells = " ".join(f"{med[s]:7.2f}" for s in STAGES)
        wall = statistics.median(r["wall"] for r in rs)
        cpu = statistics.median(r["cpu"] for r in rs)
        print(f"{lab:8} {wall:6.2f} {cpu:6.2f} {'':5} {cells}")
    answers = {(r["winner"], tuple(r["beta"])) for rs in rows.values() for r in rs}
    print("same winner and β in every run" if len(answers) == 1 else f"DIFFERENT: {answers}")
    print(f"load now {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
