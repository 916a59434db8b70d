"""A cascade's outputs: ``cascade.json``, the stacked plates, and the figure."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np

from sieve_mi.cascade.plan import Plan
from sieve_mi.outputs.palette import hex_colour

__all__ = [
    "cascade_dict",
    "copy_games",
    "plate_names",
    "side_by_side",
    "sieve_rows",
    "stacked_plates",
    "write_figure",
    "write_json",
    "write_plates",
]


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


def _plates(plan: Plan, game_dir: str) -> list:
    """Each sieve's plate (its game's sieve.stl), top sieve first."""
    import trimesh

    return [
        trimesh.load(os.path.join(game_dir, s.key, "sieve.stl"), force="mesh") for s in plan.sieves
    ]


def plate_names(plan: Plan) -> list[str]:
    """A name per sieve for slicers: ``sieve_<k>_holds_<shapes>`` (k from 1, top first)."""
    names = [f"sieve_{k + 1}_holds_{'+'.join(s.holds)}" for k, s in enumerate(plan.sieves)]
    return ["".join(c if c.isalnum() or c in "-_+" else "_" for c in n) for n in names]


def stacked_plates(plan: Plan, game_dir: str, gap: float):
    """The sieves' plates stacked top to bottom with ``gap`` between them (scene units), one mesh.

    Sieve 0's top is at z = 0; each plate lies ``gap`` below the one above it and is centred on
    its hole. Returns None when there is no sieve.
    """
    import trimesh

    parts, top = [], 0.0
    for plate in _plates(plan, game_dir):
        lo, hi = plate.bounds[:, 2]
        plate.apply_translation([0.0, 0.0, top - hi])
        parts.append(plate)
        top -= (hi - lo) + gap
    return trimesh.util.concatenate(parts) if parts else None


def side_by_side(plates: list, gap: float) -> list:
    """The plates on the print bed: left to right along +x, ``gap`` apart, each on z = 0 and
    centred on y = 0 (new meshes; the inputs are not moved)."""
    out, x = [], 0.0
    for plate in plates:
        m = plate.copy()
        lo, hi = m.bounds
        m.apply_translation([x - lo[0], -0.5 * (lo[1] + hi[1]), -lo[2]])
        out.append(m)
        x += (hi[0] - lo[0]) + gap
    return out


def write_plates(plan: Plan, tmp: str, gap: float, units: str) -> list[str]:
    """``cascade.stl`` (the plates stacked as they are used) and ``cascade.3mf`` (one named object
    per plate, side by side on the bed, for a slicer) in ``tmp``; returns the names written."""
    from sieve_mi.outputs.fabrication import UNIT_NAMES, write_objects_3mf

    game_dir = os.path.join(tmp, "games")
    mesh = stacked_plates(plan, game_dir, gap)
    if mesh is None:
        return []
    mesh.export(os.path.join(tmp, "cascade.stl"))
    bed = side_by_side(_plates(plan, game_dir), min(gap, 10.0))
    objects = list(zip(plate_names(plan), bed))
    write_objects_3mf(
        os.path.join(tmp, "cascade.3mf"), objects, UNIT_NAMES.get(units, "millimeter")
    )
    return ["cascade.stl", "cascade.3mf"]


def write_figure(path: str, plan: Plan, units: str, icons: dict | None = None) -> None:
    """``cascade.png``: each sieve's exact hole, top to bottom, and below it the tray it fills.

    Parameters
    ----------
    path : str
    plan : Plan
    units : str
    icons : dict, optional
        Shape name -> list of (n, 2) polygons (its silhouette along its passage view), drawn in
        the trays at the holes' scale.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trays = plan.trays
    n = len(trays)
    holes = [[np.asarray(p) for p in s.record["summary"]["outline"]] for s in plan.sieves]
    rows = [_tray_layout(names, icons or {}) for names in trays]
    reach = max(
        [np.abs(p).max() for h in holes for p in h]
        + [np.abs(p).max() for row in rows for _, polys in row for p in polys]
        + [1.0]
    )
    fig, axes = plt.subplots(2, n, figsize=(2.8 * n, 6.2), squeeze=False)
    for k in range(n):
        top, tray = axes[0, k], axes[1, k]
        if k < len(plan.sieves):
            top.set_facecolor(hex_colour("material"))
            for p in holes[k]:
                top.fill(
                    *p.T, color=hex_colour("hole"), edgecolor=hex_colour("edge"), linewidth=1.0
                )
            top.set_title(f"sieve {k + 1}", fontsize=9)
            top.text(
                0.5, 0.02, "passes: " + ", ".join(plan.sieves[k].passes), transform=top.transAxes,
                ha="center", va="bottom", fontsize=7, wrap=True,
            )  # fmt: skip
            top.tick_params(labelsize=7)
        else:
            top.axis("off")
        for name, polys in rows[k]:
            for p in polys:
                tray.fill(
                    *p.T, color=hex_colour("tray"), edgecolor=hex_colour("edge"), linewidth=0.8
                )
            if polys:
                pts = np.concatenate(polys)
                tray.text(pts[:, 0].mean(), -reach * 0.95, name, ha="center", fontsize=8)
        tray.set_title(f"tray {k + 1}: " + " + ".join(trays[k]), fontsize=9)
        tray.axis("off")
        for ax in (top, tray):
            ax.set_xlim(-reach * 1.05, reach * 1.05)
            ax.set_ylim(-reach * 1.05, reach * 1.05)
            ax.set_aspect("equal")
    fig.suptitle(f"cascade, top to bottom (all panels to one scale, {units})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _tray_layout(names: list, icons: dict) -> list:
    """The shapes of one tray side by side, centred on the origin: [(name, polygons), ...]."""
    placed, x = [], 0.0
    for name in names:
        polys = [np.asarray(p, dtype=float) for p in icons.get(name, [])]
        if polys:
            pts = np.concatenate(polys)
            centre_y = 0.5 * (pts[:, 1].min() + pts[:, 1].max())
            shift = np.array([x - pts[:, 0].min(), -centre_y])
            polys = [p + shift for p in polys]
            x += (pts[:, 0].max() - pts[:, 0].min()) * 1.15
        placed.append((name, polys))
    width = x / 1.15 if x else 0.0
    return [(name, [p - [width / 2, 0.0] for p in polys]) for name, polys in placed]


def write_json(path: str, data: dict) -> None:
    with open(path, "w") as fh:
        json.dump(data, fh, indent=2)
