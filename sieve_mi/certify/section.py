"""The slab-section proof: no rigid motion carries a shape through a plate of a given thickness.

Fix a point p of the shape's convex hull (the *pin*). A motion that carries the shape from wholly
above a plate of thickness t to wholly below carries p through the plate's mid-plane, and at that
moment every point of the shape strictly inside the plate's slab must lie inside the hole's prism:
the projection of the shape's *slab section* (its points within t/2 above or below p) must fit H.
So if no rotation and no horizontal offset makes that section's projection fit H, the shape cannot
pass a plate of thickness t by any rigid motion (nor a thicker one: its band holds more points).
With t at least the shape's diameter the section is the whole shape (the thick-plate theorem);
a ball around p gives the ball argument.

Which points are in the band depends only on the direction n that the rotation turns to the
vertical (n = R^T e_z, in the shape's own frame); the rest of the rotation is a turn about the
vertical. The search is a branch and bound over n on the sphere (:class:`SphereCells`: quadtree
cells on the six faces of the cube, each covered by a cap of angle alpha about its centre
direction), with v = q - p for every candidate point q of the shape (vertices and points on mesh
edges):

* v is in the band for every n of the cell if |n_c . v| + 2 sin(alpha / 2) |v| < t / 2;
* its position in the plane (coordinates x along a frame of the plane normal to n_c) moves by at
  most r = 2 sin(alpha / 2) |v| over the cell, before the free turn and offset.

A cell is excluded by a test that holds for every turn and offset (docs/certify.md, "Thin
plates"):

``diameter``
    two band points i, j with |x_i - x_j| - r_i - r_j > diam(H): the section is wider than any
    two points of H are apart;
``width``
    band points whose convex hull's minimal width, less twice their largest r, exceeds the
    minimal width of H's convex hull;
``chain``
    on a sheet (several contours): band points that hang together by steps shorter than the
    gap between copies and end further apart than one copy's diameter (:mod:`~.chain`);
``link``
    the same through a ring's loops, which cannot straddle a web (:mod:`~.link`);
``turns``
    a one-dimensional branch and bound over the turn psi: each interval of turns is excluded when
    no offset puts every chosen point within its bound (r plus the turn's displacement
    2 sin(delta / 2) |x|) of H; batched over the cells of a chunk and their intervals
    (:mod:`sieve_mi.certify.turns`: a quadtree on proved distance bounds, the exact test
    :func:`~sieve_mi.certify.bounds.translations_left` only where it leaves an interval at the
    last level).

The certificate's ``section`` entry records the pin, thickness, band, points and the tree; the
replay (:mod:`sieve_mi.certify.replay_section`) re-proves every leaf with its own geometry.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import manifold3d
import numpy as np

from sieve_mi.certify import bounds, chain, link
from sieve_mi.certify.search import EvenOdd
from sieve_mi.certify.turns import TurnTest, spread
from sieve_mi.geometry.meshes import Shape

__all__ = ["FACES", "INNER_POINTS", "SECTION_CANDIDATES", "SHEET_INNER_POINTS", "Plane",
           "SectionOutcome", "SectionSearch", "SphereCells", "caps", "hull_widths", "min_width",
           "pins", "plane_frames", "prove_section", "sphere_roots"]  # fmt: skip

#: Faces of the cube whose quadtree cells tile the sphere of directions: (axis, sign).
FACES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0))
#: Added to every cap angle (radians): covers rounding in the corner angles.
ANGLE_MARGIN = 1e-12
#: Relative margin on every displacement bound and band test (rounding).
RELATIVE_MARGIN = 1e-9
#: Directions of the batched diameter test, over a half circle.
DIAMETER_DIRECTIONS = 16
#: Points of a cell's width and turn tests: those extreme along these many directions (x2).
EXTREME_DIRECTIONS = 12
#: Band points spread over the section (:func:`~sieve_mi.certify.turns.spread`) that the turn
#: test gets beside the extreme ones (0: those only; measured on the letters, docs/performance.md).
INNER_POINTS = 0
#: The same against a hole of several regions (a sheet: a section in parts can put its extreme
#: points in two holes, its inner ones on the web; the M5 nut, docs/shake.md).
SHEET_INNER_POINTS = 8
#: Levels of the turn search: intervals of 2 pi / 8 halved this many times at most.
TURN_DEPTH = 6
#: Nodes across the hole of the turn test's grid of lower bounds on the distance to H.
LOWER_PIXELS = 800
#: Most candidate points of a section search (vertices first, then points on edges).
SECTION_CANDIDATES = 6000
#: Cells of one batched level processed at once (memory: cells x points x 16 floats).
CHUNK = 2048


@dataclass
class SphereCells:
    """A batch of cells of directions: squares ``[lo, hi]`` on faces of the cube [-1, 1]^3.

    Attributes
    ----------
    face : (n,) int ndarray
        Index into :data:`FACES`.
    lo, hi : (n, 2) float ndarray
        The square's corners in the face's two other coordinates (in increasing axis order).
    """

    face: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def __len__(self) -> int:
        return int(len(self.face))

    def take(self, idx) -> SphereCells:
        """The cells at ``idx`` (index array or boolean mask)."""
        return SphereCells(self.face[idx], self.lo[idx], self.hi[idx])

    def split(self) -> SphereCells:
        """The four quadrants of every cell, grouped per parent (child c takes the upper half of
        coordinate j iff bit (1 - j) of c is set)."""
        mid = 0.5 * (self.lo + self.hi)
        bits = np.array([[(c >> 1) & 1, c & 1] for c in range(4)], dtype=bool)
        lo = np.where(bits[None], mid[:, None], self.lo[:, None]).reshape(-1, 2)
        hi = np.where(bits[None], self.hi[:, None], mid[:, None]).reshape(-1, 2)
        return SphereCells(np.repeat(self.face, 4), lo, hi)


def sphere_roots() -> SphereCells:
    """One cell per cube face, the square [-1, 1]^2."""
    n = len(FACES)
    return SphereCells(np.arange(n), np.full((n, 2), -1.0), np.full((n, 2), 1.0))


def _on_cube(face: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Unit directions of points ``uv`` (n, ..., 2) on the cube faces ``face`` (n,)."""
    axis = np.array([FACES[f][0] for f in face])
    sign = np.array([FACES[f][1] for f in face])
    out = np.empty(uv.shape[:-1] + (3,))
    for a in range(3):
        sel = axis == a
        others = [k for k in range(3) if k != a]
        out[sel, ..., a] = sign[sel].reshape((-1,) + (1,) * (uv.ndim - 2))
        out[sel, ..., others[0]] = uv[sel, ..., 0]
        out[sel, ..., others[1]] = uv[sel, ..., 1]
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def caps(cells: SphereCells) -> tuple[np.ndarray, np.ndarray]:
    """Centre directions and cap angles of the cells.

    The angle from the centre direction is largest at a corner of the square (the set of
    directions within an angle a < pi / 2 of n_c is a convex cone, so its preimage on the face is
    convex); it is computed as 2 asin(|n_c - n_k| / 2) over the four corners, plus
    :data:`ANGLE_MARGIN`.

    Returns
    -------
    centre : (n, 3) ndarray
        Unit directions.
    alpha : (n,) ndarray
        Radians.
    """
    centre = _on_cube(cells.face, 0.5 * (cells.lo + cells.hi))
    corners = np.stack(
        [
            np.where(np.array([(c >> 1) & 1, c & 1], dtype=bool), cells.hi, cells.lo)
            for c in range(4)
        ],
        axis=1,
    )
    n_k = _on_cube(cells.face, corners)
    chord = np.linalg.norm(n_k - centre[:, None], axis=-1).max(axis=1)
    return centre, 2.0 * np.arcsin(np.minimum(1.0, 0.5 * chord)) + ANGLE_MARGIN


def plane_frames(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal vectors (e1, e2) spanning the planes normal to the unit vectors ``normal``
    (n, 3); each (n, 3)."""
    helper = np.where(
        (np.abs(normal[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    )
    e1 = np.cross(helper, normal)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(normal, e1)


def min_width(points: np.ndarray) -> float:
    """The minimal width of the convex hull of planar points (rotating calipers), scene units.

    The minimal width of a convex polygon is attained with a side of the polygon on one of the
    two supporting lines, so it is the least, over the hull's edges, of the largest distance of a
    hull vertex from the edge's line. Fewer than three points, or collinear ones: 0.

    Examples
    --------
    >>> import numpy as np
    >>> round(min_width(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [0.0, 1.0]])), 12)
    1.0
    """
    from scipy.spatial import ConvexHull, QhullError

    p = np.asarray(points, dtype=np.float64)
    if len(p) < 3:
        return 0.0
    try:
        h = p[ConvexHull(p).vertices]
    except (QhullError, ValueError):
        return 0.0
    a, b = h, np.roll(h, -1, axis=0)
    d = b - a
    length = np.linalg.norm(d, axis=1)
    ok = length > 0
    cross = d[ok, None, 0] * (h[None, :, 1] - a[ok, None, 1]) - d[ok, None, 1] * (
        h[None, :, 0] - a[ok, None, 0]
    )
    return float((np.abs(cross).max(axis=1) / length[ok]).min()) if ok.any() else 0.0


def hull_widths(contours: list[np.ndarray]) -> tuple[float, float]:
    """H's diameter (largest distance between two of its points) and the minimal width of its
    convex hull, scene units (both exact up to rounding)."""
    v = np.concatenate([np.asarray(c, dtype=np.float64) for c in contours])
    from scipy.spatial import ConvexHull, QhullError

    try:
        v = v[ConvexHull(v).vertices]
    except (QhullError, ValueError):
        pass
    diam = math.sqrt(float(((v[:, None] - v[None]) ** 2).sum(-1).max()))
    return diam, min_width(v)


@dataclass
class Node:
    """A cell of the tree over directions: a leaf with evidence, split (4 children) or open."""

    evidence: dict | None = None
    children: list | None = None

    def to_dict(self) -> dict:
        """The certificate's node: ``{"e": ...}``, ``{"c": [4 nodes]}`` or ``{"open": true}``."""
        if self.children:
            return {"c": [c.to_dict() for c in self.children]}
        return {"e": self.evidence} if self.evidence is not None else {"open": True}


@dataclass
class SectionOutcome:
    """What the section search found.

    Attributes
    ----------
    status : {"proved", "undecided"}
    pin : (3,) ndarray
        The pinned point, in the shape's centred frame, scene units.
    thickness : float
        The plate's thickness proved (or tried), scene units.
    roots : list of Node
        One per cube face.
    points : list of int
        Indices into the candidates of the points the evidence uses.
    examined, excluded, open_cells, depth : int
    seconds : float
    """

    status: str
    pin: np.ndarray
    thickness: float
    roots: list
    points: set = field(default_factory=set)
    examined: int = 0
    excluded: int = 0
    open_cells: int = 0
    depth: int = 0
    seconds: float = 0.0


class Plane:
    """The band points of a chunk of cells, their plane coordinates and displacement bounds.

    For a cell with centre direction n_c and cap angle alpha, and v = q - p:

    * v is in the band for every direction n of the cap if |n_c . v| + 2 sin(alpha / 2) |v| is
      below the half-thickness (|n . v - n_c . v| <= |n - n_c| |v|);
    * its plane coordinates x = (e1 . v, e2 . v) move by at most
      r = 2 (1 - cos alpha) |v| + sin(alpha) |n_c . v| (the rotation S taking n to n_c turns
      by beta <= alpha about an axis a normal to n_c, and the part of S v - v in the plane is
      (cos beta - 1) P v + sin beta (n_c . v) (a x n_c) + (1 - cos beta)(a . v) a; docs/certify.md).

    The band test is made for every (cell, point) pair at once; plane coordinates and bounds are
    computed per cell when asked (:meth:`cell`), or for a few chosen points (:meth:`widest`).

    Attributes
    ----------
    centre : (n, 3) ndarray
    chord : (n,) ndarray
        2 sin(alpha / 2) per cell.
    usable : (n, k) bool ndarray
        The band points of each cell, over the candidates.
    """

    def __init__(self, centre, alpha, v, lengths, band: float, eta: float):
        self.centre, self.alpha, self.chord = centre, alpha, 2.0 * np.sin(0.5 * alpha)
        self.v, self.lengths, self.eta = v, lengths, eta
        self.z = centre @ v.T
        self.usable = np.abs(self.z) + self.chord[:, None] * lengths[None] * (
            1 + RELATIVE_MARGIN
        ) < (band * (1 - RELATIVE_MARGIN) - eta)
        self.e1, self.e2 = plane_frames(centre)

    def bound(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """The displacement bounds r of points ``cols`` in cells ``rows`` (same shape)."""
        a = self.alpha[rows]
        second = 2.0 * (1.0 - np.cos(a)) * self.lengths[cols] + np.sin(a) * np.abs(
            self.z[rows, cols]
        )
        return second * (1 + RELATIVE_MARGIN) + self.eta

    def coords(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Plane coordinates x (..., 2) of points ``cols`` in cells ``rows`` (same shape)."""
        vk = self.v[cols]
        return np.stack([(self.e1[rows] * vk).sum(-1), (self.e2[rows] * vk).sum(-1)], axis=-1)

    def cell(self, c: int):
        """Cell ``c``'s band points: candidate indices, x (k, 2), r (k,)."""
        cols = np.flatnonzero(self.usable[c])
        rows = np.full(len(cols), c)
        return cols, self.coords(rows, cols), self.bound(rows, cols)

    def widest(self, dirs: np.ndarray, block: int = 32) -> tuple[np.ndarray, np.ndarray]:
        """Per cell, the pair of band points furthest apart along one of ``dirs`` (m, 2) after
        their bounds, and its proved gap |x_i - x_j| - r_i - r_j (-inf without two points).

        The pair is chosen in single precision (a choice only); its gap is computed in double.

        Returns
        -------
        pair : (n, 2) int ndarray
            Candidate indices.
        gap : (n,) ndarray
        """
        n, m = len(self.centre), len(dirs)
        pair, gap = np.zeros((n, 2), dtype=np.int64), np.full(n, -np.inf)
        have = np.flatnonzero(self.usable.sum(axis=1) >= 2)
        for s in range(0, len(have), block):
            c = have[s : s + block]
            cols = np.flatnonzero(self.usable[c].any(axis=0))  # in the band of some cell
            w = (
                dirs[None, :, 0, None] * self.e1[c, None]
                + dirs[None, :, 1, None] * self.e2[c, None]
            )
            proj = w.astype(np.float32) @ self.v[cols].T.astype(np.float32)  # (b, m, k)
            r = self.bound(c[:, None], cols[None]).astype(np.float32)
            off = ~self.usable[np.ix_(c, cols)][:, None, :]
            hi = cols[np.where(off, -np.inf, proj - r[:, None]).argmax(axis=2)]
            lo = cols[np.where(off, np.inf, proj + r[:, None]).argmin(axis=2)]
            rows = np.repeat(c, m).reshape(-1, m)
            d = np.linalg.norm(self.coords(rows, hi) - self.coords(rows, lo), axis=-1)
            d -= self.bound(rows, hi) + self.bound(rows, lo)
            best = d.argmax(axis=1)
            k = np.arange(len(c))
            pair[c] = np.column_stack([hi[k, best], lo[k, best]])
            gap[c] = d[k, best]
        return pair, gap


class SectionSearch:
    """The branch and bound over directions for one shape, pin and thickness against H.

    Parameters
    ----------
    candidates : (k, 3) ndarray
        Points of the shape (vertices and points on mesh edges), centred frame, scene units.
    hole : manifold3d.CrossSection
        H (the union of the plate's holes), scene units.
    radius : float
        The shape's radius (largest |q| of a vertex), scene units: scales the slack.
    kappa : float
        Slack of the turn test, as certify's :class:`~sieve_mi.certify.search.Settings`.
    """

    def __init__(self, candidates: np.ndarray, hole: manifold3d.CrossSection, radius: float,
                 kappa: float = 0.02):  # fmt: skip
        self.candidates = np.asarray(candidates, dtype=np.float64)
        self.hole, self.radius, self.kappa = hole, float(radius), float(kappa)
        contours = [np.asarray(c, dtype=np.float64) for c in hole.to_polygons()]
        self.diameter, self.width = hull_widths(contours)
        segs = bounds.contour_segments(contours)
        self.eta = 1e-6 * max(float(np.abs(segs).max()), self.radius)
        self.chain = chain.Chain(contours, self.eta) if len(contours) > 1 else None
        self.loops, self.link = [], None  # the shape's loops for the link test (:mod:`~.link`)
        self.cache = bounds.OffsetCache(hole, self.eta, r_min=self.eta)
        region = EvenOdd(contours)
        self.turn_test = TurnTest(self.cache, bounds.LowerDistance(segs, region, LOWER_PIXELS),
                                  region, TURN_DEPTH)  # fmt: skip
        a = np.pi * np.arange(DIAMETER_DIRECTIONS) / DIAMETER_DIRECTIONS
        self.dirs = np.column_stack([np.cos(a), np.sin(a)])
        b = 2 * np.pi * np.arange(EXTREME_DIRECTIONS) / EXTREME_DIRECTIONS
        self.extreme_dirs = np.column_stack([np.cos(b), np.sin(b)])
        #: Band points spread inside the section that each cell's turn test gets too.
        several = len(hole.decompose()) > 1
        self.inner = max(INNER_POINTS, SHEET_INNER_POINTS) if several else INNER_POINTS

    def run(self, pin, thickness: float, budget_s: float, min_angle: float = 2e-3):
        """Prove every direction excluded, or stop at the budget or at cells below ``min_angle``.

        Returns
        -------
        SectionOutcome
        """
        t0 = time.perf_counter()
        pin = np.asarray(pin, dtype=np.float64)
        v = self.candidates - pin
        lengths = np.linalg.norm(v, axis=1)
        band = 0.5 * float(thickness)
        if self.loops and self.chain is not None:
            self.link = link.Link(self.loops, pin, band, self.eta)
        level = sphere_roots()
        nodes = [Node() for _ in range(len(level))]
        out = SectionOutcome("undecided", pin, float(thickness), list(nodes))
        while len(level):
            out.depth += 1
            verdicts, done = self._level(level, v, lengths, band, t0, budget_s)
            split = []
            for i, (node, ev) in enumerate(zip(nodes, verdicts)):
                out.examined += 1
                if ev is not None:
                    node.evidence = ev
                    out.excluded += 1
                    out.points.update(_evidence_points(ev))
                elif 0.5 * float(np.max(level.hi[i] - level.lo[i])) > min_angle:
                    split.append(i)
            if not done and split:  # the budget ran out: what this level proved is kept
                break
            level, nodes = self._split(level, nodes, split)
        out.open_cells = sum(_count_open(n) for n in out.roots)
        out.status = "proved" if out.open_cells == 0 and len(level) == 0 else "undecided"
        out.seconds = time.perf_counter() - t0
        return out

    @staticmethod
    def _split(level: SphereCells, nodes: list, split: list):
        if not split:
            return level.take(np.zeros(0, dtype=np.int64)), []
        kids = level.take(np.asarray(split)).split()
        out = []
        for i in split:
            nodes[i].children = [Node() for _ in range(4)]
            out += nodes[i].children
        return kids, out

    def _level(self, level: SphereCells, v, lengths, band, t0, budget_s):
        """Evidence (or None) for every cell of a level, and whether the level was finished
        (False when the budget ran out: the cells not reached get None)."""
        centre, alpha = caps(level)
        out = []
        for s in range(0, len(level), CHUNK):
            if time.perf_counter() - t0 > budget_s:
                return out + [None] * (len(level) - len(out)), False
            sl = slice(s, s + CHUNK)
            out += self._chunk(Plane(centre[sl], alpha[sl], v, lengths, band, self.eta), t0,
                               budget_s)  # fmt: skip
        return out, time.perf_counter() - t0 <= budget_s

    def _chunk(self, plane: Plane, t0: float, budget_s: float) -> list:
        """Per cell of a chunk: the diameter test batched, the width test one by one, then the
        turn test batched over the cells left (:class:`~sieve_mi.certify.turns.TurnTest`)."""
        pair, gap = plane.widest(self.dirs)
        out, todo = [], []
        for c in range(len(plane.centre)):
            if gap[c] > self.diameter * (1 + RELATIVE_MARGIN) + self.eta:
                out.append({"kind": "diameter", "pair": pair[c].tolist()})
                continue
            if self.chain is None and time.perf_counter() - t0 > budget_s:
                out.append(None)
                continue
            pts, x, r = cell = plane.cell(c)
            out.append(None if self.chain is None else chain.evidence(self.chain, cell, pair[c]))
            if out[c] is None and self.link is not None:
                out[c] = self.link.evidence(self.chain, plane, c, cell, pair[c])
            if out[c] is not None or time.perf_counter() - t0 > budget_s:
                continue
            far = self.diameter if self.chain is None else min(self.diameter, self.chain.diameter)
            if gap[c] > far - 8.0 * float(r.max(initial=0.0)):
                continue  # nearly excluded by the diameter (or a chain): smaller cells will be
            out[c] = self._narrow(pts, x, r, plane.chord[c])
            if isinstance(out[c], tuple):
                todo.append(c)
        turns = self.turn_test.run([out[c][1] for c in todo], t0 + budget_s)
        for c, tree in zip(todo, turns):
            pts, slack = out[c][0]
            out[c] = None if tree is None else {"kind": "turns", "points": pts, "slack": slack,
                                                "turns": tree}  # fmt: skip
        return out

    def _narrow(self, pts, x, r, chord: float):
        """The width test on the cell's band points extreme along :data:`EXTREME_DIRECTIONS`
        directions (``pts`` their indices, ``x`` (k, 2), ``r`` (k,)): its evidence, or what the
        turn test needs: ((points, slack), (x, r + slack)); None with fewer than 2 points."""
        if len(pts) < 2:
            return None
        keep = np.unique((x @ self.extreme_dirs.T - r[:, None]).argmax(axis=0))
        w = min_width(x[keep]) - 2.0 * float(r[keep].max())
        if w > self.width * (1 + RELATIVE_MARGIN) + self.eta:
            return {"kind": "width", "points": pts[keep].tolist()}
        if self.inner > 0:  # band points inside the section's hull too: a non-convex H
            keep = np.concatenate([keep, spread(x, keep, self.inner)])
        pts, x, r = pts[keep], x[keep], r[keep]
        slack = self.kappa * self.radius * chord
        return (pts.tolist(), slack), (x, r + slack)


def _evidence_points(ev: dict) -> list:
    return ev["pair"] if ev["kind"] == "diameter" else ev["points"]


def _count_open(node: Node) -> int:
    if node.children:
        return sum(_count_open(c) for c in node.children)
    return int(node.evidence is None)


def pins(shape: Shape) -> list[np.ndarray]:
    """Points of the shape's convex hull to pin, best first: the centre of its frame (where the
    mesh is centred), the centroid of its convex hull, the centre of its inscribed ball; those
    outside the hull (up to rounding) or within 1 % of its radius of an earlier one are left out.

    Returns
    -------
    list of (3,) ndarray
        Centred frame, scene units.
    """
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(shape.hull)
    except (QhullError, ValueError):  # a flat shape: its centre only
        return [np.zeros(3)]
    found = [np.zeros(3), shape.hull[hull.vertices].mean(axis=0)]
    ball = bounds.inscribed_ball(shape)
    if ball is not None:
        found.append(np.asarray(ball[0], dtype=np.float64))
    out: list[np.ndarray] = []
    tol = 1e-9 * max(shape.radius, 1e-300)
    for p in found:
        inside = float((hull.equations[:, :3] @ p + hull.equations[:, 3]).max()) <= -tol
        fresh = all(np.linalg.norm(p - q) > 0.01 * shape.radius for q in out)
        if inside and fresh:
            out.append(p)
    return out or [np.zeros(3)]


def prove_section(shape: Shape, hole: manifold3d.CrossSection, thickness: float, budget_s: float,
                  settings) -> tuple[SectionOutcome, dict]:  # fmt: skip
    """The section proof at ``thickness`` (module docstring), over :func:`pins` in turn, each
    with an equal share of what is left of ``budget_s``.

    Parameters
    ----------
    shape : Shape
    hole : manifold3d.CrossSection
        The union of the plate's holes, scene units.
    thickness : float
        Scene units.
    budget_s : float
        Seconds for all pins together.
    settings : sieve_mi.certify.search.Settings
        ``edge_spacing``, ``max_candidates``, ``min_angle`` (floored at 1e-3 here) and
        ``kappa``.

    Returns
    -------
    (SectionOutcome, dict)
        The last outcome (the proved one, if any) and its certificate entry (see
        :mod:`sieve_mi.certify.certificate`).
    """
    from sieve_mi.certify.record import certificate_entry
    from sieve_mi.certify.search import candidate_points

    t0 = time.perf_counter()
    most = min(settings.max_candidates, SECTION_CANDIDATES)
    points, on_edge = candidate_points(
        shape, type(settings)(**{**settings.__dict__, "max_candidates": most}), "none"
    )
    search = SectionSearch(points, hole, shape.radius, settings.kappa)
    search.loops = link.find_loops(shape) if search.chain is not None else []
    todo = pins(shape)
    out = None
    for k, pin in enumerate(todo):
        left = budget_s - (time.perf_counter() - t0)
        if left <= 0:
            break
        out = search.run(pin, thickness, left / (len(todo) - k), max(settings.min_angle, 1e-3))
        if out.status == "proved":
            break
    if out is None:
        roots = [Node() for _ in FACES]  # the set-up used the budget: every face open
        out = SectionOutcome("undecided", todo[0], float(thickness), roots, open_cells=len(roots))
    out.seconds = time.perf_counter() - t0
    return out, certificate_entry(out, points, on_edge, settings.kappa, search.loops)
