"""Shake trials: the known answers of issue 30 at full size, and the time per 1,000 trials.

Usage: ``python -m benchmarks.shake [--trials N] [--duration S] [--workers W] [--only NAME,...]
[--exact-plate] [--timestep MS]``; ``python -m benchmarks.shake --levers DIR --only NAMES
--trials N [--which before,now,...]`` times the trial-speed levers on a solve's plate, one after
another in one run (:func:`levers`).

Runs each case (a 22 mm round hole with a 24 mm and a 20 mm ball, 2 mm plate with 14 mm of
material around it; a 22 mm square hole with a 20 mm cube, 2 mm plate, 5 mm border) with the
default shaker settings (and the issue-45 pair: a 23 mm and a 21 mm ball on a 22 mm hole cut as
a 256-gon; ``--exact-plate`` collides with the plate's exact convex pieces, as before the merge of
:data:`sieve_mi.shake.model.PLATE_SIMPLIFY_M`) and prints one Markdown row per case: trials, passed, fraction with its
95 % Wilson interval, median time to pass, the resting sink and the wall-clock seconds per
1,000 trials.
"""

from __future__ import annotations

import argparse
import time

import manifold3d
import trimesh

from sieve_mi.shake.fidelity import measure_sink
from sieve_mi.shake.geometry import part_from_mesh, plate_from_mesh, plate_from_outline
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.stats import summarize
from sieve_mi.shake.trials import run_trials

CASES = {
    "ball24-round22": ("round", 14.0, lambda: trimesh.creation.icosphere(3, 12.0)),
    "ball20-round22": ("round", 14.0, lambda: trimesh.creation.icosphere(3, 10.0)),
    "cube20-square22": ("square", 5.0, lambda: trimesh.creation.box((20.0, 20.0, 20.0))),
    "ball23-round22x256": ("round256", 14.0, lambda: trimesh.creation.icosphere(3, 11.5)),
    "ball21-round22x256": ("round256", 14.0, lambda: trimesh.creation.icosphere(3, 10.5)),
}


def _hole(kind: str) -> manifold3d.CrossSection:
    if kind.startswith("round"):
        return manifold3d.CrossSection.circle(11.0, 256 if kind == "round256" else 96)
    return manifold3d.CrossSection.square([22.0, 22.0], center=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--only", default="")
    ap.add_argument("--timestep", type=float, default=0.25, help="ms (the default 0.25)")
    ap.add_argument("--exact-plate", action="store_true", help="no merge of the plate's pieces")
    ap.add_argument(
        "--seat",
        metavar="DIR",
        help="instead: how close --only's shapes of solve DIR come to "
        "their pass pose over --trials trials (benchmarks.shake.seating)",
    )
    ap.add_argument("--levers", metavar="DIR", help="instead: time the levers (levers())")
    ap.add_argument("--which", default=",".join(LEVERS), help="the levers, in this order")
    args = ap.parse_args()
    if args.levers:
        print(LEVER_HEAD, flush=True)
        for which in args.which.split(","):
            for name in args.only.split(","):
                print(levers(args.levers, name, args.trials, which, args.duration), flush=True)
        return
    if args.seat:
        for name in args.only.split(","):
            print(seating(args.seat, name, args.trials), flush=True)
        return
    if args.exact_plate:
        from sieve_mi.shake import model

        if args.workers != 1:
            ap.error("--exact-plate patches this process only: give --workers 1")
        model.PLATE_SIMPLIFY_M = 0.0
    settings = ShakeSettings(
        trials=args.trials, duration=args.duration, workers=args.workers, timestep=args.timestep
    )
    print("| case | trials | passed | fraction [95 % CI] | median s | sink mm | deepest mm "
          "| s / 1,000 trials |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, (kind, margin, mesh) in CASES.items():
        if args.only and name not in args.only.split(","):
            continue
        plate = plate_from_outline(_hole(kind), margin, 2.0)
        part = part_from_mesh(mesh(), name, None, settings.coacd_threshold)
        sink = measure_sink(plate, part, settings, 1e-3)["sink_mm"]
        t0 = time.perf_counter()
        outcomes = run_trials(plate, part, settings, 1e-3)
        s, deep = summarize(outcomes), max(o.penetration for o in outcomes) * 1e3
        per_k = (time.perf_counter() - t0) / settings.trials * 1000
        med = "-" if s["median_time_s"] is None else f"{s['median_time_s']:.2f}"
        lo, hi = s["ci95"]
        print(
            f"| {name} | {s['trials']} | {s['passed']} | {s['fraction']:.3f} [{lo:.3f}, {hi:.3f}] "
            f"| {med} | {sink:.4f} | {deep:.3f} | {per_k:.0f} |",
            flush=True,
        )


#: The trial-speed levers of :func:`levers`: what each changes from today's defaults.
LEVERS = {
    "before": "the engine's part and plate as before: every hull vertex, the plate's outline "
    "simplified by Ramer-Douglas-Peucker",
    "allhull": "every hull vertex of the part (PART_SIMPLIFY_M = 0)",
    "rdp": "the plate's outline simplified by Ramer-Douglas-Peucker (CrossSection.simplify)",
    "now": "today's defaults, one process",
    "nomulticcd": "MuJoCo's multi-point convex contacts off (mjDSBL_MULTICCD)",
    "dt0.5": "timestep 0.5 ms",
    "workers2": "today's defaults on 2 worker processes (wall-clock)",
}
LEVER_HEAD = (
    "| lever | shape | trials | passed | CPU s / trial | wall s / trial | deepest mm |\n"
    "| --- | --- | --- | --- | --- | --- | --- |"
)


def _rdp_pieces(pieces, tolerance):
    """The plate's pieces merged as before the greedy chords: Ramer-Douglas-Peucker."""
    from sieve_mi.geometry.plate import convex_pieces

    region = manifold3d.CrossSection(list(pieces))
    return convex_pieces(region.simplify(tolerance) if tolerance > 0 else region)


def levers(folder: str, name: str, trials: int, which: str, duration: float = 10.0) -> str:
    """Shake ``name`` of a solve's ``folder`` (or the case ``name`` of :data:`CASES`) ``trials``
    times with one lever of
    :data:`LEVERS` pulled (in this process, one worker, but ``workers2``); one Markdown row:
    passes, CPU and wall seconds per trial, the deepest penetration of any trial (mm)."""
    import mujoco

    from sieve_mi.shake import geometry, model
    from sieve_mi.shake import trials as trial_mod
    from sieve_mi.shake.inputs import from_folder, select

    if name in CASES:  # a case of the table (folder unused)
        kind, margin, make = CASES[name]
        plate, part = (
            plate_from_outline(_hole(kind), margin, 2.0),
            part_from_mesh(make(), name, None, 0.05),
        )
    else:
        inp = select(from_folder(folder, [name]), [name])
        plate = plate_from_mesh(inp.plate, inp.plate_path, inp.units)
        _, role, _, mesh = inp.parts[0]
        part = part_from_mesh(mesh, name, role, 0.05)
    settings = ShakeSettings(trials=trials, duration=duration, workers=1,
                             timestep=0.5 if which == "dt0.5" else 0.25)  # fmt: skip
    keep, build, pieces = model.PART_SIMPLIFY_M, trial_mod.build_model, geometry.collision_pieces
    if which in ("before", "allhull"):
        model.PART_SIMPLIFY_M = 0.0
    if which in ("before", "rdp"):
        geometry.collision_pieces = _rdp_pieces
    if which == "nomulticcd":

        def build_nomulti(*a, **k):
            m = build(*a, **k)
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MULTICCD)
            return m

        trial_mod.build_model = build_nomulti
    if which == "workers2":
        settings = ShakeSettings(trials=trials, duration=duration, workers=2)
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        out = run_trials(plate, part, settings, 1e-3)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        model.PART_SIMPLIFY_M, trial_mod.build_model, geometry.collision_pieces = (
            keep,
            build,
            pieces,
        )
    deep = max(o.penetration for o in out) * 1e3
    cpu_cell = "-" if which == "workers2" else f"{cpu / trials:.3f}"
    return (f"| {which} | {name} | {trials} | {sum(o.passed for o in out)} | {cpu_cell} | "
            f"{wall / trials:.3f} | {deep:.3f} |")  # fmt: skip


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
    holes = shapely.union_all([shapely.Polygon(h) for h in section_holes(plate_mesh, "plate")])
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


def _symmetry(mesh) -> int:
    """Turns about z (2: 180°, 1: none) that map the part's pass-pose silhouette onto itself
    (symmetric difference under 1 % of its area)."""
    from shapely import affinity

    sil = _silhouette(mesh)
    c = sil.centroid
    turned = affinity.rotate(sil, 180.0, origin=c)
    return 2 if sil.symmetric_difference(turned).area < 0.01 * sil.area else 1


def seating(folder: str, name: str, trials: int, every: int = 40, settings=None) -> dict:
    """How close a part's shaken trials come to its pass pose on a solve's plate.

    The part (``pass_<i>.stl`` of the solve, already in its pass pose over its place in the
    hole) passes when it lies the right side up (tilt from its pass pose under 5°), turned to
    within a few degrees of its place (yaw, modulo the silhouette's own symmetry) and centred on
    its place to within a fraction of a millimetre (``window``). Every ``every`` steps of each
    trial this records the tilt, the yaw error, the horizontal distance of the centre of mass from
    its place and how deep the part's lowest point is below the plate's top face (a part seated
    in the hole's mouth is below it).

    Returns
    -------
    dict
        Fractions of sampled time: ``flat_up`` (tilt < 5°), ``flat_down`` (> 175°, the mirror
        image up), ``up_and_turned`` (flat up, yaw error < 6°), ``up_turned_near`` (and within 2
        mm of its place), ``in_mouth`` (lowest point over 1 mm below the top face) with the
        median tilt and distance from its place there; the closest approach to its place while
        up and turned (mm); the symmetry used; trials, passes.
    """
    import mujoco
    import numpy as np

    from sieve_mi.shake.inputs import from_folder, select
    from sieve_mi.shake.model import build_model
    from sieve_mi.shake.settings import metres_per_unit
    from sieve_mi.shake.trials import run_trial

    settings = settings or ShakeSettings(trials=trials, workers=1)
    inp = select(from_folder(folder), [name])
    unit_m = metres_per_unit(inp.units)
    plate = plate_from_mesh(inp.plate, inp.plate_path)
    ((_, role, _, mesh),) = inp.parts
    part = part_from_mesh(mesh, name, role, settings.coacd_threshold)
    fold = _symmetry(mesh)
    period = 360.0 / fold
    seat = (part.com[:2] - plate.offset[:2]) * unit_m
    low = np.concatenate(part.hulls) * unit_m  # the pieces' vertices, body frame
    model = build_model(plate, part, settings, unit_m)
    data = mujoco.MjData(model)
    rows, rot = [], np.empty(9)

    def observe(k, data, lift):
        if k % every or data.qpos[4] < -plate.thickness * unit_m:
            return
        mujoco.mju_quat2Mat(rot, data.qpos[5:9])
        r = rot.reshape(3, 3)
        tilt = np.degrees(np.arccos(np.clip(r[2, 2], -1, 1)))
        yaw = (np.degrees(np.arctan2(r[1, 0], r[0, 0])) + period / 2) % period - period / 2
        off = np.linalg.norm(data.qpos[2:4] - seat) * 1e3
        depth = (lift - (data.qpos[4] + (low @ r.T)[:, 2].min())) * 1e3
        rows.append((tilt, abs(yaw), off, depth))

    passes = sum(
        run_trial(model, data, i, plate, part, settings, unit_m, observe).passed
        for i in range(trials)
    )
    a = np.asarray(rows)
    up, turned, mouth = a[:, 0] < 5, a[:, 1] < 6, a[:, 3] > 1
    return {
        "name": name,
        "trials": trials,
        "passed": passes,
        "symmetry": fold,
        "flat_up": float(up.mean()),
        "flat_down": float((a[:, 0] > 175).mean()),
        "up_and_turned": float((up & turned).mean()),
        "up_turned_near": float((up & turned & (a[:, 2] < 2)).mean()),
        "closest_mm": float(a[up & turned, 2].min()) if (up & turned).any() else None,
        "in_mouth": float(mouth.mean()),
        "in_mouth_tilt_deg": float(np.median(a[mouth, 0])) if mouth.any() else None,
        "in_mouth_offset_mm": float(np.median(a[mouth, 2])) if mouth.any() else None,
    }


if __name__ == "__main__":
    main()
