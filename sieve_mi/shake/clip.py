"""``shake.gif``: a short Mitsuba-rendered clip of one trial per shape (like ``passage.gif``).

For each shape the first trial that passed (else trial 0) is run again and the simulation's state
sampled: the part's pose and the plate's pose (its lift and twist, as the engine moved it), both
in the world frame, so the clip shows the plate shaking and the part on it as simulated. The
shapes come one after another (set A green, a blocked B red, a B that got through orange): a
passing trial's last :data:`CLIP_S` seconds, up to the moment the part is wholly below the
plate; a trial that did not pass, its first :data:`CLIP_S` seconds from the release.

The frames are :data:`FRAMES_PER_SHAPE` instants of the trial, about evenly spaced. The 50 Hz
motion is far faster than the clip: frames a whole number of periods apart would all catch the
plate at one point of its stroke. So each frame is moved (by at most half a period, 10 ms) to
the instant a quarter period further into the cycle than the frame before
(:func:`frame_steps`): successive frames catch the plate at rest height, at the top, at rest
height and at the bottom of its stroke, and the clip shows its full travel (2 x amplitude).
Every frame shows the simulated state at its instant; nothing is interpolated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sieve_mi.errors import raise_if_signalled
from sieve_mi.outputs.passage import Passage
from sieve_mi.shake.geometry import Part, Plate
from sieve_mi.shake.model import build_model, plate_motion
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.trials import drop_state

__all__ = ["CLIP_S", "FRAMES_PER_SHAPE", "Trajectory", "frame_steps", "trajectory", "write_clip"]

#: Longest stretch of a trial shown, seconds.
CLIP_S = 3.0
#: Frames per shape.
FRAMES_PER_SHAPE = 16


@dataclass
class Trajectory:
    """The sampled frames of one trial.

    Attributes
    ----------
    keys : (k, 8) float
        Rows (u, w, x, y, z, tx, ty, tz): the frame's local phase ``i / k`` in [0, 1), the part's
        rotation and its centre of mass in the world frame (scene units; the plate's top face at
        rest is z = 0).
    plate : (k, 2) float
        The plate's pose at each frame as the engine had it: lift (scene units) and twist about
        the vertical axis through its centre (radians).
    times : (k,) float
        Seconds after release.
    """

    keys: np.ndarray
    plate: np.ndarray
    times: np.ndarray


def frame_steps(last: int, dt: float, frequency: float, frames: int = FRAMES_PER_SHAPE):
    """Step indices of the frames of a stretch of steps 0..``last``.

    Frame k is the step nearest to the evenly spaced k / (frames - 1) of the stretch at which
    the shaker is k quarter periods into its cycle (modulo whole periods; it moves by at most
    half a period), so successive frames catch the plate at successive quarters of its stroke;
    the last frame is step ``last`` itself (the part just below the plate, when it passed). A
    stretch shorter than ``frames - 1`` periods (or a still plate) is sampled evenly.

    Parameters
    ----------
    last : int
        The stretch's last step.
    dt : float
        Step, seconds.
    frequency : float
        Shaker frequency, Hz (0: a still plate).
    frames : int

    Returns
    -------
    (frames,) int
        Non-decreasing, from 0 to ``last``.
    """
    even = np.linspace(0.0, last, frames)
    period = 1.0 / (frequency * dt) if frequency > 0 else math.inf  # steps per shaker period
    if last < (frames - 1) * period:
        return np.round(even).astype(int)
    quarter = (np.arange(frames) % 4) * period / 4
    steps = np.round(np.round((even - quarter) / period) * period + quarter).astype(int)
    steps = np.clip(steps, 0, last)
    steps[-1] = last
    return steps


def trajectory(
    plate: Plate, part: Part, settings: ShakeSettings, unit_m: float, trial: int, passed=False
):
    """The frames of trial ``trial``: the part's and the plate's poses at :func:`frame_steps`.

    Parameters
    ----------
    plate, part, settings, unit_m
        As for :func:`~sieve_mi.shake.trials.run_trial`.
    trial : int
    passed : bool
        Whether the trial passed: then it is run to the end and its last :data:`CLIP_S` seconds
        are shown (ending wholly below the plate), else its first :data:`CLIP_S` seconds.

    Returns
    -------
    Trajectory
    """
    model = build_model(plate, part, settings, unit_m)
    data = mujoco.MjData(model)
    pos, quat = drop_state(trial, plate, part, settings, unit_m)
    data.qpos[2:5], data.qpos[5:9] = pos, quat
    dt = model.opt.timestep
    steps = int(round((settings.duration if passed else min(settings.duration, CLIP_S)) / dt))
    z, dz, phi, dphi = plate_motion(np.arange(steps) * dt, settings)
    below = -plate.thickness * unit_m - settings.amplitude * 1e-3 - part.radius * unit_m
    states = []
    for k in range(steps):
        data.qpos[0], data.qpos[1], data.qvel[0], data.qvel[1] = z[k], phi[k], dz[k], dphi[k]
        mujoco.mj_step(model, data)
        states.append(np.concatenate([[data.time], data.qpos[:9]]))
        if data.qpos[4] < below:  # wholly below the plate's lowest position: the clip ends
            break
    first = max(0, len(states) - 1 - int(round(CLIP_S / dt)))  # the last CLIP_S seconds
    window = frame_steps(len(states) - 1 - first, dt, settings.frequency)
    picked = np.array([states[first + i] for i in window])
    n = len(picked)
    keys = np.zeros((n, 8))
    keys[:, 0] = np.arange(n) / n
    keys[:, 1:5], keys[:, 5:] = picked[:, 6:10], picked[:, 3:6] / unit_m
    return Trajectory(keys, np.column_stack([picked[:, 1] / unit_m, picked[:, 2]]), picked[:, 0])


@dataclass
class _Framed(Passage):
    """A passage whose camera frames a given box: the clip's frames are rendered in groups (one
    per plate pose), and every group must be seen from the same camera."""

    box: np.ndarray | None = None

    def bounds(self) -> np.ndarray:
        """The given box (2, 3), scene units."""
        return self.box


def _posed_plate(vertices: np.ndarray, lift: float, twist: float) -> np.ndarray:
    """The plate's vertices turned by ``twist`` about the vertical axis and lifted by ``lift``."""
    c, s = math.cos(twist), math.sin(twist)
    out = vertices @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    out[:, 2] += lift
    return out


def write_clip(path: str, plate_mesh, plate: Plate, shapes: list) -> dict:
    """Render the clip.

    Parameters
    ----------
    path : str
        The GIF to write.
    plate_mesh : trimesh.Trimesh
        The plate as given (scene units); at rest centred, its top face at z = 0.
    plate : Plate
    shapes : list of (mesh, com (3,), role, passed, Trajectory)
        Each shape's mesh (scene units), its centre of mass in the mesh's frame, ``"A"``/``"B"``/
        None, whether the shown trial passed, and :func:`trajectory`'s frames.

    Returns
    -------
    dict
        ``file``, ``frames``, ``frame_ms``, ``plate_lift`` (the plate's lift in each frame, scene
        units: the stroke the clip shows) and ``box`` (the box every frame's camera frames,
        :func:`sieve_mi.outputs.animation.camera`; scene units).
    """
    from sieve_mi.backend import use_variant
    from sieve_mi.outputs.animation import FRAME_MS, gif_frames
    from sieve_mi.outputs.passage import Piece

    use_variant(None)
    pieces, n = [], len(shapes)
    for i, (mesh, com, role, passed, traj) in enumerate(shapes):
        v = np.asarray(mesh.vertices, dtype=np.float64) - com
        kind = "pass" if role == "A" else "block"
        piece = Piece(mesh.metadata.get("name", f"shape{i}"), kind, i, v, np.asarray(mesh.faces),
                      0.0, 0.0, 1.0, bool(passed), np.zeros(2), (i / n, (i + 1) / n), traj.keys)  # fmt: skip
        pieces.append(piece)
    pv = np.asarray(plate_mesh.vertices, dtype=np.float64) - plate.offset
    faces = np.asarray(plate_mesh.faces)
    # Frame j of shape i: phase (i + u_j) / n lands on the key u_j exactly; its plate pose.
    s = np.concatenate([(i + t.keys[:, 0]) / n for i, (*_, t) in enumerate(shapes)])
    # Poses equal but for rounding and the part's push on the heavy plate (the same point of the
    # stroke, ~1e-8 mm apart) are drawn as one and rendered together; the rounding (1e-6 scene
    # units, 1e-9 rad) is far below a pixel.
    poses = np.concatenate([t.plate for *_, t in shapes])
    poses = np.column_stack([np.round(poses[:, 0], 6), np.round(poses[:, 1], 9)])
    groups = {}
    for j, pose in enumerate(poses):
        groups.setdefault((float(pose[0]), float(pose[1])), []).append(j)
    passages = {
        key: _Framed(_posed_plate(pv, *key), faces, plate.thickness, 0.0, pieces) for key in groups
    }
    bounds = np.array([Passage.bounds(p) for p in passages.values()])
    box = np.array([bounds[:, 0].min(0), bounds[:, 1].max(0)])
    pics = [None] * len(s)
    for key, idx in groups.items():
        passages[key].box = box
        for j, pic in zip(idx, gif_frames(passages[key], s[idx])[0]):
            pics[j] = pic
        raise_if_signalled()
    pics[0].save(path, save_all=True, append_images=pics[1:], duration=FRAME_MS, loop=0)
    return {
        "file": "shake.gif",
        "frames": len(pics),
        "frame_ms": FRAME_MS,
        "plate_lift": [float(z) for z in poses[:, 0]],
        "box": box.tolist(),
    }
