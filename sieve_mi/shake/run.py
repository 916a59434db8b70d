"""One shake run: every part's geometry, fidelity and trials, gathered into ``shake.json``'s dict."""

from __future__ import annotations

import time

import numpy as np

from sieve_mi.errors import SieveError, interruption
from sieve_mi.progress import Progress
from sieve_mi.shake.fidelity import judge, measure_sink
from sieve_mi.shake.geometry import Plate, part_from_mesh, plate_from_mesh
from sieve_mi.shake.inputs import ShakeInput
from sieve_mi.shake.model import PLATE_MASS_RATIO, PLATE_SIMPLIFY_M, build_model, plate_motion
from sieve_mi.shake.settings import (
    CONTACT,
    MAX_ACCELERATION_G,
    PART_SIZE_MM,
    PLATE_SIZE_MM,
    SHAKEN_BOUND_MM,
    SHAKEN_FRACTION,
    SINK_BOUND_MM,
    ShakeSettings,
    metres_per_unit,
)
from sieve_mi.shake.stats import summarize
from sieve_mi.shake.trials import run_trials
from sieve_mi.telemetry import Run

__all__ = [
    "FORMAT",
    "check_plate",
    "check_sizes",
    "engine_doc",
    "motion_doc",
    "preflight",
    "shake",
    "shape_entry",
    "trial_bar",
]

#: Version of the ``shake.json`` layout.
FORMAT = 1


def trial_bar(enabled: bool, total: int, desc: str = "shake") -> Progress:
    """Progress of shake trials on stderr (:class:`sieve_mi.progress.Progress`): a bar over
    ``total`` trials on a terminal; in a log one line per shape when its trials are done
    (:func:`shape_entry`), no ``done in`` line; nothing when not ``enabled``."""
    return Progress(enabled, total, desc, unit="trial", done_line=False)


def engine_doc() -> dict:
    """The engine as ``shake.json`` records it: MuJoCo's version, integrator, contact
    parameters, the plate's mass ratio and the fidelity bounds (mm; the shaken one is the
    least of ``shaken_bound_mm`` and ``shaken_fraction`` of the plate's thickness)."""
    import mujoco

    return {
        "engine": f"MuJoCo {mujoco.__version__}",
        "integrator": "Euler",
        "contact": {k: list(v) if isinstance(v, tuple) else v for k, v in CONTACT.items()},
        "plate_mass_ratio": PLATE_MASS_RATIO,
        "sink_bound_mm": SINK_BOUND_MM,
        "shaken_bound_mm": SHAKEN_BOUND_MM,
        "shaken_fraction": SHAKEN_FRACTION,
    }


def shape_entry(part, role, path, plate, settings, unit_m, progress, trials=None):
    """One part's trials on one plate, their statistics and the part's fidelity there.

    Parameters
    ----------
    part : Part
        The part; its name names the entry.
    role, path
        The part's role on this plate (``"A"``, ``"B"`` or None) and its file, for the entry.
    plate : Plate
    settings : ShakeSettings
    unit_m : float
        Metres per scene unit.
    progress : sieve_mi.progress.Progress
        The run's bar (:func:`trial_bar`): named after the shape, a step per trial, and in a log
        a line of the shape's result.
    trials : sequence of int, optional
        The trials to run (default every one, see :func:`~sieve_mi.shake.trials.run_trials`).

    Returns
    -------
    (dict, float)
        ``shake.json``'s entry of the shape, and the seconds it took.
    """
    t0, name = time.perf_counter(), part.name
    check_plate(plate, settings, unit_m)
    fidelity = measure_sink(plate, part, settings, unit_m)
    progress.describe(name)
    outcomes = run_trials(
        plate, part, settings, unit_m, lambda outcome: progress.update(1), indices=trials
    )
    summary = summarize(outcomes)
    seconds = time.perf_counter() - t0
    left = progress.left()
    progress.write(
        f"{progress.desc}: {name}: {summary['passed']} of {summary['trials']} passed "
        f"({100 * summary['fraction']:.1f} %) in {seconds:.1f} s" + (f"; {left}" if left else ""),
        terminal=False,
    )
    fidelity, lines = judge(name, fidelity, outcomes)
    entry = {"name": name, "role": role, "file": path, "geometry": part.to_dict()}
    entry.update(summary)
    entry["fidelity"] = fidelity
    entry["warnings"] = list(part.warnings) + lines
    return entry, seconds


def shake(
    inp: ShakeInput, settings: ShakeSettings, progress: bool = True, clip: str | None = None
) -> dict:
    """Shake every part of ``inp`` on its plate.

    Parameters
    ----------
    inp : ShakeInput
    settings : ShakeSettings
    progress : bool
        Progress on stderr.
    clip : str, optional
        Also render one trial per shape into this GIF (:mod:`sieve_mi.shake.clip`); where
        Mitsuba cannot be loaded, the GIF is not made and a line of ``warnings`` says why.

    Returns
    -------
    dict
        ``shake.json``'s content: ``format``, ``units``, ``settings`` (with ``units`` of each),
        ``engine``, ``plate``, ``shapes`` (one dict per part: counts, ``fraction``, ``ci95``,
        ``median_time_s``, ``pass_times_s``, ``geometry`` (incl. ``hausdorff``), ``fidelity``,
        ``warnings``), ``fidelity_ok`` (every shape's fidelity held), ``warnings`` (every
        shape's; the clip's, not made), ``clip`` (where it was made), ``timings`` (seconds; the
        only part that changes between equal runs).

    Raises
    ------
    SieveError
        Before any trial: a part or plate of a size the engine is not used for
        (:func:`check_sizes`, :func:`check_plate`), a motion too harsh for the plate
        (:func:`check_plate`), or a model MuJoCo refuses (:func:`preflight`).
    """
    unit_m, run = metres_per_unit(inp.units), Run().start()
    with run.stage("geometry"):
        check_sizes(inp, unit_m)
        plate = plate_from_mesh(inp.plate, inp.plate_path, inp.units)
        check_plate(plate, settings, unit_m, inp.plate_path)
        threshold, bound = settings.coacd_threshold, settings.hausdorff_bound * 1e-3 / unit_m
        parts = [
            (name, role, path, part_from_mesh(mesh, name, role, threshold, bound=bound))
            for name, role, path, mesh in inp.parts
        ]
        preflight(plate, parts, inp.plate_path, settings, unit_m)
    bar = trial_bar(progress, settings.trials * len(parts))
    shapes = []
    try:
        for _, role, path, part in parts:
            entry, seconds = shape_entry(part, role, path, plate, settings, unit_m, bar)
            shapes.append(entry)
            run.timings[f"trials_{len(shapes) - 1}_s"] = seconds  # as the progress line said
    finally:
        bar.close()
    extra, unmade = {}, []
    if clip is not None:
        with run.stage("clip"):
            why = _renderer_missing()
            if why is None:
                extra["clip"] = _clip(clip, inp, plate, parts, shapes, settings, unit_m)
            else:  # the trials' results are written all the same
                unmade.append(f"shake.gif not made: Mitsuba, which renders it, cannot be "
                              f"loaded here ({why})")  # fmt: skip
    run.timings["total_s"] = run.elapsed()
    return {
        "format": FORMAT,
        "units": inp.units,
        "plate": {"file": inp.plate_path, **plate.to_dict(PLATE_SIMPLIFY_M / unit_m)},
        "settings": {**settings.to_dict(), "units": ShakeSettings.units()},
        "motion": motion_doc(settings),
        "engine": engine_doc(),
        "shapes": shapes,
        "fidelity_ok": all(s["fidelity"]["within_bound"] for s in shapes),
        "warnings": list(plate.warnings) + [w for s in shapes for w in s["warnings"]] + unmade,
        **extra,
        "timings": run.timings,
    }


def _renderer_missing() -> str | None:
    """Why ``shake.gif`` cannot be rendered here (Mitsuba or Dr.Jit not importable, as in a pack
    of the engine alone such as ``tools/gpu_shake.sh``'s, or no backend for its variant:
    :func:`sieve_mi.backend.use_variant`'s one line), else None."""
    from sieve_mi.backend import use_variant

    try:
        use_variant(None)
    except (ImportError, SieveError) as exc:
        stop = interruption(exc)  # an import that swallowed a Ctrl-C is the Ctrl-C
        if stop is not None:
            raise stop from exc
        return str(exc)
    return None


def _clip(path, inp, plate, parts, shapes, settings, unit_m) -> dict:
    """Render one trial per shape (its first passing trial, else trial 0) into ``path``."""
    from sieve_mi.shake.clip import trajectory, write_clip

    rows, trials = [], []
    for (name, role, _, part), (_, _, _, mesh), entry in zip(parts, inp.parts, shapes):
        times = entry["pass_times_s"]
        trial = next((i for i, t in enumerate(times) if t is not None), 0)
        frames = trajectory(plate, part, settings, unit_m, trial, times[trial] is not None)
        mesh.metadata["name"] = name
        rows.append((mesh, part.com, role, times[trial] is not None, frames))
        trials.append(trial)
    info = write_clip(path, inp.plate, plate, rows)
    return {**info, "trials": trials}


def motion_doc(settings: ShakeSettings) -> dict:
    """The shaker motion in words and its peak values (m/s, g, rad/s)."""
    import math

    z, dz, _, dphi = plate_motion(0.0, settings)
    w = 2 * math.pi * settings.frequency
    return {
        "kind": "vertical throw with an in-phase twist about the vertical axis"
        if settings.twist
        else "vertical throw",
        "peak_speed_m_s": float(dz),
        "peak_acceleration_g": float(settings.amplitude * 1e-3 * w * w / 9.81),
        "peak_twist_rate_rad_s": float(dphi),
    }


def _across_mm(mesh, unit_m: float) -> float:
    """The largest side of a mesh's bounding box, mm."""
    return float(max(mesh.extents)) * unit_m * 1e3


def check_sizes(inp: ShakeInput, unit_m: float) -> None:
    """Refuse, before any work, a part or plate the engine is not used for.

    A part is from :data:`~sieve_mi.shake.settings.PART_SIZE_MM` [0] to [1] across (the largest
    side of its bounding box); a plate at most :data:`~sieve_mi.shake.settings.PLATE_SIZE_MM`
    [1]. A smaller part is also one MuJoCo cannot compile (a 0.1 um one: "mesh surface area is
    too small"); a size far off mostly means the wrong units.

    Raises
    ------
    SieveError
        One line naming the file, its size and what to check.
    """
    lo, hi = PART_SIZE_MM
    for _, _, path, mesh in inp.parts:
        mm = _across_mm(mesh, unit_m)
        if not lo <= mm <= hi:
            raise SieveError(
                f"{path}: the part is {_size(mm, inp.units, unit_m)} across; shake simulates "
                f"parts {lo:g} to {hi:g} mm across: check the mesh's scale and units"
            )
    mm = _across_mm(inp.plate, unit_m)
    if mm > PLATE_SIZE_MM[1]:
        raise SieveError(
            f"{inp.plate_path}: the plate is {_size(mm, inp.units, unit_m)} across; shake "
            f"simulates plates up to {PLATE_SIZE_MM[1]:g} mm across: check the mesh's scale "
            "and units"
        )


def _size(mm: float, units: str, unit_m: float) -> str:
    """A length in words: ``"0.0002 mm"``, ``"20,000 mm (20 m)"`` (the scene's units too)."""

    def fmt(x: float) -> str:
        return f"{x:,.0f}" if x >= 1000 else f"{x:.3g}"

    text = f"{fmt(mm)} mm"
    return text if units == "mm" else f"{text} ({fmt(mm * 1e-3 / unit_m)} {units})"


def check_plate(plate: Plate, settings: ShakeSettings, unit_m: float, path: str = "") -> None:
    """Refuse a plate thinner than the contacts' soft layer, and a twist that shakes the plate's
    corners harder than :data:`~sieve_mi.shake.settings.MAX_ACCELERATION_G`.

    Raises
    ------
    SieveError
        One line naming the plate (``path``, when given), the value and what to do.
    """
    where = f"{path}: " if path else "shake: "
    mm = plate.thickness * unit_m * 1e3
    if mm < PLATE_SIZE_MM[0]:
        raise SieveError(
            f"{where}the plate is {mm:.3g} mm thick; shake simulates plates of at least "
            f"{PLATE_SIZE_MM[0]:g} mm (its contacts' soft layer): check the units and scale"
        )
    corner = float(np.hypot(*plate.half_size)) * unit_m * 1e3
    g = settings.peak_acceleration_g(corner)
    if g > MAX_ACCELERATION_G:
        raise SieveError(
            f"{where}a twist of {settings.twist:g} degrees at {settings.frequency:g} Hz shakes "
            f"the plate's corners ({corner:.3g} mm from its centre) at {g:,.0f} g; sieve "
            f"shakers give at most {MAX_ACCELERATION_G:g} g: lower the twist, the amplitude or "
            "the frequency"
        )


def preflight(plate: Plate, parts: list, plate_path: str, settings, unit_m: float) -> None:
    """Compile each part's model once before any trial: what MuJoCo refuses (a part too light
    for its inertia, a degenerate piece) is one line naming the file, not a traceback later.

    Parameters
    ----------
    plate : Plate
    parts : list of (name, role, path, Part)
    plate_path : str
    settings : ShakeSettings
    unit_m : float
    """
    for _, _, path, part in parts:
        try:
            build_model(plate, part, settings, unit_m)
        except ValueError as exc:
            what = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            blame = plate_path if "'plate" in str(exc) else path or part.name
            raise SieveError(
                f"{blame}: MuJoCo cannot simulate it ({what}); the part is "
                f"{2 * part.radius * unit_m * 1e3:.3g} mm across at {settings.density:g} kg/m^3: "
                "check the mesh's units and scale, or the density"
            ) from None
