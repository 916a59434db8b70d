"""Exclusion tests: rigorous reasons why no pose in a set of rotations lets the shape through H.

All tests err towards "not excluded"; the margins are stated where they are added (see
docs/certify.md for the full argument).

* :func:`inscribed_ball` and :func:`no_disk_fits`: a ball of radius rho inside the (closed) shape
  projects to a disk of radius rho in every rotation; if no such disk fits in H, no rotation
  passes (a root-level proof).
* :func:`width_test`: a batched pre-test for many cells at once: the points' dilated extent along a
  direction exceeds the width of H's convex hull along it.
* :class:`LowerDistance` and :func:`translation_quadtree`: a batched test of many cells at once on
  a grid of proved lower bounds of the distance to H: a quadtree over translations that must
  discard every box (non-convex H too).
* :class:`OffsetCache` and :func:`translations_left`: the exact test of a cell, the intersection over
  the points of (H grown by each point's displacement bound) shifted by the point's projection.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.solid import triangle_distance, winding_numbers

__all__ = [
    "LowerDistance",
    "OffsetCache",
    "RADIUS_STEP",
    "ROUND_SEGMENTS",
    "boundary_distance",
    "contour_segments",
    "directions",
    "inscribed_ball",
    "inside",
    "no_disk_fits",
    "translation_quadtree",
    "translations_left",
    "width_test",
]

#: Segments per full circle of the round joins of H's offsets (chords within 0.5 % of the radius).
ROUND_SEGMENTS = 32
#: Growth factor of the radius grid offsets are rounded up to (one cached offset per grid value).
RADIUS_STEP = 1.02


# ------------------------------------------------------------------------------------------------
# Polygon distances (the search's own; the replay has an independent implementation)
# ------------------------------------------------------------------------------------------------


def contour_segments(contours: list[np.ndarray]) -> np.ndarray:
    """All edges of closed contours as an (m, 2, 2) array of (start, end) points."""
    segs = [np.stack([c, np.roll(c, -1, axis=0)], axis=1) for c in contours if len(c) >= 2]
    return np.concatenate(segs) if segs else np.zeros((0, 2, 2))


def boundary_distance(points: np.ndarray, segs: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Exact Euclidean distance from each point to the nearest segment, (n,).

    Parameters
    ----------
    points : (n, 2) ndarray
    segs : (m, 2, 2) ndarray
    """
    a, d = segs[:, 0], segs[:, 1] - segs[:, 0]
    dd = np.maximum((d * d).sum(1), 1e-300)
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk, None, :] - a[None]
        u = np.clip((p * d[None]).sum(-1) / dd[None], 0.0, 1.0)
        r = p - u[..., None] * d[None]
        out[s : s + chunk] = np.sqrt((r * r).sum(-1).min(axis=1))
    return out


def inside(points: np.ndarray, segs: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Even-odd point-in-polygon over all segments (crossings of a ray towards +x), (n,) bool."""
    a, b = segs[:, 0], segs[:, 1]
    out = np.empty(len(points), dtype=bool)
    for s in range(0, len(points), chunk):
        x, y = points[s : s + chunk, 0:1], points[s : s + chunk, 1:2]
        straddle = (a[None, :, 1] > y) != (b[None, :, 1] > y)
        dy = np.where(straddle, b[None, :, 1] - a[None, :, 1], 1.0)
        xc = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy
        out[s : s + chunk] = (straddle & (xc > x)).sum(axis=1) % 2 == 1
    return out


# ------------------------------------------------------------------------------------------------
# Root level: a ball inside the shape against the largest disk inside H
# ------------------------------------------------------------------------------------------------


#: Surface samples (besides vertices and face centres) that rank candidate centres.
BALL_SAMPLES = 2048
#: Exact distance evaluations of the compass search that moves the best centre uphill.
BALL_CLIMB = 400
_BALLS: dict = {}


def inscribed_ball(shape: Shape, grid: int = 12, exact: int = 4) -> tuple[np.ndarray, float] | None:
    """A ball (centre, radius) inside the solid bounded by the shape, or None.

    Only for closed meshes (every edge shared by exactly two triangles, consistently oriented):
    then the winding number is constant off the surface, a point with winding number != 0 is
    enclosed, and every line through it meets the surface. Candidate centres are the shape's
    centre and a ``grid`` x ``grid`` x ``grid`` lattice over its bounding box, ranked by their
    distance to the nearest vertex, face centre or surface sample (a k-d tree, only to choose);
    the ``exact`` best inside ones (winding test; a candidate that a parity count of crossings
    puts outside is not tested, :func:`_parity_inside`) get the exact distance to the nearest
    triangle.
    The best then climbs the exact distance by a compass search (:data:`BALL_CLIMB` evaluations),
    so a ball between lattice points is found to within a small fraction of its radius. The
    radius is the exact distance at the final centre (checked inside again) lowered by a relative
    1e-9 for rounding, so the ball is rigorous whichever centre is chosen (a CAD part's
    bounding-box centre may lie in a notch). Answers are kept per mesh (its bytes); a
    dumbbell's balls, missed by the lattice, are found by the climb (tests/certify/test_ball.py).
    """
    import hashlib

    v, f = np.ascontiguousarray(shape.vertices), np.ascontiguousarray(shape.faces)
    key = (hashlib.blake2b(v.tobytes() + f.tobytes(), digest_size=16).digest(), grid, exact)
    if key not in _BALLS:
        if len(_BALLS) > 64:
            _BALLS.clear()
        _BALLS[key] = _inscribed(shape, grid, exact)
    found = _BALLS[key]
    return None if found is None else (found[0].copy(), found[1])


def _inscribed(shape: Shape, grid: int, exact: int) -> tuple[np.ndarray, float] | None:
    """:func:`inscribed_ball`, computed."""
    import trimesh
    from scipy.spatial import cKDTree

    mesh = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    if not (mesh.is_watertight and mesh.is_winding_consistent):
        return None
    tri = shape.vertices[shape.faces]
    lo, hi = shape.vertices.min(0), shape.vertices.max(0)
    axes = [lo[i] + (hi[i] - lo[i]) * (np.arange(grid) + 0.5) / grid for i in range(3)]
    lattice = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    candidates = np.vstack([np.zeros((1, 3)), lattice])
    samples = trimesh.sample.sample_surface(mesh, BALL_SAMPLES, seed=0)[0]
    near = cKDTree(np.vstack([shape.vertices, tri.mean(1), samples])).query(candidates)[0]
    maybe = np.concatenate([[True], _parity_inside(axes, tri)])
    best = None
    tried = 0
    for k in np.concatenate([[0], 1 + np.argsort(-near[1:], kind="stable")]):
        if tried >= exact:
            break
        if not maybe[k]:
            continue  # outside by the parity filter: not tried (the winding number decides)
        centre = candidates[k]
        enclosed = abs(round(winding_numbers(centre[None], tri)[0])) >= 1
        if k and not enclosed:
            continue  # outside: not a candidate (only inside points count towards ``exact``)
        tried += 1
        rho = float(triangle_distance(centre, tri).min())
        if rho <= 1e-9 * shape.radius or not enclosed:
            continue
        if best is None or rho > best[1]:
            best = (np.array(centre, dtype=np.float64), rho)
    if best is None:
        return None
    best = _climb(best, tri, float(np.max(hi - lo)) / grid)
    return best[0], best[1] * (1.0 - 1e-9)


def _parity_inside(axes: list[np.ndarray], tri: np.ndarray) -> np.ndarray:
    """Which points of the lattice ``axes`` (x, y, z values; ``meshgrid`` "ij" order, flattened)
    the triangles ``tri`` (F, 3, 3) enclose, by the parity of the crossings of the line parallel
    to z through each (x, y) below each point, (N,) bool; every point of a line that touches an
    edge or a vertex is kept. Only a filter (rounding may miscount a crossing): a point it keeps
    is tested by its winding number."""
    xs, ys, zs = axes
    px, py = (g.ravel()[:, None] for g in np.meshgrid(xs, ys, indexing="ij"))  # (C, 1)
    a, b, c = (tri[None, :, i] for i in range(3))  # (1, F, 3)

    def edge(u, v):  # z of (v - u) x (p - u): which side of the edge u -> v the line passes
        du, dv = px - u[..., 0], py - u[..., 1]
        return (v[..., 0] - u[..., 0]) * dv - (v[..., 1] - u[..., 1]) * du

    e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
    hit = ((e0 > 0) & (e1 > 0) & (e2 > 0)) | ((e0 < 0) & (e1 < 0) & (e2 < 0))
    touch = ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
    unsure = (touch & ~hit).any(axis=1)  # a line through an edge or vertex: its points all kept
    col, face = np.nonzero(hit)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[face]
    o = tri[face, 0]
    z = o[:, 2] - (n[:, 0] * (px[col, 0] - o[:, 0]) + n[:, 1] * (py[col, 0] - o[:, 1])) / n[:, 2]
    below = np.zeros((len(px), len(zs) + 1), dtype=np.int64)
    # a crossing at z lies below zs[i] for i >= searchsorted(zs, z, "right")
    np.add.at(below, (col, np.searchsorted(zs, z, side="right")), 1)
    odd = np.cumsum(below, axis=1)[:, : len(zs)] % 2 == 1
    return (odd | unsure[:, None]).ravel()


def _climb(start: tuple[np.ndarray, float], tri: np.ndarray, step: float):
    """Compass search from ``start`` (centre, exact distance) for a larger exact distance to the
    triangles ``tri`` (F, 3, 3), first step ``step``, over the 26 lattice directions at once; a
    move is kept only where the centre stays enclosed (winding number), so the result is a ball
    inside the solid. A move must gain a relative 1e-6: on a plateau (a coin's mid-plane) the
    centre stays where it is (the section proofs pin it). Each round tests only the triangles
    that can be nearest to a moved centre: the distance is 1-Lipschitz, so none is nearer than
    rho + step, and a triangle whose bounding sphere is further than that from every move
    (rho + 2 step from the centre) is skipped."""
    centre, rho = start
    moves = np.array([m for m in np.ndindex(3, 3, 3) if m != (1, 1, 1)], dtype=np.float64) - 1.0
    moves /= np.linalg.norm(moves, axis=1, keepdims=True)  # the 26 lattice directions
    mid = tri.mean(axis=1)
    reach = np.linalg.norm(tri - mid[:, None, :], axis=2).max(axis=1)
    evaluations = 0
    while evaluations < BALL_CLIMB and step > 1e-3 * rho:
        near = tri[np.linalg.norm(mid - centre, axis=1) - reach <= rho + 2.0 * step]
        pts = centre + step * moves
        d = triangle_distance(pts, near).min(axis=1)
        evaluations += len(pts)
        k = int(np.argmax(d))
        if d[k] > rho * (1.0 + 1e-6) and abs(round(winding_numbers(pts[k][None], tri)[0])) >= 1:
            centre, rho = pts[k], float(d[k])
        else:
            step *= 0.5
    return centre, rho


def no_disk_fits(segs: np.ndarray, rho: float, *, max_boxes: int = 200_000) -> bool:
    """True if no disk of radius ``rho`` fits inside the polygon with edges ``segs`` (proved).

    Branch and bound over square boxes covering the polygon's bounding box: a box of centre c and
    half-diagonal e holds no centre of such a disk if d(c, boundary) + e < rho (the distance to the
    boundary is 1-Lipschitz) or if c is outside and d(c, boundary) > e (the box lies outside). A
    centre inside with d >= rho is a disk that fits: False. Boxes are refined until decided.
    """
    lo, hi = segs.reshape(-1, 2).min(0), segs.reshape(-1, 2).max(0)
    half = 0.5 * float(np.max(hi - lo))
    c = (0.5 * (lo + hi))[None, :]
    margin = 1e-9 * max(half, rho)
    while len(c):
        if len(c) > max_boxes:
            return False
        e = half * math.sqrt(2.0)
        d = boundary_distance(c, segs)
        ins = inside(c, segs)
        if np.any(ins & (d >= rho)):
            return False
        keep = ~((d + e < rho - margin) | (~ins & (d > e + margin)))
        c, half = c[keep], 0.5 * half
        offs = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]]) * half
        c = (c[:, None, :] + offs[None]).reshape(-1, 2)
    return True


# ------------------------------------------------------------------------------------------------
# Batched pre-test: widths along fixed directions
# ------------------------------------------------------------------------------------------------


def directions(count: int) -> np.ndarray:
    """``count`` unit directions evenly spread over a half circle, (count, 2)."""
    a = np.pi * np.arange(count) / count
    return np.column_stack([np.cos(a), np.sin(a)])


def width_test(
    proj: np.ndarray, radii: np.ndarray, support: np.ndarray, dirs: np.ndarray, eta: float
) -> tuple[np.ndarray, np.ndarray]:
    """Cells whose points cannot all fit along some direction, for all cells at once.

    If pi_i + t lies in H + disk(r_i) for every point i, then along a unit direction u,
    max_i (u . pi_i - r_i) - min_i (u . pi_i + r_i) <= width of hull(H) along u. A cell where
    this fails by more than ``eta`` for some u is excluded.

    Parameters
    ----------
    proj : (n, k, 2) ndarray
        The points projected at each cell's centre rotation.
    radii : (n, k) ndarray
        Their displacement bounds.
    support : (2, M) ndarray
        max and min of u . x over H's vertices, per direction.
    dirs : (M, 2) ndarray
    eta : float
        Margin, scene units.

    Returns
    -------
    excluded : (n,) bool ndarray
    direction : (n,) int ndarray
        The direction that excludes each excluded cell (-1 otherwise).
    """
    spread = np.empty((len(proj), len(dirs)))
    for s in range(0, len(proj), 4096):  # (4096, k, M) at a time
        dots = proj[s : s + 4096] @ dirs.T
        r = radii[s : s + 4096, :, None]
        spread[s : s + 4096] = (dots - r).max(axis=1) - (dots + r).min(axis=1)
    excess = spread - (support[0] - support[1])[None, :] - eta
    best = excess.argmax(axis=1)
    excluded = excess[np.arange(len(best)), best] > 0
    return excluded, np.where(excluded, best, -1)


# ------------------------------------------------------------------------------------------------
# Batched test: a quadtree over translations on proved lower bounds of the distance to H
# ------------------------------------------------------------------------------------------------


class LowerDistance:
    """Proved lower bounds of the distance to H (0 inside) at any point, from a grid.

    At every grid node g (``pixels`` across H's bounding box and a 5 % margin): 0 if g is
    inside H (even-odd), else the distance to the nearest of boundary samples at most s apart
    along every edge (both ends included), less s / 2: every boundary point has a sample within
    s / 2, so this is at most the distance to the boundary, which outside H is the distance to H.
    A point x reads its nearest node g: d(x, H) >= d(g, H) - |x - g| (1-Lipschitz), and also
    d(x, H) >= the distance from x to H's bounding box; the larger of the two (each lowered by a
    relative 1e-12 for rounding).

    Parameters
    ----------
    segs : (m, 2, 2) ndarray
        H's edges.
    region : object with ``contains_points((P, 2)) -> (P,) bool``
        H, even-odd (:class:`~sieve_mi.certify.search.EvenOdd`).
    pixels : int
        Nodes across the longer side.
    """

    def __init__(self, segs: np.ndarray, region, pixels: int = 600):
        from scipy.spatial import cKDTree

        self.hlo, self.hhi = segs.reshape(-1, 2).min(0), segs.reshape(-1, 2).max(0)
        size = float(np.max(self.hhi - self.hlo))
        self.lo = self.hlo - 0.05 * size
        self.pitch = 1.1 * size / pixels
        n = np.ceil((self.hhi + 0.05 * size - self.lo) / self.pitch).astype(np.int64) + 1
        gx, gy = np.meshgrid(np.arange(n[0]), np.arange(n[1]), indexing="ij")
        nodes = self.lo + self.pitch * np.column_stack([gx.ravel(), gy.ravel()])
        inside = region.contains_points(nodes)
        spacing = 0.5 * self.pitch
        a, d = segs[:, 0], segs[:, 1] - segs[:, 0]
        k = np.ceil(np.linalg.norm(d, axis=1) / spacing).astype(np.int64) + 1
        u = np.concatenate([np.linspace(0.0, 1.0, j) for j in k])
        seg = np.repeat(np.arange(len(k)), k)
        samples = a[seg] + u[:, None] * d[seg]
        lower = np.zeros(len(nodes))
        near = cKDTree(samples).query(nodes[~inside])[0]
        lower[~inside] = np.maximum(0.0, near - 0.5 * spacing * (1 + 1e-9) - 1e-12 * size)
        self.flat, self.top = lower, n - 1

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """(P,) lower bounds of the distance from points (P, 2) to H, scene units."""
        ij = np.rint((x - self.lo) / self.pitch).astype(np.int64)
        np.clip(ij, 0, self.top, out=ij)
        off = x - (self.lo + self.pitch * ij)
        grid = self.flat[ij[:, 0] * (self.top[1] + 1) + ij[:, 1]]
        grid -= np.sqrt((off * off).sum(1)) * (1 + 1e-12)
        out = np.maximum(self.hlo - x, 0.0) + np.maximum(x - self.hhi, 0.0)
        return np.maximum(grid, np.sqrt((out * out).sum(1)) * (1 - 1e-12))


def translation_quadtree(
    lower: LowerDistance, proj: np.ndarray, radii: np.ndarray, steps: int = 6, cap: int = 64
) -> np.ndarray:
    """Cells in which no translation puts every point within its radius of H, all cells at once.

    If proj_i + t lies within r_i of H for every point i, then t lies in every box
    (bounding box of H, grown by r_i) - proj_i, and for a square of centre c and half-diagonal e
    holding t, d(c + proj_i, H) <= r_i + e. A quadtree over that box discards squares where some
    point's lower bound (:class:`LowerDistance`) exceeds r_i + e; a cell is excluded when no
    square is left after ``steps`` refinements (or none at all). A cell with more than ``cap``
    squares at some step is given up on (not excluded).

    Parameters
    ----------
    lower : LowerDistance
    proj : (n, k, 2) ndarray
        The points projected at each cell's centre rotation, scene units.
    radii : (n, k) ndarray
        Their displacement bounds (with every margin), scene units.
    steps, cap : int

    Returns
    -------
    (n,) bool ndarray
        Excluded cells.
    """
    tlo = (lower.hlo[None, None] - radii[..., None] - proj).max(axis=1)
    thi = (lower.hhi[None, None] + radii[..., None] - proj).min(axis=1)
    excluded = (tlo > thi).any(axis=1)
    cell = np.flatnonzero(~excluded)
    centre, half = 0.5 * (tlo + thi)[cell], 0.5 * (thi - tlo).max(axis=1)[cell]
    given_up = np.zeros(len(radii), dtype=bool)
    quarter = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]])
    for step in range(steps + 1):
        keep = np.empty(len(cell), dtype=bool)
        for s in range(0, len(cell), 20_000):
            c = cell[s : s + 20_000]
            x = (centre[s : s + 20_000, None, :] + proj[c]).reshape(-1, 2)
            e = math.sqrt(2.0) * half[s : s + 20_000, None]
            far = lower(x).reshape(len(c), -1) > radii[c] + e
            keep[s : s + 20_000] = ~far.any(axis=1)
        cell, centre, half = cell[keep], centre[keep], half[keep]
        if step == steps or not len(cell):
            break
        crowded = np.bincount(cell, minlength=len(radii)) > cap // 4
        given_up |= crowded
        ok = ~crowded[cell]
        cell, centre, half = cell[ok], centre[ok], 0.5 * half[ok]
        centre = (centre[:, None, :] + quarter[None] * half[:, None, None]).reshape(-1, 2)
        cell, half = np.repeat(cell, 4), np.repeat(half, 4)
    excluded[:] = True
    excluded[cell] = False
    excluded[given_up] = False
    return excluded


# ------------------------------------------------------------------------------------------------
# The exact test of one cell: intersection of shifted offsets
# ------------------------------------------------------------------------------------------------


class OffsetCache:
    """Offsets of H by radii rounded up to a geometric grid, each computed once.

    Round joins place their vertices on the arc of the offset distance (to the 1e-8 coordinate
    grid of manifold3d), so chords fall inside the arc by at most the sagitta; offsetting by
    r / cos(pi / n) + eta puts every chord outside the arc of radius r: the polygon contains
    H + disk(r) (docs/certify.md; ``tests/certify/test_certify.py`` checks it on this manifold3d).
    """

    def __init__(self, hole: manifold3d.CrossSection, eta: float, r_min: float):
        self.hole = hole
        self.eta = eta
        self.r_min = r_min
        self.cache: dict[int, manifold3d.CrossSection] = {}

    def grid_index(self, r: float) -> int:
        """Index of the smallest grid radius >= r."""
        if r <= self.r_min:
            return 0
        return int(math.ceil(math.log(r / self.r_min) / math.log(RADIUS_STEP) + 1e-12))

    def get(self, r: float) -> manifold3d.CrossSection:
        """A polygon containing H + disk(r)."""
        i = self.grid_index(r)
        if i not in self.cache:
            radius = self.r_min * RADIUS_STEP**i
            delta = radius / math.cos(math.pi / ROUND_SEGMENTS) + self.eta
            self.cache[i] = self.hole.offset(
                delta, manifold3d.JoinType.Round, circular_segments=ROUND_SEGMENTS
            )
        return self.cache[i]


def translations_left(
    cache: OffsetCache, proj: np.ndarray, radii: np.ndarray
) -> manifold3d.CrossSection:
    """The translations t with pi_i + t in (a polygon containing) H + disk(r_i) for every point i.

    Parameters
    ----------
    cache : OffsetCache
    proj : (k, 2) ndarray
        Projections of the points at the cell's centre rotation.
    radii : (k,) ndarray
        Displacement bounds, scene units; 0 gives H itself (grown by ``eta``).

    Returns
    -------
    manifold3d.CrossSection
        Empty iff the cell is excluded by these points.
    """
    parts = [
        cache.get(float(r)).translate((-float(p[0]), -float(p[1]))) for p, r in zip(proj, radii)
    ]
    if len(parts) == 1:
        return parts[0]
    return manifold3d.CrossSection.batch_boolean(parts, manifold3d.OpType.Intersect)
