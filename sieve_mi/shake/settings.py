"""The settings of a shake run: shaker motion, physics, trials; and the engine's fixed constants.

Lengths of the shaker (amplitude, wall, drop) are in millimetres whatever the scene's units: they
describe the machine, not the parts. The parts and the plate are read in scene units and
converted with :data:`UNIT_TO_M`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from sieve_mi.errors import SieveError

__all__ = [
    "CONTACT",
    "SINK_BOUND_MM",
    "UNIT_TO_M",
    "ShakeSettings",
    "metres_per_unit",
]

#: Metres per scene unit, for the units a scene may name.
UNIT_TO_M = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254, "um": 1e-6}

#: The stated fidelity bound: a part resting on the still plate sinks into it by less than this
#: (millimetres). Measured for every shape of every run (see :mod:`sieve_mi.shake.fidelity`).
SINK_BOUND_MM = 0.02

#: MuJoCo contact parameters (fixed; recorded in every output). ``solref`` = (time constant s,
#: damping ratio): a stiff, critically damped contact; ``solimp`` = (d0, dwidth, width m, mid,
#: power): impedance 0.99 reached within 0.05 mm of penetration; elliptic friction cones.
CONTACT = {
    "solref": (0.001, 1.0),
    "solimp": (0.95, 0.99, 5e-5, 0.5, 2.0),
    "cone": "elliptic",
    "condim": 3,
}


@dataclass(frozen=True)
class ShakeSettings:
    """What a shake run does; every field is a ``sieve-mi shake`` option of the same name.

    Attributes
    ----------
    trials : int
        Independent trials per shape (each: one drop, then shaking for ``duration``).
    duration : float
        Shaking time per trial, seconds.
    amplitude : float
        Peak vertical displacement of the plate, millimetres (z = amplitude sin 2 pi f t).
    frequency : float
        Shaker frequency, Hz (mains-driven electromagnetic shakers: 50 or 60).
    twist : float
        Peak rotation of the plate about the vertical axis through its centre, degrees, in
        phase with the vertical motion (the "3-D throwing motion" of lab shakers).
    wall : float
        Height of the frame wall around the plate above its top face, millimetres.
    drop : float
        Gap between the plate's top face and the part's bounding sphere at release, millimetres.
    density : float
        Density of every part, kg/m^3 (PLA: 1240).
    friction : float
        Coulomb friction coefficient between part and plate.
    timestep : float
        Integration step, milliseconds.
    seed : int
        Seed of the trials' random drops (same seed, same numbers).
    coacd_threshold : float
        CoACD's concavity threshold for non-convex parts (smaller: more, tighter pieces).
    workers : int
        Threads of MuJoCo's rollout; 0: every CPU core. Results do not depend on it.
    """

    trials: int = 200
    duration: float = 10.0
    amplitude: float = 1.0
    frequency: float = 50.0
    twist: float = 0.5
    wall: float = 50.0
    drop: float = 5.0
    density: float = 1240.0
    friction: float = 0.4
    timestep: float = 0.25
    seed: int = 0
    coacd_threshold: float = 0.05
    workers: int = 0

    def __post_init__(self):
        _check_settings(self)

    def to_dict(self) -> dict:
        """The settings as JSON-ready values (units in :meth:`units`)."""
        return asdict(self)

    @staticmethod
    def units() -> dict:
        """Unit of each setting, for the output."""
        return {
            "duration": "s",
            "amplitude": "mm",
            "frequency": "Hz",
            "twist": "deg",
            "wall": "mm",
            "drop": "mm",
            "density": "kg/m^3",
            "timestep": "ms",
        }


_LIMITS = {
    "trials": (1, 1_000_000),
    "duration": (0.01, 3600.0),
    "amplitude": (0.0, 50.0),
    "frequency": (0.0, 1000.0),
    "twist": (0.0, 45.0),
    "wall": (0.0, 10_000.0),
    "drop": (0.0, 10_000.0),
    "density": (1.0, 100_000.0),
    "friction": (0.0, 10.0),
    "timestep": (0.01, 2.0),
    "seed": (0, 2**63 - 1),
    "coacd_threshold": (0.01, 1.0),
    "workers": (0, 1024),
}


def _check_settings(s: ShakeSettings) -> None:
    """Refuse a value out of range (or not a finite number) with one line naming the option."""
    for f in fields(s):
        value, (lo, hi) = getattr(s, f.name), _LIMITS[f.name]
        flag = "--" + f.name.replace("_", "-")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SieveError(f"shake {flag} {value!r}: expected a number")
        if f.type in ("int", int) and not isinstance(value, int):
            raise SieveError(f"shake {flag} {value!r}: expected a whole number")
        if not math.isfinite(value) or not lo <= value <= hi:
            raise SieveError(f"shake {flag} {value}: expected a number from {lo} to {hi}")
    if s.timestep * 1e-3 * 2 > CONTACT["solref"][0]:
        raise SieveError(
            f"shake --timestep {s.timestep}: at most {CONTACT['solref'][0] / 2 * 1e3:g} ms "
            "(half the contact time constant, or contacts go unstable)"
        )


def metres_per_unit(units: str) -> float:
    """Metres per scene unit; a one-line SieveError for a unit it does not know."""
    try:
        return UNIT_TO_M[units]
    except KeyError:
        raise SieveError(
            f"shake: unknown units {units!r}; use one of {', '.join(UNIT_TO_M)}"
        ) from None
