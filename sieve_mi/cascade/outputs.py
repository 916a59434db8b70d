"""A cascade's outputs: ``cascade.json``, the stacked plates, and the figure."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np

from sieve_mi.cascade.plan import Plan
from sieve_mi.outputs.palette import hex_colour
from sieve_mi.outputs.plots import draw_contours, grid_figure, plan_view, save, wrap

__all__ = [
    "CASCADE_PANEL",
    "cascade_dict",
    "cascade_figure",
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


#: cascade.png: the width of a panel, inches.
CASCADE_PANEL = 2.6


def write_figure(path: str, plan: Plan, units: str, icons: dict | None = None) -> None:
    """``cascade.png``: the picture of :func:`cascade_figure`."""
    save(cascade_figure(plan, units, icons), path)


def cascade_figure(plan: Plan, units: str, icons: dict | None = None):
    """cascade.png's figure: each sieve's exact hole, and under the sieves the trays they fill.

    The top row holds the sieves, left to right from the top of the stack; the row below holds
    the trays, one more than there are sieves (the last one catches what passes every sieve),
    so the sieves' row is centred over it, half a panel in: no cell is left empty. Every panel
    is to one scale, with axes and a scale bar in ``units``
    (:func:`~sieve_mi.outputs.plots.plan_view`); what a sieve holds and passes, and what a tray
    holds, are its panel's title, above the panel and wrapped to its width.

    Parameters
    ----------
    plan : Plan
    units : str
    icons : dict, optional
        Shape name -> list of (n, 2) polygons (its silhouette along its passage view), drawn in
        the trays at the holes' scale, left to right in the order the title names them.

    Returns
    -------
    matplotlib.figure.Figure
    """
    holes = [[np.asarray(p) for p in s.record["summary"]["outline"]] for s in plan.sieves]
    trays = [_tray_layout(names, icons or {}) for names in plan.trays]
    reach = max(
        [np.abs(p).max() for h in holes for p in h]
        + [np.abs(p).max() for row in trays for _, polys in row for p in polys]
        + [1.0]
    )
    size, lim = CASCADE_PANEL, 1.05 * reach
    sieve_titles = [wrap(_sieve_title(s, k), size, 8) for k, s in enumerate(plan.sieves)]
    tray_titles = [wrap(_tray_title(plan, k), size, 8) for k in range(len(trays))]
    texts = [t for t in (sieve_titles, tray_titles) if t]
    title = f"cascade, top to bottom (all panels to one scale, {units})"
    title = wrap(title, size * max(map(len, texts)) + 0.3, 10)  # the figure's width
    fig, rows = grid_figure(
        [len(t) for t in texts], size, 110, title_size=8, suptitle_lines=title.count("\n") + 1,
        title_lines=[max(t.count("\n") + 1 for t in row) for row in texts],
    )  # fmt: skip
    for k, ax in enumerate(rows[0] if holes else []):
        plan_view(ax, lim, units, plate=True, ylabel=k == 0)
        draw_contours(
            ax, holes[k], facecolor=hex_colour("hole"), edgecolor=hex_colour("edge"), linewidth=1.0
        )
        ax.set_title(sieve_titles[k], fontsize=8)
    for k, ax in enumerate(rows[-1]):
        plan_view(ax, lim, units, ylabel=k == 0)
        for _, polys in trays[k]:
            draw_contours(
                ax, polys, facecolor=hex_colour("tray"), edgecolor=hex_colour("edge"), linewidth=0.8
            )
        ax.set_title(tray_titles[k], fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _sieve_title(sieve, k: int) -> str:
    """Sieve k's title: what it holds and what it passes."""
    return f"sieve {k + 1} holds {' + '.join(sieve.holds)}\npasses: {', '.join(sieve.passes)}"


def _tray_title(plan: Plan, k: int) -> str:
    """Tray k's title: which sieve it lies under and the shapes it holds, left to right."""
    names = plan.trays[k]
    where = (
        f"on sieve {k + 1}" if k < len(plan.sieves) else "under every sieve" if plan.sieves else ""
    )
    order = " (left to right)" if len(names) > 1 else ""
    return f"tray {k + 1}{', ' + where if where else ''}: {' + '.join(names)}{order}"


def _tray_layout(names: list, icons: dict) -> list:
    """The shapes of one tray side by side, centred on the origin: [(name, polygons), ...]."""
    placed, x, right = [], 0.0, 0.0
    for name in names:
        polys = [np.asarray(p, dtype=float) for p in icons.get(name, [])]
        if polys:
            pts = np.concatenate(polys)
            centre_y = 0.5 * (pts[:, 1].min() + pts[:, 1].max())
            shift = np.array([x - pts[:, 0].min(), -centre_y])
            polys = [p + shift for p in polys]
            right = x + pts[:, 0].max() - pts[:, 0].min()
            x = right + 0.15 * (pts[:, 0].max() - pts[:, 0].min())
        placed.append((name, polys))
    return [(name, [p - [right / 2, 0.0] for p in polys]) for name, polys in placed]


def write_json(path: str, data: dict) -> None:
    with open(path, "w") as fh:
        json.dump(data, fh, indent=2)
