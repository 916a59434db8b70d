"""Wall time of sorting all eight euro coins (``scenes/euro-coins-8.toml``): plan before play.

    python -m benchmarks.cascade_coins [--mode serial|ray|both] [--workers 2]

Each run sorts the mixture from an empty game cache into a temporary folder (the Ray run starts
a local Ray, included in its time) and prints the date, the machine (CPUs, processor, load
average before and after), then one row per run: wall seconds, seconds spent measuring the shapes
and deciding the exact rules, holds ruled out, screening and full games played, the trays; then
each game (stage, what it holds, seconds) and each sieve's margin and certified status.
Target (issue "Performance", the cascade part): the eight coins into eight trays in at most 10
minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
MIXTURE = os.path.join(os.path.dirname(HERE), "scenes", "euro-coins-8.toml")


def run(mode: str, workers: int, folder: str) -> tuple[float, dict]:
    """One sort from an empty cache: (wall seconds, cascade.json)."""
    from sieve_mi.cascade.games import EngineSettings
    from sieve_mi.cascade.mixture import load_mixture
    from sieve_mi.cascade.sort import sort_mixture

    t0 = time.perf_counter()
    report = sort_mixture(
        load_mixture(MIXTURE),
        os.path.join(folder, mode),
        engine=EngineSettings(
            use_ray=mode == "ray", workers=workers if mode == "ray" else None, progress=False
        ),
    )
    return time.perf_counter() - t0, report


def rows(mode: str, wall: float, rep: dict) -> list[str]:
    """The run's table row, then one line per game and per sieve."""
    stages = [g["stage"] for g in rep["games"]]
    trays = " / ".join("+".join(t) for t in rep["trays"])
    out = [
        f"| {mode} | {wall:.1f} | {rep['timings']['measure_s']:.1f} | "
        f"{len(rep['rules']['ruled_out'])} | {stages.count('screen')} | {stages.count('full')} | "
        f"{trays} |"
    ]
    for g in rep["games"]:
        out.append(
            f"    {g['stage']:<7}hold {'+'.join(g['holds']):<6} {g['game_s']:7.1f} s  {g['winner']}"
        )
    for s in rep["sieves"]:
        cert = ", ".join(b.get("certified", "-") for b in s["blocks"])
        out.append(
            f"    sieve {s['index'] + 1} holds {'+'.join(s['holds']):<6} protrusion "
            f"{s['margins']['protrusion']:.3f} mm, beta {s['margins']['beta']:.4f}, {cert}"
        )
    return out


def main() -> None:
    import sieve_mi  # noqa: F401  (points Dr.Jit at a usable libLLVM)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", choices=("serial", "ray", "both"), default="serial")
    ap.add_argument("--workers", type=int, default=os.cpu_count())
    args = ap.parse_args()
    modes = ("serial", "ray") if args.mode == "both" else (args.mode,)
    load = os.getloadavg()
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        for mode in modes:
            wall, rep = run(mode, args.workers, tmp)
            lines += rows(mode, wall, rep)
    print(f"date: {datetime.date.today().isoformat()}")
    print(
        f"machine: {platform.node()}, {os.cpu_count()} CPUs, "
        f"{platform.processor() or platform.machine()}; load average before "
        f"{load[0]:.2f}, after {os.getloadavg()[0]:.2f}"
    )
    print(
        "| mode | wall s | measure + rules s | holds ruled out | screening games | full games | trays |"
    )
    print("|---|---|---|---|---|---|---|")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
