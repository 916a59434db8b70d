"""A scene's ``[shake]`` table: the shake trials after a solve, and the pass rate it aims for.

The table sits below :mod:`sieve_mi.scene` in the floor plan (the scene holds it) and its keys
``trials``, ``duration`` and ``seed`` are the shaker's own: :class:`~sieve_mi.shake.settings.
ShakeSettings` declares them as these (:func:`sieve_mi.settings.like`), so each has one home, one
bound and one meaning for a scene key, a ``sieve-mi shake`` option and a mixture's ``[shake]`` key.
``target`` is the scene's alone (:mod:`sieve_mi.shake.target`).
"""

from __future__ import annotations

from dataclasses import dataclass

from sieve_mi.settings import checked, documented, setting

__all__ = ["Shake"]


@checked("shake")
@documented
@dataclass
class Shake:
    """``[shake]``: shake each shape on the solved plate (MuJoCo) and, with a target, design for
    the pass rate (docs/shake.md, "A pass-rate target")."""

    trials: int | None = setting(
        None,
        "independent trials per shape (one drop, then shaking)",
        minimum=1,
        maximum=1_000_000,
        default_doc="none: no trials after the solve (200 with a target; --shake N sets it)",
    )
    duration: float = setting(
        10.0, "shaking time per trial", unit="s", minimum=0.01, maximum=3600.0
    )
    seed: int = setting(
        0, "seed of the random drops (same seed, same numbers)", minimum=0, maximum=2**63 - 1
    )
    target: float | None = setting(
        None,
        "the fraction of each A's trials that must pass within duration: the solver grows the "
        "tolerance, widens the turning window, then adds turned and mirrored copies on a "
        "tray-sized sheet, until it does",
        minimum=0,
        exclusive_min=True,
        maximum=1,
        default_doc="none",
    )
