"""A cascade's outputs: ``cascade.json``, the stacked plates, and the figure."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np

from sieve_mi.cascade.plan import Plan


def sieve_rows(plan: Plan) -> list[dict]:
    """One row per sieve, top to bottom: what it holds and passes, winner, margins, folder.

    The margins are those of the weakest held shape: its β (share of its silhouette outside the
    hole) and protrusion (scene units) in its best attempt; ``certified`` where the games ran
    with ``[verdict] certify``.
    """
    rows = []
    for k, s in enumerate(plan.sieves):
        summary = s.record["summary"]
        held = [b for b in summary["block"] if b["name"] in s.holds]
        row = {
            "index": k,
            "holds": list(s.holds),
            "passes": list(s.passes),
            "winner": summary["winner"],
            "margins": {
                "beta": min(b["beta"] for b in held),
                "protrusion": min(b["protrusion"] for b in held),
            },
            "blocks": [
                {
                    key: b[key]
                    for key in ("name", "blocked", "beta", "protrusion", "certified")
                    if key in b
                }
                for b in held
            ],
            "hole_area": summary["hole"]["area"],
            "folder": f"games/{s.key}",
        }
        rows.append(row)
    return rows


def cascade_dict(plan: Plan, *, shapes: list, games: list, runner: dict, timings: dict) -> dict:
    """``cascade.json``'s content (also written as the folder's ``report.json``)."""
    return {
        "trays": plan.trays,
        "sieves": sieve_rows(plan),
        "inseparable": [
            {"pair": list(i.pair), "reason": i.reason, "games": i.keys} for i in plan.inseparable
        ],
        "shapes": shapes,
        "games": games,
        "runner": runner,
        "warnings": plan.warnings,
        "timings": timings,
    }


def copy_games(folders: dict, dest: str) -> None:
    """Copy every game folder (``{key: path}``) into ``dest/games/<key>/``."""
    for key, path in folders.items():
        shutil.copytree(path, os.path.join(dest, "games", key))


def stacked_plates(plan: Plan, game_dir: str, gap: float):
    """The sieves' plates stacked top to bottom with ``gap`` between them (scene units), one mesh.

    Sieve 0's top is at z = 0; each plate lies ``gap`` below the one above it and is centred on
    its hole. Returns None when there is no sieve.
    """
    import trimesh

    parts, top = [], 0.0
    for s in plan.sieves:
        plate = trimesh.load(os.path.join(game_dir, s.key, "sieve.stl"), force="mesh")
        lo, hi = plate.bounds[:, 2]
        plate.apply_translation([0.0, 0.0, top - hi])
        parts.append(plate)
        top -= (hi - lo) + gap
    return trimesh.util.concatenate(parts) if parts else None


def write_plates(plan: Plan, tmp: str, gap: float, units: str) -> list[str]:
    """``cascade.stl`` and ``cascade.3mf`` in ``tmp``; returns the names written."""
    from sieve_mi.fabrication import UNIT_NAMES, write_3mf

    mesh = stacked_plates(plan, os.path.join(tmp, "games"), gap)
    if mesh is None:
        return []
    mesh.export(os.path.join(tmp, "cascade.stl"))
    write_3mf(os.path.join(tmp, "cascade.3mf"), mesh, UNIT_NAMES.get(units, "millimeter"))
    return ["cascade.stl", "cascade.3mf"]


def write_figure(path: str, plan: Plan, units: str) -> None:
    """``cascade.png``: each sieve's exact hole, top to bottom, with the tray it fills."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = max(1, len(plan.sieves))
    fig, axes = plt.subplots(1, n, figsize=(3.4 * n, 4.3), squeeze=False)
    for k, s in enumerate(plan.sieves):
        ax = axes[0, k]
        for poly in s.record["summary"]["outline"]:
            p = np.asarray(poly)
            ax.fill(p[:, 0], p[:, 1], color="#9ecae1", edgecolor="#08519c", linewidth=1.0)
        ax.set_aspect("equal")
        ax.set_title(f"sieve {k + 1}\nholds: {', '.join(s.holds)}", fontsize=9)
        ax.set_xlabel(f"passes: {', '.join(s.passes)}\n({units})", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.suptitle(
        "cascade, top to bottom — trays: " + " | ".join("+".join(t) for t in plan.trays),
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_json(path: str, data: dict) -> None:
    with open(path, "w") as fh:
        json.dump(data, fh, indent=2)
