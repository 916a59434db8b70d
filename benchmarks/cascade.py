"""Wall time of a 6-shape sorting cascade, serial vs Ray, in one run (issue 15).

    python -m benchmarks.cascade [--workers 2]

Six shapes whose order is known (passage radii in mm): a 28 mm cube (14), a 20 mm ball (10), a
14 mm cube (7), a 10 mm ball (5), a 30 x 10 x 4 mm bar (2) and a 20 x 1.5 mm coin (0.75). Both
runs play the same games from an empty cache; the Ray run starts a local Ray (included in its
time). Prints one table row per mode and the ratio.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time

import trimesh

from sieve_mi.testing.settings import CASCADE_SOLVER, TINY_LAYOUT, settings_toml

SETTINGS = settings_toml(
    fabrication={"tolerance": 0.5},
    solver={**CASCADE_SOLVER, "iterations": 2, "steps": 40},
    verdict={"starts": 24, "steps": 150, "resolution": 128},
    layout=TINY_LAYOUT,
)

SHAPES = {
    "cube28": lambda: trimesh.creation.box((28.0, 28.0, 28.0)),
    "ball20": lambda: trimesh.creation.icosphere(3, 10.0),
    "cube14": lambda: trimesh.creation.box((14.0, 14.0, 14.0)),
    "ball10": lambda: trimesh.creation.icosphere(3, 5.0),
    "bar": lambda: trimesh.creation.box((30.0, 10.0, 4.0)),
    "coin": lambda: trimesh.creation.cylinder(10.0, 1.5, sections=64),
}


def write_mixture(folder: str) -> str:
    os.makedirs(os.path.join(folder, "meshes"), exist_ok=True)
    text = 'name = "six"\n'
    for name, make in SHAPES.items():
        make().export(os.path.join(folder, "meshes", f"{name}.stl"))
        text += f'[[shape]]\nmesh = "meshes/{name}.stl"\n'
    path = os.path.join(folder, "six.toml")
    with open(path, "w") as fh:
        fh.write(text + SETTINGS)
    return path


def main() -> None:
    import sieve_mi  # noqa: F401
    from sieve_mi.cascade.games import EngineSettings
    from sieve_mi.cascade.mixture import load_mixture
    from sieve_mi.cascade.sort import sort_mixture

    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=os.cpu_count())
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = write_mixture(tmp)
        rows = {}
        for mode in ("serial", "ray"):
            t0 = time.perf_counter()
            rep = sort_mixture(
                load_mixture(path),
                os.path.join(tmp, mode),
                engine=EngineSettings(
                    use_ray=mode == "ray",
                    workers=args.workers if mode == "ray" else None,
                    progress=False,
                ),
            )
            rows[mode] = (time.perf_counter() - t0, rep)
    print(
        f"machine: {platform.node()} {os.cpu_count()} CPUs, {platform.processor() or platform.machine()}"
    )
    print("| mode | wall s | games played | trays |\n|---|---|---|---|")
    for mode, (wall, rep) in rows.items():
        trays = " / ".join("+".join(t) for t in rep["trays"])
        print(f"| {mode} | {wall:.1f} | {rep['runner']['played']} | {trays} |")
    print(f"ray / serial wall time: {rows['ray'][0] / rows['serial'][0]:.2f}")


if __name__ == "__main__":
    main()
