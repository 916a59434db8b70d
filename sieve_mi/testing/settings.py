"""Small solver settings for tests and benchmarks: a solve in seconds, not a meaningful search.

Each set is written once, here: as TOML text to append to a scene file's ``[[pass]]`` and
``[[block]]`` tables (:data:`TINY`, or :func:`settings_toml` of the tables below with a key or
two changed), and as a :class:`sieve_mi.scene.Solver` table for code that calls the players
directly (:func:`tiny_solver`).

Examples
--------
>>> print(settings_toml(solver={**TINY_SOLVER, "steps": 30}, layout=TINY_LAYOUT).strip())
[solver]
resolution = 64
particles = 3
iterations = 1
starts = 4
steps = 30
retries = 0
[layout]
rounds = 1
alternatives = 0
restarts = 0
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from types import MappingProxyType

from sieve_mi.scene import Solver

__all__ = [
    "CASCADE_SOLVER",
    "TINY",
    "TINY_LAYOUT",
    "TINY_SOLVER",
    "TINY_VERDICT",
    "settings_toml",
    "tiny_solver",
]

#: ``[solver]`` keys of a tiny search: a 64-pixel raster, 3 particles and 1 iteration,
#: player B with 4 starts of 20 Adam steps, no retry of a lost search.
TINY_SOLVER = MappingProxyType(
    {"resolution": 64, "particles": 3, "iterations": 1, "starts": 4, "steps": 20, "retries": 0}
)
#: ``[verdict]`` keys of a short verdict: 8 starts of 40 steps on a 96-pixel raster, and one
#: second per proof of a block.
TINY_VERDICT = MappingProxyType(
    {"starts": 8, "steps": 40, "resolution": 96, "certify_budget": 1.0, "section_budget": 3.0}
)
#: ``[layout]`` keys that place each of several A once: one round, no alternatives, no restarts.
TINY_LAYOUT = MappingProxyType({"rounds": 1, "alternatives": 0, "restarts": 0})
#: ``[solver]`` keys of a sorting cascade's many games: :data:`TINY_SOLVER` with 30 steps, 6
#: canonical views and no polish.
CASCADE_SOLVER = MappingProxyType({**TINY_SOLVER, "steps": 30, "canonical": 6, "polish": 0})


def settings_toml(**tables: Mapping) -> str:
    """Settings tables as TOML text, to append to a scene's ``[[pass]]`` and ``[[block]]`` tables.

    Parameters
    ----------
    **tables : mapping
        Per table (``solver=``, ``verdict=``, ``layout=``, ``fabrication=``) its keys and
        values (bool, int, float or str), in the order given.

    Returns
    -------
    str
        Starting and ending with a newline.
    """
    lines = [""]
    for name, keys in tables.items():
        lines.append(f"[{name}]")
        lines += [f"{key} = {_toml_value(value)}" for key, value in keys.items()]
    return "\n".join(lines) + "\n"


def _toml_value(value) -> str:
    """One TOML value: ``true``/``false``, a quoted string, or a number."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


#: A tiny search and a short verdict as scene-file text (end-to-end tests: seconds per solve).
TINY = settings_toml(solver=TINY_SOLVER, verdict=TINY_VERDICT)


def tiny_solver(**changes) -> Solver:
    """A ``[solver]`` table with the tiny search (:data:`TINY_SOLVER`), no canonical views and
    no polish, for calls of :meth:`sieve_mi.game.player_a.PlayerA.search` and ``polish``.

    Parameters
    ----------
    **changes
        Other values for any of its keys (``particles=8``, ``polish=12``, ...).

    Returns
    -------
    sieve_mi.scene.Solver
        Its values are not checked (as for any table made in code).
    """
    return Solver(**{**TINY_SOLVER, "canonical": 0, "polish": 0, **changes})
