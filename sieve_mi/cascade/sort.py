"""``sieve-mi sort``: design a cascade for a mixture and write its outputs.

Before any game, every shape is measured (:func:`prepare`) and every ordered pair of shapes is
checked by the exact rules (:class:`~sieve_mi.cascade.rules.Rules`); the planner
(:func:`~sieve_mi.cascade.plan.plan_cascade`) then screens the candidates that the rules leave
at reduced settings (:mod:`sieve_mi.cascade.stages`) and plays full games for the planned
sieves only.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from sieve_mi.cascade.games import Engine, EngineSettings, GameSpec, game_key
from sieve_mi.cascade.mixture import Mixture
from sieve_mi.cascade.outputs import (
    cascade_dict,
    copy_games,
    write_figure,
    write_json,
    write_plates,
)
from sieve_mi.cascade.plan import plan_cascade
from sieve_mi.cascade.rules import Body, Rules, body
from sieve_mi.cascade.stages import FULL, SCREEN, screening_tables, worth_screening
from sieve_mi.geometry.size import passage_radius
from sieve_mi.outputs import outdir
from sieve_mi.outputs.provenance import sha256
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.telemetry import Run

__all__ = ["prepare", "rules_for", "sort_mixture"]


def prepare(mixture: Mixture) -> tuple[dict, list, dict, list]:
    """Load every mesh into its entry (so games travel without files), hash the files, and
    measure the shapes.

    Returns
    -------
    digests : dict
        sha256 of each shape's mesh file, by name.
    rows : list of dict
        Per shape: name, mesh, scale, passage radius and its view, bounding radius, canonical
        extents (largest first), whether it is convex (only a convex shape rules holds out), its
        inscribed ball's radius and its end-first radius (scene units).
    icons : dict
        Per shape: its exact silhouette seen along the passage view, as polygons (for figures).
    bodies : list of Body
        What the rules need of each shape (:func:`sieve_mi.cascade.rules.body`).
    """
    from sieve_mi.geometry.meshes import load_trimesh, shape_from_trimesh
    from sieve_mi.geometry.outline import silhouette
    from sieve_mi.geometry.rotations import align

    digests, rows, icons, bodies = {}, [], {}, []
    for e in mixture.shapes:
        path = mixture.resolve(e.mesh)
        e.data = load_trimesh(path)
        digests[e.name] = sha256(path)
        shape = shape_from_trimesh(e.data, name=e.name, scale=e.scale)
        radius, view = passage_radius(shape)
        b = body(shape)
        rows.append(
            {
                "name": e.name,
                "mesh": e.mesh,
                "scale": e.scale,
                "passage_radius": radius,
                "view": [float(x) for x in view],
                "radius": float(shape.radius),
                "extents": [round(float(x), 6) for x in b.extents],
                "convex": b.convex,
                "inscribed_ball": round(b.ball, 6),
                "end_first_radius": round(b.end_first, 6),
            }
        )
        bodies.append(b)
        sil = silhouette(shape, align(view, [0.0, 0.0, 1.0]), np.zeros(2))
        icons[e.name] = [np.asarray(p) for p in sil.to_polygons()]
    return digests, rows, icons, bodies


def rules_for(mixture: Mixture, bodies: list[Body]) -> Rules:
    """The exact rules for a mixture's shapes, with its growth: ``[fabrication] tolerance +
    block_margin`` (scene units; a held shape is blocked only if it fails against the hole grown
    by the block margin too)."""
    fab = mixture.tables["fabrication"]
    return Rules(bodies, fab.tolerance + fab.block_margin, mixture.units)


def sort_mixture(
    mixture: Mixture,
    out_dir: str,
    *,
    engine: EngineSettings | None = None,
    seed: int | None = None,
    shake: ShakeSettings | None = None,
) -> dict:
    """Design a cascade for ``mixture`` and write it to ``out_dir``; returns ``cascade.json``.

    Parameters
    ----------
    mixture : Mixture
    out_dir : str
        The cascade's folder (refused unless empty, missing or an earlier sieve-mi output).
        Finished games wait in ``<out_dir>.games`` until the folder is written.
    engine : EngineSettings, optional
        Where the games run (serially or on Ray), their Mitsuba variant, and the progress output
        (default: :class:`EngineSettings`' defaults).
    seed : int, optional
        Overrides ``[solver] seed`` for every game.
    shake : ShakeSettings, optional
        Then shake each sieve with the parts that reach it, ``shake.trials`` parts per shape
        (:mod:`sieve_mi.cascade.purity`), into ``cascade.json``'s ``shake``.
    """
    run = Run().start()
    with run.stage("measure"):  # the rules' time included
        inputs = [mixture.path] + [mixture.resolve(e.mesh) for e in mixture.shapes]
        outdir.validate(out_dir, inputs=inputs)
        settings = (engine or EngineSettings()).resolved()
        seed = mixture.tables["solver"].seed if seed is None else seed
        digests, shapes, icons, bodies = prepare(mixture)
        order = [r["name"] for r in sorted(shapes, key=lambda r: (-r["passage_radius"], r["name"]))]
        rules = rules_for(mixture, bodies)
    make_spec, screen_spec = _spec_makers(mixture, seed, settings.variant, digests)
    with Engine(out_dir, settings) as games:
        plan = plan_cascade(
            order,
            games.play,
            make_spec,
            parallel=settings.use_ray,
            screen_spec=screen_spec,
            hopeless=rules.hopeless,
            margin=rules.margin,
        )
    folders = games.folders()
    shaken = None
    if shake is not None:  # MuJoCo (the optional extra sieve-mi[shake]) is imported only then
        from sieve_mi.cascade.purity import shake_plan

        shaken = shake_plan(plan, folders, mixture, shake, settings.progress)
    report = cascade_dict(
        plan,
        shapes=shapes,
        games=_games(games.records),
        runner=games.info(),
        timings={
            "measure_s": round(run.timings["measure_s"], 3),
            "rules_s": round(rules.seconds, 3),
            "total_s": round(run.elapsed(), 3),
        },
    )
    report["rules"] = {"grow": rules.grow, "ruled_out": rules.table()}
    report["levels"] = plan.levels
    report["screening"] = None if screen_spec is None else screen_spec.settings
    report["order"] = order
    if shaken is not None:
        report["shake"] = shaken
    spacing = 2.0 * max(r["radius"] for r in shapes)  # a gap the largest shape fits in
    _write(out_dir, inputs, plan, report, folders, spacing, mixture.units, icons)
    games.clear_cache()
    return report


def _games(records: dict) -> list[dict]:
    """``cascade.json``'s games: every game played or reused, with its stage (screen or full)."""
    return [
        {
            "key": k,
            **r["label"],
            "stage": r["label"].get("stage", FULL),
            "winner": r["summary"]["winner"],
            "game_s": r["summary"].get("game_s"),
        }
        for k, r in records.items()
    ]


def _spec_makers(mixture: Mixture, seed: int, variant: str, digests: dict):
    """``make_spec(holds, passes)`` of the full games and ``screen_spec`` of the screening games
    (:mod:`sieve_mi.cascade.stages`; None where they are not worth playing), each a
    :class:`GameSpec` labelled with its stage. ``screen_spec.settings`` holds the screening
    games' ``[solver]``, ``[verdict]`` and ``[layout]`` tables as dicts."""
    lowered = screening_tables(mixture.tables)
    screened = dataclasses.replace(mixture, tables=lowered)
    names = ("solver", "verdict", "layout")

    def maker(source: Mixture, stage: str, prefix: str):
        def make_spec(holds, passes) -> GameSpec:
            scene = source.scene(passes, holds, name="sieve", seed=seed)
            key = game_key(prefix + "+".join(holds), scene, seed, variant, digests)
            label = {"holds": list(holds), "passes": list(passes), "stage": stage}
            return GameSpec(key, scene, seed, variant, label)

        return make_spec

    worth = worth_screening(mixture.tables, lowered)
    screen_spec = maker(screened, SCREEN, "screen-hold-") if worth else None
    if screen_spec is not None:
        screen_spec.settings = {n: dataclasses.asdict(lowered[n]) for n in names}
    return maker(mixture, FULL, "hold-"), screen_spec


def _write(out_dir, inputs, plan, report, folders, spacing, units, icons) -> None:
    with outdir.writing(out_dir, command="sort", inputs=inputs) as tmp:
        copy_games(folders, tmp)
        report["files"] = write_plates(plan, tmp, spacing, units)
        write_figure(os.path.join(tmp, "cascade.png"), plan, units, icons)
        write_json(os.path.join(tmp, "cascade.json"), report)
        write_json(os.path.join(tmp, "report.json"), report)
