"""Fidelity measured, not assumed: how far a part sinks into the plate in the engine.

MuJoCo's contacts are soft: a resting part sits slightly inside the plate. For each part the
part is dropped in a few orientations onto a still, solid plate of the same size and thickness,
left to settle, and its deepest hull vertex below the top face is measured (the *sink*); then
the plate shakes and the deepest penetration over a few periods is measured too. The run states
:data:`~sieve_mi.shake.settings.SINK_BOUND_MM` and whether every part kept under it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sieve_mi.shake.geometry import Part, Plate
from sieve_mi.shake.model import build_model, plate_motion
from sieve_mi.shake.settings import SINK_BOUND_MM, ShakeSettings
from sieve_mi.shake.trials import drop_state

__all__ = ["ORIENTATIONS", "SETTLE_S", "SHAKE_S", "measure_sink"]

#: Drop orientations per part (the first trials' orientations).
ORIENTATIONS = 3
#: Settling time on the still plate, seconds.
SETTLE_S = 0.5
#: Shaking time for the dynamic penetration, seconds.
SHAKE_S = 0.2


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
        (deepest penetration while shaken, mm), ``bound_mm``, ``within_bound`` (bool),
        ``orientations``.
    """
    model = build_model(plate, part, settings, unit_m, flat=True)
    data = mujoco.MjData(model)
    hulls = np.concatenate(part.hulls) * unit_m
    dt = model.opt.timestep
    sink, shaken = 0.0, 0.0
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
    return {
        "sink_mm": sink * 1e3,
        "shaken_penetration_mm": shaken * 1e3,
        "bound_mm": SINK_BOUND_MM,
        "within_bound": bool(sink * 1e3 < SINK_BOUND_MM),
        "orientations": ORIENTATIONS,
    }
