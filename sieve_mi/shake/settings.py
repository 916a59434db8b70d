"""The settings of a shake run: shaker motion, physics, trials; and the engine's fixed constants.

Every setting is declared once, as a field of :class:`ShakeSettings` made by
:func:`sieve_mi.settings.setting` (its default, meaning, unit and bounds), the way the scene's tables
and ``check``'s options are (``trials``, ``duration`` and ``seed`` as the scene's ``[shake]`` keys,
:class:`sieve_mi.shaker.Shake`): the ``sieve-mi shake`` options, the ``[shake]`` table of a mixture
file and values given in code are all checked by :func:`sieve_mi.settings.read_value` against that
declaration, with the one-line error a bad scene key gets (``shake: --trials: must be >= 1,
got 0``).

Lengths of the shaker (amplitude, wall, drop) are in millimetres whatever the scene's units: they
describe the machine, not the parts. The parts and the plate are read in scene units and
converted with :data:`UNIT_TO_M`.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, fields

from sieve_mi.errors import SieveError
from sieve_mi.settings import documented, known_names, like, read_value, setting, spec_of
from sieve_mi.shaker import Shake

__all__ = [
    "CONTACT",
    "MAX_ACCELERATION_G",
    "PART_SIZE_MM",
    "PLATE_SIZE_MM",
    "SHAKEN_BOUND_MM",
    "SHAKEN_FRACTION",
    "SINK_BOUND_MM",
    "STEPS_PER_PERIOD",
    "TIMESTEP_MAX_MS",
    "UNIT_TO_M",
    "ShakeSettings",
    "check_workers",
    "metres_per_unit",
]

#: Metres per scene unit, for the units a scene may name.
UNIT_TO_M = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254, "um": 1e-6}

#: Standard gravity, m/s^2 (the g of accelerations).
G = 9.81

#: The stated fidelity bound: a part resting on the still plate sinks into it by less than this
#: (millimetres). Measured for every shape of every run (see :mod:`sieve_mi.shake.fidelity`).
SINK_BOUND_MM = 0.02

#: The bound on the penetration while shaken, millimetres: a part pressed this deep into the plate
#: (or a hole's edge) is half the default 1 mm fabrication tolerance away from where a real one
#: would be. A thin plate's bound is :data:`SHAKEN_FRACTION` of its thickness when that is less.
SHAKEN_BOUND_MM = 0.5
#: The largest penetration while shaken as a fraction of the plate's thickness.
SHAKEN_FRACTION = 0.25

#: Largest peak acceleration of the shaker, in g (9.81 m/s^2): lab sieve shakers throw at up to
#: a few tens of g (Retsch AS 200: 3 mm at 60 Hz is 43 g; the default 1 mm at 50 Hz is 10 g).
#: Settings beyond it are refused, as is a twist that throws the plate's corners harder.
MAX_ACCELERATION_G = 50.0
#: Least integration steps per shaker period (a coarser step does not follow the motion).
STEPS_PER_PERIOD = 20

#: Sizes of part the engine is used for: the largest side of its bounding box, millimetres. The
#: least is ten times the width of the contacts' soft layer (``solimp``'s 0.05 mm); a part of
#: more than a metre is no sieve's.
PART_SIZE_MM = (0.5, 1000.0)
#: A plate's least thickness (the contacts' soft layer) and largest side, millimetres.
PLATE_SIZE_MM = (0.05, 10_000.0)

#: MuJoCo contact parameters (fixed; recorded in every output). ``solref`` = (time constant s,
#: damping ratio): a stiff, critically damped contact; ``solimp`` = (d0, dwidth, width m, mid,
#: power): impedance 0.99 reached within 0.05 mm of penetration; elliptic friction cones.
CONTACT = {
    "solref": (0.001, 1.0),
    "solimp": (0.95, 0.99, 5e-5, 0.5, 2.0),
    "cone": "elliptic",
    "condim": 3,
}

#: Longest integration step, ms: half the contact time constant (longer steps make contacts
#: unstable).
TIMESTEP_MAX_MS = CONTACT["solref"][0] / 2 * 1e3


@known_names("shake")
@documented
@dataclass(frozen=True)
class ShakeSettings:
    """What a shake run does; every field is a ``sieve-mi shake`` option of the same name
    (``coacd_threshold``: ``--coacd-threshold``) and a key of a mixture's ``[shake]`` table.

    A value out of its bounds (or of the wrong type) is refused when the settings are made, with
    one :class:`~sieve_mi.errors.SieveError` line naming the setting (``shake: trials: must be
    >= 1, got 0``).
    """

    trials: int = like(Shake, "trials", default=200, default_doc=None)
    duration: float = like(Shake, "duration")
    amplitude: float = setting(
        1.0,
        "peak vertical displacement of the plate, z = amplitude sin(2 pi f t); "
        "Retsch AS 200: up to 3",
        unit="mm",
        minimum=0.0,
        maximum=50.0,
    )
    frequency: float = setting(
        50.0, "shaker frequency (mains: 50 or 60)", unit="Hz", minimum=0.0, maximum=1000.0
    )
    twist: float = setting(
        0.0,
        "peak rotation of the plate about the vertical axis through its centre, in phase with "
        "the lift (the slight rotary part of a 3-D throwing motion; no maker publishes its size, "
        "so it is off unless set)",
        unit="deg",
        minimum=0.0,
        maximum=45.0,
    )
    wall: float = setting(
        50.0, "height of the frame wall above the plate", unit="mm", minimum=0.0, maximum=10_000.0
    )
    drop: float = setting(
        5.0,
        "gap between the plate and the part's bounding sphere at release",
        unit="mm",
        minimum=0.0,
        maximum=10_000.0,
    )
    density: float = setting(
        1240.0, "density of every part (PLA 1240)", unit="kg/m^3", minimum=1.0, maximum=100_000.0
    )
    friction: float = setting(
        0.4, "Coulomb friction coefficient part-plate", minimum=0.0, maximum=10.0
    )
    timestep: float = setting(
        0.25,
        "integration step (at most half the contact time constant)",
        unit="ms",
        minimum=0.01,
        maximum=TIMESTEP_MAX_MS,
    )
    seed: int = like(Shake, "seed")
    coacd_threshold: float = setting(
        0.05,
        "CoACD's concavity threshold for non-convex parts (smaller: more, tighter pieces)",
        minimum=0.01,
        maximum=1.0,
    )
    hausdorff_bound: float = setting(
        0.4,
        "largest Hausdorff distance between a non-convex part and its convex pieces: a piece "
        "bulging out further is split again (0: CoACD's pieces as they are); a part left over "
        "it is reported",
        unit="mm",
        minimum=0.0,
        maximum=100.0,
    )
    workers: int = setting(
        0,
        "worker processes (0: every CPU core); results do not depend on it",
        minimum=0,
        maximum=1024,
    )

    def __post_init__(self):
        for f in fields(self):  # as a scene key is checked; an int for a float becomes a float
            value = read_value(ShakeSettings, f.name, getattr(self, f.name), "shake")
            object.__setattr__(self, f.name, value)
        check_workers(self.workers, "shake: workers")
        self._check_motion()

    def peak_acceleration_g(self, radius_mm: float = 0.0) -> float:
        """The plate's peak acceleration, g, at ``radius_mm`` from its centre: the lift's and
        the twist's (in phase, so they peak together): (2 pi f)^2 sqrt(A^2 + (r phi0)^2)."""
        w = 2 * math.pi * self.frequency
        reach = radius_mm * math.radians(self.twist)
        return w * w * math.hypot(self.amplitude, reach) * 1e-3 / G

    def _check_motion(self) -> None:
        """Refuse a shaker no lab has (:data:`MAX_ACCELERATION_G`) and a step too coarse for
        its period (:data:`STEPS_PER_PERIOD`): one line each, naming the values."""
        g = self.peak_acceleration_g()
        if g > MAX_ACCELERATION_G:
            raise SieveError(
                f"shake: amplitude {self.amplitude:g} mm at frequency {self.frequency:g} Hz is a "
                f"peak acceleration of {g:,.0f} g; sieve shakers give at most "
                f"{MAX_ACCELERATION_G:g} g (3 mm at 60 Hz is 43 g): lower the amplitude or the "
                "frequency"
            )
        if self.frequency > 0 and self.timestep * 1e-3 * self.frequency > 1 / STEPS_PER_PERIOD:
            most = 1e3 / (self.frequency * STEPS_PER_PERIOD)
            raise SieveError(
                f"shake: timestep {self.timestep:g} ms is more than 1/{STEPS_PER_PERIOD} of the "
                f"shaker's period at {self.frequency:g} Hz; use a timestep of at most "
                f"{most:.3g} ms or a lower frequency"
            )

    def to_dict(self) -> dict:
        """The settings as JSON-ready values (units in :meth:`units`)."""
        return asdict(self)

    @staticmethod
    def units() -> dict:
        """Unit of each setting that has one, for the output."""
        return {f.name: spec_of(f).unit for f in fields(ShakeSettings) if spec_of(f).unit}


def check_workers(workers: int, say: str) -> int:
    """``workers`` if it is at most :func:`sieve_mi.backend.max_threads` (four per core, the
    bound ``--threads`` has: more processes only compete for the cores, each with its own
    engine); ``say`` names the setting in the error (``"shake: --workers"``).

    Raises
    ------
    SieveError
        ``"shake: --workers 1024: must be a whole number from 0 to 8 (0: every core; four per
        core on this machine's 2 cores)"``.
    """
    from sieve_mi.backend import max_threads

    top = max_threads()
    if isinstance(workers, int) and not isinstance(workers, bool) and workers > top:
        raise SieveError(
            f"{say} {workers}: must be a whole number from 0 to {top} (0: every core; four per "
            f"core on this machine's {os.cpu_count() or 1} cores)"
        )
    return workers


def metres_per_unit(units: str) -> float:
    """Metres per scene unit; a one-line SieveError for a unit it does not know."""
    try:
        return UNIT_TO_M[units]
    except KeyError:
        raise SieveError(
            f"shake: unknown units {units!r}; use one of {', '.join(UNIT_TO_M)}"
        ) from None
