"""The replay of a slab-section proof (a certificate's ``section``), with its own geometry.

Nothing of :mod:`sieve_mi.certify.section` is used: the replay rebuilds every cell of directions
by halving the cube's faces, recomputes the cap, the band test and each point's bound, and
re-proves each leaf (docs/certify.md, "Thin plates"):

1. the band is half the thickness, and the pin lies in the convex hull of the mesh's vertices
   (a point outside might never cross the plate);
2. every point is a vertex of the mesh or lies on one of its edges (recomputed from the edge);
3. every leaf: each evidence point v = q - pin is in the band for the whole cap
   (|n_c . v| + 2 sin(alpha / 2) |v| below the band), with the plane bound
   r = 2 (1 - cos alpha) |v| + sin(alpha) |n_c . v|; then ``diameter`` evidence by
   |P (v_i - v_j)| - r_i - r_j > diam(H), ``width`` evidence by the minimal width of the points'
   hull less twice their largest r above H's hull's minimal width, ``turns`` evidence by a
   translation quadtree (:func:`~sieve_mi.certify.replay_geometry.no_translation`) on every
   interval of turns, ``chain`` evidence (a sheet: :mod:`sieve_mi.certify.chain`) by every step
   |x_k - x_(k+1)| + r_k + r_(k+1) below a lower bound on the distance between the convex hulls
   of any two of H's contours (:func:`hull_separation`, less 2 eta) and the ends further apart
   (after their r) than the largest diameter of one contour; ``link`` evidence (a ring across a
   web, :mod:`sieve_mi.certify.link`) as a chain over mesh points and loop vertices (each in the
   band), where a step between two vertices of one loop is a link: the section's ``loops`` lie
   inside the mesh (:meth:`SectionReplay.check_loops`: samples along each edge further from every
   triangle than half their spacing, and enclosed), and over the cell that loop's surely-signed
   vertices change sign exactly twice, each stretch between them in the band and stepping by
   less than the separation, both vertices on the stretches;
4. the section is proved iff every leaf is re-proved and none is open.
"""

from __future__ import annotations

import math

import numpy as np

from sieve_mi.certify.replay_geometry import Hole, no_translation

__all__ = ["CUBE_FACES", "SectionReplay", "hull_min_width", "hull_separation", "largest_distance"]

#: The cube's faces in the certificate's order: (axis, sign).
CUBE_FACES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0))
#: Relative margin the search keeps on bounds and tests; the replay demands the same.
MARGIN = 1e-9


def largest_distance(points: np.ndarray) -> float:
    """The largest distance between two of the planar points (all pairs), scene units."""
    best = 0.0
    for i in range(0, len(points), 512):
        d = ((points[i : i + 512, None] - points[None]) ** 2).sum(-1)
        best = max(best, float(d.max()))
    return math.sqrt(best)


def hull_min_width(points: np.ndarray) -> float:
    """The minimal width of the convex hull of planar points: the least over the hull's edges of
    the largest distance of a point from the edge's line (0 for fewer than 3 or collinear)."""
    from scipy.spatial import ConvexHull

    try:
        h = points[ConvexHull(points).vertices]
    except Exception:  # fewer than 3 points, or collinear: no width
        return 0.0
    best = math.inf
    for k in range(len(h)):
        a, b = h[k], h[(k + 1) % len(h)]
        edge = b - a
        length = math.hypot(edge[0], edge[1])
        if length > 0:
            cross = edge[0] * (h[:, 1] - a[1]) - edge[1] * (h[:, 0] - a[0])
            best = min(best, float(np.abs(cross).max()) / length)
    return 0.0 if best == math.inf else best


def hull_separation(contours: list) -> float:
    """A lower bound on the distance between the convex hulls of any two contours: per pair the
    larger of the bounding circles' gap (about the vertices' mean) and the separating-axis gap
    over both hulls' edge normals (u . b - u . a over the vertices, either way round); ``inf``
    for one contour, 0 or less where two hulls may meet."""
    from scipy.spatial import ConvexHull

    hulls = []
    for c in contours:
        c = np.asarray(c, dtype=np.float64)
        try:
            hulls.append(c[ConvexHull(c).vertices])
        except Exception:  # degenerate: its vertices stand for the hull
            hulls.append(c)
    mid = [h.mean(axis=0) for h in hulls]
    rad = [float(np.linalg.norm(h - m, axis=1).max()) for h, m in zip(hulls, mid)]
    best = math.inf
    for i in range(len(hulls)):
        for j in range(i + 1, len(hulls)):
            circles = float(np.linalg.norm(mid[i] - mid[j])) - rad[i] - rad[j]
            if circles >= best:
                continue
            axes = []
            for h in (hulls[i], hulls[j]):
                d = np.roll(h, -1, axis=0) - h
                n = np.column_stack([d[:, 1], -d[:, 0]])
                norm = np.linalg.norm(n, axis=1)
                axes.append(n[norm > 0] / norm[norm > 0, None])
            u = np.concatenate(axes)
            a, b = hulls[i] @ u.T, hulls[j] @ u.T
            axis = float(np.maximum(b.min(0) - a.max(0), a.min(0) - b.max(0)).max())
            best = min(best, max(circles, axis))
    return best


def _direction(face: int, uv: np.ndarray) -> np.ndarray:
    axis, sign = CUBE_FACES[face]
    p = np.insert(np.asarray(uv, dtype=np.float64), axis, sign)
    return p / np.linalg.norm(p)


def _cap(face: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre direction and angle (largest over the four corners, plus 1e-12), radians."""
    n_c = _direction(face, 0.5 * (lo + hi))
    worst = 0.0
    for c in range(4):
        corner = np.array([hi[0] if c & 2 else lo[0], hi[1] if c & 1 else lo[1]])
        worst = max(worst, float(np.linalg.norm(_direction(face, corner) - n_c)))
    return n_c, 2.0 * math.asin(min(1.0, 0.5 * worst)) + 1e-12


def _frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The certificate's frame of the plane normal to n: e1 = (h x n) / |h x n| with h the
    x axis when |n_x| < 0.9, else the y axis; e2 = n x e1 (the turns are measured in it)."""
    h = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(h, n)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


class SectionReplay:
    """Re-prove a certificate's ``section`` against the mesh (vertices, faces) and hole."""

    def __init__(self, section: dict, vertices: np.ndarray, faces: np.ndarray, hole: Hole):
        self.section, self.hole = section, hole
        self.vertices, self.faces = vertices, faces
        self.errors: list[str] = []
        self.leaves = self.open = 0
        self.thickness = float(section["thickness"])
        self.band = float(section["band"])
        self.pin = np.asarray(section["pin"], dtype=np.float64)
        self.points = np.asarray(section["points"], dtype=np.float64).reshape(-1, 3)
        self.diameter = largest_distance(hole.vertices)
        self.width = hull_min_width(hole.vertices)
        scale = max(
            float(np.abs(hole.vertices).max()),
            float(np.linalg.norm(vertices[np.unique(faces)], axis=1).max()),
        )
        self.eta = 1e-6 * scale
        self._chain = None  # (step, diameter) of the chain test, computed when first needed
        self.loops = [
            np.asarray(q, dtype=np.float64).reshape(-1, 3) for q in section.get("loops") or []
        ]
        self._loops_ok = None  # whether the loops lie inside the mesh, checked when first needed

    def run(self) -> bool:
        """Every check; True when the section is proved (``errors`` lists the problems)."""
        if abs(self.band - 0.5 * self.thickness) > 1e-12 * self.thickness:
            self.errors.append(f"section.band: {self.band!r} is not half the thickness")
        self._check_pin()
        self._check_points()
        if self.errors:
            return False
        for face, node in enumerate(self.section["tree"]):
            self._walk(node, face, np.full(2, -1.0), np.full(2, 1.0), 0)
        return not self.errors and self.open == 0

    def _check_pin(self) -> None:
        from scipy.spatial import ConvexHull

        v = self.vertices[np.unique(self.faces)]
        try:
            eq = ConvexHull(v).equations
        except Exception:
            self.errors.append("section.pin: the mesh is flat; a pin cannot be checked")
            return
        tol = 1e-9 * float(np.abs(v).max())
        if float((eq[:, :3] @ self.pin + eq[:, 3]).max()) > tol:
            self.errors.append("section.pin: not inside the convex hull of the mesh")

    def _check_points(self) -> None:
        f = np.sort(self.faces, axis=1)
        edges = {tuple(e) for e in np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])}
        known = {tuple(v) for v in self.vertices[np.unique(self.faces)]}
        for k, ref in enumerate(self.section["on_edge"]):
            if ref is None:
                ok = tuple(self.points[k]) in known
            else:
                i, j, lam = int(ref[0]), int(ref[1]), float(ref[2])
                ok = (min(i, j), max(i, j)) in edges and 0.0 <= lam <= 1.0
                if ok:
                    a, b = self.vertices[i], self.vertices[j]
                    self.points[k] = a + lam * (b - a)
            if not ok:
                self.errors.append(f"section.points[{k}]: neither a vertex nor on an edge")
                return

    def _walk(self, node, face: int, lo: np.ndarray, hi: np.ndarray, depth: int) -> None:
        if len(self.errors) >= 10:
            return
        if not isinstance(node, dict) or depth > 40:
            self.errors.append(f"section.tree: a node at depth {depth} is malformed")
        elif "c" in node:
            kids = node["c"]
            if not isinstance(kids, list) or len(kids) != 4:
                self.errors.append(
                    f"section.tree: a split cell at depth {depth} has not 4 children"
                )
                return
            mid = 0.5 * (lo + hi)
            for c, kid in enumerate(kids):
                upper = np.array([(c >> 1) & 1, c & 1], dtype=bool)
                self._walk(kid, face, np.where(upper, mid, lo), np.where(upper, hi, mid), depth + 1)
        elif "e" in node:
            self.leaves += 1
            if not self._leaf(face, lo, hi, node["e"]):
                self.errors.append(
                    f"section.tree: leaf face {face} square {lo.tolist()}..{hi.tolist()}: "
                    "evidence does not hold"
                )
        else:
            self.open += 1

    def _leaf(self, face: int, lo: np.ndarray, hi: np.ndarray, ev) -> bool:
        """Re-prove one cell of directions from its evidence."""
        if not isinstance(ev, dict):
            return False
        idx = np.asarray(ev.get("pair") if ev.get("kind") == "diameter" else ev.get("points"))
        if idx.ndim != 1 or len(idx) < 2 or idx.dtype.kind not in "iu":
            return False
        if idx.min() < 0 or idx.max() >= len(self.points):
            return False
        n_c, alpha = _cap(face, lo, hi)
        v = self.points[idx] - self.pin
        length = np.linalg.norm(v, axis=1)
        z = v @ n_c
        inside = np.abs(z) + 2.0 * math.sin(0.5 * alpha) * length * (1 + MARGIN)
        if not np.all(inside < self.band * (1 - MARGIN) - self.eta):
            return False
        r = (2.0 * (1.0 - math.cos(alpha)) * length + math.sin(alpha) * np.abs(z)) * (1 + MARGIN)
        r = r + self.eta
        if ev["kind"] == "diameter":
            d = v[0] - v[1]
            apart = math.sqrt(max(0.0, float(d @ d) - float(d @ n_c) ** 2)) - r[0] - r[1]
            return apart > self.diameter * (1 + MARGIN) + self.eta
        e1, e2 = _frame(n_c)
        x = np.column_stack([v @ e1, v @ e2])
        if ev["kind"] == "width":
            return hull_min_width(x) - 2.0 * float(r.max()) > self.width * (1 + MARGIN) + self.eta
        if ev["kind"] == "turns":
            return self._turns(x, r, ev)
        if ev["kind"] == "chain":
            return self._chain_holds(x, r)
        if ev["kind"] == "link":
            return self._link_holds(x, r, ev, n_c, alpha, (e1, e2))
        return False

    def _chain_holds(self, x: np.ndarray, r: np.ndarray, skip=()) -> bool:
        """The points (in their order) step by less than the hulls' separation and end further
        apart than one contour's diameter (the steps from the points ``skip`` to the next are not
        tested: links)."""
        if self._chain is None:
            gap = hull_separation(self.hole.contours)
            far = max(largest_distance(c) for c in self.hole.contours)
            step = gap * (1 - MARGIN) - 2.0 * self.eta if math.isfinite(gap) else 0.0
            self._chain = (step, far * (1 + MARGIN) + self.eta)
        step, far = self._chain
        steps = np.linalg.norm(np.diff(x, axis=0), axis=1) + r[:-1] + r[1:]
        steps[list(skip)] = 0.0
        ends = float(np.linalg.norm(x[0] - x[-1])) - r[0] - r[-1]
        return step > 0 and bool(np.all(steps < step)) and ends > far

    def _turns(self, x: np.ndarray, r: np.ndarray, ev: dict) -> bool:
        """Every interval of turns of the evidence's tree excluded by a translation quadtree."""
        slack = float(ev.get("slack", -1.0))
        roots = (ev.get("turns") or {}).get("roots")
        if not (0 < slack < math.inf) or not isinstance(roots, list) or len(roots) != 8:
            return False
        lengths = np.linalg.norm(x, axis=1)
        step = 2.0 * math.pi / 8

        def holds(node, lo: float, hi: float, depth: int) -> bool:
            if not isinstance(node, dict) or depth > 30:
                return False
            if "c" in node:
                kids = node["c"]
                mid = 0.5 * (lo + hi)
                return (isinstance(kids, list) and len(kids) == 2
                        and holds(kids[0], lo, mid, depth + 1)
                        and holds(kids[1], mid, hi, depth + 1))  # fmt: skip
            if node.get("e") is not True:
                return False
            mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
            c, s = math.cos(mid), math.sin(mid)
            placed = np.column_stack([c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1]])
            grow = 2.0 * math.sin(0.5 * half) * lengths * (1 + MARGIN)
            return no_translation(self.hole, placed, r + grow, slack)

        return all(holds(n, k * step, (k + 1) * step, 0) for k, n in enumerate(roots))

    def check_loops(self) -> bool:
        """Every loop lies in the mesh's interior: on every edge, k samples (spacing at most 2 %
        of the mesh's radius) each further from every triangle than half the spacing (so the ball
        about it holds the edge's points near it and no surface) and enclosed by the mesh (its
        winding number, computed here); the mesh closed and consistently oriented."""
        import trimesh

        if self._loops_ok is not None:
            return self._loops_ok
        self._loops_ok = False
        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        if not self.loops or any(len(q) < 3 or not np.all(np.isfinite(q)) for q in self.loops):
            self.errors.append("section.loops: none, or one of fewer than 3 finite vertices")
            return False
        if not (mesh.is_watertight and mesh.is_winding_consistent):
            self.errors.append("section.loops: need a closed, consistently oriented mesh")
            return False
        radius = float(np.linalg.norm(self.vertices[np.unique(self.faces)], axis=1).max())
        pts, half = [], []
        for q in self.loops:
            a, b = q, np.roll(q, -1, axis=0)
            length = np.linalg.norm(b - a, axis=1)
            k = np.maximum(1, np.ceil(length / (0.02 * radius))).astype(int)
            pts += [a[e] + np.arange(k[e])[:, None] / k[e] * (b[e] - a[e]) for e in range(len(a))]
            half.append(np.repeat(0.5 * length / k, k))
        pts, half = np.concatenate(pts), np.concatenate(half)
        tri = self.vertices[self.faces]
        near, wind = np.full(len(pts), np.inf), np.zeros(len(pts))
        for s in range(0, len(pts), 64):
            p = pts[s : s + 64]
            flat = np.repeat(p, len(tri), axis=0)
            foot = trimesh.triangles.closest_point(np.tile(tri, (len(p), 1, 1)), flat)
            near[s : s + 64] = np.linalg.norm(foot - flat, axis=1).reshape(len(p), -1).min(1)
            v = tri[None] - p[:, None, None]
            la, lb, lc = np.linalg.norm(v, axis=3).transpose(2, 0, 1)
            num = (v[:, :, 0] * np.cross(v[:, :, 1], v[:, :, 2])).sum(-1)
            den = la * lb * lc + lc * (v[:, :, 0] * v[:, :, 1]).sum(-1)
            den += la * (v[:, :, 1] * v[:, :, 2]).sum(-1) + lb * (v[:, :, 2] * v[:, :, 0]).sum(-1)
            wind[s : s + 64] = np.arctan2(num, den).sum(1) / (2 * np.pi)
        if not np.all(near > half * (1 + MARGIN) + self.eta):
            self.errors.append("section.loops: an edge comes nearer the surface than its samples")
            return False
        if not np.all(np.abs(wind) >= 0.5):
            self.errors.append("section.loops: a point of a loop is outside the mesh")
            return False
        self._loops_ok = True
        return True

    def _stretches(self, v: np.ndarray, n_c: np.ndarray, alpha: float) -> list | None:
        """A loop's two stretches over the cap (``v``: its vertices less the pin): runs from the
        last surely-signed vertex of one sign to the first of the other; None unless there are
        exactly two, every unsure vertex on them, both in the band."""
        length = np.linalg.norm(v, axis=1)
        reach = 2.0 * math.sin(0.5 * alpha) * length * (1 + MARGIN)
        z = v @ n_c
        sure = [k for k in range(len(v)) if abs(z[k]) > reach[k] + self.eta]
        if len(sure) < 2:
            return None
        out = []
        for a, b in zip([sure[-1]] + sure[:-1], sure):
            if (z[a] > 0) != (z[b] > 0):
                out.append([(a + i) % len(v) for i in range((b - a) % len(v) + 1)])
        unsure = set(range(len(v))) - set(sure)
        if len(out) != 2 or not unsure <= set(out[0]) | set(out[1]):
            return None  # a vertex off the stretches unsure: the plane might cross there too
        inband = np.abs(z) + reach < self.band * (1 - MARGIN) - self.eta
        return out if all(inband[s].all() for s in out) else None

    def _link_holds(self, x: np.ndarray, r: np.ndarray, ev: dict, n_c, alpha, frame) -> bool:
        """The path's items (an index into the evidence's points, or ``[loop, vertex]``) step as
        a chain, except from one vertex of a loop's stretches to another of the same loop's (the
        link, once the loop's stretches are checked); its ends further apart than D."""
        path = ev.get("path")
        if not isinstance(path, list) or len(path) < 2 or not self.check_loops():
            return False
        xs, rs, where = [], [], []
        for item in path:
            if isinstance(item, int) and 0 <= item < len(x):
                xs.append(x[item])
                rs.append(r[item])
                where.append(None)
                continue
            if not (isinstance(item, list) and len(item) == 2
                    and all(isinstance(i, int) for i in item)
                    and 0 <= item[0] < len(self.loops)
                    and 0 <= item[1] < len(self.loops[item[0]])):  # fmt: skip
                return False
            v = self.loops[item[0]][item[1]] - self.pin
            z, length = float(v @ n_c), float(np.linalg.norm(v))
            reach = 2.0 * math.sin(0.5 * alpha) * length * (1 + MARGIN)
            if not abs(z) + reach < self.band * (1 - MARGIN) - self.eta:
                return False  # a loop vertex must be a band point too
            xs.append([v @ frame[0], v @ frame[1]])
            where.append(tuple(item))
            rs.append((2.0 * (1.0 - math.cos(alpha)) * length + math.sin(alpha) * abs(z))
                      * (1 + MARGIN) + self.eta)  # fmt: skip
        xs, rs = np.asarray(xs, dtype=np.float64), np.asarray(rs, dtype=np.float64)
        self._chain_holds(xs[:2], rs[:2])  # sets the bounds
        steps = np.linalg.norm(np.diff(xs, axis=0), axis=1) + rs[:-1] + rs[1:]
        links = [k for k in range(len(path) - 1) if not steps[k] < self._chain[0]]
        for k in links:  # a step too long for the chain: a link, or the evidence fails
            if not (where[k] and where[k + 1] and where[k][0] == where[k + 1][0]):
                return False
            q = where[k][0]
            v = self.loops[q] - self.pin
            found = self._stretches(v, n_c, alpha)
            if found is None or not all(any(w[1] in s for s in found) for w in where[k : k + 2]):
                return False
            z = v @ n_c
            rl = (2.0 * (1.0 - math.cos(alpha)) * np.linalg.norm(v, axis=1)
                  + math.sin(alpha) * np.abs(z)) * (1 + MARGIN) + self.eta  # fmt: skip
            xl = np.column_stack([v @ frame[0], v @ frame[1]])
            if not all(self._chain_steps(xl[s], rl[s]) for s in found):
                return False
        return self._chain_holds(xs, rs, skip=links)

    def _chain_steps(self, x: np.ndarray, r: np.ndarray) -> bool:
        """Every step of the points shorter than the chain test's (its ends not tested)."""
        self._chain_holds(x[:2], r[:2])  # sets the bounds
        step = self._chain[0]
        steps = np.linalg.norm(np.diff(x, axis=0), axis=1) + r[:-1] + r[1:]
        return step > 0 and bool(np.all(steps < step))
