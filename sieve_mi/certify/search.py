"""Branch and bound over rotation space: exclude cells, split the rest, or find a passage.

Level by level (breadth first): all cells of a level get the batched tests with the points they
inherited and their first-order displacement bounds (:func:`~sieve_mi.certify.cells.first_order`):
the width test (:func:`~sieve_mi.certify.bounds.width_test`, NumPy over cells x points x
directions), then a quadtree over translations on proved distance bounds
(:func:`~sieve_mi.certify.bounds.translation_quadtree`); each
survivor gets the exact polygon test with its own point set, which grows by the candidate point
(a vertex, or a point on a mesh edge: :func:`edge_points`) that sticks out furthest at the cell's
centre pose before the cell is split. A cell whose centre pose puts the exact silhouette inside H
is a passage and ends the search.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import manifold3d
import numpy as np

from sieve_mi.certify import bounds, cells, symmetry
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import placed_vertices, projection
from sieve_mi.geometry.rotations import from_matrix
from sieve_mi.settings import refuse_unknown, shown

__all__ = [
    "BATCH_MIN",
    "DistanceField",
    "EvenOdd",
    "LEVEL_CHUNK",
    "Node",
    "Outcome",
    "PASSAGE_PROBES",
    "CellSearch",
    "Settings",
    "count_open",
    "candidate_points",
    "farthest_points",
    "representative",
]


#: A level's batched quadtree test runs once the width test leaves at least this many cells.
BATCH_MIN = 256
#: Cells of a level whose batched tests run at once: the clock is read between such chunks, so
#: a deep level's tests do not run past the budget.
LEVEL_CHUNK = 4096
#: A candidate passage's points are tested inside H first at this many of them, those furthest
#: out by the distance grid (the same answer as testing all: all of them are tested if these are in).
PASSAGE_PROBES = 64


@dataclass
class Settings:
    """Search settings.

    Attributes
    ----------
    budget_s : float
        Wall-clock budget, seconds; cells left then are reported open (status "undecided").
    min_angle : float
        Cells whose covering angle (radians on S^3) falls below this are not split further.
    initial_points : int
        Hull vertices every cell starts with (farthest-point sampled, farthest from the centre
        first); also the points of the batched width pre-test.
    max_points : int
        Points a cell may use before it is split.
    directions : int
        Directions of the width pre-test.
    kappa : float
        Slack: every point's displacement bound is computed as if it were ``kappa`` times the
        shape's radius further from the centre, so an exclusion holds with room to spare, which
        the independent replay needs to confirm it on a finite translation grid.
    edge_spacing : float
        Points may also be taken on the mesh's edges, this fraction of the shape's radius apart
        (0: vertices only). A non-convex hole can hold every vertex while an edge crosses its
        boundary; an edge point then witnesses the exclusion. With a symmetry reduction, only on
        the edges the group maps onto edges (:func:`~sieve_mi.certify.symmetry.symmetric_edges`).
    max_candidates : int
        The spacing grows so that vertices and edge points number at most this many.
    bound : str
        ``"first-order"`` (default): each point's displacement bound over a cell is the smaller
        of the first-order one (:func:`~sieve_mi.certify.cells.first_order`) and the isotropic
        2 sin(theta) |p|; ``"isotropic"``: the latter only (certificates before the first-order
        bound).
    """

    budget_s: float = 30.0
    min_angle: float = 1e-4
    initial_points: int = 8
    max_points: int = 24
    directions: int = 36
    kappa: float = 0.02
    edge_spacing: float = 0.01
    max_candidates: int = 60_000
    bound: str = "first-order"

    def __post_init__(self):
        """Refuse a value the search cannot use, in one line naming the setting."""
        for name, (low, inclusive, whole) in _LOWEST.items():
            value = getattr(self, name)
            if not _at_least(value, low, inclusive, whole):
                kind = "a whole number" if whole else "a number"
                raise SieveError(f"certify settings: {name}: expected {kind} "
                                 f"{'>=' if inclusive else '>'} {low}, got {shown(value)}")  # fmt: skip

    def __setattr__(self, name, value):
        refuse_unknown(Settings, name, "certify settings")  # a typo is not kept silently
        object.__setattr__(self, name, value)


#: Each numeric :class:`Settings` field: its lowest value, whether that is allowed, whether the
#: value is a whole number.
_LOWEST = {
    "budget_s": (0, False, False),
    "min_angle": (0, False, False),
    "initial_points": (1, True, True),
    "max_points": (1, True, True),
    "directions": (1, True, True),
    "kappa": (0, True, False),
    "edge_spacing": (0, True, False),
    "max_candidates": (1, True, True),
}


def _at_least(value, low: float, inclusive: bool, whole: bool) -> bool:
    """Whether ``value`` is a finite number (whole where ``whole``) above ``low`` (or at it)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or abs(value) > 1e300:
        return False
    if isinstance(value, float) and not (
        math.isfinite(value) and (value.is_integer() or not whole)
    ):
        return False
    return value >= low if inclusive else value > low


@dataclass
class Node:
    """A cell of the search tree: a leaf with evidence, a split cell with 8 children, or open."""

    face: int
    lo: np.ndarray
    hi: np.ndarray
    evidence: dict | None = None
    children: list | None = None


@dataclass
class Outcome:
    """What the branch and bound found."""

    roots: list
    passage: dict | None = None
    examined: int = 0
    excluded: int = 0
    open_cells: int = 0
    excluded_volume: float = 0.0
    depth: int = 0
    points: set = field(default_factory=set)
    candidates: np.ndarray | None = None
    on_edge: dict = field(default_factory=dict)


def edge_points(
    shape: Shape, edges: np.ndarray, spacing: float, most: int
) -> tuple[np.ndarray, np.ndarray]:
    """Points on the mesh's edges, at most ``spacing`` apart along each edge (ends excluded).

    Parameters
    ----------
    shape : Shape
    edges : (k, 2) int ndarray
        Vertex index pairs (i < j) of the edges to sample.
    spacing : float
        Scene units; grown until at most ``most`` points result.
    most : int

    Returns
    -------
    points : (n, 3) ndarray
        ``v_i + lam (v_j - v_i)``, scene units.
    refs : (n, 3) ndarray
        ``i, j, lam`` per point (i < j index ``shape.vertices``; 0 < lam < 1).
    """
    a, b = shape.vertices[edges[:, 0]], shape.vertices[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    total = float(length.sum())
    spacing = max(spacing, total / max(most, 1), 1e-300)
    k = np.floor(length / spacing).astype(np.int64)
    if k.sum() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    e = np.repeat(np.arange(len(edges)), k)
    m = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k) + 1
    lam = m / (k[e] + 1.0)
    pts = a[e] + lam[:, None] * (b[e] - a[e])
    return pts, np.column_stack([edges[e], lam])


def candidate_points(shape: Shape, settings: Settings, group: str) -> tuple[np.ndarray, dict]:
    """The points evidence may use: the vertices, then edge points (on the edges the symmetry
    group ``group`` maps onto edges, :data:`Settings.edge_spacing` apart, at most
    ``max_candidates`` in all); and ``{index: [i, j, lam]}`` for the edge points.

    Returns
    -------
    points : (k, 3) ndarray
        Centred frame, scene units.
    on_edge : dict
    """
    vertices = shape.vertices[np.unique(shape.faces)]
    if settings.edge_spacing <= 0:
        return vertices, {}
    edges = symmetry.symmetric_edges(shape, group)
    most = max(0, settings.max_candidates - len(vertices))
    pts, refs = edge_points(shape, edges, settings.edge_spacing * shape.radius, most)
    refs = {len(vertices) + k: [int(r[0]), int(r[1]), float(r[2])] for k, r in enumerate(refs)}
    return np.concatenate([vertices, pts]), refs


def farthest_points(vertices: np.ndarray, hull_idx: np.ndarray, count: int) -> list[int]:
    """``count`` hull vertex indices by farthest-point sampling, the farthest from the centre first."""
    pts = vertices[hull_idx]
    chosen = [int(np.argmax(np.linalg.norm(pts, axis=1)))]
    d = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    while len(chosen) < min(count, len(pts)):
        j = int(np.argmax(d))
        chosen.append(j)
        d = np.minimum(d, np.linalg.norm(pts - pts[j], axis=1))
    return [int(hull_idx[j]) for j in chosen]


def representative(section: manifold3d.CrossSection) -> np.ndarray:
    """A translation in ``section``: the centroid of its contour of largest area (a heuristic
    choice; a vertex of that contour when the centroid is degenerate)."""
    best, best_area = None, -np.inf
    for contour in section.to_polygons():
        c = np.asarray(contour, dtype=np.float64)
        nxt = np.concatenate([c[1:], c[:1]])  # each vertex's successor, in one copy
        x, y, xn, yn = c[:, 0], c[:, 1], nxt[:, 0], nxt[:, 1]
        cross = x * yn - xn * y
        area = 0.5 * cross.sum()
        if area > best_area:
            best, best_area = (c, x, y, xn, yn, cross), area
    if best is None:
        return np.zeros(2)
    c, x, y, xn, yn, cross = best
    if abs(best_area) < 1e-300:
        return c.mean(axis=0)
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * best_area)


class EvenOdd:
    """H as a point set, filled even-odd over its contours: fast point-in-polygon for the search.

    Each contour is a prepared shapely polygon; a point is inside H when an odd number of them
    contain it (GEOS's exact predicates; a point on a contour counts as outside it). Its users
    need exactness away from the outline only: the heuristics, and
    :class:`~sieve_mi.certify.bounds.LowerDistance`, whose nodes on or near the outline get a bound
    of about 0 either way.

    Parameters
    ----------
    contours : list of (n, 2) ndarrays
        H's contours (any orientation), scene units; those of fewer than 3 points bound nothing.

    Examples
    --------
    >>> import numpy as np
    >>> outer = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    >>> region = EvenOdd([outer, 1.0 + 0.5 * outer])  # a 4 mm square with a 2 mm square hole
    >>> region.contains_points(np.array([[0.5, 0.5], [2.0, 2.0], [5.0, 1.0]])).tolist()
    [True, False, False]
    """

    def __init__(self, contours: list[np.ndarray]):
        import shapely

        self.rings = [
            shapely.Polygon(np.asarray(c, dtype=np.float64)) for c in contours if len(c) >= 3
        ]
        for ring in self.rings:
            shapely.prepare(ring)

    def contains_points(self, points: np.ndarray) -> np.ndarray:
        """(P,) bool: whether each of the points (P, 2) lies inside H."""
        import shapely

        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        inside = np.zeros(len(points), dtype=bool)
        for ring in self.rings:
            inside ^= shapely.contains_xy(ring, points[:, 0], points[:, 1])
        return inside


class DistanceField:
    """H's signed distance on a pixel grid, for the heuristics (which point to add, where to look).

    Never used for an exclusion: it is off by up to about a pixel (1/1000 of the grid's size).

    Parameters
    ----------
    region : EvenOdd
        H.
    segs : (m, 2, 2) ndarray
        H's edges.
    pad : float
        Margin around H's bounding box, scene units; points beyond it read the border's value.
    """

    def __init__(self, region, segs: np.ndarray, pad: float, pixels: int = 1000):
        from scipy.ndimage import distance_transform_edt

        lo = segs.reshape(-1, 2).min(0) - pad
        hi = segs.reshape(-1, 2).max(0) + pad
        self.lo, self.pitch = lo, float(max(hi - lo)) / pixels
        n = np.ceil((hi - lo) / self.pitch).astype(int) + 1
        gx, gy = np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij")
        centres = lo + self.pitch * np.column_stack([gx.ravel(), gy.ravel()])
        inside = region.contains_points(centres).reshape(n)
        self.grid = self.pitch * (distance_transform_edt(~inside) - distance_transform_edt(inside))
        self.top = n - 1
        self.flat = self.grid.ravel()
        self._origin, self._inv = self.lo - 0.5 * self.pitch, 1.0 / self.pitch

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """(P,) approximate signed distances (positive outside H) at points (P, 2), scene units."""
        ij = ((xy - self._origin) * self._inv).astype(np.intp)
        # np.minimum / np.maximum per column: the same cells as np.clip, at two thirds of the cost
        i = np.minimum(np.maximum(ij[:, 0], 0), self.top[0])
        j = np.minimum(np.maximum(ij[:, 1], 0), self.top[1])
        return self.flat[i * (self.top[1] + 1) + j]


def _none(level: cells.Cells) -> cells.Cells:
    """No cells (``level``'s arrays, emptied)."""
    return cells.Cells(level.face[:0], level.lo[:0], level.hi[:0])


def count_open(node: Node) -> int:
    """Leaves of the subtree without evidence (not excluded)."""
    if node.children:
        return sum(count_open(c) for c in node.children)
    return int(node.evidence is None)


class CellSearch:
    """One branch and bound of ``shape`` against the hole ``hole`` (one CrossSection, scene units)."""

    def __init__(self, shape: Shape, hole: manifold3d.CrossSection, settings: Settings, group: str):
        self.shape, self.hole, self.settings = shape, hole, settings
        self.vertices, self.on_edge = candidate_points(shape, settings, group)
        self.lengths = np.linalg.norm(self.vertices, axis=1)
        self.segs = bounds.contour_segments([np.asarray(c) for c in hole.to_polygons()])
        scale = float(np.abs(self.segs).max())
        self.eta = 1e-6 * max(scale, shape.radius)
        self.cache = bounds.OffsetCache(hole, self.eta, r_min=self.eta)
        self.dirs = bounds.directions(settings.directions)
        hv = self.segs[:, 0] @ self.dirs.T
        self.support = np.stack([hv.max(axis=0), hv.min(axis=0)])
        hull_idx = self._hull_indices()
        self.start = farthest_points(self.vertices, hull_idx, settings.initial_points)
        self.group = group
        self.region = EvenOdd([np.asarray(c) for c in hole.to_polygons()])
        self.field = DistanceField(self.region, self.segs, 2.0 * shape.radius)
        self.lower: bounds.LowerDistance | None = None
        #: The clock the budget is read on (seconds; a test may put a fake one here).
        self.clock = time.perf_counter

    def _hull_indices(self) -> np.ndarray:
        hull = {tuple(p) for p in self.shape.hull}
        idx = [i for i, p in enumerate(self.vertices) if tuple(p) in hull]
        return np.asarray(idx if idx else range(len(self.vertices)), dtype=np.int64)

    def radii(self, fr: cells.Frames, theta: np.ndarray, points: np.ndarray):
        """Projections at the cells' centres and the points' displacement bounds with margins.

        The bound is the smaller of the first-order one (:func:`~sieve_mi.certify.cells.first_order`)
        and the isotropic 2 sin(theta) |p|, plus the slack of :class:`Settings` ``kappa`` (the
        isotropic bound of a point ``kappa`` R_B from the centre) and ``eta``.

        Parameters
        ----------
        fr : Frames
            n cells.
        theta : (n,) ndarray
            Their covering angles, radians.
        points : (k, 3) or (n, k, 3) ndarray
            Scene units.

        Returns
        -------
        proj : (n, k, 2) ndarray
        radii : (n, k) ndarray
            Scene units.
        """
        proj, bound = cells.first_order(fr, points)
        iso = 2.0 * np.sin(theta)[:, None] * np.linalg.norm(points, axis=-1)
        if self.settings.bound == "first-order":
            iso = np.minimum(bound, iso)
        slack = 2.0 * np.sin(theta)[:, None] * self.settings.kappa * self.shape.radius
        return proj, iso + slack + self.eta

    def run(self, roots: cells.Cells, started: float | None = None) -> Outcome:
        """Branch and bound from ``roots`` until every cell is decided, a passage or the budget
        (``budget_s`` counted from ``started``, a :attr:`clock` value; default now)."""
        t0 = self.clock() if started is None else started
        nodes = [Node(int(f), lo, hi) for f, lo, hi in zip(roots.face, roots.lo, roots.hi)]
        out = Outcome(roots=nodes, points=set(self.start), candidates=self.vertices)
        out.on_edge = self.on_edge
        level, points = roots, [list(self.start) for _ in nodes]
        while len(level) and out.passage is None:
            out.depth += 1
            level, nodes, points = self._level(level, nodes, points, out, t0)
        out.open_cells = sum(count_open(n) for n in out.roots)
        return out

    def _level(self, level, nodes, points, out: Outcome, t0: float):
        """Decide or split every cell of one level, :data:`LEVEL_CHUNK` cells' batched tests at a
        time; returns the next level's cells (none once a passage is found or the clock passed
        the budget: the clock is read before every chunk's batched tests and every cell)."""
        theta = cells.covering_angles(level)
        fr = cells.frames(level)
        batched = len(level) > LEVEL_CHUNK  # every chunk of a large level gets the quadtree
        split = ([], [])
        for s in range(0, len(nodes), LEVEL_CHUNK):
            if out.passage is not None or self._late(t0):
                return _none(level), [], []
            sl = slice(s, s + LEVEL_CHUNK)
            excluded, direction, boxed = self._pretest(fr.take(sl), theta[sl], points[sl], batched)
            for k in range(len(excluded)):
                i = s + k
                if out.passage is not None or self._late(t0):
                    return _none(level), [], []
                out.examined += 1
                if excluded[k]:
                    ev = {
                        "kind": "width",
                        "direction": int(direction[k]),
                        "points": list(points[i]),
                    }
                elif boxed[k]:
                    ev = {"kind": "translations", "points": list(points[i])}
                elif (ev := self._exact(fr.take([i]), theta[i : i + 1], points[i], out)) is None:
                    continue
                elif isinstance(ev, list):
                    split[0].append(i)
                    split[1].append(ev)
                    continue
                nodes[i].evidence = ev
                out.excluded += 1
                out.excluded_volume += float(cells.volumes(level.take([i]))[0])
                out.points.update(ev["points"])
        return self._split(level, nodes, split[0], split[1])

    def _late(self, t0: float) -> bool:
        """Whether the clock (:attr:`clock`) passed the budget counted from ``t0``."""
        return self.clock() - t0 > self.settings.budget_s

    def _exact(self, fr: cells.Frames, theta: np.ndarray, points: list, out: Outcome):
        """One cell's exact test (:meth:`_examine`): its evidence when excluded, the points to
        split it with (a list), or None (a passage, or a cell below ``min_angle``: left open)."""
        verdict, pts = self._examine(fr, theta, self._inherited(points), out)
        if verdict == "excluded":
            return {"kind": "translations", "points": pts}
        if verdict == "passage" or theta[0] < self.settings.min_angle:
            return None
        return pts

    def _split(self, level, nodes, split_idx, split_pts):
        parents = level.take(np.asarray(split_idx, dtype=np.int64))
        children = cells.split(parents)
        next_nodes, next_pts = [], []
        for k, i in enumerate(split_idx):
            kids = [
                Node(int(children.face[8 * k + c]), children.lo[8 * k + c], children.hi[8 * k + c])
                for c in range(8)
            ]
            nodes[i].children = kids
            next_nodes += kids
            next_pts += [list(split_pts[k])] * 8
        return children, next_nodes, next_pts

    def _inherited(self, pts: list) -> list:
        """The points a child cell starts with: the starting points and the parent's latest
        additions, leaving room for the child to add its own (``max_points`` in all)."""
        start = list(self.start)
        room = max(0, self.settings.max_points // 2 - len(start))
        added = [p for p in pts if p not in start]
        return start + (added[-room:] if room else [])

    def _pretest(self, fr: cells.Frames, theta: np.ndarray, points: list, batched: bool = False):
        """The batched tests of a chunk of a level's cells, each with the points it inherited:
        the width test, then, on the cells it leaves, the quadtree over translations on H's lower
        distance grid (built once at least :data:`BATCH_MIN` cells are left, or any are in a
        ``batched`` chunk).

        Returns the width test's ``(excluded, direction)`` and the cells the quadtree excluded.
        """
        most = max(len(p) for p in points)
        idx = np.array([p + [p[0]] * (most - len(p)) for p in points], dtype=np.int64)
        parts = [
            self.radii(
                fr.take(slice(s, s + 16384)),
                theta[s : s + 16384],
                self.vertices[idx[s : s + 16384]],
            )
            for s in range(0, len(idx), 16384)
        ]
        proj = np.concatenate([p for p, _ in parts])
        radii = np.concatenate([r for _, r in parts])
        excluded, direction = bounds.width_test(proj, radii, self.support, self.dirs, self.eta)
        boxed = np.zeros(len(excluded), dtype=bool)
        rest = np.flatnonzero(~excluded)
        if len(rest) >= BATCH_MIN or (batched and len(rest)):
            if self.lower is None:
                self.lower = bounds.LowerDistance(self.segs, self.region)
            boxed[rest] = bounds.translation_quadtree(self.lower, proj[rest], radii[rest])
        return excluded, direction, boxed

    def _examine(self, fr: cells.Frames, theta: np.ndarray, pts: list, out: Outcome):
        """The exact test of one cell, adding points while they help; ``(verdict, points)``.

        The point search ranks the candidates by an estimate of their bounds: the isotropic
        bound scaled by the largest first-order / isotropic ratio among the cell's points (one
        NumPy pass; any choice of points is sound). A chosen point gets its exact bound."""
        proj, radii = self.radii(fr, theta, self.vertices[pts])
        left = bounds.translations_left(self.cache, proj[0], radii[0])
        if left.is_empty():
            return "excluded", pts
        chord = 2.0 * float(np.sin(theta[0]))
        floor = chord * self.settings.kappa * self.shape.radius + self.eta
        ratio = float(np.max((radii[0] - floor) / np.maximum(chord * self.lengths[pts], 1e-300)))
        allowance = (min(ratio, 1.0) * chord) * self.lengths + floor
        proj_all = self.vertices @ fr.rot[0, :2].T
        while True:
            j = self._worst(proj_all + representative(left), allowance)
            if j is None or j in pts or len(pts) >= self.settings.max_points:
                break
            pts.append(j)
            _, r = self.radii(fr, theta, self.vertices[[j]])
            left = left ^ bounds.translations_left(self.cache, proj_all[[j]], r[0])
            if left.is_empty():
                return "excluded", pts
        if j is None and self._passage(fr.rot[0], proj_all, pts, out):
            return "passage", pts
        return "split", pts

    def _worst(self, placed: np.ndarray, allowance: np.ndarray) -> int | None:
        """The candidate furthest outside H beyond its allowance at these placed positions (a
        heuristic: H's distance grid), or None when every one is within it."""
        excess = self.field(placed) - allowance
        k = int(np.argmax(excess))
        return k if excess[k] > 0 else None

    def _passage(self, rot: np.ndarray, proj_all: np.ndarray, pts: list, out: Outcome) -> bool:
        """Whether the centre pose fits: all vertices inside at a candidate t, then the silhouette."""
        parts = [self.hole.translate((-float(x), -float(y))) for x, y in proj_all[pts]]
        left = manifold3d.CrossSection.batch_boolean(parts, manifold3d.OpType.Intersect)
        if left.is_empty():
            return False
        t = representative(left)
        placed = proj_all + t
        # the points furthest out by the distance grid first: one of them usually settles it
        few = min(PASSAGE_PROBES, len(placed))
        probes = np.argpartition(-self.field(placed), few - 1)[:few]
        if not self.region.contains_points(placed[probes]).all():
            return False
        if not self.region.contains_points(placed).all():
            return False
        quat = from_matrix(rot)
        sil = projection(placed_vertices(self.shape, quat, t), self.shape.faces)
        if (sil - self.hole).area() > 1e-12 * max(sil.area(), 1e-300):
            return False
        out.passage = {"quaternion": quat.tolist(), "translation": t.tolist()}
        return True
