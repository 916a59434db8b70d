"""The two kinds of a cascade's games: cheap screening games that pick a plan, full games that
are the cascade.

A *full* game is played with the mixture's own settings; its verdict (and, with ``[verdict]
certify``, its proof) is the sieve's. A *screening* game only chooses which of several
candidate holds to plan at a sieve (:mod:`sieve_mi.cascade.plan`), so it is played at reduced
settings (:func:`screening_tables`): player A's swarm and player B's attacks smaller, the
rasters coarser, the layout placed once, and no proof (``certify = false``: a screening game
proves nothing that is kept). The reductions only ever lower a setting (a key already below its
cap keeps its value), and keep what makes a game meaningful at all:
the canonical views (edge-on coins), the objective, the tolerance and the plate.

Screening pays only where a full game costs several screening games: :func:`worth_screening`
compares player B's Adam steps over player A's search (:func:`search_steps`), and a mixture
whose full games are already within twice a screening game's is not screened (its candidates
go straight to full games, in the planner's order).
"""

from __future__ import annotations

import copy

__all__ = [
    "FULL",
    "SCREEN",
    "SCREEN_LAYOUT",
    "SCREEN_SHARE",
    "SCREEN_SOLVER",
    "SCREEN_VERDICT",
    "screening_tables",
    "search_steps",
    "worth_screening",
]

#: Stage names, as in ``cascade.json``'s games and the progress lines.
FULL, SCREEN = "full", "screen"
#: ``[solver]`` caps of a screening game: 4 particles, 2 iterations, 4 starts of 40 steps on a
#: 96-pixel raster, 2 polish rounds, no retry of a lost search.
SCREEN_SOLVER = {
    "retries": 0,
    "particles": 4,
    "iterations": 2,
    "starts": 4,
    "steps": 40,
    "resolution": 96,
    "polish": 2,
}
#: ``[verdict]`` caps of a screening game: 16 starts of 120 steps on a 128-pixel raster, 2 s of
#: thin-plate motion search; ``certify`` is turned off.
SCREEN_VERDICT = {"starts": 16, "steps": 120, "resolution": 128, "thin_budget": 2.0}
#: Screen only when a screening game's search takes at most this share of a full game's.
SCREEN_SHARE = 0.5
#: ``[layout]`` caps of a screening game: one round, no alternatives, no restarts.
SCREEN_LAYOUT = {"rounds": 1, "alternatives": 0, "restarts": 0}


def screening_tables(tables: dict) -> dict:
    """A copy of a mixture's settings tables (``{"solver": Solver(...), ...}``) lowered to a
    screening game's: each capped key takes the smaller of its value and the cap, and
    ``[verdict] certify`` is false.

    Examples
    --------
    >>> from sieve_mi.scene import Layout, Solver, Verdict
    >>> t = screening_tables({"solver": Solver(particles=6), "verdict": Verdict(), "layout": Layout()})
    >>> t["solver"].particles, t["verdict"].starts, t["verdict"].certify, t["layout"].rounds
    (4, 16, False, 1)
    """
    out = copy.deepcopy(tables)
    for name, caps in (
        ("solver", SCREEN_SOLVER),
        ("verdict", SCREEN_VERDICT),
        ("layout", SCREEN_LAYOUT),
    ):
        table = out[name]
        for key, cap in caps.items():
            setattr(table, key, min(getattr(table, key), cap))
    out["verdict"].certify = False
    return out


def search_steps(solver) -> int:
    """Player B's Adam steps over player A's search, per B: ``particles x (iterations + 1) x
    starts x steps`` (the cost of a game's search, which dominates a cascade's games; the
    canonical views and the polish are on top)."""
    return solver.particles * (solver.iterations + 1) * solver.starts * max(solver.steps, 1)


def worth_screening(tables: dict, lowered: dict) -> bool:
    """Whether screening games (``lowered``, from :func:`screening_tables`) are worth playing
    before the full games (``tables``): their search takes at most :data:`SCREEN_SHARE` of a
    full game's (:func:`search_steps`).

    Examples
    --------
    The eight euro coins (6 particles, 4 iterations, 6 starts of 60 steps: 10,800 steps) are
    screened with 1,920; the tests' tiny cascades (720) are not.

    >>> from sieve_mi.scene import Layout, Solver, Verdict
    >>> full = {"solver": Solver(particles=6, iterations=4, starts=6, steps=60), "verdict": Verdict(), "layout": Layout()}
    >>> worth_screening(full, screening_tables(full)), search_steps(screening_tables(full)["solver"])
    (True, 1920)
    """
    return search_steps(lowered["solver"]) <= SCREEN_SHARE * search_steps(tables["solver"])
