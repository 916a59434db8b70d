"""The two-player game: player B's attacks, player A's search, the exact verdict.
Rule: the game writes no files (:mod:`sieve_mi.outputs` does).

Modules
-------
attack
    :class:`~sieve_mi.game.attack.Attack` (player B's best poses and scores), its memory, and
    :class:`~sieve_mi.game.attack.Starts` (where an attack's starts begin).
descent
    One batched descent of player B: its batch of poses, its state, its one Adam step (traced or
    frozen), its loop.
frozen
    Player B's Adam step recorded once with ``drjit.freeze`` and replayed; when that pays.
player_b
    Player B: random starts, batched descents in chunks that fit memory, raster scores.
player_a
    Player A: canonical views, then a swarm (or nlopt) over rotations, then a local polish.
maximin
    Player A's values with maximin pruning: B attacked in rounds, the most dangerous first, and
    a candidate already at or below the value it must beat attacked no further.
reuse
    Player B's attacks reused across congruent holes of the search: a short descent from the
    best poses on the class's first hole, moved with the hole.
screen
    Blocks proved before the game: a B holding a ball larger than any hole A can make.
scoring
    Raster scores of poses against holes, and B's silhouettes in a mask window.
exact
    Exact scores and polish of B's poses against the printed polygon H.
overhang
    How far each blocked B overhangs H at its best pose (exact polygon) and the proved bound.
frames
    The raster frames of the holes, and the separate layout (A's holes side by side).
candidates
    Where one more A could sit in a hole: candidate placements found by FFT.
placement
    One more A placed into a hole: eq. 14, screening, a swarm, a long re-ranking.
layout
    Several A merged into one hole: the sequential scheme and its retries.
verdict
    The long re-run of player B against the exact polygon that declares the winner.
retry
    A second chance for a lost search (``[solver] retries``): A searched again from another seed.
sheet
    The plate's thickness and its verdict: safe by diameter, or a thin-plate motion search per B.
solver
    The whole game of one scene: search, verdict, optional certification.
result
    :class:`~sieve_mi.game.result.Result`: what a solve produced.
check
    ``sieve-mi check``: do given parts pass a given plate or hole image?
fit
    ``check``'s fit scale: the largest scale that passes, grown exactly and probed by attacks.
check_settings
    The settings of ``sieve-mi check`` (its search, how it reads its inputs), declared once.
feasible
    Feasibility before the search: a B that fits inside a grown A cannot be blocked (proved).
window
    The turning window: ``[fabrication] window``, given or bisected against the verdict.
tolerance
    The widest tolerance of a solved hole: B's margin spent on ``[fabrication] tolerance``.
holes
    Separate holes, each its own: a tolerance per A, and a mirrored hole for a chiral A.
rest
    A's likely resting poses as candidates, and the preference for one (``[solver] rest_poses``).
"""

__all__ = [
    "attack",
    "candidates",
    "check",
    "check_settings",
    "descent",
    "exact",
    "fit",
    "frames",
    "frozen",
    "holes",
    "layout",
    "maximin",
    "placement",
    "player_a",
    "player_b",
    "result",
    "reuse",
    "scoring",
    "solver",
    "verdict",
]
