"""Benchmark ``certify`` on the issue-11 targets and print a Markdown table (CPU, one process).

Usage::

    python -m benchmarks.certify [--letters-hole out/letters/hole.svg] [--budget 60] [--only TEXT]
        [--no-replay]

Rows: the 24 mm sphere and the 23 mm cube against the face-on 20 mm cube's hole grown by 1 mm;
1.08x and 1.04x cubes against the unit cube's Nieuwland hole (the unit cube seen along (2, 2, -1),
tolerance 0); with ``--letters-hole``, the letters R, A, P, H against that merged hole. Each row
also replays its certificate and reports the replay time. "CPU s" is the proof's CPU time in its
process (a fairer measure than the wall-clock "seconds" on a machine shared with other jobs).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

import manifold3d
import numpy as np

from sieve_mi.certify import certify, read_svg_hole, replay
from sieve_mi.geometry.meshes import load_shape, shape_from_trimesh
from sieve_mi.geometry.outline import hole_outline
from sieve_mi.geometry.rotations import align
from sieve_mi.testing import shapes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def cases(letters_hole: str | None):
    """(label, shape, holes) for every benchmark row."""
    cube = shape_from_trimesh(shapes.cube(20.0), name="cube20")
    cube_hole = hole_outline([cube], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 1.0, [True])
    unit = shape_from_trimesh(shapes.cube(1.0), name="unit")
    q = align(np.array([2.0, 2.0, -1.0]), np.array([0.0, 0.0, 1.0]))
    nieuwland = hole_outline([unit], q[None], np.zeros((1, 2)), 0.0, closed=[True])
    yield (
        "24 mm sphere / cube hole +1 mm",
        shape_from_trimesh(shapes.sphere(12.0), name="s"),
        cube_hole,
    )
    yield "23 mm cube / cube hole +1 mm", shape_from_trimesh(shapes.cube(23.0), name="c"), cube_hole
    for s in (1.08, 1.04):
        yield f"{s}x cube / Nieuwland hole", shape_from_trimesh(shapes.cube(s), name="c"), nieuwland
    for mesh, factor in (("spot.obj", 1.3), ("spot.obj", 1.1)):
        path = os.path.join(ROOT, "..", "shared", "meshes", mesh)
        if os.path.exists(path):
            original = load_shape(path, name="spot")
            hole = hole_outline([original], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 0.0)
            big = load_shape(path, scale=factor, name=f"spot{factor}")
            yield f"{factor}x spot / spot's own shadow", big, hole, factor
    if letters_hole:
        hole = read_svg_hole(letters_hole)
        for letter in "RAPH":
            path = os.path.join(ROOT, "scenes", "meshes", f"letter_{letter}.stl")
            yield f"letter {letter} / letters hole (seed 0)", load_shape(path), hole


def row(label: str, shape, contours: list, budget: float, scale: float, check: bool = True) -> str:
    """Certify one case, replay its certificate (unless ``check`` is false: "-" in the replay
    column), and return its Markdown table row."""
    cpu = time.process_time()
    r = certify(shape, [manifold3d.CrossSection(contours)], budget_s=budget, scale=scale)
    cpu = time.process_time() - cpu
    t0 = time.perf_counter()
    rep = replay(r.certificate) if check else {"valid": True}
    tr = f"{time.perf_counter() - t0:.2f}" if check else "-"
    ok = "" if rep["valid"] else " (replay INVALID)"
    return (
        f"| {label} | {r.status}{ok} | {r.method} | {r.seconds:.2f} | {cpu:.2f} | {r.cells_examined:,} "
        f"| {r.cells_excluded:,} | {r.cells_open:,} | {r.depth} | {r.excluded_fraction:.4f} "
        f"| {r.symmetry} | {tr} |"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--letters-hole")
    ap.add_argument("--budget", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=1, help="cases certified at once (processes)")
    ap.add_argument("--only", default="", help="only the cases whose label contains this text")
    ap.add_argument("--no-replay", action="store_true", help="skip the replays (faster)")
    args = ap.parse_args()
    print(
        "| case | status | method | seconds | CPU s | cells examined | excluded | open | depth "
        "| excluded fraction | symmetry | replay s |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    t0 = time.perf_counter()
    jobs = [
        (
            label,
            shape,
            [np.asarray(c, float) for c in hole.to_polygons()],
            args.budget,
            *(rest or [1.0]),
            not args.no_replay,
        )
        for label, shape, hole, *rest in cases(args.letters_hole)
        if args.only in label
    ]
    with ProcessPoolExecutor(args.workers, mp_context=multiprocessing.get_context("fork")) as pool:
        for line in pool.map(row, *zip(*jobs)):
            print(line, flush=True)
    print(f"\nwall time {time.perf_counter() - t0:.1f} s with {args.workers} worker(s)")


if __name__ == "__main__":
    main()
