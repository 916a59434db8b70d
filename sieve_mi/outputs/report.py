"""A solve's ``report.json``, and :func:`write_outputs`, which writes the solve's whole folder.

One idea: the record of a solve (:func:`report_dict`: each shape's row, the hole, the settings,
provenance, timings and memory) and the order in which the folder's products are made — the
certificates and the plate (:mod:`~sieve_mi.outputs.fabrication`), the images
(:mod:`~sieve_mi.outputs.images`) and plots (:mod:`~sieve_mi.outputs.plots`), the figure, the
GIF (:mod:`~sieve_mi.outputs.animation`), report.json and the page
(:mod:`~sieve_mi.outputs.viewer`). Everything is written into a temporary folder beside the
destination and swapped into place at the end by :mod:`sieve_mi.outputs.outdir`, so an
interrupted or failed run never leaves half-written outputs (a run stopped after its verdict keeps
report.json and the plate), and a folder that sieve-mi did not write is never replaced.
"""

from __future__ import annotations

import json
import os
import time

import numpy as np

from sieve_mi.game.result import BlockAttempt, Result
from sieve_mi.geometry.meshes import mesh_sha256
from sieve_mi.outputs import outdir
from sieve_mi.outputs.images import safe_name, write_images
from sieve_mi.outputs.plots import write_plots
from sieve_mi.outputs.provenance import provenance

__all__ = [
    "input_paths",
    "memory_dict",
    "pass_pose",
    "report_dict",
    "write_outputs",
]


def _block_row(result: Result, j: int, record: BlockAttempt) -> dict:
    """report.json's row of B number ``j``, from its record (``result.blocks[j]``)."""
    entry, shape, attack = result.scene.blocks[j], result.block_shapes[j], result.attack
    beta = float(attack.beta[0, j])
    c, thin = record.certification, record.thin_plate
    row = {
        "mesh": entry.mesh,
        "name": shape.name,
        "beta": beta,
        "loss": beta,  # the same β, under its old name (kept for compatibility)
        "blocked": record.blocked,
        "protrusion": float(attack.protrusion[0, j]),
        "verdict": "exact-polygon",
        "rotation": [float(x) for x in attack.quats[0, j]],
        "translation": [float(x) for x in attack.trans[0, j]],
        "fitting_starts": int(attack.fits[0, j]),
        "centre": [float(x) for x in shape.centre],
        "faces": shape.face_count,
    }
    if c is not None:
        row["certified"] = c.status
        row["certification"] = c.to_dict()
    if record.margin is not None:  # blocked straight through the exact hole
        row["margin"] = record.margin
    if record.overhang is not None:  # the least overhang found and its proved bound
        row["overhang"] = record.overhang.to_dict(result.scene.units)
    if thin is not None:
        row["thin_plate"] = thin.to_dict()
    if attack.margin_beta is not None:
        row["margin_beta"] = float(attack.margin_beta[0, j])
        row["margin_loss"] = row["margin_beta"]
        row["margin_protrusion"] = float(attack.margin_protrusion[0, j])
    return row


def pass_pose(shape, quat) -> dict:
    """An A's pass pose in words and angles, the dict ``check --json`` writes under ``pose``
    (``"of": "pass"`` and :meth:`~sieve_mi.geometry.pose_words.PoseWords.to_dict`).

    Parameters
    ----------
    shape : Shape
        The pass shape, scene units.
    quat : (4,) array_like
        Its rotation (w, x, y, z) in the hole.
    """
    from sieve_mi.geometry.pose_words import describe_pose

    return {"of": "pass", **describe_pose(shape, quat).to_dict()}


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
                "pose": pass_pose(shape, result.pass_quats[i]),
            }
        )
        if i < len(result.alone) and result.alone[i] is not None:
            passes[-1]["alone_loss"] = float(result.alone[i])
        if entry.tolerance is not None:  # its own hole's ([[pass]] tolerance)
            passes[-1]["tolerance"] = float(entry.tolerance)
        for m in getattr(result, "mirrored", None) or []:  # its mirrored hole ([layout] mirrored)
            if m["of"] == i:
                passes[-1]["mirrored_translation"] = list(m["translation"])
        rest = getattr(result, "rest", None) or []
        if i < len(rest):  # the nearest resting pose (sieve_mi.game.rest)
            passes[-1]["rest"] = rest[i]
    blocks = [_block_row(result, j, b) for j, b in enumerate(result.blocks)]
    hole = result.hole
    out = {
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
        "retries": list(result.retries),
        "warnings": list(result.warnings),
        "timings": {k: round(float(v), 4) for k, v in result.timings.items()},
        "memory": memory_dict(result.memory),
        "pixel_size": hole.frame.pixel_size,
        "units": scene.units,
        "conventions": "rotation q = (w, x, y, z) acts on the mesh's points about its centre (bounding-box centre, "
        "given in file units times scale); the silhouette is the projection onto the xy-plane; "
        "translations are in the xy-plane in scene units, relative to the hole's centre",
    }
    if result.feasibility is not None:  # the feasibility test (sieve_mi.game.feasible)
        out["feasibility"] = result.feasibility.as_dict()
    return out


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
    B layers rendered by ``mi.render``, :func:`~sieve_mi.outputs.images.rendered_masks`),
    masks/a_silhouette.exr, masks/block_<j>_<name>.exr (single-layer copies;
    :mod:`sieve_mi.outputs.images`), convergence.png, overlay.png (:mod:`sieve_mi.outputs.plots`);
    with ``fabricate`` also the printable sieve (sieve.stl, sieve.3mf, hole.svg), pass_<i>.stl,
    block_<j>.stl and, with ``figure``, figure.png (see
    :func:`sieve_mi.outputs.fabrication.fabricate`), with ``animation`` passage.gif
    (:mod:`sieve_mi.outputs.animation`), the certificates of the blocks' proofs
    (certificates/block_<j>_<name>.json, and ``_margin.json`` for the margin's), the page
    report.html (:mod:`sieve_mi.outputs.viewer`) and the marker ``.sieve-mi``. Everything is
    written into a temporary folder and swapped in at the end
    (:func:`sieve_mi.outputs.outdir.writing`): an interrupted or failed run leaves the old folder
    as it was (one stopped after its verdict keeps report.json and the plate, :func:`_salvage`),
    and a folder that sieve-mi did not write is refused (:class:`~sieve_mi.errors.SieveError`),
    never replaced.
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
        meshes = None
        if fabricate:
            from sieve_mi.outputs import pictures
            from sieve_mi.outputs.fabrication import plate_files

            t0 = time.perf_counter()
            report["fabrication"], meshes = plate_files(result, tmp, pictures.built(result))
            timings["fabrication_s"] = round(time.perf_counter() - t0, 4)
            mark("fabrication")
        done.append("verdict")  # report.json and the plate, from here on kept if stopped
        passage, passage_s = _passage(result, meshes)
        with _start_pictures(result, tmp, meshes if figure else None, passage, animation) as pics:
            write_images(result, tmp)  # report.json's dict, the images and plots, from t_start
            write_plots(result, tmp)
            before = timings.get("fabrication_s", 0) + passage_s
            timings["images_s"] = round(time.perf_counter() - t_start - before, 4)
            mark("images")
            done.append("images")
            _collect_pictures(report, pics.wait(), watch, done, passage_s, figure and fabricate)
        _write_page(result, report, tmp, passage, mark, done)
    if watch is not None:
        watch.stop()
    return report


def _passage(result: Result, meshes):
    """The passage scene (:func:`sieve_mi.outputs.passage.build`) on the save's plate (the first
    of ``meshes``; None: built there), and the seconds it took."""
    from sieve_mi.outputs.passage import build

    t0 = time.perf_counter()
    passage = build(result, meshes[0] if meshes is not None else None)
    return passage, time.perf_counter() - t0


def _start_pictures(result: Result, tmp: str, meshes, passage, animation: bool):
    """figure.png (with the plate's ``meshes``) and passage.gif (with ``animation``) started
    beside the rest of the save (:func:`sieve_mi.outputs.pictures.start`)."""
    from sieve_mi.outputs import pictures

    figure_args = None
    if meshes is not None:
        from sieve_mi.outputs.fabrication import figure_args as args_of

        figure_args = args_of(result, meshes)
    return pictures.start(tmp, figure_args, passage if animation else None, result.variant)


def _collect_pictures(report: dict, got: dict, watch, done: list, passage_s: float, figure: bool):
    """Record the pictures' times (the seconds the save waited for each), the GIF's record and
    the rendering's memory in ``report``; mark their stages done."""
    timings = report["timings"]
    if figure:
        timings["figure_s"] = round(got["figure_s"], 4)
        report["fabrication"]["files"].append("figure.png")
        done.append("figure")
    timings["passage_s"] = round(passage_s, 4)
    if got["animation"] is not None:
        report["animation"] = got["animation"]
        timings["animation_s"] = round(got["animation_s"], 4)
        done.append("animation")
    if watch is not None:  # the rendering's peak counts in its stages (it may be another process)
        for stage in ("figure",) * figure + ("passage",):
            watch.peaks[stage] = round(max(watch.mark(stage), got["peak_gb"]), 4)


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


def _write_page(result: Result, report: dict, tmp: str, passage, mark, done: list) -> None:
    """report.json and report.html into ``tmp``, the page showing ``passage`` (the 3D scene).

    The page, written last, holds report.json's content and links every other file.
    ``mark(stage)`` ends a stage of the run's memory watch.
    """
    from sieve_mi.outputs.viewer import page_files, write_page

    timings = report["timings"]
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
        stem = f"certificates/block_{j}_{safe_name(result.block_shapes[j].name)}"
        entry = report["block"][j]["certification"]
        for key, cert, name in (
            ("certificate", c.certificate, f"{stem}.json"),
            ("margin_certificate", c.margin_certificate, f"{stem}_margin.json"),
        ):
            if cert:
                with open(os.path.join(tmp, name), "w") as fh:
                    json.dump(cert, fh)
                entry[key] = name
