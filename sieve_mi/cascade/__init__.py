"""Sorting a mixture of many shapes with a stack of sieves (a cascade), and seed/tolerance sweeps.
Rule: a cascade plays whole games through :mod:`sieve_mi.api`; it does not reach into them.

A cascade is a stack of sieves, coarsest on top: sieve k holds the shape(s) of tray k and lets
every shape still to be split below it fall through. Each sieve is one game of the solver
(:func:`sieve_mi.api.solve`): the falling shapes are set A, the held ones set B. The cascade is
planned before it is played: hopeless holds are ruled out exactly, the rest ranked and, where
there is a choice, screened by cheap games; full games are played for the planned sieves only. The games are
independent, so they run in parallel on Ray (:mod:`sieve_mi.cascade.games`) where it is
installed, one after another otherwise; finished games are kept, so an interrupted ``sort``
resumes.

Modules
-------
mixture
    The mixture file (``[[shape]]`` tables and the usual settings tables).
rules
    Exact rules that rule out hopeless holds before any game (with certificates).
stages
    Screening games (reduced settings, no proof) and full games.
games
    One game (a scene to solve), its key, and the serial and Ray runners with the game cache.
plan
    The cascade planner: rules, ranking, screening, full games, re-planning after a lost game,
    inseparable units.
outputs
    ``cascade.json``, the stacked plates and the figure.
purity
    ``sort --shake N``: each sieve shaken with the parts that reach it (MuJoCo,
    :mod:`sieve_mi.shake`), and in which tray each shape ends.
sort
    ``sieve-mi sort``: a mixture into trays (plan, play the games, write the cascade).
sweep
    ``sieve-mi sweep``: one scene over seeds and tolerances, the design with the largest margin.
commands
    The ``sort`` and ``sweep`` subcommands of the command line.
"""

__all__ = [
    "commands",
    "games",
    "mixture",
    "outputs",
    "plan",
    "purity",
    "rules",
    "sort",
    "stages",
    "sweep",
]
