"""Blocks proved before the game: a B holding a ball larger than any hole A can make.

A ball of radius ρ inside B projects to a disk of radius ρ in every pose, so B cannot pass a hole
that holds no disk of radius ρ. The hole made by one A lies in the disk of radius
``A.radius + tolerance (1 + ARC_ERROR + SIMPLIFY)`` around A's place (the tolerance plus a turning
window's chord bound, :mod:`sieve_mi.geometry.window`, where there is one) (its outline is at most that
far out, :mod:`sieve_mi.geometry.outline`), grown by ``block_margin`` where blocking is decided
against the grown hole; with one hole per A (``separate``) the largest of them counts. A B whose
certified inscribed ball (:func:`sieve_mi.certify.bounds.inscribed_ball`) is larger than that is
blocked by every hole this scene can make, whatever A's rotation: it cannot constrain A's
search, so player A plays against the other B only, and after the verdict the block is proved on
the exact hole by :func:`sieve_mi.certify.certify` (its root-level ball test, milliseconds) and
recorded with its certificate. Merged holes of several A are not screened (their union can hold
larger disks than any one A's).
"""

from __future__ import annotations

import numpy as np

from sieve_mi.certify import certify
from sieve_mi.certify.bounds import inscribed_ball
from sieve_mi.game.attack import Attack
from sieve_mi.game.exact import score
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import ARC_ERROR, SIMPLIFY, Boundary, dilated, is_closed
from sieve_mi.geometry.window import GROWTH
from sieve_mi.scene import Scene

__all__ = ["largest_hole_radius", "prove_proved", "proved_by_size", "with_proved"]


def largest_hole_radius(scene: Scene, passes: list[Shape]) -> float | None:
    """Radius of a disk about each A's place that holds its whole hole (grown by the block
    margin), scene units; None for a merged hole of several A (not screened)."""
    if len(passes) > 1 and scene.layout.mode == "merged":
        return None
    fab, radius = scene.fabrication, max(p.radius for p in passes)
    # a turning window turns A about its place (within its radius) and adds its chord bound
    grow = max(GROWTH * fab.tolerance, 1e-4 * radius) if fab.window else 0.0
    outline = (fab.tolerance + grow) * (1.0 + ARC_ERROR + SIMPLIFY)
    return (radius + outline + fab.block_margin) * (1.0 + 1e-9)


def proved_by_size(scene: Scene, passes: list[Shape], blocks: list[Shape]) -> dict[int, float]:
    """The B (by index) that no hole of this scene can let through, with their ball's radius
    (none with ``[solver] screen = false``).

    Examples
    --------
    A 20 mm ball (radius 10) with a 1 mm tolerance makes holes within radius ~11.003; a 30 mm cube
    holds a ball of radius 15: proved before any play. A 21 mm cube (ball 10.5) is not.
    """
    bound = largest_hole_radius(scene, passes)
    if bound is None or not scene.solver.screen:
        return {}
    out = {}
    for j, shape in enumerate(blocks):
        ball = inscribed_ball(shape)
        if ball is not None and ball[1] > bound:
            out[j] = float(ball[1])
    return out


def prove_proved(scene: Scene, blocks: list[Shape], proved: dict[int, float], outline) -> dict:
    """Certify each screened B against the exact hole (grown by the block margin): index ->
    :class:`~sieve_mi.certify.Certification` (status "proved" by the ball test)."""
    fab = scene.fabrication
    target = dilated(outline, fab.block_margin) if fab.block_margin > 0 else outline
    budget = scene.verdict.certify_budget
    return {j: certify(blocks[j], [target], budget_s=budget) for j in proved}


def with_proved(
    attack: Attack, rows: list[int], blocks: list[Shape], outline, grown, centre: np.ndarray
) -> Attack:
    """The verdict's attack on the B of ``rows`` completed with one row per screened B.

    A screened B is not attacked: its row is one exact attempt, unrotated and centred on the
    first hole (``centre``), scored against ``outline`` (and ``grown``, the margin-grown hole,
    where it is not None) like every verdict score; its ``fits`` is 0. ``attack`` has one
    column per entry of ``rows`` (margin scores iff ``grown`` is not None).
    """
    n = len(blocks)
    full = Attack(
        beta=np.ones((1, n)),
        protrusion=np.zeros((1, n)),
        quats=np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (1, n, 1)),
        trans=np.tile(np.asarray(centre, dtype=np.float64), (1, n, 1)),
        fits=np.zeros((1, n), dtype=np.int64),
    )
    margin = grown is not None
    if margin:
        full.margin_beta, full.margin_protrusion = np.ones((1, n)), np.zeros((1, n))
    for k, j in enumerate(rows):
        full.beta[0, j], full.protrusion[0, j] = attack.beta[0, k], attack.protrusion[0, k]
        full.quats[0, j], full.trans[0, j] = attack.quats[0, k], attack.trans[0, k]
        full.fits[0, j] = attack.fits[0, k]
        if margin:
            full.margin_beta[0, j] = attack.margin_beta[0, k]
            full.margin_protrusion[0, j] = attack.margin_protrusion[0, k]
    boundary = Boundary(outline)
    for j in sorted(set(range(n)) - set(rows)):
        q, t, closed = full.quats[0, j], full.trans[0, j], is_closed(blocks[j])
        s = score(blocks[j], q, t, outline, boundary, closed)
        full.beta[0, j], full.protrusion[0, j] = s.beta, s.protrusion
        if margin:
            g = score(blocks[j], q, t, grown, Boundary(grown), closed)
            full.margin_beta[0, j], full.margin_protrusion[0, j] = g.beta, g.protrusion
    return full
