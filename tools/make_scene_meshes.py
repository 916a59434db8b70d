#!/usr/bin/env python
"""Regenerate the simple scene meshes in ``scenes/meshes/`` (binary STL, millimetres).

Usage::

    python tools/make_scene_meshes.py            # (re)write the STL files
    python tools/make_scene_meshes.py --check    # exit 1 if any file is missing or differs

The output is deterministic: the same inputs give byte-identical files. The copied test meshes
(``*.obj``) in the same folder are not touched; see ``scenes/meshes/SOURCES.md``.
"""

from __future__ import annotations

import argparse
import io
import os
import sys
from collections.abc import Callable

import trimesh

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

from sieve_mi.testing import catalogue, shapes  # noqa: E402

LETTERS = "SIGRAPH"
LETTER_HEIGHT = 30.0  # mm, y-extent of each glyph
LETTER_DEPTH = 12.0
EURO_COINS = {
    "2eur": (25.75, 2.20),
    "1eur": (23.25, 2.33),
    "50c": (24.25, 2.38),
    "20c": (22.25, 2.14),
    "10c": (19.75, 1.93),
    "5c": (21.25, 1.67),
    "2c": (18.75, 1.67),
    "1c": (16.25, 1.67),
}

# file name -> zero-argument builder; every size is in mm.
SPECS: dict[str, Callable[[], trimesh.Trimesh]] = {
    "cube.stl": lambda: shapes.cube(side=20.0),
    "sphere.stl": lambda: shapes.sphere(radius=12.0, subdivisions=3),
    "small_sphere.stl": lambda: shapes.sphere(radius=9.0, subdivisions=3),
    "l_rod.stl": lambda: shapes.l_rod(arm=20.0, side=2.0),
    "bowtie.stl": lambda: shapes.bowtie(width=30.0, height=20.0, thickness=6.0, waist=6.0),
    "arch.stl": lambda: shapes.arch(
        width=30.0, height=20.0, thickness=6.0, depth=10.0, segments=16
    ),
    "prism.stl": lambda: shapes.box(12.0, 12.0, 30.0),
    # euro coins, official diameter and thickness (mm): scenes/euro-coins.toml, euro-coins-8.toml
    **{
        f"coin_{label}.stl": (lambda d=d, t=t: shapes.coin(d, t))
        for label, (d, t) in EURO_COINS.items()
    },
    **{
        f"letter_{c}.stl": (lambda c=c: shapes.letter(c, height=LETTER_HEIGHT, depth=LETTER_DEPTH))
        for c in LETTERS
    },
    # toy bricks (solid, with studs) and AAA / AA cells from catalogue sizes (sieve_mi.testing.
    # catalogue): scenes/bricks.toml, scenes/batteries.toml
    "brick_1x2.stl": lambda: catalogue.brick(2, 1),
    "brick_2x2.stl": lambda: catalogue.brick(2, 2),
    "brick_2x4.stl": lambda: catalogue.brick(4, 2),
    "cell_aaa.stl": lambda: catalogue.cell(*catalogue.CELLS["AAA"]),
    "cell_aa.stl": lambda: catalogue.cell(*catalogue.CELLS["AA"]),
    # M3 / M4 / M5 hardware, catalogue sizes (mm): scenes/m3-vs-m4.toml, scenes/nuts-shaken.toml
    # ISO 4032 hex nuts: across flats, thickness (m max), bore = nominal thread diameter
    "nut_m3.stl": lambda: catalogue.hex_nut(across_flats=5.5, thickness=2.4, bore=3.0),
    "nut_m4.stl": lambda: catalogue.hex_nut(across_flats=7.0, thickness=3.2, bore=4.0),
    # M5 (scenes/nuts-shaken.toml): ISO 4032 s = 8, m max = 4.7 (DIN 934's M5 is 4.0 thick)
    "nut_m5.stl": lambda: catalogue.hex_nut(across_flats=8.0, thickness=4.7, bore=5.0),
    # ISO 7089 plain washer, size 3: outer diameter, inner diameter, thickness
    "washer_m3.stl": lambda: catalogue.washer(outer=7.0, inner=3.2, thickness=0.5),
}


def build() -> dict[str, trimesh.Trimesh]:
    """Build every scene mesh in memory, keyed by file name."""
    return {name: make() for name, make in SPECS.items()}


def stl_bytes(mesh: trimesh.Trimesh) -> bytes:
    """Binary STL encoding of ``mesh``."""
    buf = io.BytesIO()
    mesh.export(buf, file_type="stl")
    return buf.getvalue()


def _read(path: str) -> bytes | None:
    """File contents, or None if there is no such file."""
    if not os.path.exists(path):
        return None
    with open(path, "rb") as f:
        return f.read()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", default=os.path.join(REPO, "scenes", "meshes"), help="output folder"
    )
    parser.add_argument("--check", action="store_true", help="only compare with the files on disk")
    args = parser.parse_args(argv)

    os.makedirs(args.out, exist_ok=True)
    stale = []
    for name, mesh in build().items():
        path = os.path.join(args.out, name)
        data = stl_bytes(mesh)
        if args.check:
            if _read(path) != data:
                stale.append(name)
            continue
        with open(path, "wb") as f:
            f.write(data)
        ext = mesh.extents
        print(
            f"{name:18s} {len(mesh.faces):5d} faces  extents {ext[0]:7.3f} x {ext[1]:7.3f} x {ext[2]:7.3f} mm"
        )
    if stale:
        print(
            "out of date: " + ", ".join(stale) + " (run tools/make_scene_meshes.py)",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
