"""Rest shares against MuJoCo drops: where a dropped part comes to rest on a still plate.

Usage: ``python -m benchmarks.rest_drops [--drops N] [--settle S] [--part brick_1x2|cube]``

Drops the part ``--drops`` times onto a still, solid 100 x 100 mm plate (the shake trials' drop:
uniform orientation, ``[shake] drop`` above the plate; :func:`sieve_mi.shake.trials.drop_state`),
lets it settle for ``--settle`` seconds, and counts the resting pose it ends in: the rest pose
(:func:`sieve_mi.geometry.pose_words.resting_poses`) whose down direction is nearest the body's,
within 5 degrees (else "unsettled"). Prints one Markdown row per rest pose: its position, down
direction, trimesh's quasi-static share and the drops' fraction with its 95 % Wilson interval.
"""

from __future__ import annotations

import argparse
import time

import manifold3d
import mujoco
import numpy as np

from sieve_mi.game.rest import Rests
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.rotations import to_matrix
from sieve_mi.shake.geometry import part_from_mesh, plate_from_outline
from sieve_mi.shake.model import build_model
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.stats import wilson
from sieve_mi.shake.trials import drop_state
from sieve_mi.testing import catalogue

PARTS = {
    "brick_1x2": lambda: catalogue.brick(2, 1),
    "cube": lambda: __import__("trimesh").creation.box((20.0, 20.0, 20.0)),
}
#: A settled part's down direction lies within this many degrees of a rest pose's.
SETTLED_DEG = 5.0


def drops(mesh, n: int, settle_s: float, settings: ShakeSettings) -> list[np.ndarray]:
    """The body's down direction (3,) after each of ``n`` drops, settled for ``settle_s``."""
    part = part_from_mesh(mesh, "part", None, 0.05)
    plate = plate_from_outline(manifold3d.CrossSection.square([20.0, 20.0], center=True), 40.0, 2.0)
    model = build_model(plate, part, settings, 1e-3, flat=True)
    data = mujoco.MjData(model)
    out = []
    for k in range(n):
        mujoco.mj_resetData(model, data)
        data.qpos[2:5], data.qpos[5:9] = drop_state(k, plate, part, settings, 1e-3)
        for _ in range(int(round(settle_s / model.opt.timestep))):
            mujoco.mj_step(model, data)
        out.append(to_matrix(np.asarray(data.qpos[5:9])).T @ [0.0, 0.0, -1.0])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drops", type=int, default=100)
    ap.add_argument("--settle", type=float, default=2.0)
    ap.add_argument("--part", default="brick_1x2", choices=sorted(PARTS))
    args = ap.parse_args()
    mesh = PARTS[args.part]()
    rests = Rests.of(shape_from_trimesh(mesh, name=args.part))
    t0 = time.perf_counter()
    downs = drops(mesh, args.drops, args.settle, ShakeSettings())
    seconds = time.perf_counter() - t0
    counts = np.zeros(len(rests.shares) + 1, int)
    for d in downs:
        angles = np.degrees(np.arccos(np.clip(rests.normals @ d, -1.0, 1.0)))
        k = int(np.argmin(angles))
        counts[k if angles[k] <= SETTLED_DEG else -1] += 1
    print(f"{args.part}: {args.drops} drops, settled {args.settle:g} s, {seconds:.0f} s wall")
    print("| rest pose | down | trimesh share | drops | fraction [95 % CI] |")
    print("| --- | --- | --- | --- | --- |")
    for k, (n, p) in enumerate(zip(rests.normals, rests.shares)):
        lo, hi = wilson(int(counts[k]), args.drops)
        print(f"| {rests.positions[k]} | {np.round(n, 2).tolist()} | {100 * p:.1f} % | "
              f"{counts[k]} | {100 * counts[k] / args.drops:.0f} % ({100 * lo:.0f}–{100 * hi:.0f} %) |")  # fmt: skip
    print(f"| unsettled (> {SETTLED_DEG:g}° from every rest pose) | | | {counts[-1]} | |")


if __name__ == "__main__":
    main()
