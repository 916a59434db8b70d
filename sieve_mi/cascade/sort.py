"""``sieve-mi sort``: design a cascade for a mixture and write its outputs."""

from __future__ import annotations

import os
import time

import numpy as np

from sieve_mi.cascade.games import Engine, GameSpec, game_key, ray_module
from sieve_mi.cascade.mixture import Mixture
from sieve_mi.cascade.outputs import (
    cascade_dict,
    copy_games,
    write_figure,
    write_json,
    write_plates,
)
from sieve_mi.cascade.plan import plan_cascade
from sieve_mi.cascade.purity import shake_plan
from sieve_mi.cascade.size import passage_radius
from sieve_mi.outputs import outdir
from sieve_mi.outputs.provenance import sha256
from sieve_mi.shake.settings import ShakeSettings

__all__ = ["prepare", "sort_mixture"]


def prepare(mixture: Mixture) -> tuple[dict, list, dict]:
    """Load every mesh into its entry (so games travel without files), hash the files, and
    measure the passage radii.

    Returns
    -------
    digests : dict
        sha256 of each shape's mesh file, by name.
    rows : list of dict
        Per shape: name, mesh, scale, passage radius and its view, bounding radius.
    icons : dict
        Per shape: its exact silhouette seen along the passage view, as polygons (for figures).
    """
    from sieve_mi.geometry.meshes import load_trimesh, shape_from_trimesh
    from sieve_mi.geometry.outline import silhouette
    from sieve_mi.geometry.rotations import align

    digests, rows, icons = {}, [], {}
    for e in mixture.shapes:
        path = mixture.resolve(e.mesh)
        e.data = load_trimesh(path)
        digests[e.name] = sha256(path)
        shape = shape_from_trimesh(e.data, name=e.name, scale=e.scale)
        radius, view = passage_radius(shape)
        rows.append(
            {
                "name": e.name,
                "mesh": e.mesh,
                "scale": e.scale,
                "passage_radius": radius,
                "view": [float(x) for x in view],
                "radius": float(shape.radius),
            }
        )
        sil = silhouette(shape, align(view, [0.0, 0.0, 1.0]), np.zeros(2))
        icons[e.name] = [np.asarray(p) for p in sil.to_polygons()]
    return digests, rows, icons


def sort_mixture(
    mixture: Mixture,
    out_dir: str,
    *,
    use_ray: bool | None = None,
    address: str | None = None,
    workers: int | None = None,
    variant: str | None = None,
    seed: int | None = None,
    progress: bool = True,
    shake: ShakeSettings | None = None,
) -> dict:
    """Design a cascade for ``mixture`` and write it to ``out_dir``; returns ``cascade.json``.

    Parameters
    ----------
    mixture : Mixture
    out_dir : str
        The cascade's folder (refused unless empty, missing or an earlier sieve-mi output).
        Finished games wait in ``<out_dir>.games`` until the folder is written.
    use_ray : bool, optional
        Run games as Ray tasks; default: when Ray is installed.
    address : str, optional
        A running Ray cluster (``host:port``).
    workers : int, optional
        CPUs for a local Ray (default: all of this machine's).
    variant : str, optional
    seed : int, optional
        Overrides ``[solver] seed`` for every game.
    progress : bool
    shake : ShakeSettings, optional
        Then shake each sieve with the parts that reach it, ``shake.trials`` parts per shape
        (:mod:`sieve_mi.cascade.purity`), into ``cascade.json``'s ``shake``.
    """
    from sieve_mi.backend import default_variant

    t0 = time.perf_counter()
    inputs = [mixture.path] + [mixture.resolve(e.mesh) for e in mixture.shapes]
    outdir.validate(out_dir, inputs=inputs)
    variant = variant or default_variant()
    seed = mixture.tables["solver"].seed if seed is None else seed
    use_ray = (ray_module() is not None) if use_ray is None else use_ray
    digests, shapes, icons = prepare(mixture)
    order = [r["name"] for r in sorted(shapes, key=lambda r: (-r["passage_radius"], r["name"]))]

    def make_spec(holds, passes) -> GameSpec:
        scene = mixture.scene(passes, holds, name="sieve", seed=seed)
        key = game_key("hold-" + "+".join(holds), scene, seed, variant, digests)
        label = {"holds": list(holds), "passes": list(passes)}
        return GameSpec(key, scene, seed, variant, label)

    engine = Engine(out_dir, use_ray=use_ray, address=address, workers=workers, progress=progress)
    with engine:
        plan = plan_cascade(order, engine.play, make_spec, parallel=use_ray)
    shaken = None if shake is None else shake_plan(plan, engine.folders(), mixture, shake, progress)
    games = [
        {
            "key": k,
            **r["label"],
            "winner": r["summary"]["winner"],
            "game_s": r["summary"].get("game_s"),
        }
        for k, r in engine.records.items()
    ]
    report = cascade_dict(
        plan,
        shapes=shapes,
        games=games,
        runner=engine.info(),
        timings={"total_s": round(time.perf_counter() - t0, 3)},
    )
    report["order"] = order
    if shaken is not None:
        report["shake"] = shaken
    spacing = 2.0 * max(r["radius"] for r in shapes)  # a gap the largest shape fits in
    _write(out_dir, inputs, plan, report, engine.folders(), spacing, mixture.units, icons)
    engine.clear_cache()
    return report


def _write(out_dir, inputs, plan, report, folders, spacing, units, icons) -> None:
    with outdir.writing(out_dir, command="sort", inputs=inputs) as tmp:
        copy_games(folders, tmp)
        report["files"] = write_plates(plan, tmp, spacing, units)
        write_figure(os.path.join(tmp, "cascade.png"), plan, units, icons)
        write_json(os.path.join(tmp, "cascade.json"), report)
        write_json(os.path.join(tmp, "report.json"), report)
