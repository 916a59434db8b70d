"""How far each blocked B overhangs the hole: in a maker's words, and measured on the exact polygon.

The verdict keeps, per B, the pose with the least area outside H (β first, then protrusion); its
protrusion (report.json's ``protrusion``) can be far larger than the overhang of B's best pose, e.g.
a toy brick tilted so one corner sticks out 3 mm while, standing straight, its body overhangs
0.5 mm per side. What a maker prints against is the *least overhang over poses*: the smallest,
over B's rotations and translations, of the largest distance by which its silhouette sticks out of
H. This module brackets it:

* :func:`least_overhang` searches for the pose that sticks out least: the verdict's pose and B's
  canonical views (:func:`sieve_mi.geometry.canonical.canonical_orientations`, each turned in the
  plane to several angles and to the hole's principal axes, centred on the hole, or on each of
  its pieces where it has several: separate holes) are ranked by the outside distance of
  B's hull vertices; the best few whose hull alone does not already stick out further than the
  best pose so far slide to their minimax pose
  (:func:`sieve_mi.game.exact.polish_margin`), and each is scored on the exact polygon
  (:func:`sieve_mi.game.exact.score`): the least score found is an upper bound on the least
  overhang (a pose that sticks out that much exists). No raster decides it.
* :func:`overhang` adds the proved lower bound (every pose sticks out by more): certify's margin
  bisection where it proved the block (:func:`sieve_mi.certify.blocks.prove_margin`), else a ball
  inside B that no disk of H can hold (:func:`sieve_mi.certify.blocks.ball_margin`), and says
  which, or that nothing was bisected: a "proved" line never shows a bare 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sieve_mi.game.exact import ExactAttempt, ExactScore, polish_margin, score
from sieve_mi.geometry.canonical import canonical_orientations
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import Boundary, is_closed
from sieve_mi.geometry.rotations import angle_between, from_axis_angle, quat_multiply, to_matrix

__all__ = [
    "CLOSE_ENOUGH",
    "IN_PLANE",
    "POLISHED",
    "POLISH_SAMPLES",
    "RANKED_POINTS",
    "Overhang",
    "block_overhangs",
    "least_overhang",
    "overhang",
    "overhang_text",
]

#: In-plane angles tried per canonical view (evenly spaced), besides the four that turn the view's
#: principal axes onto the hole's.
IN_PLANE = 8
#: Starts slid to their minimax pose and scored exactly, best ranked first.
POLISHED = 2
#: The search stops when its pose overhangs at most this fraction more than the proved bound.
CLOSE_ENOUGH = 0.05
#: The polish measures distances to H's boundary sampled this many times per hole size (the
#: exact score decides; a denser sampling costs seconds on a round part far outside H).
POLISH_SAMPLES = 400
#: Most hull vertices used to rank the starts (evenly thinned).
RANKED_POINTS = 256
_Z = np.array([0.0, 0.0, 1.0])


@dataclass
class Overhang:
    """One blocked B's overhang, bracketed (report.json's ``overhang``).

    Attributes
    ----------
    at_best_pose : float
        The least overhang found: the largest distance by which B's silhouette sticks out of H at
        ``rotation``, ``translation`` (exact polygon), scene units. Every B's true least overhang
        is at most this.
    rotation : (4,) ndarray
        (w, x, y, z) of that pose.
    translation : (2,) ndarray
        Scene units, in the hole's frame.
    proved_at_least : float or None
        Proved: in every pose B sticks out of H by more than this (scene units); None when
        nothing proves a bound.
    proof : str
        What ``proved_at_least`` rests on: ``"bisection"`` (certify's margin bisection),
        ``"ball"`` (a ball inside B no disk of H can hold), ``"not bisected"`` (certify proved the
        block, no margin step ran: the bound is the block margin only), ``"bisection failed"``
        (no step of the bisection proved a margin within the budget), or ``"none"``.
    searched : bool
        ``at_best_pose`` comes from the least-overhang search; False: it is the verdict's one
        exact attempt (a B proved blocked before the game by size, not searched).
    """

    at_best_pose: float
    rotation: np.ndarray
    translation: np.ndarray
    proved_at_least: float | None
    proof: str
    searched: bool = True

    def to_dict(self, units: str = "") -> dict:
        """Plain JSON-ready data, with the console's sentence (:func:`overhang_text`)."""
        out = {
            "at_best_pose": float(self.at_best_pose),
            "rotation": [float(x) for x in self.rotation],
            "translation": [float(x) for x in self.translation],
            "proved_at_least": None
            if self.proved_at_least is None
            else float(self.proved_at_least),
            "proof": self.proof,
            "searched": self.searched,
        }
        out["text"] = overhang_text(out, units)
        return out


def overhang_text(entry: dict, units: str) -> str:
    """The maker's sentence of report.json's ``overhang`` entry (lengths to 2 decimals).

    Examples
    --------
    >>> e = {"at_best_pose": 1.6, "proved_at_least": 0.8, "proof": "bisection"}
    >>> overhang_text(e, "mm")
    'overhangs the hole by ≥ 0.80 mm in every pose, 1.60 mm at its best pose'
    >>> overhang_text({**e, "proved_at_least": 0.0, "proof": "not bisected"}, "mm")
    'overhangs the hole by 1.60 mm at its best pose found; the margin was not bisected'
    """
    u = f" {units}" if units else ""
    best = entry["at_best_pose"]
    pose = "at its best pose" if entry.get("searched", True) else "at the one pose tried"
    low, proof = entry.get("proved_at_least"), entry.get("proof", "none")
    if best <= 0.0:
        return "fits the exact hole at the pose in overhang.rotation (found by the overhang search)"
    if low is not None and low > 0.0:
        return f"overhangs the hole by ≥ {low:.2f}{u} in every pose, {best:.2f}{u} {pose}"
    why = {
        "not bisected": "the margin was not bisected",
        "bisection failed": "no margin above 0 was proved within the budget",
    }.get(proof, "no lower bound proved")
    found = pose + (" found" if entry.get("searched", True) else "")
    return f"overhangs the hole by {best:.2f}{u} {found}; {why}"


def _starts(shape: Shape, boundary: Boundary) -> tuple[np.ndarray, np.ndarray]:
    """Canonical views turned in the plane, each centred on the hole's bounding box:
    (K, 4) rotations and (K, 2) translations, scene units."""
    lo, hi = boundary.a.min(0), boundary.a.max(0)
    hole_axis = _major_angle(boundary.a)
    quats, trans = [], []
    for q in canonical_orientations(shape):
        xy = (shape.hull @ to_matrix(q).T)[:, :2]
        turn = hole_axis - _major_angle(xy)
        angles = [*(turn + k * np.pi / 2 for k in range(4)),
                  *(2 * np.pi * k / IN_PLANE for k in range(IN_PLANE))]  # fmt: skip
        for a in angles:
            qa = quat_multiply(from_axis_angle(_Z, a), q)
            p = (shape.hull @ to_matrix(qa).T)[:, :2]
            quats.append(qa)
            trans.append(0.5 * (lo + hi) - 0.5 * (p.min(0) + p.max(0)))
    return np.array(quats).reshape(-1, 4), np.array(trans).reshape(-1, 2)


def _major_angle(xy: np.ndarray) -> float:
    """Angle (radians) of the principal axis of 2D points (N, 2) with the larger spread."""
    d = xy - xy.mean(0)
    w, v = np.linalg.eigh(d.T @ d)
    axis = v[:, int(np.argmax(w))]
    return float(np.arctan2(axis[1], axis[0]))


def _ranked(shape: Shape, quats, trans, hole) -> tuple[np.ndarray, np.ndarray]:
    """The poses' order by the largest outside distance of B's hull vertices (at most
    :data:`RANKED_POINTS` of them; smallest first), on a coarse sampling of H's boundary, and that
    distance less the sampling's spacing (K,), scene units: about a lower bound of each start's
    overhang. Only an order for the exact search, never a score."""
    boundary = Boundary(hole, spacing=Boundary(hole).size / 300)
    pts = shape.hull[np.unique(np.linspace(0, len(shape.hull) - 1, RANKED_POINTS).astype(int))]
    r = np.array([to_matrix(q) for q in quats])  # (K, 3, 3)
    xy = np.einsum("kij,pj->kpi", r, pts)[..., :2] + trans[:, None, :]
    far = boundary.approx_signed(xy.reshape(-1, 2)).reshape(len(quats), -1).max(axis=1)
    return np.argsort(far, kind="stable"), far - boundary.spacing


def least_overhang(
    shape: Shape,
    hole,
    start: ExactAttempt,
    *,
    closed: bool | None = None,
    polished: int = POLISHED,
    floor: float | None = None,
) -> ExactAttempt:
    """The pose of ``shape`` that sticks out of the polygon ``hole`` least, of those tried.

    Parameters
    ----------
    shape : Shape
    hole : manifold3d.CrossSection
        H, the exact hole.
    start : ExactAttempt
        A pose already scored exactly against ``hole`` (the verdict's): the answer is never worse.
    closed : bool, optional
        The mesh is watertight (default: tested).
    polished : int
        Ranked starts slid to their minimax pose and scored exactly.
    floor : float, optional
        A proved lower bound of the least overhang (scene units): the search stops once a pose
        is within :data:`CLOSE_ENOUGH` of it (no pose can do much better). It also stops at the
        first ranked start whose hull vertices alone stick out further than the best pose's
        exact overhang (the starts after it stick out further still).

    Returns
    -------
    ExactAttempt
        Its ``score.protrusion`` (scene units) is the exact overhang at its pose; 0 means the pose
        fits H.
    """
    if start.score.fits or _bracketed(start, floor):
        return start  # nothing to find: it fits, or no pose can do much better
    closed = is_closed(shape) if closed is None else closed
    boundary = Boundary(hole)
    pieces = hole.decompose()  # separate holes: start over each one, not between them
    bounds = [Boundary(h) for h in pieces] if len(pieces) > 1 else [boundary]
    quats, trans = (np.concatenate(x) for x in zip(*(_starts(shape, b) for b in bounds)))
    ranked, estimate = _ranked(shape, quats, trans, hole)
    coarse = Boundary(hole, spacing=boundary.size / POLISH_SAMPLES)  # the polish's distances
    best, tried = start, [(start.quat, start.trans)]  # the verdict already polished its pose
    for k in ranked:
        if len(tried) > polished or best.score.fits or _bracketed(best, floor):
            break
        if estimate[k] >= best.score.protrusion:  # its hull alone sticks out further: the rest too
            break
        q, t = quats[k], trans[k]
        if any(_close(q, t, p, s, shape.radius) for p, s in tried):
            continue
        tried.append((q, t))
        qq, tt = polish_margin(shape, q, t, coarse, closed=closed)
        for pq, pt in ((qq, tt), (q, t)):
            got = score(shape, pq, pt, hole, boundary, closed)
            if got.protrusion < best.score.protrusion:
                best = ExactAttempt(np.asarray(pq, float), np.asarray(pt, float), got)
    return best


def _bracketed(best: ExactAttempt, floor: float | None) -> bool:
    """The pose found overhangs at most :data:`CLOSE_ENOUGH` (relative) more than ``floor``."""
    return floor is not None and best.score.protrusion <= (1.0 + CLOSE_ENOUGH) * floor


def _close(q1, t1, q2, t2, radius: float) -> bool:
    """Two starts within a twentieth of the shape's radius of each other (one polish is enough)."""
    moved = angle_between(q1, q2) * radius + float(np.linalg.norm(np.subtract(t1, t2)))
    return moved <= 0.05 * radius


def overhang(
    shape: Shape, hole, start: ExactAttempt, margin: dict, certified=None, search: bool = True
) -> Overhang:
    """One blocked B's :class:`Overhang`: the least overhang found and the proved lower bound.

    Parameters
    ----------
    shape : Shape
    hole : manifold3d.CrossSection
        H, the exact hole.
    start : ExactAttempt
        The verdict's best pose, scored exactly against H.
    margin : dict
        Its :func:`sieve_mi.game.result.block_margin` (``proved_at_least``: the proved bound,
        computed once by the solver).
    certified : Certification, optional
        certify's answer (against H grown by ``[fabrication] block_margin``).
    search : bool
        Search for the least overhang (:func:`least_overhang`); False: ``start`` is the answer.

    Returns
    -------
    Overhang
    """
    low = margin.get("proved_at_least")
    best = least_overhang(shape, hole, start, floor=low) if search else start
    proof = _proof(certified, low)
    return Overhang(best.score.protrusion, best.quat, best.trans, low, proof, search)


def _proof(certified, low: float | None) -> str:
    """What the proved bound ``low`` of :func:`sieve_mi.game.result.block_margin` rests on
    (:attr:`Overhang.proof`)."""
    if certified is None or certified.status != "proved":
        return "none" if low is None else "ball"
    if (certified.margin or 0.0) > 0:
        return "bisection"
    return "bisection failed" if certified.margin_steps > 0 else "not bisected"


def block_overhangs(shapes, hole, attack, margins: list, certified: list, progress=None,
                    skip=()) -> list:  # fmt: skip
    """Per shape of B, its :class:`Overhang` where it has a margin (blocked straight through the
    exact hole, :func:`sieve_mi.game.result.block_margins`), else None.

    ``progress(j)`` is called after each shape. The shapes in ``skip`` (those proved blocked
    before the game by size, :mod:`sieve_mi.game.screen`: far too big, and possibly many) get no
    search: their overhang is the verdict's one exact attempt's (:attr:`Overhang.searched` False).
    """
    out = []
    for j, shape in enumerate(shapes):
        if j >= len(margins) or margins[j] is None:
            out.append(None)
        else:
            sc = ExactScore(float(attack.beta[0, j]), float(attack.protrusion[0, j]), np.nan)
            start = ExactAttempt(attack.quats[0, j].copy(), attack.trans[0, j].copy(), sc)
            c = certified[j] if j < len(certified) else None
            out.append(overhang(shape, hole, start, margins[j], c, search=j not in skip))
        if progress is not None:
            progress(j)
    return out
