"""The widest tolerance of a solved hole: B's margin spent on ``[fabrication] tolerance``.

The printed hole is A's silhouette grown by the tolerance (a round offset,
:func:`sieve_mi.geometry.outline.dilated`), and a round offset by t grown by d again is the
offset by t + d. So a pose of B that sticks out of the hole made with tolerance t0 by at most m
(its overhang, :mod:`sieve_mi.game.overhang`) fits the hole made with t0 + m: the tolerance can
grow by less than B's least overhang over poses, and not by more. The least overhang *found*
bounds it from above; :func:`widest_tolerance` bisects between the solve's tolerance (every B
blocked) and that bound against the verdict's attack on the exact polygon, as
:func:`sieve_mi.game.window.widest_window` bisects the window. For separate holes the layout
(:func:`sieve_mi.game.frames.separate_layout`) moves the holes apart as they grow, which only
adds material between them. The bisection is a search: a tolerance is *proved* only where
certify proves every B on the hole it makes.

Separate holes need not share one tolerance (:mod:`sieve_mi.game.holes`): a B passes the sieve
when it passes one of them, so each hole's widest tolerance is that hole's alone, against B's
least overhang *on that hole* (:func:`hole_margin`). :func:`widest_tolerances` bisects each
A's on its own hole, every other hole left out, then judges the whole plate at those
tolerances: a bisection's "blocked" is one attack's, and on the letters the S's widest try
(3.2122 mm) let R, P and H through on the five-hole plate's verdict (other starts); a hole
whose B the plate's verdict finds passing steps back to its next narrower blocked try.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import replace

import numpy as np

from sieve_mi.game.exact import ExactAttempt, ExactScore
from sieve_mi.game.holes import hole_tolerances
from sieve_mi.game.overhang import least_overhang
from sieve_mi.game.verdict import judge
from sieve_mi.game.window import passage_found
from sieve_mi.scene import Scene

__all__ = ["STEPS", "at_tolerance", "hole_margin", "one_hole", "widest_tolerance",
           "widest_tolerances", "with_tolerances"]  # fmt: skip

#: Bisection steps: the bracket shrinks to the B margin / 2^STEPS.
STEPS = 6


def at_tolerance(scene: Scene, tolerance: float) -> Scene:
    """A copy of ``scene`` whose ``[fabrication] tolerance`` is ``tolerance`` (the scene is
    unchanged)."""
    out = copy.copy(scene)
    fab = copy.copy(scene.fabrication)
    fab.tolerance = float(tolerance)
    object.__setattr__(out, "fabrication", fab)
    return out


def widest_tolerance(scene: Scene, passes: list, blocks: list, quats, trans, margin: float,
                     seed: int, progress: bool = False) -> tuple[float, list]:  # fmt: skip
    """The widest tolerance at which the verdict's attack blocks every B of ``blocks``.

    The bracket is [t0, t0 + ``margin`` - ``block_margin``] (t0 the scene's tolerance, at which
    every B is blocked; at the upper end the pose of least overhang found fits, so it is not
    tried); :data:`STEPS` bisection steps shrink it. A try counts as blocked when the verdict's
    attack (the scene's ``[verdict]`` settings, its own random numbers (``seed``, try)) blocks
    every B and, with ``[verdict] certify``, certify's search finds no passage either
    (:func:`~sieve_mi.game.window.passage_found`).

    Parameters
    ----------
    scene : Scene
    passes, blocks : list of Shape
    quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z), held fixed.
    trans : (m, 2) ndarray
        Each A's translation, scene units (ignored for separate holes).
    margin : float
        The least overhang found over ``blocks`` at t0 (report.json's ``overhang.at_best_pose``),
        scene units.
    seed : int
    progress : bool
        One line per try on stderr.

    Returns
    -------
    tolerance : float
        Scene units; t0 when no wider tolerance keeps every B blocked.
    tries : list of dict
        ``tolerance`` and ``blocked`` (every B) per try, in order.
    """
    lo = float(scene.fabrication.tolerance)
    hi = lo + float(margin) - float(scene.fabrication.block_margin)
    tries = []
    for k in range(STEPS if hi > lo else 0):
        t = round(0.5 * (lo + hi), 4)
        if not lo < t < hi:  # the bracket is below the rounding
            break
        play = at_tolerance(scene, t)
        v = judge(play, passes, blocks, np.asarray(quats), np.asarray(trans),
                  np.random.default_rng([seed, k]))  # fmt: skip
        ok = bool(np.all(v.attack.blocked()[0]))
        if ok and scene.verdict.certify:  # certify's cell search finds passages the attack missed
            ok = not passage_found(play, passes, blocks, np.asarray(quats), v.trans, v.outline)
        tries.append({"tolerance": t, "blocked": ok})
        if progress:
            word = "every B blocked" if ok else "a B passes"
            print(f"tolerance: {t:g}: {word}", file=sys.stderr, flush=True)
        lo, hi = (t, hi) if ok else (lo, t)
    return lo, tries


def one_hole(scene: Scene, i: int) -> Scene:
    """A copy of ``scene`` with A number ``i`` alone (its own hole, no mirrored one) at its own
    tolerance as ``[fabrication] tolerance``."""
    out = at_tolerance(scene, float(hole_tolerances(scene)[i]))
    entry = copy.copy(scene.passes[i])
    entry.tolerance = None
    lay = copy.copy(scene.layout)
    lay.mirrored = False
    object.__setattr__(out, "passes", [entry])
    object.__setattr__(out, "layout", lay)
    return out


def hole_margin(scene: Scene, shape, blocks: list, quat, seed: int) -> float:
    """B's least overhang found on one A's hole: 0 when the verdict lets a B through.

    Parameters
    ----------
    scene : Scene
        One A (:func:`one_hole`).
    shape : Shape
        That A.
    blocks : list of Shape
    quat : (4,) ndarray
        A's rotation (w, x, y, z).
    seed : int

    Returns
    -------
    float
        The least over B of the least overhang found (:func:`~sieve_mi.game.overhang.least_overhang`
        from the verdict's pose), scene units.
    """
    q = np.asarray(quat, dtype=np.float64)[None]
    v = judge(scene, [shape], blocks, q, np.zeros((1, 2)), np.random.default_rng([seed, 99]))
    a = v.attack
    if not np.all(a.blocked()[0]):
        return 0.0
    least = np.inf
    for j, b in enumerate(blocks):
        sc = ExactScore(float(a.beta[0, j]), float(a.protrusion[0, j]), np.nan)
        start = ExactAttempt(a.quats[0, j].copy(), a.trans[0, j].copy(), sc)
        least = min(least, least_overhang(b, v.outline, start).score.protrusion)
    return float(least)


def widest_tolerances(scene: Scene, passes: list, blocks: list, quats, seed: int,
                      progress: bool = False) -> tuple[list, list]:  # fmt: skip
    """Each separate hole's widest tolerance: :func:`widest_tolerance` of each A alone on its
    own hole (:func:`one_hole`), from its own tolerance, against B's least overhang on that hole
    (:func:`hole_margin`).

    Parameters
    ----------
    scene : Scene
        ``[layout] mode = "separate"``.
    passes, blocks : list of Shape
    quats : (m, 4) ndarray
        Each A's rotation, held fixed.
    seed : int
    progress : bool
        One line per hole and try on stderr.

    Returns
    -------
    tolerances : list of float
        Per A, scene units (its own tolerance where no wider one keeps every B blocked).
    tries : list of dict
        Per A: ``name``, ``margin`` (B's least overhang found on its hole at its own tolerance),
        ``bisection`` (:func:`widest_tolerance`'s tries) and ``on_plate`` (the tolerance kept
        once the whole plate's verdict blocks every B: a hole it finds a B passing steps back
        to its next narrower blocked try).
    """
    out, tries = [], []
    for i, a in enumerate(passes):
        one = one_hole(scene, i)
        margin = hole_margin(one, a, blocks, quats[i], seed)
        if progress:
            print(f"tolerance: {a.name}'s hole: B overhangs by {margin:.4g} at tolerance "
                  f"{one.fabrication.tolerance:g}", file=sys.stderr, flush=True)  # fmt: skip
        t, got = widest_tolerance(one, [a], blocks, np.asarray(quats[i])[None], np.zeros((1, 2)),
                                  margin, seed, progress)  # fmt: skip
        out.append(t)
        tries.append({"name": a.name, "margin": margin, "bisection": got})
    return _on_the_plate(scene, passes, blocks, quats, out, tries, seed, progress), tries


def with_tolerances(scene: Scene, tolerances) -> Scene:
    """A copy of ``scene`` whose A have the given ``[[pass]] tolerance`` each (scene units)."""
    out = copy.copy(scene)
    passes = [replace(e, tolerance=float(t)) for e, t in zip(scene.passes, tolerances)]
    object.__setattr__(out, "passes", passes)
    return out


def _on_the_plate(scene, passes, blocks, quats, widest, tries, seed, progress) -> list:
    """Each hole's widest tolerance, checked on the whole plate (mirrored holes too): each hole's
    bisection is a search, and the plate's verdict (other random starts) may find a B passing
    a hole its own bisection held. While it does, that hole steps back to its next narrower
    blocked try (its own tolerance at last). Returns the tolerances (each ``tries`` entry gets
    ``on_plate``: the tolerance kept)."""
    own = hole_tolerances(scene)
    out = list(widest)
    for k in range(len(passes) * (STEPS + 1)):
        v = judge(with_tolerances(scene, out), passes, blocks, np.asarray(quats),
                  np.zeros((len(passes), 2)), np.random.default_rng([seed, 1000 + k]))  # fmt: skip
        through = np.flatnonzero(~v.attack.blocked()[0])
        if not len(through):
            break
        owner = list(range(len(passes))) + [m["of"] for m in v.mirrored]
        places = np.vstack([v.trans, *[[m["translation"]] for m in v.mirrored]])
        near = {}  # the hole nearest each B's place: one step back each
        for j in through:
            near[owner[int(np.argmin(np.linalg.norm(places - v.attack.trans[0, j], axis=1)))]] = j
        for i, j in near.items():
            held = [t["tolerance"] for t in tries[i]["bisection"] if t["blocked"]]
            out[i] = max([t for t in held if t < out[i]], default=float(own[i]))
            if progress:
                print(f"tolerance: on the plate, {blocks[j].name} passes {passes[i].name}'s hole: "
                      f"back to {out[i]:g}", file=sys.stderr, flush=True)  # fmt: skip
    for t, row in zip(out, tries):
        row["on_plate"] = t
    return out
