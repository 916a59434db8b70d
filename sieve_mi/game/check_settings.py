"""Settings of ``sieve-mi check`` (and ``certify``): its search, and how it reads its inputs.

Neither table is a table of a scene file: each field is an option of the command line
(:func:`sieve_mi.options.add_options` builds it) and a setting of :func:`sieve_mi.check` in code,
checked as a scene file's key is (:mod:`sieve_mi.settings`). The budgets that are also a
scene's (starts, steps, resolution, learning rate, seed, thin-plate budget) are declared once,
on the scene's tables, and taken from there with their bounds (:func:`~sieve_mi.settings.like`).
"""

from __future__ import annotations

from dataclasses import dataclass

from sieve_mi.scene import UNITS, ShapeEntry, Solver, Verdict
from sieve_mi.settings import checked, documented, like, setting

__all__ = ["AXIS_NAMES", "CheckInputs", "CheckSettings"]

#: Accepted ``check --axis`` and ``certify --axis`` values: the plate's axis a shape moves along.
AXIS_NAMES = ("x", "y", "z")


@checked("check")
@documented
@dataclass
class CheckSettings:
    """``sieve-mi check``'s search: player B's budget (the verdict's defaults) and the fit scale.

    Not a table of a scene file: the options ``--starts``, ``--steps``, ``--learning-rate``,
    ``--resolution``, ``--seed``, ``--thin-budget``, ``--no-fit`` and ``--fit-tolerance`` of
    ``sieve-mi check``, and ``settings=`` of :func:`sieve_mi.check` in code (imported as
    ``sieve_mi.game.check.CheckSettings``), checked as the options are.
    """

    starts: int = like(Verdict, "starts", doc="random starts of the fitting search")
    steps: int = like(Verdict, "steps", minimum=1)
    learning_rate: float = like(Solver, "learning_rate", maximum=1.0)
    resolution: int = like(Verdict, "resolution", doc="raster side in pixels for --sieve")
    seed: int = like(Solver, "seed", doc="random seed")
    thin_budget: float = like(
        Verdict,
        "thin_budget",
        doc="seconds of motion search through a plate (--sieve) thinner than the part",
    )
    fit: bool = setting(True, "the fit-scale search (the largest scale that passes)")
    fit_tolerance: float = setting(
        0.01,
        "relative precision of the fit scale",
        minimum=1e-6,
        maximum=1,
        exclusive_max=True,
    )


@checked("check")
@documented
@dataclass
class CheckInputs:
    """How ``sieve-mi check`` reads its part and its sieve (``certify``: ``scale`` and ``axis``).

    Not a table of a scene file: command-line options only.
    """

    scale: float = like(ShapeEntry, "scale", maximum=1_000_000)
    axis: str = setting("z", "direction the shape moves through the plate", choices=AXIS_NAMES)
    pixel_size: float | None = setting(
        None,
        "size of one pixel of --hole",
        unit="scene units",
        minimum=0,
        exclusive_min=True,
        maximum=1_000_000,
        default_doc="the image's PNG pHYs; required with --hole where it has none",
    )
    units: str = setting("mm", "unit name for the report", choices=UNITS)
