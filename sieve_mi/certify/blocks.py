"""Certify a solve's blocks: each blocked B against the exact hole that gets printed."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sieve_mi.certify.certificate import Certification
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import dilated, hole_outline, is_closed
from sieve_mi.scene import Scene

__all__ = ["certify_blocks"]


def certify_blocks(
    scene: Scene,
    pass_shapes: list[Shape],
    block_shapes: list[Shape],
    quats: np.ndarray,
    trans: np.ndarray,
    blocked: np.ndarray,
    progress: Callable[[str], None] | None = None,
) -> list[Certification | None]:
    """Try to prove, for every B the verdict found blocked, that it cannot pass in any pose.

    The hole is the exact outline the plate is cut from (:func:`sieve_mi.geometry.outline.hole_outline`:
    A's placed projections, dilated by the tolerance, gaps filled), grown by ``block_margin``
    when there is one, so a proof covers the printed plate and the margin the scene asks for.

    Parameters
    ----------
    scene : Scene
        ``[fabrication]`` gives the outline; ``[verdict] certify_budget`` each proof's budget.
    pass_shapes, block_shapes : list of Shape
    quats : (m, 4) ndarray
        A's rotations.
    trans : (m, 2) ndarray
        A's translations, scene units.
    blocked : (n,) ndarray of bool
        The verdict's answer per B; only blocked B are certified.
    progress : callable, optional
        Called with one line per proof as it ends.

    Returns
    -------
    list of Certification or None
        Per B, its certification, or None where the verdict already let it through.
    """
    from sieve_mi.certify import certify

    fab = scene.fabrication
    closed = [is_closed(s) for s in pass_shapes]
    hole = hole_outline(pass_shapes, quats, trans, fab.tolerance, fab.fill_holes, closed)
    if fab.block_margin > 0:
        hole = dilated(hole, fab.block_margin)
    out: list[Certification | None] = []
    for shape, is_blocked in zip(block_shapes, blocked):
        if not is_blocked:
            out.append(None)
            continue
        c = certify(shape, [hole], budget_s=scene.verdict.certify_budget)
        out.append(c)
        if progress is not None:
            progress(f"certify {shape.name}: {c.status} ({c.seconds:.1f} s)")
    return out
