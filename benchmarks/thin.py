"""Benchmark the thin-plate motion search (sieve_mi.motion) on the known cases of the issue "Thin sheets".

Usage::

    python -m benchmarks.thin [--seeds 5] [--budget 60]

For each case and seed: the answer, the seconds to it, collision/distance queries, planner runs and
crossing poses. A passage is found and verified; "no passage found" uses the whole budget.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import manifold3d
import trimesh

from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.motion import thin_plate
from sieve_mi.testing import shapes


def cases() -> dict:
    """name -> (shape, hole, thickness, expected status)."""
    rod = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="rod")
    return {
        "L-rod, 9 mm hole, 1 mm plate": (rod, manifold3d.CrossSection.circle(4.5, 64), 1.0),
        "L-rod, 10 mm hole, 2 mm plate": (rod, manifold3d.CrossSection.circle(5.0, 64), 2.0),
        "L-rod, 10 mm hole, 4 mm plate": (rod, manifold3d.CrossSection.circle(5.0, 64), 4.0),
        "coin 19.75x1.93 vs 19.5x3 slot, 1 mm": (
            shape_from_trimesh(shapes.coin(19.75, 1.93), name="coin"),
            manifold3d.CrossSection.square([19.5, 3.0], center=True),
            1.0,
        ),
        "cube 20 vs 22 square hole, 2 mm": (
            shape_from_trimesh(shapes.cube(20.0), name="cube"),
            manifold3d.CrossSection.square([22, 22], center=True),
            2.0,
        ),
        "ball 24 vs 22 round hole, 2 mm": (
            shape_from_trimesh(trimesh.creation.icosphere(3, 12.0), name="ball"),
            manifold3d.CrossSection.circle(11.0, 128),
            2.0,
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--budget", type=float, default=60.0)
    args = ap.parse_args()
    print(
        f"# {platform.node()} {platform.processor() or platform.machine()} {time.strftime('%Y-%m-%d')}"
    )
    print("| case | answers | seconds (median, max) | queries (median) |")
    print("| --- | --- | --- | --- |")
    for name, (shape, hole, t) in cases().items():
        runs = [thin_plate(shape, hole, t, budget_s=args.budget, seed=s) for s in range(args.seeds)]
        answers = ", ".join(
            sorted({f"{sum(r.status == x for r in runs)}× {x}" for x in {r.status for r in runs}})
        )
        secs = [r.seconds for r in runs]
        print(f"| {name} | {answers} | {statistics.median(secs):.2f}, {max(secs):.2f} | "
              f"{statistics.median(r.checks for r in runs):.0f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()


def section_levels(shape, hole, thickness: float, levels: int, inner: int = 0) -> list[dict]:
    """The slab-section search (centre pin) of ``shape`` against ``hole`` at ``thickness``,
    levels 1 to ``levels`` of caps, with ``inner`` band points spread inside the section added to
    the turn test (:data:`sieve_mi.certify.section.INNER_POINTS`): per level, caps, excluded,
    caps given up on a fit, CPU seconds and the caps it leaves for the next level."""
    import numpy as np

    from sieve_mi.certify.search import Settings, candidate_points
    from sieve_mi.certify.section import SECTION_CANDIDATES, SectionSearch

    points, _ = candidate_points(shape, Settings(max_candidates=SECTION_CANDIDATES), "none")
    search = SectionSearch(points, hole, shape.radius)
    search.inner, rows = inner, []
    level_of = search._level

    def timed(level, *args):
        c0, fits = time.process_time(), search.turn_test.stats["fits"]
        verdicts, done = level_of(level, *args)
        excluded = sum(v is not None for v in verdicts)
        rows.append({"level": len(rows) + 1, "caps": len(level), "excluded": excluded,
                     "fits": search.turn_test.stats["fits"] - fits,
                     "cpu_s": time.process_time() - c0, "left": 4 * (len(level) - excluded)})  # fmt: skip
        return verdicts, done

    search._level = timed
    search.run(np.zeros(3), thickness, budget_s=1e9, min_angle=2.0 ** -(levels - 1))
    return rows


def letters_section(cert: str, thickness: float = 20.0, levels: int = 6) -> None:
    """:func:`section_levels` of the letter in a letters solve's certificate ``cert`` (its exact
    hole), extreme band points only and with 12 spread ones, in one run (a Markdown table)."""
    import json

    import numpy as np

    from sieve_mi.geometry.meshes import Shape

    data = json.load(open(cert))
    v, f = np.asarray(data["shape"]["vertices"]), np.asarray(data["shape"]["faces"])
    shape = shape_from_trimesh(trimesh.Trimesh(v, f, process=False), name=data["shape"]["name"])
    assert isinstance(shape, Shape)
    hole = manifold3d.CrossSection([np.asarray(c) for c in data["hole"]])
    print(
        "| inner points | level | caps | excluded | given up on a fit | CPU s | caps / CPU s | left |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for inner in (0, 12):
        for r in section_levels(shape, hole, thickness, levels, inner):
            print(f"| {inner} | {r['level']} | {r['caps']} | {r['excluded']} | {r['fits']} | "
                  f"{r['cpu_s']:.1f} | {r['caps'] / max(r['cpu_s'], 1e-9):.0f} | {r['left']} |",
                  flush=True)  # fmt: skip
