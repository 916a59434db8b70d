"""``shake.gif``: a short Mitsuba-rendered clip of one trial per shape (like ``passage.gif``).

For each shape the first trial that passed (else trial 0) is run again and its part's pose
sampled; the clip shows the shapes one after another on the plate (set A green, a blocked B red,
a B that got through orange), each from its release until it is wholly below the plate or for
:data:`CLIP_S` seconds. The plate is drawn still: the part's height is taken relative to the
shaken plate (the 1 mm motion would not show at this scale).
"""

from __future__ import annotations

import mujoco
import numpy as np

from sieve_mi.shake.geometry import Part, Plate
from sieve_mi.shake.model import build_model, plate_motion
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.trials import drop_state

__all__ = ["CLIP_S", "FRAMES_PER_SHAPE", "trajectory", "write_clip"]

#: Longest stretch of a trial shown, seconds.
CLIP_S = 3.0
#: Frames per shape.
FRAMES_PER_SHAPE = 16


def trajectory(plate: Plate, part: Part, settings: ShakeSettings, unit_m: float, trial: int):
    """Poses of trial ``trial``'s part at :data:`FRAMES_PER_SHAPE` evenly spaced times.

    Returns
    -------
    (k, 8) float
        Rows (u, w, x, y, z, tx, ty, tz): local phase in [0, 1], rotation, position of the
        centre of mass relative to the plate (scene units).
    """
    model = build_model(plate, part, settings, unit_m)
    data = mujoco.MjData(model)
    pos, quat = drop_state(trial, plate, part, settings, unit_m)
    data.qpos[2:5], data.qpos[5:9] = pos, quat
    dt = model.opt.timestep
    steps = int(round(min(settings.duration, CLIP_S) / dt))
    z, dz, phi, dphi = plate_motion(np.arange(steps) * dt, settings)
    below = -plate.thickness * unit_m - settings.amplitude * 1e-3 - part.radius * unit_m
    poses = []
    for k in range(steps):
        data.qpos[0], data.qpos[1], data.qvel[0], data.qvel[1] = z[k], phi[k], dz[k], dphi[k]
        mujoco.mj_step(model, data)
        p = data.qpos[2:9].copy()
        p[2] -= data.qpos[0]
        poses.append(p)
        if p[2] < below:  # wholly below the plate: the clip ends here
            break
    idx = np.linspace(0, len(poses) - 1, FRAMES_PER_SHAPE).round().astype(int)
    keys = np.zeros((FRAMES_PER_SHAPE, 8))
    keys[:, 0] = np.linspace(0.0, 1.0, FRAMES_PER_SHAPE)
    for r, i in enumerate(idx):
        keys[r, 1:5], keys[r, 5:] = poses[i][3:7], poses[i][:3] / unit_m
    return keys


def write_clip(path: str, plate_mesh, plate: Plate, shapes: list) -> dict:
    """Render the clip.

    Parameters
    ----------
    path : str
        The GIF to write.
    plate_mesh : trimesh.Trimesh
        The plate as given (scene units); drawn centred, its top face at z = 0.
    plate : Plate
    shapes : list of (mesh, com (3,), role, passed, keys)
        Each shape's mesh (scene units), its centre of mass in the mesh's frame, ``"A"``/``"B"``/
        None, whether the shown trial passed, and :func:`trajectory`'s keys.

    Returns
    -------
    dict
        ``file``, ``frames``, ``frame_ms``.
    """
    from sieve_mi.backend import use_variant
    from sieve_mi.outputs.animation import FRAME_MS, gif_frames
    from sieve_mi.outputs.passage import Passage, Piece

    use_variant(None)
    pieces, n = [], len(shapes)
    for i, (mesh, com, role, passed, keys) in enumerate(shapes):
        v = np.asarray(mesh.vertices, dtype=np.float64) - com
        kind = "pass" if role == "A" else "block"
        piece = Piece(mesh.metadata.get("name", f"shape{i}"), kind, i, v, np.asarray(mesh.faces),
                      0.0, 0.0, 1.0, bool(passed), np.zeros(2), (i / n, (i + 1) / n), keys)  # fmt: skip
        pieces.append(piece)
    pv = np.asarray(plate_mesh.vertices, dtype=np.float64) - plate.offset
    passage = Passage(pv, np.asarray(plate_mesh.faces), plate.thickness, 0.0, pieces)
    s = np.concatenate(
        [np.linspace(i / n, (i + 1) / n, FRAMES_PER_SHAPE, endpoint=False) for i in range(n)]
    )
    pics, _ = gif_frames(passage, s)
    pics[0].save(path, save_all=True, append_images=pics[1:], duration=FRAME_MS, loop=0)
    return {"file": "shake.gif", "frames": len(pics), "frame_ms": FRAME_MS}
