"""``sieve-mi sweep``: one scene over seeds (and tolerances), on the cascade's game engine.

Every (seed, tolerance) is one game; they run in parallel on Ray where it is installed. The kept
design is the one with the largest smallest margin: A must win, then the weakest B's β is as
large as it can be, then its protrusion (scene units).
"""

from __future__ import annotations

import copy
import os
import shutil

from sieve_mi.cascade.games import Engine, EngineSettings, GameSpec, game_key, weakest
from sieve_mi.cascade.outputs import copy_games, write_json
from sieve_mi.outputs import outdir
from sieve_mi.outputs.provenance import sha256
from sieve_mi.scene import Scene
from sieve_mi.telemetry import Run

__all__ = ["margin", "sweep_scene", "sweep_table"]


def margin(summary: dict) -> tuple:
    """A run's rank: (A won, weakest B's β, weakest B's protrusion); larger is better."""
    weak = weakest(summary)
    return (summary["winner"] == "A", weak["beta"], weak["protrusion"])


def _loaded(scene: Scene) -> tuple[Scene, dict]:
    """A copy of the scene with its meshes loaded into the entries, and their file digests."""
    from sieve_mi.geometry.meshes import load_trimesh, mesh_sha256

    scene = copy.deepcopy(scene)
    digests = {}
    for e in scene.passes + scene.blocks:
        e.name = e.name or os.path.splitext(os.path.basename(e.mesh))[0]
        if e.data is None:
            path = scene.resolve(e.mesh)
            e.data = load_trimesh(path)
            digests[e.name] = sha256(path)
        else:  # a mesh given in code: its arrays' bytes
            digests[e.name] = mesh_sha256(e.data.vertices, e.data.faces)
    return scene, digests


def sweep_scene(
    scene: Scene,
    out_dir: str,
    *,
    seeds: list[int],
    tolerances: list[float] | None = None,
    engine: EngineSettings | None = None,
) -> dict:
    """Solve ``scene`` for every seed and tolerance; write all runs and the best one.

    Writes ``out_dir/sweep.json`` (also as ``report.json``): ``"runs"`` (seed, tolerance,
    winner, weakest B, β, protrusion, seconds, folder), ``"best"`` (the kept run); every run's
    folder as ``solve`` writes it under ``games/``, and the kept one again as ``best/``.

    Parameters
    ----------
    scene : Scene
    out_dir : str
        The sweep's folder (refused unless empty, missing or an earlier sieve-mi output).
    seeds : list of int
    tolerances : list of float, optional
        ``[fabrication] tolerance`` values (scene units); default: the scene's.
    engine : EngineSettings, optional
        Where the games run (serially or on Ray), their Mitsuba variant, and the progress output
        (default: :class:`EngineSettings`' defaults).

    Returns
    -------
    dict
        ``sweep.json``.
    """
    run = Run().start()
    inputs = [scene.path] + [
        scene.resolve(e.mesh) for e in scene.passes + scene.blocks if e.data is None
    ]
    outdir.validate(out_dir, inputs=inputs)
    settings = (engine or EngineSettings()).resolved()
    base, digests = _loaded(scene)
    tolerances = tolerances or [base.fabrication.tolerance]
    specs = _specs(base, digests, seeds, tolerances, settings.variant)
    with Engine(out_dir, settings) as games:
        records = games.play(specs)
    runs = [_run_row(spec, records[spec.key]["summary"]) for spec in specs]
    best = max(runs, key=lambda r: r["rank"])
    report = {
        "scene": scene.path,
        "runs": [{k: v for k, v in r.items() if k != "rank"} for r in runs],
        "best": {k: v for k, v in best.items() if k != "rank"},
        "runner": games.info(),
        "timings": {"total_s": round(run.elapsed(), 3)},
    }
    with outdir.writing(out_dir, command="sweep", inputs=inputs) as tmp:
        copy_games(games.folders(), tmp)
        shutil.copytree(os.path.join(tmp, best["folder"]), os.path.join(tmp, "best"))
        write_json(os.path.join(tmp, "sweep.json"), report)
        write_json(os.path.join(tmp, "report.json"), report)
    games.clear_cache()
    return report


def _specs(base: Scene, digests: dict, seeds, tolerances, variant: str) -> list[GameSpec]:
    """One game per (tolerance, seed)."""
    specs = []
    for tol in tolerances:
        for seed in seeds:
            s = copy.deepcopy(base)
            s.fabrication.tolerance = tol
            s.solver.seed = seed
            key = game_key(f"seed{seed}-tol{tol:g}", s, seed, variant, digests)
            specs.append(GameSpec(key, s, seed, variant, {"seed": seed, "tolerance": tol}))
    return specs


def _run_row(spec: GameSpec, summary: dict) -> dict:
    """A run's row of the table: its weakest B and its rank (:func:`margin`)."""
    weak = weakest(summary)
    return {
        **spec.label,
        "winner": summary["winner"],
        "weakest": weak["name"],
        "beta": weak["beta"],
        "protrusion": weak["protrusion"],
        "game_s": summary.get("game_s"),
        "folder": f"games/{spec.key}",
        "rank": margin(summary),
    }


def sweep_table(report: dict) -> str:
    """All runs as text, the kept one marked with ``*``."""
    lines = [
        f"  {'seed':>5}{'tol':>7}  {'winner':<7}{'weakest B':<16}{'beta':>8}{'protr.':>9}{'s':>7}"
    ]
    best = report["best"]
    for r in report["runs"]:
        mark = "*" if r["folder"] == best["folder"] else " "
        lines.append(
            f"{mark} {r['seed']:>5}{r['tolerance']:>7g}  {r['winner']:<7}{r['weakest']:<16}"
            f"{r['beta']:>8.4f}{r['protrusion']:>9.3f}{(r['game_s'] or 0):>7.1f}"
        )
    lines.append(f"kept: seed {best['seed']}, tolerance {best['tolerance']:g} (folder best/)")
    return "\n".join(lines)
