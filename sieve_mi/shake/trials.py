"""Shake trials: drop a part at random, shake, record whether and when it fell through.

Trials are independent: trial ``i`` of a run draws its drop from the seed sequence
``(seed, i)`` alone and runs in a fresh state of the same model, so its result does not depend
on how trials are spread over worker processes (same seed, same numbers).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass

import mujoco
import numpy as np

from sieve_mi.shake.geometry import Part, Plate
from sieve_mi.shake.model import build_model, engine_warnings, plate_motion, wall_thickness
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.workers import worker_pool

__all__ = [
    "CHECK_EVERY",
    "Outcome",
    "drop_state",
    "run_trial",
    "run_trials",
]

#: Steps between two checks of whether the part fell through or left the frame.
CHECK_EVERY = 10


@dataclass(frozen=True)
class Outcome:
    """One trial's result.

    Attributes
    ----------
    passed : bool
        The part ended wholly below the plate's lowest position.
    time : float
        When it did, seconds after release (nan if it did not).
    escaped : bool
        It left the frame over the wall (counted as not passed).
    penetration : float
        The deepest contact penetration of the trial, m (the part into the plate, a hole's edge
        or the wall).
    warnings : tuple of str
        The engine's warnings (``mjWARN_BADQACC``: the simulation went unstable and MuJoCo
        reset it); the trial ends at the first, as not passed.
    """

    passed: bool
    time: float
    escaped: bool = False
    penetration: float = 0.0
    warnings: tuple = ()


def drop_state(trial: int, plate: Plate, part: Part, settings: ShakeSettings, unit_m: float):
    """Where trial ``trial`` releases the part: (position (3,) m, quaternion (4,) w-x-y-z).

    Orientation uniform on SO(3); the centre of mass uniform over the plate shrunk by the part's
    bounding radius (so it starts clear of the wall), its bounding sphere ``settings.drop``
    above the plate's highest position.
    """
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng([settings.seed, trial])
    q = Rotation.random(random_state=rng).as_quat()  # x, y, z, w
    r = part.radius * unit_m
    room = np.maximum(np.asarray(plate.half_size) * unit_m - r, 0.0)
    xy = rng.uniform(-1.0, 1.0, 2) * room
    z = settings.amplitude * 1e-3 + settings.drop * 1e-3 + r
    return np.array([xy[0], xy[1], z]), np.array([q[3], q[0], q[1], q[2]])


def run_trial(
    model, data, trial: int, plate: Plate, part: Part, settings, unit_m: float, observe=None
):
    """Run one trial in ``model`` (from :func:`~sieve_mi.shake.model.build_model`).

    ``observe``, if given, is called as ``observe(k, data, lift)`` after every step ``k`` (the
    plate's lift then, m), for diagnostics such as ``benchmarks.shake.seating``.

    Every step the deepest contact penetration is kept; every :data:`CHECK_EVERY` steps the
    engine's warnings are read, and a warned trial ends there (MuJoCo resets an unstable
    simulation to its start, so what follows is no trial).

    Returns
    -------
    Outcome
    """
    mujoco.mj_resetData(model, data)
    pos, quat = drop_state(trial, plate, part, settings, unit_m)
    data.qpos[2:5], data.qpos[5:9] = pos, quat
    dt = model.opt.timestep
    steps = int(round(settings.duration / dt))
    z, dz, phi, dphi = plate_motion(np.arange(steps) * dt, settings)
    below = -plate.thickness * unit_m - settings.amplitude * 1e-3 - part.radius * unit_m
    frame = np.asarray(plate.half_size) * unit_m + wall_thickness(part, unit_m)
    qpos, qvel = data.qpos, data.qvel
    deepest = 0.0
    for k in range(steps):
        qpos[0], qpos[1], qvel[0], qvel[1] = z[k], phi[k], dz[k], dphi[k]
        mujoco.mj_step(model, data)
        if data.ncon:
            deepest = max(deepest, -float(data.contact.dist.min()))
        if observe is not None:
            observe(k, data, z[k])
        if k % CHECK_EVERY == 0:
            warned = engine_warnings(data)
            if warned:
                return Outcome(False, math.nan, penetration=deepest, warnings=warned)
            outside = bool(np.any(np.abs(qpos[2:4]) > frame))
            if outside:  # over the wall (whatever its height now)
                return Outcome(False, math.nan, escaped=True, penetration=deepest)
            if qpos[4] < below:
                return Outcome(True, float(data.time), penetration=deepest)
    warned = engine_warnings(data)
    return Outcome(False, math.nan, penetration=deepest, warnings=warned)


def _cpus() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


_WORKER = {}


def _preload() -> None:
    """Have the fork server import the engine once, before it forks the first worker: every
    later worker of the process (the next shape, the next try of a target) starts with MuJoCo
    imported, not 2 s later (docs/shake.md, "Trial speed"). Only the first call before the
    server starts counts; the server itself holds no thread."""
    import multiprocessing

    multiprocessing.set_forkserver_preload([__name__])


def _init_worker(plate, part, settings, unit_m) -> None:
    model = build_model(plate, part, settings, unit_m)
    _WORKER.update(model=model, data=mujoco.MjData(model), args=(plate, part, settings, unit_m))


def _worker_trial(trial: int) -> Outcome:
    w = _WORKER
    return run_trial(w["model"], w["data"], trial, *w["args"])


def run_trials(
    plate: Plate,
    part: Part,
    settings: ShakeSettings,
    unit_m: float,
    progress=None,
    indices=None,
):
    """The trials of one part, on ``settings.workers`` processes.

    Parameters
    ----------
    plate, part, settings, unit_m
        As for :func:`run_trial`.
    progress : callable or None
        Called with each finished trial's :class:`Outcome` (in trial order).
    indices : sequence of int, optional
        The trials to run (a cascade runs on a lower sieve only the trials that passed the sieves
        above); default every trial, ``range(settings.trials)``. Trial ``i`` is the same
        whatever else runs.

    Returns
    -------
    list of Outcome
        One per trial run, in the order of ``indices``.
    """
    indices = list(range(settings.trials) if indices is None else indices)
    workers = settings.workers or _cpus()
    workers = max(1, min(workers, len(indices)))
    out = []
    if workers == 1:
        _init_worker(plate, part, settings, unit_m)
        for i in indices:
            out.append(_worker_trial(i))
            if progress:
                progress(out[-1])
        return out
    # MuJoCo and Dr.Jit hold threads: the workers start from a clean process, not a fork.
    method = "forkserver" if sys.platform.startswith("linux") else "spawn"
    if method == "forkserver":
        _preload()
    chunk = max(1, len(indices) // (16 * workers))  # few futures even for a million trials
    init = (plate, part, settings, unit_m)
    with worker_pool(workers, method=method, initializer=_init_worker, initargs=init,
                     what="shake trial") as pool:  # fmt: skip
        for outcome in pool.map(_worker_trial, indices, chunksize=chunk):
            out.append(outcome)
            if progress:
                progress(outcome)
    return out
