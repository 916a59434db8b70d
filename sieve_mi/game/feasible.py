"""Feasibility before the search: a B that the tolerance makes impossible to block, proved.

Every hole that passes A contains A's silhouette in its pass pose, dilated by the tolerance
(:func:`sieve_mi.geometry.outline.hole_outline`: proj_q(A) + disk(tolerance), never less), and B
counts as blocked only if it also fails the hole grown by ``block_margin``. So with g =
tolerance + block_margin, whatever rotation q player A picks, B passes as soon as some pose of B
fits in proj_q(A) + disk(g) = proj_q(A + ball(g)). Two exact arguments show that for **every**
q at once (one view of A proves nothing: A's pose is A's choice), the cascade's rules
(:mod:`sieve_mi.cascade.rules`) made exact to the vertex:

**Fits inside.** If a rigid motion puts B's hull inside hull(A) + ball(g), B passes every hole
that passes A. :func:`sieve_mi.geometry.containment.least_growth` finds such a motion and the
least g it needs, checked exactly (the distance of each placed hull vertex of B to hull(A); the
grown hull is convex, so B's hull is inside). M4 nut (7 mm across flats, 3.2 mm thick) inside
an M3 nut (5.5, 2.4) grown by 0.954 mm: corner over corner, sqrt(0.866² + 0.4²).

**End first.** If hull(A) holds a ball of radius rho, every hole holds a disk of radius rho + g;
B seen end first (a canonical view, :func:`sieve_mi.geometry.size.end_first_radius`) in a disk
of radius r passes once g >= r - rho.

Both need hull(A)'s projection inside the hole: A convex (:func:`sieve_mi.geometry.bodies.body`),
or ``[fabrication] fill_holes`` with every hull edge of A on A's own edges
(:func:`sieve_mi.geometry.bodies.hull_edges_on_surface`: the outline of hull(A)'s projection lies
in A's projection, so filling its gaps gives hull(A)'s; a nut's bore, a washer's hole). Any other
A proves nothing (a sound omission). Each argument holds from its threshold up, so the smallest
threshold, less ``block_margin``, is a tolerance from which B is proved impossible: the largest
tolerance that could work is below it (an upper bound from these arguments, not a promise that
it works). A margin of :data:`~sieve_mi.geometry.bodies.SAFETY` times A's radius covers
round-off. The quick necessary conditions of
:func:`~sieve_mi.geometry.containment.growth_lower_bound` skip the search where fitting inside
is out of reach at g (then only "not ruled out" is said, without a threshold).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.geometry.bodies import SAFETY, Body, ball_in_facets, body, hull_edges_on_surface
from sieve_mi.geometry.canonical import principal_axes
from sieve_mi.geometry.containment import growth_lower_bound, hull_frames, least_growth
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.rotations import align, from_matrix, to_matrix
from sieve_mi.geometry.size import canonical_extents, enclosing_circle, end_first_radius
from sieve_mi.scene import Scene

__all__ = [
    "BlockFeasibility",
    "Feasibility",
    "certificate_pose",
    "feasibility",
    "round_up",
    "with_certificates",
]


def round_up(x: float, digits: int = 3) -> float:
    """``x`` rounded up to ``digits`` significant digits (a bound printed never looks tighter
    than proved).

    Examples
    --------
    >>> round_up(0.95428), round_up(0.25), round_up(0.0)
    (0.955, 0.25, 0.0)
    """
    if x <= 0 or not math.isfinite(x):
        return x
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(x)))
    return math.ceil(x * scale * (1 - 1e-12)) / scale


@dataclass
class BlockFeasibility:
    """What the feasibility test found for one shape of B (scene units).

    Attributes
    ----------
    name : str
    status : {"impossible", "not ruled out"}
        "impossible": proved unblockable at this scene's tolerance and block margin.
    rule : {"fits-inside", "end-first"} or None
        The argument with the smallest threshold found (None when none was computed).
    passing : str or None
        The A it uses.
    grow : float or None
        The threshold: the argument holds for tolerance + block_margin >= grow.
    max_tolerance : float or None
        ``grow - block_margin`` (at least 0): every tolerance from it on is proved impossible,
        so a working tolerance is below it; None when no threshold was computed.
    reason : str
        One sentence for people.
    certificate : dict
        fits-inside: ``rotation`` (w, x, y, z) and ``translation`` (3,) of B about A's centre
        in A's frame; end-first: ``radius`` (r), ``ball`` (rho).
    index : int or None
        ``passing``'s index among the scene's A (names may repeat).
    """

    name: str
    status: str = "not ruled out"
    rule: str | None = None
    passing: str | None = None
    grow: float | None = None
    max_tolerance: float | None = None
    reason: str = ""
    certificate: dict = field(default_factory=dict)
    index: int | None = None

    def as_dict(self) -> dict:
        """report.json's entry."""
        return {
            "name": self.name,
            "status": self.status,
            "rule": self.rule,
            "passing": self.passing,
            "grow": None if self.grow is None else round(self.grow, 6),
            "max_tolerance": None if self.max_tolerance is None else round(self.max_tolerance, 6),
            "reason": self.reason,
            "certificate": self.certificate,
        }


@dataclass
class Feasibility:
    """The feasibility test of a scene: one :class:`BlockFeasibility` per B, in scene order.

    Attributes
    ----------
    blocks : list of BlockFeasibility
    tolerance, block_margin : float
        The scene's, scene units.
    solid : list of str or None
        Per A, why its hull stands for it ("convex", "filled") or None (the A proves nothing).
    seconds : float
    """

    blocks: list
    tolerance: float
    block_margin: float
    solid: list
    seconds: float = 0.0

    @property
    def impossible(self) -> list[int]:
        """Indices of the B proved impossible to block."""
        return [j for j, b in enumerate(self.blocks) if b.status == "impossible"]

    def lines(self) -> list[str]:
        """One line per impossible B (nothing when the test found none)."""
        return [self.blocks[j].reason for j in self.impossible]

    def as_dict(self) -> dict:
        """report.json's ``feasibility``."""
        worst = [self.blocks[j].max_tolerance for j in self.impossible]
        return {
            "feasible": not self.impossible,
            "tolerance": self.tolerance,
            "block_margin": self.block_margin,
            "max_tolerance": min(worst) if worst else None,
            "solid": list(self.solid),
            "block": [b.as_dict() for b in self.blocks],
            "seconds": round(self.seconds, 3),
        }


def _solid(shape: Shape, fill_holes: bool) -> tuple[Body | None, str | None]:
    """A's :class:`Body` with its hull standing for it, and why; (None, None) when it cannot."""
    from scipy.spatial import ConvexHull, QhullError

    b = body(shape)
    if b.convex:
        return b, "convex"
    if not fill_holes or not hull_edges_on_surface(shape):
        return None, None
    try:
        ball = ball_in_facets(ConvexHull(b.points).equations)[1]
    except (QhullError, ValueError):
        return None, None
    return dataclasses.replace(b, convex=True, ball=ball), "filled"


def _held(shape: Shape) -> Body:
    """B's :class:`Body` as the arguments need it: its hull's inscribed ball (``ball``, B need
    not be convex) and no end-first radius yet (``end_first`` NaN, :func:`_end_first`)."""
    from scipy.spatial import ConvexHull, QhullError

    axes = principal_axes(shape)
    along = shape.hull @ axes.T
    try:
        ball = ball_in_facets(ConvexHull(shape.hull).equations)[1]
    except (QhullError, ValueError):
        ball = 0.0
    return Body(shape.name, np.asarray(shape.hull, dtype=np.float64), axes, float(shape.radius),
                False, ball, float("nan"), canonical_extents(shape),
                along.max(axis=0) - along.min(axis=0))  # fmt: skip


def _end_first(x: Body, shape: Shape) -> float:
    """B's end-first radius (:func:`sieve_mi.geometry.size.end_first_radius`), once."""
    if math.isnan(x.end_first):
        x.end_first = end_first_radius(shape)[0]
    return x.end_first


def _arguments(x: Body, shape: Shape, a: Body, grow: float) -> list[tuple[float, str, dict]]:
    """Thresholds (scene units, SAFETY included) of both arguments for B ``x`` (its ``shape``)
    over A ``a``: (threshold, rule, certificate). End first is skipped where B's ball alone
    (a lower bound on its end-first radius) is too big at ``grow``, fits inside where
    :func:`growth_lower_bound` is above ``grow``."""
    need = SAFETY * a.radius
    out = []
    if a.ball > 0.0 and x.ball - a.ball + need <= grow:
        r = _end_first(x, shape)
        out.append((r - a.ball + need, "end-first", {"radius": r, "ball": a.ball}))
    floor = growth_lower_bound(x.points, a.points, x.ball)
    if floor + need <= grow:
        found = least_growth(x.points, a.points, hull_frames(x.points, x.axes),
                             hull_frames(a.points, a.axes), target=grow, floor=floor)  # fmt: skip
        if found is not None:
            cert = {"rotation": found.quaternion,
                    "translation": [float(v) for v in found.translation]}  # fmt: skip
            out.append((found.grow + need, "fits-inside", cert))
    return out


def _reason(scene: Scene, rec: BlockFeasibility, how: str, cert: dict) -> str:
    """The sentence for an impossible B."""
    fab, u = scene.fabrication, scene.units
    at = f"tolerance {fab.tolerance:g} {u}"
    if fab.block_margin > 0:
        at += f" (plus block_margin {fab.block_margin:g} {u})"
    a = rec.passing
    if rec.rule == "fits-inside":
        why = (f"it fits inside {a} grown by {round_up(rec.grow)} {u} (turned and moved, every "
               f"vertex of its hull checked), so every hole that passes {a} passes it")  # fmt: skip
    else:
        why = (f"seen end first it fits in a disk of radius {round_up(cert['radius'], 4)} {u}, "
               f"inside every hole that passes {a} (its inscribed ball, radius "
               f"{cert['ball']:.4g} {u}, grown by the tolerance)")  # fmt: skip
    if how == "filled":
        why += f" ({a}'s through-holes are filled: [fabrication] fill_holes)"
    if rec.max_tolerance <= 0:
        alone = "the block margin alone lets it through" if fab.block_margin > 0 else (
            "it passes with no tolerance at all")  # fmt: skip
        limit = f"no tolerance can work ({alone})"
    else:
        limit = (f"the largest tolerance that could work is below {round_up(rec.max_tolerance)} "
                 f"{u} (an upper bound from this argument)")  # fmt: skip
    return f"{rec.name} cannot be blocked at {at}: {why}; {limit}"


def feasibility(scene: Scene, passes: list[Shape], blocks: list[Shape]) -> Feasibility:
    """Which B the scene's tolerance makes impossible to block (module docstring); seconds.

    Parameters
    ----------
    scene : Scene
        Its ``[fabrication]`` tolerance, block_margin and fill_holes are used.
    passes, blocks : list of Shape
        A and B.

    Returns
    -------
    Feasibility
    """
    t0 = time.perf_counter()
    fab = scene.fabrication
    grow = fab.tolerance + fab.block_margin
    solids = [_solid(a, fab.fill_holes) for a in passes]
    out = []
    for shape in blocks:
        rec = BlockFeasibility(shape.name, reason=f"{shape.name}: not ruled out by the tolerance")
        usable = [(i, s) for i, s in enumerate(solids) if s[0] is not None]
        x = _held(shape) if usable else None
        found = [(thr, rule, cert, i, how) for i, (a, how) in usable
                 for thr, rule, cert in _arguments(x, shape, a, grow)]  # fmt: skip
        if found:
            thr, rule, cert, i, how = min(found, key=lambda f: f[0])
            rec.rule, rec.passing, rec.grow, rec.certificate = rule, passes[i].name, thr, cert
            rec.index = i
            rec.max_tolerance = max(0.0, thr - fab.block_margin)
            if thr <= grow:
                rec.status = "impossible"
                rec.reason = _reason(scene, rec, how, cert)
        out.append(rec)
    kinds = [how for _, how in solids]
    return Feasibility(out, fab.tolerance, fab.block_margin, kinds, time.perf_counter() - t0)


def certificate_pose(
    rec: BlockFeasibility, shape: Shape, a_shape: Shape, a_quat: np.ndarray, a_trans: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A pose (rotation (4,), translation (2,)) in which the impossible B ``shape`` passes the
    hole of A ``a_shape`` placed at (``a_quat``, ``a_trans``): its certificate made concrete."""
    ra = to_matrix(np.asarray(a_quat, dtype=np.float64))
    if rec.rule == "fits-inside":
        rot = ra @ to_matrix(np.asarray(rec.certificate["rotation"]))
        t = ra @ np.asarray(rec.certificate["translation"])
        return from_matrix(rot), t[:2] + np.asarray(a_trans, dtype=np.float64)
    from scipy.spatial import ConvexHull

    centre = ball_in_facets(ConvexHull(a_shape.hull).equations)[0]
    _, view = end_first_radius(shape)
    q = align(view, [0.0, 0.0, 1.0])
    circle = enclosing_circle((shape.hull @ to_matrix(q).T)[:, :2])[0]
    return q, (ra @ centre)[:2] + np.asarray(a_trans, dtype=np.float64) - circle


def with_certificates(scene: Scene, passes: list[Shape], blocks: list[Shape], rows: list[int],
                      feas: Feasibility, quats: np.ndarray, v) -> None:  # fmt: skip
    """Complete the verdict ``v`` (a :class:`~sieve_mi.game.verdict.Judgement` whose attack has
    a column per B of ``rows``, or per B already) with the impossible B: each gets one exact
    attempt in its certificate's pose (:func:`certificate_pose`, where it passes), not an attack.

    B that are neither in ``rows`` nor impossible (the size screen's, already completed by
    :func:`sieve_mi.game.screen.with_proved` where there are any) keep their rows. Adds one
    warning per impossible B, naming the tolerance.
    """
    from sieve_mi.game.exact import score
    from sieve_mi.game.scoring import mask_window
    from sieve_mi.game.screen import with_proved
    from sieve_mi.geometry.outline import Boundary, dilated, is_closed
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    fab = scene.fabrication
    grown = dilated(v.outline, fab.block_margin) if fab.block_margin > 0 else None
    if v.attack.beta.shape[1] < len(blocks):  # columns for rows only: complete them
        masks = dict(zip(rows, v.block_masks))
        v.attack = with_proved(v.attack, rows, blocks, v.outline, grown, v.trans[0])
        v.block_masks = [masks.get(j) for j in range(len(blocks))]
    for j in feas.impossible:
        rec, i = feas.blocks[j], feas.blocks[j].index
        q, t = certificate_pose(rec, blocks[j], passes[i], quats[i], v.trans[i])
        closed = is_closed(blocks[j])
        s = score(blocks[j], q, t, v.outline, Boundary(v.outline), closed)
        v.attack.quats[0, j], v.attack.trans[0, j] = q, t
        v.attack.beta[0, j], v.attack.protrusion[0, j] = s.beta, s.protrusion
        v.attack.fits[0, j] = 0
        if grown is not None:
            g = score(blocks[j], q, t, grown, Boundary(grown), closed)
            v.attack.margin_beta[0, j], v.attack.margin_protrusion[0, j] = g.beta, g.protrusion
        v.block_masks[j] = None
        v.warnings.append(f"B wins whatever A does: {rec.reason}")
    v.block_masks = [m if m is not None else mask_window(SilhouetteRenderer(b), v.hole,
                     v.attack.quats[0, j], v.attack.trans[0, j])
                     for j, (b, m) in enumerate(zip(blocks, v.block_masks))]  # fmt: skip
