"""Holds ruled out before any game: exact reasons why no sieve can hold one shape while another
falls through.

A sieve that holds X while shapes A_1 ... A_m fall through is one game. Player A chooses a pose
(rotation q, place) of every A and the hole H; H contains each placed A's silhouette grown by the
tolerance (:func:`sieve_mi.geometry.outline.hole_outline`: the exact outline never comes inward
of proj(A) + disk(tolerance), merged or ``separate`` holes alike, filled or not). X counts as
blocked only if no pose of X fits through H, nor through H grown by ``[fabrication]
block_margin``. So with g = tolerance + block_margin, every hole that passes A contains, for the
rotation q that A was given, proj_q(A) + disk(g) grown to H + disk(block_margin) — and X is not
blocked as soon as some pose of X fits inside proj_q(A) + disk(g). A rule that drops the hold
"X over A" must show that for **every** rotation q of A; showing it for one view of A (say the
one A passes best in) proves nothing, because A's pose is A's choice and a hole made in another
view may block X. Both rules below hold for every q at once:

**Fits inside** (:func:`fits_inside`). If a rigid motion M puts X inside A + ball(g) (in 3D),
then for every rotation q the projection of q M X lies in proj_q(A + ball(g)) = proj_q(A) +
disk(g): X, turned by q M and moved along, falls through wherever A does. The check: for 24
rotations M (X's principal axes onto A's, every proper signed permutation) a small linear
program finds the translation that puts X's hull vertices deepest inside a convex polytope
that lies inside A + ball(g): the hull of A's hull vertices each moved by g along 38 unit
directions (A's principal axes and their diagonals, and an icosahedron's vertices), which is
hull(A) + hull(38 points on the sphere of radius g), inside hull(A) + ball(g). A positive depth is
a certificate (rotation, translation, depth), so a false "hopeless" cannot come from the search,
only from A not being what the check assumes (below). Eight euro coins: each coin fits inside
every coin that is at least as wide and at most 2g thinner (the 1 cent inside the 2 and 5 cent,
which are as thick), so of the 56 ordered pairs, 27 are ruled out before any game.

**End first** (:func:`end_first`). If A holds a ball of radius rho, every proj_q(A) holds a disk of
radius rho (the ball's shadow), so every hole that passes A holds a disk of radius rho + g. If X,
in one of its canonical views, fits inside a disk of radius r <= rho + g
(:func:`sieve_mi.geometry.size.end_first_radius`), X goes through end first. A pencil over a big
ball: hopeless, though the pencil fits inside no ball. rho is the largest ball inside A's hull (a
linear program on its facets).

Both rules need hull(A) to be A's solid, i.e. A convex and closed: then proj_q(A) is the
projection of its hull. :func:`body` accepts A when its mesh is watertight, one body, convex at
every edge (trimesh's local test, to 1e-5 of its size) and as voluminous as its hull (to 1e-6); any
other A rules out nothing (a sound omission: those holds are played). X needs nothing: its hull
contains it. Round-off and the tests' tolerances are covered by demanding a margin of
:data:`SAFETY` times A's radius. The rules are sufficient, not necessary: a hold they leave may
still be hopeless (X turned off A's principal axes, or through the union of several A), and is
then played.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np

from sieve_mi.geometry.bodies import SAFETY, Body, body
from sieve_mi.geometry.canonical import proper_signed_permutations
from sieve_mi.geometry.rotations import from_matrix
from sieve_mi.geometry.size import predicted_margin

__all__ = [
    "SAFETY",
    "Body",
    "Rules",
    "Ruling",
    "body",
    "end_first",
    "fits_inside",
    "grown_hull",
]


def _directions(axes: np.ndarray) -> np.ndarray:
    """38 unit directions (38, 3): the principal axes, their face and corner diagonals (26, in
    the frame of ``axes``) and an icosahedron's 12 vertices."""
    cube = np.array([v for v in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(v)])
    phi = (1.0 + 5.0**0.5) / 2.0
    ico = np.array(
        [
            p
            for s1 in (-1, 1)
            for s2 in (-1, 1)
            for p in ([0, s1, s2 * phi], [s1, s2 * phi, 0], [s2 * phi, 0, s1])
        ],
        dtype=np.float64,
    )
    d = np.concatenate([cube @ axes, ico])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def grown_hull(b: Body, grow: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A convex polytope inside hull(b) + ball(``grow``): unit facet normals (F, 3), offsets
    (F,) and widths (F,), the polytope being {x : normals @ x <= offsets} and its width along
    each normal.

    It is the hull of every hull vertex moved by ``grow`` along each of :func:`_directions`, i.e.
    hull(b) + hull(those 38 points on the sphere of radius ``grow``).
    """
    from scipy.spatial import ConvexHull

    key = round(float(grow), 12)
    if key not in b._grown:
        pts = (b.points[:, None, :] + grow * _directions(b.axes)[None]).reshape(-1, 3)
        hull = ConvexHull(pts)
        normals, offsets = hull.equations[:, :3], -hull.equations[:, 3]
        widths = offsets - (normals @ pts[hull.vertices].T).min(axis=1)
        b._grown[key] = (normals, offsets, widths)
    return b._grown[key]


_TURNS = proper_signed_permutations()


def _deepest(normals: np.ndarray, room: np.ndarray) -> tuple[float, np.ndarray]:
    """max s over translations t with normals @ t + s <= room: the depth s and t (3,)."""
    from scipy.optimize import linprog

    a = np.column_stack([normals, np.ones(len(normals))])
    res = linprog([0, 0, 0, -1.0], A_ub=a, b_ub=room, bounds=[(None, None)] * 4)
    if not res.success:
        return -np.inf, np.zeros(3)
    return float(res.x[3]), res.x[:3]


@dataclass
class Ruling:
    """Why holding ``held`` while ``passing`` falls through is hopeless (scene units).

    Attributes
    ----------
    held, passing : str
    rule : {"fits-inside", "end-first"}
    margin : float
        How much the rule has to spare: the depth of X inside A's grown hull, or rho + g - r.
    reason : str
        One sentence for people.
    certificate : dict
        fits-inside: ``rotation`` (w, x, y, z, turning the held shape about its centre) and
        ``translation`` (3,), from the passing shape's centre; end-first: ``radius`` (r),
        ``ball`` (rho), ``grow`` (g).
    """

    held: str
    passing: str
    rule: str
    margin: float
    reason: str
    certificate: dict

    def as_dict(self) -> dict:
        """For ``cascade.json``."""
        return {
            "held": self.held,
            "passing": self.passing,
            "rule": self.rule,
            "margin": round(self.margin, 6),
            "reason": self.reason,
            "certificate": self.certificate,
        }


def fits_inside(held: Body, passing: Body, grow: float, units: str = "mm") -> Ruling | None:
    """The *fits inside* rule (module docstring): a certificate that ``held`` fits inside
    ``passing`` grown by ``grow`` (scene units), or None (none found, or ``passing`` not convex)."""
    if not passing.convex:
        return None
    normals, offsets, widths = grown_hull(passing, grow)
    need = SAFETY * passing.radius
    room = passing.widths + 2.0 * grow - need  # the grown hull's widths along its axes
    for turn in _TURNS:
        if np.any(np.abs(turn) @ held.widths > room):  # too wide along one of A's axes
            continue
        rot = passing.axes.T @ turn @ held.axes
        along = normals @ rot @ held.points.T
        support = along.max(axis=1)
        if np.any(support - along.min(axis=1) > widths - need):  # too wide: no translation helps
            continue
        depth, shift = _deepest(normals, offsets - support)
        if depth > need:
            reason = (
                f"{held.name} passes every hole that passes {passing.name}: it fits inside "
                f"{passing.name} grown by {grow:g} {units} (turned onto its principal axes, "
                f"{depth:.3g} {units} to spare)"
            )
            cert = {
                "rotation": [float(x) for x in from_matrix(rot)],
                "translation": [float(x) for x in shift],
            }
            return Ruling(held.name, passing.name, "fits-inside", depth, reason, cert)
    return None


def end_first(held: Body, passing: Body, grow: float, units: str = "mm") -> Ruling | None:
    """The *end first* rule (module docstring): ``held`` fits, in one of its canonical views, in
    a disk no larger than ``passing``'s inscribed ball grown by ``grow``; or None."""
    if not passing.convex or passing.ball <= 0.0:
        return None
    spare = passing.ball + grow - held.end_first
    if spare <= SAFETY * passing.radius:
        return None
    reason = (
        f"{held.name} passes every hole that passes {passing.name}: seen end first it fits in a "
        f"disk of radius {held.end_first:.4g} {units}, inside {passing.name}'s inscribed ball "
        f"({passing.ball:.4g} {units}) grown by {grow:g}"
    )
    cert = {"radius": held.end_first, "ball": passing.ball, "grow": grow}
    return Ruling(held.name, passing.name, "end-first", spare, reason, cert)


class Rules:
    """The rules for every ordered pair of a mixture's shapes, decided once (before any game).

    Parameters
    ----------
    bodies : list of Body
    grow : float
        ``[fabrication] tolerance + block_margin``, scene units.
    units : str
        For the reasons' text.
    """

    def __init__(self, bodies: list[Body], grow: float, units: str = "mm"):
        t0 = time.perf_counter()
        self.bodies = {b.name: b for b in bodies}
        self.grow = float(grow)
        self.pairs: dict = {}
        for x, a in itertools.permutations(bodies, 2):
            ruling = end_first(x, a, grow, units) or fits_inside(x, a, grow, units)
            if ruling is not None:
                self.pairs[x.name, a.name] = ruling
        self.seconds = time.perf_counter() - t0

    def hopeless(self, holds: list, passes: list) -> dict | None:
        """The first ruling that no sieve holds all of ``holds`` while ``passes`` fall through:
        one held shape that passes every hole one passing shape passes (``Ruling.as_dict()``
        plus ``holds``), or None."""
        for x in holds:
            for a in passes:
                if (x, a) in self.pairs:
                    return {"holds": list(holds), **self.pairs[x, a].as_dict()}
        return None

    def margin(self, holds: list, passes: list) -> float:
        """The smallest :func:`sieve_mi.geometry.size.predicted_margin` of a held shape over a
        passing one (scene units; larger is more promising)."""
        b = self.bodies
        return min(
            predicted_margin(b[x].extents, b[a].extents, self.grow) for x in holds for a in passes
        )

    def table(self) -> list[dict]:
        """Every ruled-out pair, for ``cascade.json``."""
        return [r.as_dict() for r in self.pairs.values()]
