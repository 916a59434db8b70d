"""Benchmark sieve-mi end to end on a fixed set of scenes, with the paper's hyperparameters.

Usage::

    python -m benchmarks.run [--variant llvm_ad_mono|cuda_ad_mono] [--only NAME[,NAME]] [--objective clearance|overlap]
                             [--quick] [--set TABLE.KEY=VALUE ...] [--out benchmarks/results] [--tag MACHINE]

Every scene runs in its own process (so its peak memory is its own) and prints one table row:
faces, raster pixels, edge samples, search and verdict time, winner, and per-B loss and
protrusion. Results go to ``<out>/<machine>-<variant>.json`` and ``.md`` (machine: ``--tag`` or the
host name).

``--set`` changes one scene key for every scene of the run, e.g. ``--set solver.settle=false`` or
``--set layout.mode='"separate"'`` (the value is TOML); rows and file names then say so, so that
two runs compare a setting (run them one after the other, on the same machine).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE_MESHES = os.path.join(ROOT, "scenes", "meshes")
BENCH_MESHES = os.path.join(HERE, "meshes")
CACHE = os.path.join(ROOT, "build", "benchmark-meshes")

#: name -> (pass meshes [(path, scale)], block meshes [(path, scale)], paper's comparable time or None)
SCENES = {
    "cube-sphere": ([("cube.stl", 1.0)], [("sphere.stl", 1.0)], None),
    "bowtie-sphere": ([("bowtie.stl", 1.0)], [("sphere.stl", 0.6)], None),
    "arch-prism": ([("arch.stl", 1.0)], [("prism.stl", 1.0)], None),
    "spot-cow": ([("spot.obj", 23.0)], [("cow.obj", 4.2)], None),
    "cow-bunny": ([("cow.obj", 4.2)], [("bunny", 250.0)], None),
    "cow-beetle500k": ([("cow.obj", 4.2)], [("beetle500k", 12.0)], None),
    "letters": (
        [("letter_S.stl", 1.0), ("letter_I.stl", 1.0), ("letter_G.stl", 1.0)],
        [
            ("letter_R.stl", 1.0),
            ("letter_A.stl", 1.0),
            ("letter_P.stl", 1.0),
            ("letter_H.stl", 1.0),
        ],
        2099.7,
    ),
}
#: Scene keys beyond the defaults, per benchmark scene (kept equal to the bundled scene files).
EXTRA = {"letters": {"fabrication": {"tolerance": "0.5"}}}
PAPER = (
    "search 10x10 PSO, 10 starts x 100 Adam steps; verdict 100 starts x 500 steps; 256^2 rasters"
)


def mesh_path(name: str) -> str:
    """Path of a benchmark mesh, generating the subdivided one on first use."""
    if name == "bunny":
        return os.path.join(BENCH_MESHES, "stanford-bunny.obj")
    if name == "beetle500k":
        path = os.path.join(CACHE, "beetle500k.ply")
        if not os.path.exists(path):
            import trimesh

            m = trimesh.load(os.path.join(BENCH_MESHES, "beetle.obj"), force="mesh")
            v, f = m.vertices, m.faces
            for _ in range(4):
                v, f = trimesh.remesh.subdivide(v, f)
            os.makedirs(CACHE, exist_ok=True)
            trimesh.Trimesh(v, f, process=False).export(path)
        return path
    return os.path.join(SCENE_MESHES, name)


def scene_text(name: str, objective: str, quick: bool, overrides=()) -> str:
    """The scene file of a benchmark scene; ``overrides`` are ``TABLE.KEY=VALUE`` strings (TOML
    values) applied last."""
    passes, blocks, _ = SCENES[name]
    lines = [f'name = "bench-{name}"']
    for p, s in passes:
        lines += ["[[pass]]", f'mesh = "{mesh_path(p)}"', f"scale = {s}"]
    for p, s in blocks:
        lines += ["[[block]]", f'mesh = "{mesh_path(p)}"', f"scale = {s}"]
    tables = {"solver": {"objective": f'"{objective}"'}}
    for table, keys in EXTRA.get(name, {}).items():
        tables.setdefault(table, {}).update(keys)
    if quick:
        tables["solver"].update(particles="4", iterations="2", starts="4", steps="30")
        tables.setdefault("verdict", {}).update(starts="20", steps="100")
    for table, key, value in map(parse_override, overrides):
        tables.setdefault(table, {})[key] = value
    for table, keys in tables.items():
        lines += [f"[{table}]"] + [f"{k} = {v}" for k, v in keys.items()]
    return "\n".join(lines) + "\n"


def parse_override(text: str) -> tuple[str, str, str]:
    """``"solver.settle=false"`` -> ``("solver", "settle", "false")``."""
    key, sep, value = text.partition("=")
    table, dot, name = key.strip().partition(".")
    if not (sep and dot and table and name and value.strip()):
        raise ValueError(f"--set {text!r}: write TABLE.KEY=VALUE, e.g. solver.settle=false")
    return table, name.strip(), value.strip()


def run_one(name: str, variant: str, objective: str, quick: bool, overrides=()) -> dict:
    """Run one scene in this process and return its row (called in a child process)."""
    import sieve_mi  # noqa: F401
    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "scene.toml")
        with open(path, "w") as fh:
            fh.write(scene_text(name, objective, quick, overrides))
        scene = load_scene(path)
        t0 = time.perf_counter()
        result = solve(scene, variant=variant, progress=False)
        total = time.perf_counter() - t0
    from sieve_mi.objectives.clearance import ClearanceObjective

    frame = result.hole.frame
    clear = ClearanceObjective(result.block_shapes, frame)
    samples = clear.segment_count * clear.samples
    return {
        "scene": name,
        "objective": objective,
        "variant": variant,
        "faces_pass": [s.face_count for s in result.pass_shapes],
        "faces_block": [s.face_count for s in result.block_shapes],
        "pixels": frame.resolution**2,
        "edge_samples": int(samples),
        "init_s": result.timings.get("init_s", 0.0),
        "load_s": result.timings.get("load_s", 0.0),
        "search_s": result.timings.get("search_s", 0.0),
        "verdict_s": result.timings.get("verdict_s", 0.0),
        "total_s": total,
        "winner": result.winner,
        "loss": [float(x) for x in result.attack.beta[0]],
        "protrusion": [float(x) for x in result.attack.protrusion[0]],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "stage_peaks_gb": dict(result.memory.peaks) if result.memory is not None else {},
        "quick": quick,
        "overrides": list(overrides),
    }


def machine() -> str:
    """A short description of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores"


def markdown(rows: list[dict], header: str) -> str:
    out = [
        header,
        "",
        "| scene | objective | faces A / B | pixels | edge samples | init + load s | search s | verdict s | total s | winner | B loss | B protrusion | peak MB | peak GB by stage |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        if "error" in r:
            out.append(
                f"| {r['scene']} | {r['objective']} | error: {r['error']} |  |  |  |  |  |  |  |  |  |  |  |"
            )
            continue
        out.append(
            "| {scene} | {objective} | {fa} / {fb} | {pixels} | {edge_samples} | {il:.1f} | {search_s:.1f} | {verdict_s:.1f} | {total_s:.1f} | {winner} | {losses} | {prot} | {peak_rss_mb:.0f} | {stages} |".format(
                fa="+".join(map(str, r["faces_pass"])),
                fb="+".join(map(str, r["faces_block"])),
                il=r.get("init_s", 0.0) + r.get("load_s", 0.0),
                losses=", ".join(f"{x:.3f}" for x in r["loss"]),
                prot=", ".join(f"{x:.2f}" for x in r["protrusion"]),
                stages=", ".join(f"{k} {v:.2f}" for k, v in r.get("stage_peaks_gb", {}).items()),
                **r,
            )
        )
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--only", help="comma-separated scene names: " + ", ".join(SCENES))
    p.add_argument(
        "--objective", default="clearance", help="clearance, overlap, or both (comma-separated)"
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="reduced settings (smoke test, not comparable to the paper)",
    )
    p.add_argument("--out", default=os.path.join(HERE, "results"))
    p.add_argument("--tag", help="machine name in the result file names (default: the host name)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="change a scene key in every scene (TOML value; repeatable)",
    )
    p.add_argument("--one", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    objectives = args.objective.split(",")
    try:
        for o in args.set:
            parse_override(o)
    except ValueError as exc:
        print(f"benchmarks: {exc}", file=sys.stderr)
        return 2
    if args.one:
        row = run_one(args.one, args.variant, objectives[0], args.quick, args.set)
        print("ROW " + json.dumps(row))
        return 0
    names = args.only.split(",") if args.only else list(SCENES)
    for n in names:
        if n not in SCENES:
            print(f"benchmarks: unknown scene '{n}'; known: {', '.join(SCENES)}", file=sys.stderr)
            return 2
    rows = []
    header = f"Machine: {machine()}; variant {args.variant}; settings: {'QUICK (not comparable)' if args.quick else PAPER}"
    if args.set:
        header += "; changed: " + ", ".join(args.set)
    print(header)
    for n in names:
        for obj in objectives:
            cmd = [
                sys.executable,
                "-m",
                "benchmarks.run",
                "--one",
                n,
                "--variant",
                args.variant,
                "--objective",
                obj,
            ] + (["--quick"] if args.quick else [])
            cmd += [f"--set={o}" for o in args.set]
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            line = [ln for ln in proc.stdout.splitlines() if ln.startswith("ROW ")]
            if proc.returncode != 0 or not line:
                err = (proc.stderr.strip().splitlines() or ["failed"])[-1]
                rows.append({"scene": n, "objective": obj, "error": err})
                print(f"{n:16s} {obj:9s} ERROR {err}", flush=True)
                continue
            r = json.loads(line[0][4:])
            rows.append(r)
            print(
                f"{n:16s} {obj:9s} faces {sum(r['faces_pass'])}/{sum(r['faces_block'])}  init+load {r.get('init_s', 0) + r.get('load_s', 0):5.1f} s  search {r['search_s']:7.1f} s  verdict {r['verdict_s']:6.1f} s  "
                f"winner {r['winner']}  loss {', '.join(f'{x:.3f}' for x in r['loss'])}  protrusion {', '.join(f'{x:.2f}' for x in r['protrusion'])}  "
                f"peak {r['peak_rss_mb']:.0f} MB",
                flush=True,
            )
    os.makedirs(args.out, exist_ok=True)
    tag = (
        f"{args.tag or platform.node() or 'machine'}-{args.variant}{'-quick' if args.quick else ''}"
        + "".join("-" + "".join(c if c.isalnum() else "_" for c in o) for o in args.set)
    )
    with open(os.path.join(args.out, f"{tag}.json"), "w") as fh:
        json.dump({"machine": machine(), "variant": args.variant, "rows": rows}, fh, indent=2)
    with open(os.path.join(args.out, f"{tag}.md"), "w") as fh:
        fh.write(markdown(rows, header))
    print(markdown(rows, header))
    return 0


if __name__ == "__main__":
    sys.exit(main())
