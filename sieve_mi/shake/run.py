"""One shake run: every part's geometry, fidelity and trials, gathered into ``shake.json``'s dict."""

from __future__ import annotations

import sys
import time

from sieve_mi.shake.fidelity import measure_sink
from sieve_mi.shake.geometry import part_from_mesh, plate_from_mesh
from sieve_mi.shake.inputs import ShakeInput
from sieve_mi.shake.model import PLATE_MASS_RATIO, plate_motion
from sieve_mi.shake.settings import CONTACT, SINK_BOUND_MM, ShakeSettings, metres_per_unit
from sieve_mi.shake.stats import summarize
from sieve_mi.shake.trials import run_trials

__all__ = ["FORMAT", "Progress", "engine_doc", "motion_doc", "shake", "shape_entry"]

#: Version of the ``shake.json`` layout.
FORMAT = 1


class Progress:
    """Progress on stderr: a tqdm bar over trials on a terminal; elsewhere one plain line per
    shape when its trials are done (no carriage-return frames in logs); nothing when quiet."""

    def __init__(self, enabled: bool, total: int, desc: str = "shake"):
        self.enabled, self.total, self.bar, self.desc = enabled, total, None, desc
        self.plain = enabled and not sys.stderr.isatty()
        if enabled and not self.plain:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="trial", dynamic_ncols=True)

    def shape(self, name: str) -> None:
        """A new shape starts."""
        if self.bar is not None:
            self.bar.set_description(f"{self.desc} {name}")

    def trial(self, outcome) -> None:
        """One trial is done."""
        if self.bar is not None:
            self.bar.update(1)

    def done(self, name: str, summary: dict, seconds: float) -> None:
        """A shape's trials are done."""
        if self.plain:
            print(
                f"{self.desc}: {name}: {summary['passed']} of {summary['trials']} passed "
                f"({100 * summary['fraction']:.1f} %) in {seconds:.1f} s",
                file=sys.stderr,
                flush=True,
            )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def engine_doc() -> dict:
    """The engine as ``shake.json`` records it: MuJoCo's version, integrator, contact
    parameters, the plate's mass ratio and the sink bound (mm)."""
    import mujoco

    return {
        "engine": f"MuJoCo {mujoco.__version__}",
        "integrator": "Euler",
        "contact": {k: list(v) if isinstance(v, tuple) else v for k, v in CONTACT.items()},
        "plate_mass_ratio": PLATE_MASS_RATIO,
        "sink_bound_mm": SINK_BOUND_MM,
    }


def shape_entry(name, role, path, part, plate, settings, unit_m, progress, trials=None):
    """One part's trials on one plate, their statistics and the part's fidelity there.

    Parameters
    ----------
    name, role, path
        The part's name, role (``"A"``, ``"B"`` or None) and file, for the entry.
    part : Part
    plate : Plate
    settings : ShakeSettings
    unit_m : float
        Metres per scene unit.
    progress : Progress
    trials : sequence of int, optional
        The trials to run (default every one, see :func:`~sieve_mi.shake.trials.run_trials`).

    Returns
    -------
    (dict, float)
        ``shake.json``'s entry of the shape, and the seconds it took.
    """
    t0 = time.perf_counter()
    fidelity = measure_sink(plate, part, settings, unit_m)
    progress.shape(name)
    outcomes = run_trials(plate, part, settings, unit_m, progress.trial, indices=trials)
    summary = summarize(outcomes)
    seconds = time.perf_counter() - t0
    progress.done(name, summary, seconds)
    entry = {"name": name, "role": role, "file": path, "geometry": part.to_dict()}
    entry.update(summary)
    entry["fidelity"] = fidelity
    entry["warnings"] = list(part.warnings)
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
        Also render one trial per shape into this GIF (:mod:`sieve_mi.shake.clip`).

    Returns
    -------
    dict
        ``shake.json``'s content: ``format``, ``units``, ``settings`` (with ``units`` of each),
        ``engine``, ``plate``, ``shapes`` (one dict per part: counts, ``fraction``, ``ci95``,
        ``median_time_s``, ``pass_times_s``, ``geometry`` (incl. ``hausdorff``), ``fidelity``),
        ``fidelity_ok``, ``timings`` (seconds; the only part that changes between equal runs).
    """
    unit_m = metres_per_unit(inp.units)
    t0 = time.perf_counter()
    plate = plate_from_mesh(inp.plate, inp.plate_path)
    parts = [
        (name, role, path, part_from_mesh(mesh, name, role, settings.coacd_threshold))
        for name, role, path, mesh in inp.parts
    ]
    timings = {"geometry_s": time.perf_counter() - t0}
    bar = Progress(progress, settings.trials * len(parts))
    shapes = []
    try:
        for name, role, path, part in parts:
            entry, seconds = shape_entry(name, role, path, part, plate, settings, unit_m, bar)
            shapes.append(entry)
            timings[f"trials_{len(shapes) - 1}_s"] = seconds
    finally:
        bar.close()
    extra = {}
    if clip is not None:
        t1 = time.perf_counter()
        extra["clip"] = _clip(clip, inp, plate, parts, shapes, settings, unit_m)
        timings["clip_s"] = time.perf_counter() - t1
    timings["total_s"] = time.perf_counter() - t0
    return {
        "format": FORMAT,
        "units": inp.units,
        "plate": {"file": inp.plate_path, **plate.to_dict()},
        "settings": {**settings.to_dict(), "units": ShakeSettings.units()},
        "motion": motion_doc(settings),
        "engine": engine_doc(),
        "shapes": shapes,
        "fidelity_ok": all(s["fidelity"]["within_bound"] for s in shapes),
        **extra,
        "timings": timings,
    }


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
