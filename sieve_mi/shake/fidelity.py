"""Fidelity measured, not assumed: how far a part sinks into the plate in the engine, at rest and
while shaken, and whether the engine warned.

MuJoCo's contacts are soft: a resting part sits slightly inside the plate. For each part the
part is dropped in a few orientations onto a still, solid plate of the same size and thickness,
left to settle, and its deepest hull vertex below the top face is measured (the *sink*); then
the plate shakes and the deepest penetration over a few periods is measured too. The trials
themselves record their deepest contact penetration and the engine's warnings
(:class:`~sieve_mi.shake.trials.Outcome`). A shape's fidelity holds when its sink is under
:data:`~sieve_mi.shake.settings.SINK_BOUND_MM`, its penetration while shaken (in the test and in
every trial) under :func:`shaken_bound_mm`, and the engine raised no warning; the run states
whether every shape's held (``fidelity_ok``), and a warning line for each that did not.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sieve_mi.shake.geometry import Part, Plate
from sieve_mi.shake.model import (
    WARNINGS,
    build_model,
    engine_hulls,
    engine_warnings,
    plate_motion,
)
from sieve_mi.shake.settings import SHAKEN_BOUND_MM, SHAKEN_FRACTION, SINK_BOUND_MM, ShakeSettings
from sieve_mi.shake.trials import drop_state

__all__ = ["ORIENTATIONS", "SETTLE_S", "SHAKE_S", "judge", "measure_sink", "shaken_bound_mm"]

#: Drop orientations per part (the first trials' orientations).
ORIENTATIONS = 3
#: Settling time on the still plate, seconds.
SETTLE_S = 0.5
#: Shaking time for the dynamic penetration, seconds.
SHAKE_S = 0.2


def shaken_bound_mm(plate: Plate, unit_m: float) -> float:
    """The bound on the penetration while shaken, mm: :data:`SHAKEN_BOUND_MM`, or
    :data:`SHAKEN_FRACTION` of the plate's thickness when that is less."""
    return min(SHAKEN_BOUND_MM, SHAKEN_FRACTION * plate.thickness * unit_m * 1e3)


def _deepest(model, data, hulls_m: np.ndarray, plate_z: float) -> float:
    """Depth (m) of the part's deepest hull vertex below the plate's top face (<= 0: above it)."""
    mujoco.mj_kinematics(model, data)  # poses at the current qpos (mj_step leaves the old ones)
    body = model.nbody - 1
    world = hulls_m @ data.xmat[body].reshape(3, 3).T + data.xpos[body]
    return float(plate_z - world[:, 2].min())


def measure_sink(plate: Plate, part: Part, settings: ShakeSettings, unit_m: float) -> dict:
    """The part's sink on a still plate and its deepest penetration on a shaken one.

    Parameters
    ----------
    plate, part, settings, unit_m
        As for :func:`~sieve_mi.shake.trials.run_trial`; the plate's holes are left out.

    Returns
    -------
    dict
        ``sink_mm`` (largest resting sink over the orientations, mm), ``shaken_penetration_mm``
        (deepest penetration while shaken, mm), ``bound_mm`` (the sink's), ``shaken_bound_mm``,
        ``orientations``, ``engine_warnings`` (warning name: in how many of the orientations'
        runs the engine raised it).
    """
    model = build_model(plate, part, settings, unit_m, flat=True)
    data = mujoco.MjData(model)
    hulls = np.concatenate(engine_hulls(part, unit_m)) * unit_m  # the vertices the engine has
    dt = model.opt.timestep
    sink, shaken, warned = 0.0, 0.0, []
    for k in range(ORIENTATIONS):
        mujoco.mj_resetData(model, data)
        pos, quat = drop_state(k, plate, part, settings, unit_m)
        data.qpos[2:5] = [0.0, 0.0, pos[2]]  # over the middle, clear of the walls
        data.qpos[5:9] = quat
        for _ in range(int(round(SETTLE_S / dt))):
            mujoco.mj_step(model, data)
        sink = max(sink, _deepest(model, data, hulls, 0.0))
        n = int(round(SHAKE_S / dt))
        z, dz, phi, dphi = plate_motion(np.arange(n) * dt, settings)
        for i in range(n):
            data.qpos[0], data.qpos[1], data.qvel[0], data.qvel[1] = z[i], phi[i], dz[i], dphi[i]
            mujoco.mj_step(model, data)
            shaken = max(shaken, _deepest(model, data, hulls, float(data.qpos[0])))
        warned.extend(engine_warnings(data))
    return {
        "sink_mm": sink * 1e3,
        "shaken_penetration_mm": shaken * 1e3,
        "bound_mm": SINK_BOUND_MM,
        "shaken_bound_mm": shaken_bound_mm(plate, unit_m),
        "orientations": ORIENTATIONS,
        "engine_warnings": {w: warned.count(w) for w in sorted(set(warned))},
    }


def judge(name: str, fidelity: dict, outcomes: list) -> tuple[dict, list[str]]:
    """A shape's fidelity with its trials': whether every bound held, and why not in words.

    Parameters
    ----------
    name : str
        The shape's name (starts each warning).
    fidelity : dict
        :func:`measure_sink`'s result.
    outcomes : list of Outcome
        The shape's trials.

    Returns
    -------
    (dict, list of str)
        ``fidelity`` with ``trial_penetration_mm`` (deepest contact penetration over the trials,
        mm), ``unstable_trials`` (trials the engine warned in), the trials' warnings added to
        ``engine_warnings`` (name: runs, trials and the test's drops, that raised it) and
        ``within_bound`` (every bound held, no warning); and one warning line per bound that
        did not hold.
    """
    out = dict(fidelity)
    deepest = max((o.penetration for o in outcomes), default=0.0) * 1e3
    out["trial_penetration_mm"] = float(deepest)
    warned = dict(out["engine_warnings"])
    for o in outcomes:
        for w in o.warnings:
            warned[w] = warned.get(w, 0) + 1
    out["engine_warnings"] = {w: warned[w] for w in sorted(warned)}
    out["unstable_trials"] = sum(bool(o.warnings) for o in outcomes)
    lines = _warning_lines(name, out, len(outcomes))
    out["within_bound"] = not lines
    return out, lines


def _warning_lines(name: str, f: dict, trials: int) -> list[str]:
    """One line per bound ``f`` (:func:`judge`'s dict) does not keep."""
    lines = []
    if not f["sink_mm"] < f["bound_mm"]:
        lines.append(
            f"{name}: resting sink {f['sink_mm']:.3g} mm is over the bound {f['bound_mm']:g} mm"
        )
    shaken = max(f["shaken_penetration_mm"], f["trial_penetration_mm"])
    if not shaken <= f["shaken_bound_mm"]:
        lines.append(
            f"{name}: penetration while shaken {shaken:.3g} mm is over the bound "
            f"{f['shaken_bound_mm']:.3g} mm (the soft contacts let the part into the plate: "
            "its fractions are not to be trusted; shake more gently or use a thicker plate)"
        )
    for w, count in f["engine_warnings"].items():
        meaning = next((m for n, m in WARNINGS.values() if n == w), w)
        lines.append(
            f"{name}: MuJoCo warned {w}, {meaning}, in {count} run(s) (the trials and the "
            f"fidelity test's drops); {f['unstable_trials']} of {trials} trial(s) ended there, "
            "counted as not passed"
        )
    return lines
