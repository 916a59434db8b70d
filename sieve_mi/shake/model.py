"""The MuJoCo model of one shake trial: a plate driven along a shaker motion, a frame, a part.

The plate hangs on two joints (a vertical slide and a twist about the vertical axis) whose
positions and velocities are set before every step to the shaker's motion, so the contact solver
sees the plate's true velocity (a mocap body would teleport at zero velocity). It is made so heavy
that one step of contact reaction moves it by nothing measurable. Lengths in metres here.
"""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np

from sieve_mi.geometry.plate import prism_vertices
from sieve_mi.shake.geometry import Part, Plate, collision_hull
from sieve_mi.shake.settings import CONTACT, ShakeSettings

__all__ = [
    "PART_SIMPLIFY_M",
    "PLATE_MASS_RATIO",
    "PLATE_SIMPLIFY_M",
    "WALL_THICKNESS_MM",
    "WARNINGS",
    "build_model",
    "engine_hulls",
    "engine_warnings",
    "plate_motion",
    "wall_thickness",
]

#: The plate's mass as a multiple of the part's.
PLATE_MASS_RATIO = 1e6
#: How far the plate's collision outline may stray from the exact one, metres: the width of the
#: contacts' soft layer (``solimp``), the depth the engine lets a resting part sink anyway. A
#: 256-gon 22 mm hole in 256 convex pieces becomes 64 pieces, and 100 ten-second trials of a
#: 23 mm ball seated on its rim cost a third of the CPU time (docs/performance.md, "Shake trials").
PLATE_SIMPLIFY_M = CONTACT["solimp"][2]
#: How far each of a part's convex pieces may shrink for the engine, metres (the same soft layer,
#: :func:`~sieve_mi.shake.geometry.collision_hull`): a coin cut as a 96-gon prism goes in as a
#: 32-gon (192 hull vertices to 64), and a 20-cent coin's ten-second trial on its 2 mm plate costs
#: a fifth less CPU time (docs/shake.md, "Trial speed"). 0 keeps every hull vertex.
PART_SIMPLIFY_M = CONTACT["solimp"][2]
#: Least thickness of the frame wall, millimetres; it is at least the part's diameter too, so no
#: fast part can tunnel through it in one step.
WALL_THICKNESS_MM = 2.0


#: MuJoCo's warnings by index in ``MjData.warning``: (name, what it means).
WARNINGS = {
    int(mujoco.mjtWarning.mjWARN_INERTIA): ("mjWARN_INERTIA", "a body's inertia is too small"),
    int(mujoco.mjtWarning.mjWARN_CONTACTFULL): ("mjWARN_CONTACTFULL", "too many contacts"),
    int(mujoco.mjtWarning.mjWARN_CNSTRFULL): ("mjWARN_CNSTRFULL", "too many constraints"),
    int(mujoco.mjtWarning.mjWARN_BADQPOS): ("mjWARN_BADQPOS", "unstable simulation (position)"),
    int(mujoco.mjtWarning.mjWARN_BADQVEL): ("mjWARN_BADQVEL", "unstable simulation (velocity)"),
    int(mujoco.mjtWarning.mjWARN_BADQACC): (
        "mjWARN_BADQACC",
        "unstable simulation (NaN, Inf or huge acceleration; MuJoCo reset it)",
    ),
    int(mujoco.mjtWarning.mjWARN_BADCTRL): ("mjWARN_BADCTRL", "bad control value"),
}


def _drop_message(text: str) -> None:
    """MuJoCo's warning handler here: its own (a line on stderr, and MUJOCO_LOG.TXT written into
    the working folder) is replaced; the counts in ``MjData.warning`` are what is reported."""


def engine_warnings(data) -> tuple:
    """The names of the warnings MuJoCo raised in ``data`` since its last reset (``WARNINGS``)."""
    return tuple(
        WARNINGS.get(i, (f"mjWARN_{i}", ""))[0]
        for i in range(len(data.warning))
        if data.warning[i].number
    )


def wall_thickness(part: Part, unit_m: float) -> float:
    """Thickness of the frame wall for ``part``, metres."""
    return max(WALL_THICKNESS_MM * 1e-3, 2 * part.radius * unit_m)


def plate_motion(t: np.ndarray, settings: ShakeSettings) -> tuple[np.ndarray, ...]:
    """The shaker's motion at times ``t``: lift (m), its speed (m/s), twist (rad), its rate.

    z(t) = A sin(2 pi f t), the vertical throw of electromagnetic lab sieve shakers, and
    phi(t) = phi0 sin(2 pi f t), the slight rotation in phase of their "3-D throwing motion"
    (``settings.twist``; 0 unless set, since no maker publishes its size; docs/shake.md).

    Parameters
    ----------
    t : float or (n,) float
        Seconds.
    settings : ShakeSettings

    Returns
    -------
    (z, dz, phi, dphi)
        Arrays shaped like ``t``.
    """
    w = 2 * math.pi * settings.frequency
    amp = settings.amplitude * 1e-3
    phi0 = math.radians(settings.twist)
    s, c = np.sin(w * np.asarray(t)), np.cos(w * np.asarray(t))
    return amp * s, amp * w * c, phi0 * s, phi0 * w * c


def build_model(plate: Plate, part: Part, settings: ShakeSettings, unit_m: float, *, flat=False):
    """Compile the trial's model.

    Parameters
    ----------
    plate : Plate
    part : Part
    settings : ShakeSettings
    unit_m : float
        Metres per scene unit.
    flat : bool
        Leave the holes out (a solid plate of the same size and thickness; for the fidelity test).

    Returns
    -------
    mujoco.MjModel
        Joints: 0 the plate's slide, 1 its twist, 2 the part's free joint (qpos[2:9]).
    """
    if mujoco.get_mju_user_warning() is not _drop_message:
        mujoco.set_mju_user_warning(_drop_message)  # no text on stderr, no file in the cwd
    spec = mujoco.MjSpec()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    opt = spec.option
    opt.timestep = settings.timestep * 1e-3
    opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    mass = part.volume * unit_m**3 * settings.density
    wall = wall_thickness(part, unit_m)
    _add_plate(spec, plate, settings, unit_m, (mass * PLATE_MASS_RATIO, wall), flat)
    _add_part(spec, part, settings, unit_m, mass)
    return spec.compile()


def _contact(geom, settings: ShakeSettings) -> None:
    geom.solref = list(CONTACT["solref"])
    geom.solimp = list(CONTACT["solimp"])
    geom.condim = CONTACT["condim"]
    geom.friction = [settings.friction, 0.0, 0.0]


def _add_plate(spec, plate: Plate, settings, unit_m: float, mass_wall, flat: bool) -> None:
    """The plate body: convex prisms (or one slab when ``flat``) and the frame's four walls.

    ``mass_wall`` is (the plate's mass kg, the wall's thickness m).
    """
    mass, t = mass_wall
    body = spec.worldbody.add_body(name="plate", gravcomp=1.0)
    body.add_joint(name="lift", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
    body.add_joint(name="twist", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    hx, hy = (float(v) * unit_m for v in plate.half_size)
    body.explicitinertial = True
    body.ipos, body.iquat = [0, 0, 0], [1, 0, 0, 0]
    body.mass = mass
    body.inertia = [mass * (hx * hx + hy * hy) / 3] * 3
    th = plate.thickness * unit_m
    if flat:
        slab = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) / unit_m
        pieces = [slab]
    else:
        pieces = plate.collision(PLATE_SIMPLIFY_M / unit_m)
    for i, poly in enumerate(pieces):
        mesh = spec.add_mesh(name=f"plate{i}")
        mesh.uservert = (prism_vertices(poly * unit_m, -th, 0.0)).ravel().tolist()
        _contact(body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"plate{i}"), settings)
    top = settings.wall * 1e-3
    hz, cz = (top + th) / 2, (top - th) / 2
    for size, pos in (
        ([t / 2, hy + t, hz], [hx + t / 2, 0, cz]),
        ([t / 2, hy + t, hz], [-hx - t / 2, 0, cz]),
        ([hx + t, t / 2, hz], [0, hy + t / 2, cz]),
        ([hx + t, t / 2, hz], [0, -hy - t / 2, cz]),
    ):
        geom = body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=size, pos=pos)
        _contact(geom, settings)


def _add_part(spec, part: Part, settings, unit_m: float, mass: float) -> None:
    """The part: a free body at its centre of mass, one mesh geom per convex piece."""
    body = spec.worldbody.add_body(name="part", pos=[0, 0, 1.0])
    body.add_freejoint()
    body.explicitinertial = True
    body.ipos, body.iquat = [0, 0, 0], [1, 0, 0, 0]  # else MjSpec puts the centre of mass at pos
    body.mass = mass
    i = part.inertia * unit_m**5 * settings.density
    body.fullinertia = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
    for k, hull in enumerate(engine_hulls(part, unit_m)):
        mesh = spec.add_mesh(name=f"part{k}")
        mesh.uservert = (hull * unit_m).ravel().tolist()
        _contact(body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"part{k}"), settings)


def engine_hulls(part: Part, unit_m: float) -> list[np.ndarray]:
    """The part's convex pieces as the engine collides them, scene units: each within
    :data:`PART_SIMPLIFY_M` of ``part.hulls`` (:func:`~sieve_mi.shake.geometry.collision_hull`)."""
    return [_engine_hull(h, PART_SIMPLIFY_M / unit_m) for h in part.hulls]


def _engine_hull(hull: np.ndarray, tolerance: float) -> np.ndarray:
    """A convex piece as the engine gets it (:func:`~sieve_mi.shake.geometry.collision_hull`
    within ``tolerance``, scene units), computed once per piece and process."""
    hull = np.ascontiguousarray(hull, dtype=np.float64)
    return _kept_hull(hull.tobytes(), hull.shape[0], float(tolerance))


@functools.lru_cache(maxsize=64)
def _kept_hull(data: bytes, n: int, tolerance: float) -> np.ndarray:
    return collision_hull(np.frombuffer(data, dtype=np.float64).reshape(n, 3), tolerance)
