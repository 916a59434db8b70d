"""Writing a solve's outputs: report.json, hole and mask images, convergence and overlay plots.

Everything is written into a temporary folder beside the destination and swapped into place at
the end by :mod:`sieve_mi.outputs.outdir`, so an interrupted or failed run never leaves half-written
outputs, and a folder that sieve-mi did not write is never replaced.
"""

from __future__ import annotations

import json
import os
import time

import numpy as np

from sieve_mi.backend import bitmap_threads
from sieve_mi.game.result import Result
from sieve_mi.geometry.meshes import mesh_sha256
from sieve_mi.geometry.pixels import png_metadata
from sieve_mi.outputs import outdir
from sieve_mi.outputs.palette import block_colour, hex_colour
from sieve_mi.outputs.plots import draw_contours, grid_figure, new_figure, plan_view, save, wrap
from sieve_mi.outputs.provenance import provenance

__all__ = [
    "GAME_VALUE",
    "MERGED_VALUE",
    "OVERLAY_COLUMNS",
    "OVERLAY_PANEL",
    "STAGES",
    "convergence_figure",
    "exr_metadata",
    "memory_dict",
    "memory_line",
    "stage_line",
    "input_paths",
    "mask_layers",
    "merge_hint",
    "overlay_figure",
    "paste_window",
    "rendered_masks",
    "report_dict",
    "summary_table",
    "window_origin",
    "write_exr",
    "write_layers",
    "write_outputs",
    "write_png",
]


def _safe(name: str) -> str:
    """A file-name-safe version of a shape name."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def write_exr(path: str, image: np.ndarray, metadata: dict | None = None) -> None:
    """Write a single-channel float32 OpenEXR image with Mitsuba's Bitmap, plus header metadata.

    Parameters
    ----------
    path : str
    image : (H, W) ndarray
        Row 0 at the top.
    metadata : dict of str to float or str, optional
        Header attributes (:func:`exr_metadata`).
    """
    import mitsuba as mi

    bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    header = bitmap.metadata()
    for key, value in (metadata or {}).items():
        header[key] = value
    with bitmap_threads():
        bitmap.write(path)


def exr_metadata(result: Result, origin: tuple[float, float] | None = None) -> dict:
    """The header every written EXR carries: pixel size, units, top-left corner, sieve-mi version.

    Parameters
    ----------
    result : Result
    origin : (float, float), optional
        Scene (x, y) of the image's top-left corner; default the hole frame's.
    """
    from sieve_mi.outputs.provenance import VERSION

    frame = result.hole.frame
    x0, y0 = origin if origin is not None else (-frame.half_extent, frame.half_extent)
    return {
        "pixel_size": float(frame.pixel_size),
        "units": result.scene.units,
        "frame_origin": f"{float(x0)!r} {float(y0)!r}",
        "frame_note": "frame_origin is the top-left corner (x y); row 0 at the top, +y up",
        "software": f"sieve-mi {VERSION}",
    }


def write_layers(path: str, layers: dict, metadata: dict) -> None:
    """Write a multi-layer OpenEXR: one named float32 channel per (N, N) array, plus metadata.

    Parameters
    ----------
    path : str
    layers : dict of str to (N, N) ndarray
        Channel name to image (row 0 at the top); all of one size.
    metadata : dict of str to float or str
        Header attributes (e.g. the pixel size), shown by viewers such as tev.
    """
    import mitsuba as mi

    names = list(layers)
    stack = np.stack([np.asarray(layers[n], dtype=np.float32) for n in names], axis=-1)
    bitmap = mi.Bitmap(
        np.ascontiguousarray(stack),
        pixel_format=mi.Bitmap.PixelFormat.MultiChannel,
        channel_names=names,
    )
    header = bitmap.metadata()
    for key, value in metadata.items():
        header[key] = value
    with bitmap_threads():
        bitmap.write(path)


def paste_window(window, frame) -> np.ndarray:
    """A B attempt's mask window (:class:`~sieve_mi.game.scoring.MaskWindow`) on the frame's lattice.

    The window is a piece of the same pixel lattice, possibly reaching beyond the frame; what lies
    beyond is cut off. Returns an (N, N) bool array.
    """
    mask, n = window.mask, frame.resolution
    row0, col0 = window_origin(window, frame)
    out = np.zeros((n, n), dtype=bool)
    r0, c0 = max(row0, 0), max(col0, 0)
    r1, c1 = min(row0 + mask.shape[0], n), min(col0 + mask.shape[1], n)
    if r1 > r0 and c1 > c0:
        out[r0:r1, c0:c1] = mask[r0 - row0 : r1 - row0, c0 - col0 : c1 - col0]
    return out


def window_origin(window, frame) -> tuple[int, int]:
    """Lattice (row, column) of a :class:`~sieve_mi.game.scoring.MaskWindow`'s top-left pixel."""
    x0, _, _, y1 = window.extent
    h = frame.pixel_size
    return int(round((frame.half_extent - y1) / h)), int(round((x0 + frame.half_extent) / h))


def rendered_masks(result: Result) -> tuple[list, list]:
    """The silhouettes that get written, rendered by Mitsuba (``mi.render`` under the lattice's
    orthographic sensors, :meth:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.render`).

    Returns
    -------
    a : list of (N, N) bool ndarrays
        Each A at its pass pose, on the hole's frame (equal to ``result.a_masks``).
    b : list of MaskWindow
        Each B in its best attempt, on the window of ``result.block_masks`` (equal to it).
    """
    from sieve_mi.game.scoring import MaskWindow
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    frame = result.hole.frame
    a = [
        SilhouetteRenderer(shape).render(q, t, frame)
        for shape, q, t in zip(result.pass_shapes, result.pass_quats, result.pass_trans)
    ]
    b = []
    for j, (shape, window) in enumerate(zip(result.block_shapes, result.block_masks)):
        row0, col0 = window_origin(window, frame)
        q, t = result.attack.quats[0, j], result.attack.trans[0, j]
        mask = SilhouetteRenderer(shape).render(q, t, frame, row0, col0, window.mask.shape[0])
        b.append(MaskWindow(window.extent, mask))
    return a, b


def mask_layers(result: Result, rendered: tuple | None = None) -> dict:
    """The layers of ``masks.exr``: the exact hole at pixel centres, the conservative raster the
    attack used, player B's distance field (scene units), every A's silhouette and every B's best
    attempt, all on the hole's lattice.

    Channel names follow OpenEXR's ``layer.channel`` rule (the layer is the text before the last
    dot), one luminance channel ``Y`` per layer: ``hole.Y``, ``cover.Y``, ``distance.Y``,
    ``a<i>_<name>.Y``, ``b<j>_<name>.Y``. ``rendered`` is :func:`rendered_masks`'s answer
    (computed when not given).
    """
    from sieve_mi.geometry.outline import rasterize

    hole = result.hole
    a_masks, b_windows = rendered_masks(result) if rendered is None else rendered
    layers = {
        "hole.Y": rasterize(result.outline, hole.frame),
        "cover.Y": hole.mask,
        "distance.Y": hole.outside,
    }
    for i, (m, shape) in enumerate(zip(a_masks, result.pass_shapes)):
        layers[f"a{i}_{_safe(shape.name)}.Y"] = m
    for j, (shape, window) in enumerate(zip(result.block_shapes, b_windows)):
        layers[f"b{j}_{_safe(shape.name)}.Y"] = paste_window(window, hole.frame)
    return layers


def write_png(
    path: str, mask: np.ndarray, pixel_size: float | None = None, units: str = "mm"
) -> None:
    """Write a binary mask as an 8-bit grey PNG (white = inside).

    With ``pixel_size`` (in ``units``) the PNG records it: ``pHYs`` in pixels per metre and the
    exact value as text (:func:`sieve_mi.geometry.pixels.png_metadata`).
    """
    from PIL import Image

    extra = {} if pixel_size is None else png_metadata(pixel_size, units)
    Image.fromarray((np.asarray(mask) > 0).astype(np.uint8) * 255).save(path, "PNG", **extra)


def _block_row(result: Result, j: int) -> dict:
    """report.json's row of B number ``j``."""
    entry, shape, attack = result.scene.blocks[j], result.block_shapes[j], result.attack
    beta = float(attack.beta[0, j])
    row = {
        "mesh": entry.mesh,
        "name": shape.name,
        "beta": beta,
        "loss": beta,  # the same β, under its old name (kept for compatibility)
        "blocked": bool(attack.blocked()[0, j]),
        "protrusion": float(attack.protrusion[0, j]),
        "verdict": "exact-polygon",
        "rotation": [float(x) for x in attack.quats[0, j]],
        "translation": [float(x) for x in attack.trans[0, j]],
        "fitting_starts": int(attack.fits[0, j]),
        "centre": [float(x) for x in shape.centre],
        "faces": shape.face_count,
    }
    c = result.certified[j] if j < len(result.certified) else None
    if c is not None:
        row["certified"] = c.status
        row["certification"] = c.to_dict()
        if c.status == "passage":  # the exact hole lets it through: not blocked after all
            row["blocked"] = False
    if row["blocked"]:
        grown = result.scene.fabrication.block_margin
        row["margin"] = block_margin(shape, result.outline, row["protrusion"], c, grown)
    thin = result.sheet.per_block[j] if getattr(result, "sheet", None) is not None else None
    if thin is not None:
        row["thin_plate"] = thin.to_dict()
        if thin.status == "passage":  # through the thin plate by tilting and turning
            row["blocked"] = False
    if attack.margin_beta is not None:
        row["margin_beta"] = float(attack.margin_beta[0, j])
        row["margin_loss"] = row["margin_beta"]
        row["margin_protrusion"] = float(attack.margin_protrusion[0, j])
    return row


def report_dict(result: Result) -> dict:
    """The content of ``report.json``."""
    scene = result.scene
    passes = []
    for i, (entry, shape) in enumerate(zip(scene.passes, result.pass_shapes)):
        passes.append(
            {
                "mesh": entry.mesh,
                "name": shape.name,
                "rotation": [float(x) for x in result.pass_quats[i]],
                "translation": [float(x) for x in result.pass_trans[i]],
                "centre": [float(x) for x in shape.centre],
                "faces": shape.face_count,
            }
        )
        if i < len(result.alone) and result.alone[i] is not None:
            passes[-1]["alone_loss"] = float(result.alone[i])
    blocks = [_block_row(result, j) for j in range(len(scene.blocks))]
    hole = result.hole
    return {
        "name": scene.name,
        "winner": result.winner,
        "pass": passes,
        "block": blocks,
        "hole": {
            "area": float(result.outline.area()),
            "raster_area": hole.area,
            "resolution": hole.frame.resolution,
            "half_extent": hole.frame.half_extent,
        },
        "settings": _settings(result),
        "variant": result.variant,
        "provenance": _provenance(result),
        "search_value": None if np.isnan(result.search_value) else float(result.search_value),
        "convergence": [float(x) for x in result.history.best],
        "stages": [{"stage": label, "iterations": n} for label, n in result.stages],
        "polish": list(result.polish),
        "warnings": list(result.warnings),
        "timings": {k: round(float(v), 4) for k, v in result.timings.items()},
        "memory": memory_dict(result.memory),
        "pixel_size": hole.frame.pixel_size,
        "units": scene.units,
        "conventions": "rotation q = (w, x, y, z) acts on the mesh's points about its centre (bounding-box centre, "
        "given in file units times scale); the silhouette is the projection onto the xy-plane; "
        "translations are in the xy-plane in scene units, relative to the hole's centre",
    }


def _settings(result: Result) -> dict:
    """The settings that ran: the scene's, with the seed that was used (``--seed`` overrides)."""
    out = result.scene.settings()
    if result.seed is not None and "solver" in out:
        out["solver"] = dict(out["solver"], seed=int(result.seed))
    return out


def _provenance(result: Result) -> dict:
    """report.json's provenance; a mesh built in code is hashed by its vertex and face bytes."""

    scene = result.scene
    entries = scene.passes + scene.blocks
    files = [(e.mesh, scene.resolve(e.mesh)) for e in entries if e.data is None]
    out = provenance(scene.path, files, result.variant, result.seed)
    from_files = iter(out["meshes"])
    meshes = []
    for e in entries:
        if e.data is None:
            meshes.append(next(from_files))
        else:
            meshes.append({"mesh": e.mesh, "sha256": mesh_sha256(e.data.vertices, e.data.faces)})
    out["meshes"] = meshes
    return out


#: overlay.png: the width of a panel (inches) and the most panels in a row.
OVERLAY_PANEL = 3.6
OVERLAY_COLUMNS = 4


#: convergence.png's y label: the game value (one A, or separate holes) ...
GAME_VALUE = "best game value (min beta)"
#: ... or, for several A merged into one hole, each A's search, then the placement's energy.
MERGED_VALUE = "best min beta, then eq. 14 energy"


def convergence_figure(history: list[float], final: float | None = None, ylabel: str = GAME_VALUE):
    """convergence.png's figure: player A's best game value per search iteration.

    ``ylabel`` names the value: :data:`GAME_VALUE`, or :data:`MERGED_VALUE` for a merged hole of
    several A (its curve runs through each A's search, min beta, then the placement swarm,
    whose value is eq. 14's energy, not a beta).

    ``final`` (report.json's ``search_value``: the game value of the search's last stage, polish
    or placement) is drawn as a dashed line; what the dashed line is, and a note when the curve
    is flat, go into a caption under the plot, never onto the curve.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(5.0, 3.4, 120)
    ax = fig.subplots()
    notes = []
    if history:
        ax.plot(range(len(history)), history, marker="o", color=hex_colour("curve"))
        if final is not None and np.isfinite(final) and final != history[-1]:
            ax.axhline(final, linestyle="--", color=hex_colour("curve"), alpha=0.6)
            notes.append(f"dashed: the value after the last stage (search_value), {final:.5g}")
        if len(history) > 1 and max(history) - min(history) <= 1e-12 * max(1.0, abs(history[0])):
            notes.append("flat: the canonical views already held the best rotation")
    else:
        ax.text(0.5, 0.5, "A's rotation was fixed: no search", ha="center", va="center",
                transform=ax.transAxes)  # fmt: skip
    ax.set_xlabel("search iteration")
    ax.set_ylabel(ylabel)
    ax.set_title("Convergence of player A's search")
    ax.grid(alpha=0.3)
    if notes:
        fig.supxlabel(wrap("\n".join(notes), 4.8, 8), fontsize=8)
    return fig


def _draw_section(ax, section, **style) -> None:
    """Draw a manifold3d CrossSection (all its contours as one compound path) on an axis."""
    draw_contours(ax, section.to_polygons(), **style)


def overlay_figure(result: Result):
    """overlay.png's figure: the exact hole H, A's projection (dashed) and B's best attempts.

    One panel per B (at most :data:`OVERLAY_COLUMNS` in a row, a shorter last row centred), all
    to one scale, each with axes and a scale bar in scene units (:func:`plots.plan_view
    <sieve_mi.outputs.plots.plan_view>`); each panel's title (the B, blocked or not, β and
    protrusion) is wrapped to the panel's width.

    Returns
    -------
    matplotlib.figure.Figure
    """
    hole, a_sections, b_sections = result.overlay_sections()
    lim = 1.04 * max(
        [result.hole.frame.half_extent]
        + [
            float(np.abs(s.bounds()).max())
            for s in [hole, *a_sections, *b_sections]
            if not s.is_empty()
        ]
    )
    titles = [_overlay_title(result, j) for j in range(len(b_sections))] or [""]
    titles = [wrap(t, OVERLAY_PANEL, 9) for t in titles]
    counts = _rows(len(titles), OVERLAY_COLUMNS)
    title = f"{result.scene.name}: winner {result.winner} (exact hole white, A dashed)"
    title = wrap(title, OVERLAY_PANEL * max(counts) + 0.3, 10)  # the figure's width
    starts = np.cumsum([0, *counts])
    lines = [max(t.count("\n") + 1 for t in titles[a:b]) for a, b in zip(starts, starts[1:])]
    fig, rows = grid_figure(
        counts, OVERLAY_PANEL, 120, title_lines=lines, suptitle_lines=title.count("\n") + 1
    )
    panels = [(c, ax) for row in rows for c, ax in enumerate(row)]
    for j, (c, ax) in enumerate(panels):
        plan_view(ax, lim, result.scene.units, plate=True, ylabel=c == 0)
        _draw_section(
            ax, hole, facecolor=hex_colour("hole"), edgecolor=hex_colour("edge"), linewidth=0.6
        )
        for sec in a_sections:
            _draw_section(
                ax, sec, fill=False, edgecolor=hex_colour("pass"), linewidth=1.0, linestyle="--"
            )
        if j < len(b_sections):
            colour = hex_colour(block_colour(bool(result.blocks[j].blocked)))
            _draw_section(ax, b_sections[j], facecolor=colour, alpha=0.55, linewidth=0)
        ax.set_title(titles[j], fontsize=9)
    fig.suptitle(title, fontsize=10)
    return fig


def _rows(n: int, columns: int) -> list[int]:
    """Panels per row for ``n`` panels, at most ``columns`` in a row, rows as even as can be."""
    rows = -(-n // columns)
    base, extra = divmod(n, rows)
    return [base + 1] * extra + [base] * (rows - extra)


def _overlay_title(result: Result, j: int) -> str:
    """A B's panel title: its name, blocked or not (and how a blocked-straight B passes), β and
    protrusion."""
    blocked = result.blocks[j].blocked  # a thin-plate or certified passage passes
    status = "blocked" if blocked else "PASSES"
    if result.attack.blocked()[0][j] and not blocked:
        status += _motion_note(result, j)
    return (
        f"{result.block_shapes[j].name}: {status}\nbeta={result.attack.beta[0, j]:.4f}, "
        f"protrusion={result.attack.protrusion[0, j]:.3g} {result.scene.units}"
    )


def _motion_note(result: Result, j: int) -> str:
    """Why a B blocked straight down passes after all: a thin plate's motion or certify's pose."""
    sheet = getattr(result, "sheet", None)
    thin = sheet.per_block[j] if sheet is not None else None
    if thin is not None and thin.status == "passage":
        return f" by tilting through the {thin.thickness:g} {result.scene.units} plate"
    return " (a pose certify found)"


def input_paths(scene) -> list[str]:
    """The scene file and every mesh it names (absolute): an output folder may not hold them."""
    files = [scene.resolve(e.mesh) for e in (*scene.passes, *scene.blocks) if e.data is None]
    return [scene.path, *files]


def write_outputs(
    result: Result,
    out_dir: str,
    *,
    fabricate: bool = True,
    figure: bool = True,
    animation: bool = True,
) -> dict:
    """Write every output of a solve into ``out_dir`` (replacing it) and return the report dict.

    Files: report.json, hole.png, hole.exr, masks.exr (every mask as one multi-layer EXR, the A and
    B layers rendered by ``mi.render``, :func:`rendered_masks`), masks/a_silhouette.exr,
    masks/block_<j>_<name>.exr (single-layer copies), convergence.png, overlay.png; with ``fabricate`` also the printable sieve (sieve.stl, sieve.3mf,
    hole.svg), pass_<i>.stl, block_<j>.stl and, with ``figure``, figure.png (see
    :func:`sieve_mi.outputs.fabrication.fabricate`), with ``animation`` passage.gif
    (:mod:`sieve_mi.outputs.animation`), the certificates of the blocks' proofs
    (certificates/block_<j>_<name>.json, and ``_margin.json`` for the margin's), the page
    report.html (:mod:`sieve_mi.outputs.viewer`) and the marker
    ``.sieve-mi``. Everything is written
    into a temporary folder and swapped in at the end (:func:`sieve_mi.outputs.outdir.writing`): an
    interrupted or failed run leaves the old folder as it was, and a folder that sieve-mi did not
    write is refused (:class:`~sieve_mi.errors.SieveError`), never replaced.
    """
    t_start = time.perf_counter()
    report = report_dict(result)
    timings, watch = report["timings"], result.memory
    mark = watch.mark if watch is not None else (lambda stage: None)
    if watch is not None:
        watch.start()
    done: list[str] = []  # the stages whose files are complete, for a run stopped midway
    salvage = _salvage(report, done, figure and fabricate, animation)
    inputs = input_paths(result.scene)
    with outdir.writing(out_dir, command="solve", inputs=inputs, salvage=salvage) as tmp:
        _write_certificates(result, report, tmp)
        if fabricate:
            from sieve_mi.outputs.fabrication import figure_file, plate_files

            t0 = time.perf_counter()
            report["fabrication"], meshes = plate_files(result, tmp)
            timings["fabrication_s"] = round(time.perf_counter() - t0, 4)
            mark("fabrication")
        done.append("verdict")  # report.json and the plate, from here on kept if stopped
        _write_images(result, tmp)  # report.json's dict and the images, from t_start
        timings["images_s"] = round(
            time.perf_counter() - t_start - timings.get("fabrication_s", 0), 4
        )
        mark("images")
        done.append("images")
        if fabricate and figure:
            timings["figure_s"] = round(figure_file(result, tmp, report["fabrication"], meshes), 4)
            mark("figure")
            done.append("figure")
        _write_passage(result, report, tmp, animation, mark, done)
    if watch is not None:
        watch.stop()
    return report


#: The files of each output stage after the verdict (a stage's files are kept only when it ended).
_STAGE_FILES = {
    "images": ("hole.png", "hole.exr", "masks.exr", "masks", "convergence.png", "overlay.png"),
    "figure": ("figure.png",),
    "animation": ("passage.gif",),
    "page": ("report.html",),
}


def _salvage(report: dict, done: list, figure: bool, animation: bool):
    """What a solve stopped while writing its outputs keeps (:func:`outdir.writing`'s ``salvage``).

    Once the verdict's files are written (the certificates, the plate and its placed shapes),
    an interrupt keeps them: the unfinished stages' files are removed, report.json is written
    with ``"incomplete"`` naming the missing files, and one line on stderr says so. Before that,
    nothing is kept (the old folder stays as it was).
    """
    import shutil

    def keep(tmp: str) -> str | None:
        if "verdict" not in done:
            return None
        stages = ["images"] + ["figure"] * figure + ["animation"] * animation + ["page"]
        missing = [f for st in stages if st not in done for f in _STAGE_FILES[st]]
        for name in missing:
            path = os.path.join(tmp, name)
            if os.path.isdir(path):
                shutil.rmtree(path, ignore_errors=True)
            elif os.path.lexists(path):
                os.remove(path)
        if not missing:  # stopped after every file: the folder is complete
            return "stopped after writing every output; they are kept"
        report["incomplete"] = {"reason": "stopped while writing the outputs", "missing": missing}
        with open(os.path.join(tmp, "report.json"), "w") as fh:
            json.dump(report, fh, indent=2)
        return (
            "stopped while writing the outputs; kept report.json and the plate; "
            f"missing: {', '.join(missing)} (solve again to make them)"
        )

    return keep


def _write_passage(
    result: Result, report: dict, tmp: str, animation: bool, mark, done: list
) -> None:
    """passage.gif (with ``animation``), report.json and report.html into ``tmp``.

    The GIF's record and its time go into ``report`` before report.json is written; the page,
    written last, holds report.json's content and links every other file. ``mark(stage)`` ends
    a stage of the run's memory watch.
    """
    from sieve_mi.outputs.passage import build
    from sieve_mi.outputs.viewer import page_files, write_page

    timings = report["timings"]
    t0 = time.perf_counter()
    passage = build(result)
    timings["passage_s"] = round(time.perf_counter() - t0, 4)
    if animation:
        from sieve_mi.outputs.animation import write_gif

        t0 = time.perf_counter()
        report["animation"] = write_gif(os.path.join(tmp, "passage.gif"), passage)
        timings["animation_s"] = round(time.perf_counter() - t0, 4)
        done.append("animation")
    mark("passage")
    t0 = time.perf_counter()
    files = page_files(tmp) + ["report.json"]
    write_page(os.path.join(tmp, "report.html"), result, report, passage, sorted(set(files)))
    timings["page_s"] = round(time.perf_counter() - t0, 4)  # the page shows the times before it
    if result.started is not None:
        timings["total_s"] = round(time.perf_counter() - result.started, 4)
    mark("page")
    report["memory"] = memory_dict(result.memory)
    with open(os.path.join(tmp, "report.json"), "w") as fh:
        json.dump(report, fh, indent=2)
    done.append("page")


def _write_certificates(result: Result, report: dict, tmp: str) -> None:
    """Each B's certificate (and its margin proof's) as ``certificates/block_<j>_<name>.json``
    (``..._margin.json``), named in the B's ``certification`` in ``report``; replayable with
    ``sieve-mi certify --replay``."""
    for j, c in enumerate(result.certified or []):
        if c is None or not c.certificate:
            continue
        os.makedirs(os.path.join(tmp, "certificates"), exist_ok=True)
        stem = f"certificates/block_{j}_{_safe(result.block_shapes[j].name)}"
        entry = report["block"][j]["certification"]
        for key, cert, name in (
            ("certificate", c.certificate, f"{stem}.json"),
            ("margin_certificate", c.margin_certificate, f"{stem}_margin.json"),
        ):
            if cert:
                with open(os.path.join(tmp, name), "w") as fh:
                    json.dump(cert, fh)
                entry[key] = name


def _write_images(result: Result, tmp: str) -> None:
    """The hole and mask images and the convergence and overlay plots, into folder ``tmp``."""
    os.makedirs(os.path.join(tmp, "masks"))
    frame, meta = result.hole.frame, exr_metadata(result)
    rendered = a_masks, b_windows = rendered_masks(result)
    layers = mask_layers(result, rendered)
    exact = layers["hole.Y"]  # pixel centres inside the printed polygon
    write_png(os.path.join(tmp, "hole.png"), exact, frame.pixel_size, result.scene.units)
    write_exr(os.path.join(tmp, "hole.exr"), exact.astype(np.float32), meta)
    a_union = np.logical_or.reduce(a_masks)
    write_exr(os.path.join(tmp, "masks", "a_silhouette.exr"), a_union.astype(np.float32), meta)
    if len(a_masks) > 1:
        for i, (m, shape) in enumerate(zip(a_masks, result.pass_shapes)):
            write_exr(
                os.path.join(tmp, "masks", f"pass_{i}_{_safe(shape.name)}.exr"),
                m.astype(np.float32),
                meta,
            )
    for j, (shape, window) in enumerate(zip(result.block_shapes, b_windows)):
        x0, _, _, y1 = window.extent
        write_exr(
            os.path.join(tmp, "masks", f"block_{j}_{_safe(shape.name)}.exr"),
            window.mask.astype(np.float32),
            exr_metadata(result, (x0, y1)),
        )
    write_layers(os.path.join(tmp, "masks.exr"), layers, meta)
    history, final = result.history.best, result.search_value
    merged = len(result.pass_shapes) > 1 and result.scene.layout.mode == "merged"
    label = MERGED_VALUE if merged else GAME_VALUE
    save(convergence_figure(history, final, label), os.path.join(tmp, "convergence.png"))
    save(overlay_figure(result), os.path.join(tmp, "overlay.png"))


def summary_table(report: dict) -> str:
    """A short plain-text table of the result, one row per shape."""
    units = report["units"]
    proofs = any("certified" in b for b in report["block"])
    rows = [("role", "shape", "beta", f"protrusion ({units})", "result")]
    rows[0] += ("certified",) if proofs else ()
    thin = any(b.get("thin_plate", {}).get("status", "safe") != "safe" for b in report["block"])
    rows[0] += ("thin plate",) if thin else ()
    for p in report["pass"]:
        rows.append(("pass", p["name"], "-", "-", "passes (part of the hole)"))
        rows[-1] += ("-",) if proofs else ()
        rows[-1] += ("-",) if thin else ()
    for b in report["block"]:
        rows.append(
            (
                "block",
                b["name"],
                f"{b.get('beta', b.get('loss')):.4f}",  # reports before 'beta' say 'loss'
                f"{b['protrusion']:.3f}",
                "blocked" if b["blocked"] else "PASSES",
            )
        )
        if proofs:
            rows[-1] += (_certified_cell(b),)
        if thin:
            rows[-1] += (_thin_cell(b),)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    t = report["timings"]
    lines.append("")
    lines.append(
        f"winner: {report['winner']}   search {t.get('search_s', 0):.1f} s, verdict {t.get('verdict_s', 0):.1f} s, "
        f"pixel size {report['pixel_size']:.4g} {units}"
    )
    if "total_s" in t:
        lines.append(stage_line(t))
    memory = memory_line(report)
    if memory:
        lines.append(memory)
    plate = sheet_line(report)
    if plate:
        lines.append(plate)
    hint = merge_hint(report)
    if hint:
        lines.append(hint)
    return "\n".join(lines)


#: report.json's stage timings, in the order they run, with the console's labels.
STAGES = (
    ("startup_s", "startup"), ("init_s", "init"), ("load_s", "load"), ("screen_s", "screen"),
    ("search_s", "search"),
    ("verdict_s", "verdict"), ("certify_s", "certify"), ("thin_s", "thin plate"),
    ("images_s", "images"),
    ("fabrication_s", "plate"), ("figure_s", "figure"), ("passage_s", "passage"),
    ("animation_s", "gif"), ("page_s", "page"),
)  # fmt: skip


def memory_dict(watch) -> dict | None:
    """report.json's ``memory``: the process's peak resident memory and each stage's, GB.

    Parameters
    ----------
    watch : sieve_mi.backend.MemoryWatch or None

    Returns
    -------
    dict or None
        ``{"peak_gb": float, "stages_gb": {stage: float}}``; None without a watch.
    """
    if watch is None:
        return None
    return {"peak_gb": watch.peak, "stages_gb": dict(watch.peaks)}


def memory_line(report: dict) -> str | None:
    """``memory: peak 0.72 GB (search 0.72, verdict 0.57, ...)`` from report.json, or None."""
    mem = report.get("memory")
    if not mem:
        return None
    stages = ", ".join(f"{k} {v:.2f}" for k, v in mem["stages_gb"].items() if v >= 0.005)
    return f"memory: peak {mem['peak_gb']:.2f} GB ({stages})"


def stage_line(timings: dict) -> str:
    """``time: 12.3 s = search 4.1 + verdict 3.2 + ...`` from report.json's timings."""
    parts = [f"{label} {timings[key]:.1f}" for key, label in STAGES if timings.get(key, 0) >= 0.05]
    return f"time: {timings['total_s']:.1f} s = " + " + ".join(parts) + " s"


def block_margin(shape, hole, found: float, certified=None, grown: float = 0.0) -> dict:
    """How far a blocked B sticks out of H at best, bracketed (report.json's ``margin``).

    ``found_at_most``: the protrusion of the best pose found (the true margin is at most this).
    ``proved_at_least``: from a certification that proved the block (``certified``, a
    :class:`~sieve_mi.certify.Certification` against H grown by ``grown``, the scene's
    ``block_margin``), ``grown`` plus its margin bisection's m
    (:func:`sieve_mi.certify.blocks.prove_margin`, whose steps try the ball test first); without
    one, from a ball certified inside B, the largest m for which no disk of its radius fits H
    grown by m (:func:`sieve_mi.certify.blocks.ball_margin`). None when nothing proves it.
    """
    from sieve_mi.certify.blocks import ball_margin
    from sieve_mi.certify.bounds import inscribed_ball

    if certified is not None and certified.status == "proved":
        proved = grown + (certified.margin or 0.0)
    else:
        ball = inscribed_ball(shape)
        proved = (ball_margin(ball[1], hole) if ball is not None else 0.0) or None
    return {"proved_at_least": proved, "found_at_most": float(found)}


def sheet_line(report: dict) -> str | None:
    """``plate: 2 mm thick, not proved (safe: 28.4 mm) ...`` when the plate is thinner than the
    safe thickness (:mod:`sieve_mi.game.sheet`); None on a proved plate."""
    sheet = report.get("fabrication", {}).get("sheet")
    if sheet is None or sheet["proved"]:
        return None
    u = report["units"]
    head = f"plate: {sheet['thickness']:g} {u} thick"
    if sheet["mode"] == "thinnest":
        head += f", the thinnest of {len(sheet['bisection'])} tried where no B was found to pass"
    return (
        head
        + f"; not proved (a motion search), the proved plate is {sheet['safe_thickness']:g} {u}"
    )


def _thin_cell(block: dict) -> str:
    """The console's 'thin plate' cell of one B: safe by diameter, passage or none found."""
    t = block.get("thin_plate")
    if t is None:
        return "-"
    if t["status"] == "safe":
        return f"safe ({t.get('by', 'diameter')})"
    return f"{t['status']} ({t['seconds']:.1f} s)"


def _certified_cell(block: dict) -> str:
    """The console's 'certified' cell of one B: the status and what it rests on."""
    c = block.get("certification")
    if c is None:
        return "-"
    if c["status"] == "undecided":
        return f"undecided ({100 * c['excluded_fraction']:.1f} % excluded, {c['seconds']:.0f} s)"
    return f"{c['status']} ({c['seconds']:.1f} s)"


def merge_hint(report: dict) -> str | None:
    """Advice when a merged hole of several pass shapes lets some B through but each shape alone did not."""
    passes = report["pass"]
    mode = report.get("settings", {}).get("layout", {}).get("mode", "merged")
    if report["winner"] != "B" or len(passes) < 2 or mode != "merged":
        return None
    alone = [p.get("alone_loss") for p in passes]
    if any(a is None or not a > 0 for a in alone):
        return None
    through = ", ".join(b["name"] for b in report["block"] if not b["blocked"])
    each = ", ".join(f"{p['name']} {a:.3f}" for p, a in zip(passes, alone))
    return (
        f"hint: the merged hole lets {through} through, but each pass shape alone blocked every block shape "
        f'(weakest loss: {each}); set [layout] mode = "separate" for a valid sieve, or try another --seed'
    )
