"""Shake trials: the known answers of issue 30 at full size, and the time per 1,000 trials.

Usage: ``python -m benchmarks.shake [--trials N] [--duration S] [--workers W] [--only NAME,...]``

Runs each case (a 22 mm round hole with a 24 mm and a 20 mm ball, 2 mm plate with 14 mm of
material around it; a 22 mm square hole with a 20 mm cube, 2 mm plate, 5 mm border) with the
default shaker settings and prints one Markdown row per case: trials, passed, fraction with its
95 % Wilson interval, median time to pass, the resting sink and the wall-clock seconds per
1,000 trials.
"""

from __future__ import annotations

import argparse
import time

import manifold3d
import trimesh

from sieve_mi.shake.fidelity import measure_sink
from sieve_mi.shake.geometry import part_from_mesh, plate_from_outline
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.stats import summarize
from sieve_mi.shake.trials import run_trials

CASES = {
    "ball24-round22": ("round", 14.0, lambda: trimesh.creation.icosphere(3, 12.0)),
    "ball20-round22": ("round", 14.0, lambda: trimesh.creation.icosphere(3, 10.0)),
    "cube20-square22": ("square", 5.0, lambda: trimesh.creation.box((20.0, 20.0, 20.0))),
}


def _hole(kind: str) -> manifold3d.CrossSection:
    if kind == "round":
        return manifold3d.CrossSection.circle(11.0, 96)
    return manifold3d.CrossSection.square([22.0, 22.0], center=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--only", default="")
    args = ap.parse_args()
    settings = ShakeSettings(trials=args.trials, duration=args.duration, workers=args.workers)
    print("| case | trials | passed | fraction [95 % CI] | median s | sink mm | s / 1,000 trials |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, (kind, margin, mesh) in CASES.items():
        if args.only and name not in args.only.split(","):
            continue
        plate = plate_from_outline(_hole(kind), margin, 2.0)
        part = part_from_mesh(mesh(), name, None, settings.coacd_threshold)
        sink = measure_sink(plate, part, settings, 1e-3)["sink_mm"]
        t0 = time.perf_counter()
        s = summarize(run_trials(plate, part, settings, 1e-3))
        per_k = (time.perf_counter() - t0) / settings.trials * 1000
        med = "-" if s["median_time_s"] is None else f"{s['median_time_s']:.2f}"
        lo, hi = s["ci95"]
        print(
            f"| {name} | {s['trials']} | {s['passed']} | {s['fraction']:.3f} [{lo:.3f}, {hi:.3f}] "
            f"| {med} | {sink:.4f} | {per_k:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()


def _silhouette(mesh):
    """The xy projection of a mesh (shapely polygon, union of its projected triangles)."""
    import shapely

    tris = [
        shapely.Polygon(t[:, :2]) for t in mesh.triangles if shapely.Polygon(t[:, :2]).area > 1e-12
    ]
    return shapely.union_all(tris).buffer(0)


def window(
    plate_mesh, part_mesh, tol_deg: float = 6.0, step_mm: float = 0.1, step_deg: float = 0.25
):
    """How much room a part in its pass pose has to fit the plate's holes.

    Returns (the area of xy offsets at which the unrotated silhouette fits, mm^2; the range of
    yaw angles, degrees, at which it fits at some offset of the grid; the plate's area, mm^2).
    """
    import numpy as np
    import shapely
    from shapely import affinity

    from sieve_mi.shake.geometry import section_holes

    lo, hi = plate_mesh.bounds
    holes = shapely.union_all(
        [shapely.Polygon(h) for h in section_holes(plate_mesh, 0.5 * (lo[2] + hi[2]), "plate")]
    )
    sil = _silhouette(part_mesh)
    c = sil.centroid
    offsets = np.arange(-1.5, 1.5 + 1e-9, step_mm)

    def fits_at(g):
        return [
            (dx, dy)
            for dx in offsets
            for dy in offsets
            if holes.contains(affinity.translate(g, dx, dy))
        ]

    area = len(fits_at(sil)) * step_mm**2
    yaws = [
        a
        for a in np.arange(-tol_deg, tol_deg + 1e-9, step_deg)
        if fits_at(affinity.rotate(sil, a, origin=c))
    ]
    span = (max(yaws) - min(yaws) + step_deg) if yaws else 0.0
    return area, span, float((hi[0] - lo[0]) * (hi[1] - lo[1]))
