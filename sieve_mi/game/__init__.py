"""The two-player game: player B's attacks, player A's search, the exact verdict.
Rule: the game writes no files (:mod:`sieve_mi.outputs` does).

Modules
-------
attack
    :class:`~sieve_mi.game.attack.Attack` (player B's best poses and scores) and its memory.
players
    Player B (batched Adam over poses) and player A (swarm or nlopt over rotations).
frozen
    Frozen (recorded once, replayed) Adam steps of player B.
scoring
    Raster scores of poses against holes, and B's silhouettes in a mask window.
exact
    Exact scores and polish of B's poses against the printed polygon H.
layout
    Frames, and several A in one hole (merged) or side by side (separate).
verdict
    The long re-run of player B against the exact polygon that declares the winner.
solver
    The whole game of one scene: search, verdict, optional certification.
result
    :class:`~sieve_mi.game.result.Result`: what a solve produced.
check
    ``sieve-mi check``: do given parts pass a given plate or hole image?
"""

__all__ = [
    "attack",
    "check",
    "exact",
    "frozen",
    "layout",
    "players",
    "result",
    "scoring",
    "solver",
    "verdict",
]
