"""The turning window of a solve: ``[fabrication] window``, given or bisected against the verdict.

A window δ cuts the hole for every turn of each A within ±δ about the vertical
(:mod:`sieve_mi.geometry.window`), so a shaken part lying in its pass pose need not be turned
exactly. ``window = "auto"`` bisects the widest δ in [0, :data:`WIDEST`] at which the verdict's
attack (exact polygon scores, as in every verdict) still blocks every B; the final verdict and
certify then judge the hole at that δ like any other. The bisection is a search: B's attack is a
heuristic, so a δ is *proved* only where certify proves every B on its hole.
"""

from __future__ import annotations

import copy
import sys

import numpy as np

from sieve_mi.game.verdict import judge
from sieve_mi.scene import Scene

__all__ = ["STEPS", "WIDEST", "at_window", "passage_found", "window_record", "widest_window"]

#: The widest window tried, degrees (either way: ±90° covers every turn of a part that looks the
#: same turned by 180°).
WIDEST = 90.0
#: Bisection steps after the widest (the bracket shrinks to WIDEST / 2^STEPS).
STEPS = 6
#: Seconds of certify's search per B and try, looking for a passage the attack missed.
CERTIFY_S = 5.0


def at_window(scene: Scene, degrees: float) -> Scene:
    """A copy of ``scene`` whose ``[fabrication] window`` is ``degrees`` (the scene is unchanged)."""
    out = copy.copy(scene)
    fab = copy.copy(scene.fabrication)
    fab.window = float(degrees)
    object.__setattr__(out, "fabrication", fab)
    return out


def widest_window(scene: Scene, passes: list, blocks: list, found, seed: int,
                  progress: bool = False) -> tuple[float, list]:  # fmt: skip
    """The widest window (degrees) at which the verdict's attack blocks every B of ``blocks``.

    :data:`WIDEST` is tried first (kept when every B is blocked there), then :data:`STEPS`
    bisection steps between 0 (the search's own hole) and the widest tried that let a B through.
    A try counts as blocked when the verdict's attack blocks every B and, with ``[verdict]
    certify``, certify's search (:data:`CERTIFY_S` per B, at most the certify budget) finds no
    passage through the printed hole either. Each try is a verdict with the
    scene's ``[verdict]`` settings and its own random numbers (``seed``, try).

    Parameters
    ----------
    scene : Scene
    passes, blocks : list of Shape
        ``blocks``: the B the game plays (not those proved by size, blocked at any window).
    found : SearchOutcome
        Player A's rotations and translations.
    seed : int
    progress : bool
        One line per try on stderr.

    Returns
    -------
    degrees : float
        0 when no wider window keeps every B blocked.
    tries : list of dict
        ``degrees`` and ``blocked`` (every B) per try, in order.
    rng : numpy.random.Generator
        The random numbers the try at ``degrees`` started from (a fresh generator for 0): the
        final verdict starting from them repeats that try's attack, so it agrees with it.
    """
    lo, hi, tries, best = 0.0, WIDEST, [], None
    for k in range(STEPS + 1):
        d = hi if k == 0 else round(0.5 * (lo + hi), 3)
        rng = np.random.default_rng([seed, k])
        v = judge(at_window(scene, d), passes, blocks, found.quats, found.trans, rng,
                  memory=found.memory)  # fmt: skip
        ok = bool(np.all(v.attack.blocked()[0]))
        if ok and scene.verdict.certify:  # certify's cell search finds passages the attack missed
            ok = not passage_found(
                at_window(scene, d), passes, blocks, found.quats, v.trans, v.outline
            )
        tries.append({"degrees": d, "blocked": ok})
        if progress:
            word = "every B blocked" if ok else "a B passes"
            print(f"turning window: ±{d:g}°: {word}", file=sys.stderr, flush=True)
        if ok:
            lo, best = d, k
            if k == 0:
                break
        else:
            hi = d
    return lo, tries, np.random.default_rng([seed, len(tries) if best is None else best])


def window_record(scene: Scene, passes: list, mode: str, tries: list | None = None) -> dict | None:
    """report.json's ``fabrication.window`` for a scene whose window is a number: ``degrees``,
    ``samples``, ``chord_bound`` (:class:`~sieve_mi.geometry.window.Window`), ``mode`` ("given"
    or "auto") and, for "auto", the ``bisection`` tries; None without a window."""
    import math

    from sieve_mi.geometry.window import Window, turn_samples

    fab = scene.fabrication
    if not fab.window and mode == "given":
        return None
    radius = max(float(p.radius) for p in passes)
    turns, grow = turn_samples(radius, math.radians(fab.window), fab.tolerance)
    out = Window(float(fab.window), len(turns), grow).to_dict()
    out["mode"] = mode
    if tries is not None:
        out["bisection"] = tries
    return out


def passage_found(scene: Scene, passes: list, blocks: list, quats, trans, outline=None) -> bool:
    """Whether certify's search (:data:`CERTIFY_S` per B, at most the certify budget) finds a
    passage of some B through the scene's printed hole (the verdict's ``outline`` where given,
    :func:`sieve_mi.certify.blocks.printed_hole`)."""
    from sieve_mi.certify import certify
    from sieve_mi.certify.blocks import printed_hole

    hole = printed_hole(scene, passes, quats, trans, outline)
    budget = min(CERTIFY_S, scene.verdict.certify_budget)
    return any(certify(b, [hole], budget_s=budget).status == "passage" for b in blocks)
