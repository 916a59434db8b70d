"""``sieve-mi check``'s fit scale: the largest uniform scale of a part that still passes a sieve.

:func:`fit_scale` brackets it and bisects, one whole attack of player B per scale tried
(:func:`sieve_mi.game.check.attempt`). With a plate's exact holes it gallops instead: every
attack's pose is first grown exactly (:func:`grown_scale`, polygons only, no attack) to the
largest scale it fits at, and the next attack (a *probe*, :func:`probe_starts` starts, the first
from the poses found before, stopping at the first fit) is tried just above that. A probe that
passes costs a fraction of an attack; the search ends at the first probe that is blocked a
tolerance above a scale that was seen to pass.
"""

from __future__ import annotations

import math

import manifold3d

from sieve_mi.geometry.meshes import Shape

__all__ = ["fit_scale", "grown_scale", "probe_starts", "scaled"]


def scaled(shape: Shape, s: float) -> Shape:
    """The shape uniformly scaled about its centre by ``s``."""
    return Shape(
        name=shape.name,
        path=shape.path,
        vertices=shape.vertices * s,
        faces=shape.faces,
        centre=shape.centre * s,
        radius=shape.radius * s,
        hull=shape.hull * s,
    )


def probe_starts(starts: int) -> int:
    """Starts of one fit-scale probe: a quarter of the verdict's ``starts``, at least 8 (at most
    ``starts``). The verdict at scale 1 explored the poses with all of them; a probe, a few
    percent larger or smaller, begins its first starts at the best pose of each earlier attempt
    (:class:`~sieve_mi.game.attack.AttackMemory`, up to a third of its starts)."""
    return min(int(starts), max(8, int(starts) // 4))


def fit_scale(evaluate, first, rel_tol: float, limit: int = 12, grow=None) -> tuple[float, list]:
    """Largest scale that passes, by bracketing (doubling or halving) and geometric bisection.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(s) -> ShapeCheck`` (:class:`sieve_mi.game.check.ShapeCheck`: its ``scale``,
        ``passes`` and pose are read).
    first : ShapeCheck
        The verdict at scale 1.
    rel_tol : float
        Stop when hi / lo - 1 is below this.
    limit : int
        Most doublings or halvings before giving up on a bracket.
    grow : callable, optional
        ``grow(v) -> float``: the largest scale at which the pose of the ShapeCheck ``v`` fits, verified exactly (0 when none was found; with a plate, :func:`grown_scale`).
        With it the search starts from the scale the poses already found allow and gallops up
        from there (:func:`_gallop`): far fewer attacks than bisecting from scale 1.

    Returns
    -------
    scale : float
        The largest scale seen to pass (0 if none passed).
    bracket : [lo, hi]
        lo passes, hi is blocked (hi is inf when every tried scale passed).
    """
    if grow is not None:
        return _gallop(evaluate, first, rel_tol, limit, grow)
    lo, hi = (1.0, None) if first.passes else (None, 1.0)
    for _ in range(limit):
        if lo is not None and hi is not None:
            break
        s = 2.0 * lo if hi is None else 0.5 * hi
        if evaluate(s).passes:
            lo = s
        else:
            hi = s
    if lo is None:
        return 0.0, [0.0, hi]
    if hi is None:
        return lo, [lo, math.inf]
    while hi / lo - 1.0 > rel_tol:
        s = math.sqrt(lo * hi)
        if evaluate(s).passes:
            lo = s
        else:
            hi = s
    return lo, [lo, hi]


def _gallop(evaluate, first, rel_tol: float, limit: int, grow) -> tuple[float, list]:
    """:func:`fit_scale` with ``grow``: every attempt's pose raises the passing scale ``lo`` to
    the largest it fits at (a blocked pose too, shrunk), and the next attack is tried a step
    above ``lo`` (the step ``rel_tol`` at first and after each block, doubled after each pass, at
    most a doubling) or at the bracket's geometric middle, whichever is lower. A probe that
    passes is cheap (its starts begin at the poses that passed before and stop at the first
    fit), one that is blocked runs every start to the end: this search tries few scales above
    the fit scale. Where the attacks find the best pose it ends at the first block."""
    lo, hi, step, v = None, None, rel_tol, first
    # tries without a bracket, at most: ``limit`` halvings, or as many doublings after the
    # steps that lead up to a doubling
    halvings, gallops = limit, limit + math.ceil(math.log2(1.0 / rel_tol))
    while True:
        g = grow(v)
        if g > 0 and (lo is None or g > lo):
            lo = g
        if v.passes:
            lo, step = max(lo, v.scale), min(2.0 * step, 1.0)
        else:
            hi, step = (v.scale if hi is None else min(hi, v.scale)), rel_tol
        if lo is None:
            halvings -= 1
        elif hi is None:
            gallops -= 1
        elif hi <= lo * (1.0 + rel_tol) * (1.0 + 1e-12):
            break
        if halvings < 0 or gallops < 0:
            break
        if lo is None:
            v = evaluate(0.5 * hi)
        else:
            v = evaluate(
                lo * (1.0 + step) if hi is None else min(lo * (1.0 + step), math.sqrt(lo * hi))
            )
    if lo is None:
        return 0.0, [0.0, hi]
    return lo, [lo, math.inf if hi is None else hi]


def grown_scale(
    shape: Shape, quat, trans, hole: manifold3d.CrossSection, s: float, rel_tol: float
) -> float:
    """The largest scale at which ``shape``, held at one pose, fits the polygon ``hole``.

    Exact (:func:`sieve_mi.game.exact.score` decides each scale): from ``s``, doubled while it
    fits (at most 12 times) or, when it does not fit at ``s``, halved until it does (at most 12
    times), then bisected geometrically to ``rel_tol``. A fit need not be monotone in the scale
    in a hole that is not convex about the pose; the scale returned is one that fits.

    Parameters
    ----------
    shape : Shape
        The part at scale 1, scene units.
    quat : (4,) array_like
        The pose's rotation (w, x, y, z).
    trans : (2,) array_like
        Its translation, scene units (the part is scaled about it).
    hole : manifold3d.CrossSection
        The sieve's holes, in the same coordinates.
    s : float
        The scale to start from.
    rel_tol : float
        Relative precision of the answer.

    Returns
    -------
    float
        A scale at which the pose fits, within ``rel_tol`` of the largest one; 0 when none of
        the scales tried fits.
    """
    from sieve_mi.game.exact import score
    from sieve_mi.geometry.outline import Boundary, is_closed

    boundary, closed = Boundary(hole), is_closed(shape)

    def fits(x: float) -> bool:
        return score(scaled(shape, x), quat, trans, hole, boundary, closed).fits

    lo, hi = (s, None) if fits(s) else (None, s)
    for _ in range(12):
        if lo is not None and hi is not None:
            break
        x = 2.0 * lo if hi is None else 0.5 * hi
        lo, hi = (x, hi) if fits(x) else (lo, x)
    if lo is None or hi is None:
        return 0.0 if lo is None else lo
    while hi / lo - 1.0 > rel_tol:
        x = math.sqrt(lo * hi)
        lo, hi = (x, hi) if fits(x) else (lo, x)
    return lo
