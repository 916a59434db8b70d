"""Independent replay of a certificate: re-check every leaf without the search code.

Nothing here uses manifold3d or :mod:`sieve_mi.certify.bounds` / ``search``: the hole is the
certificate's contours, distances are exact point-to-segment distances computed here, point in
polygon is matplotlib's ``Path`` (even-odd over the contours), and the distance to the mesh for the
ball evidence is trimesh's ``triangles.closest_point``. The replay

0. checks the structure (:func:`check_structure`: every field's type and shape, every number
   finite and at most :data:`MAX_COORDINATE`, every index in range; a SieveError naming the
   field otherwise);
1. checks that the stored mesh matches its hash (and the file at ``shape.path``, when present) and
   that every evidence point is a vertex of the mesh or lies on one of its edges (recomputed here
   from the edge and its parameter; edge points only without a symmetry reduction);
2. checks the claimed symmetry group on the mesh and that the tree's roots are its domain's faces;
3. walks the tree, rebuilding each cell's box by halving (so the leaves cover the domain by
   construction; a split node must have exactly 8 children);
4. re-proves each leaf with each point's displacement bound over the cell, 2 sin(theta) |p| or,
   for certificates whose ``settings.bound`` is ``"first-order"``, the smaller of that and the
   first-order bound (:func:`first_order_bounds`, computed here by the chain rule through the
   normalised quaternion; docs/certify.md): ``width`` evidence by the width inequality along its
   direction,
   ``translations`` evidence by a quadtree over translations that must discard every box (a box of
   centre c and half-diagonal e is discarded when some point i has c + pi_i outside H at distance
   > r_i + e; boxes are refined down to the slack the search left, kappa times the displacement
   bound of the shape's radius), ``ball`` evidence by the winding number, the distance to the mesh
   and a quadtree showing that no disk of the ball's radius fits in H;
5. checks a claimed passage: every vertex inside H, no projected edge crossing H's boundary, and no
   vertex of H inside a projected triangle;
6. re-derives the ``status`` from what steps 1-5 showed (a ball root or every cell excluded:
   proved; a passage that fits: passage; open cells and no passage: undecided) and rejects a
   claimed status that differs, or claims that contradict (a ball proof with a passage or a cell
   tree, a passage where every cell is excluded). Every rejection lists at least one error, each
   starting with the field it concerns.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time

import numpy as np

from sieve_mi.errors import SieveError

__all__ = [
    "MAX_COORDINATE",
    "MAX_DIRECTIONS",
    "MAX_ERRORS",
    "Hole",
    "MAX_BOXES",
    "SAMPLE_SPACING",
    "Replay",
    "cell_angle",
    "disk_never_fits",
    "first_order_bounds",
    "no_translation",
    "points_in_triangles",
    "quaternion",
    "STATUSES",
    "check_structure",
    "replay",
    "rotation",
    "segments_cross",
]

MAX_BOXES = 400_000
#: Boundary sample spacing of :meth:`Hole.beyond`, relative to the hole's size.
SAMPLE_SPACING = 2e-4


class Hole:
    """H from its contours: exact distance to the boundary and even-odd point in polygon."""

    def __init__(self, contours: list):
        from matplotlib.path import Path

        self.contours = [np.asarray(c, dtype=np.float64) for c in contours]
        self.paths = [Path(c) for c in self.contours]
        self.a = np.concatenate(self.contours)
        self.b = np.concatenate([np.roll(c, -1, axis=0) for c in self.contours])
        self.vertices = self.a
        self._tree = None

    def contains(self, p: np.ndarray) -> np.ndarray:
        count = np.zeros(len(p), dtype=np.int64)
        for path in self.paths:
            count += path.contains_points(p)
        return count % 2 == 1

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Distance from each point to the boundary, via complex arithmetic, (n,)."""
        za = self.a[:, 0] + 1j * self.a[:, 1]
        zd = (self.b[:, 0] + 1j * self.b[:, 1]) - za
        out = np.empty(len(p))
        for s in range(0, len(p), 1024):
            z = (p[s : s + 1024, 0] + 1j * p[s : s + 1024, 1])[:, None] - za[None]
            u = (z * np.conj(zd)).real / np.maximum(np.abs(zd) ** 2, 1e-300)
            out[s : s + 1024] = np.abs(z - np.clip(u, 0, 1) * zd).min(axis=1)
        return out

    def outside_by(self, p: np.ndarray) -> np.ndarray:
        """Distance from each point to H (0 inside), (n,)."""
        return np.where(self.contains(p), 0.0, self.distance(p))

    def beyond(self, p: np.ndarray, bound: np.ndarray) -> np.ndarray:
        """(n,) bool: each point lies outside H further than its ``bound`` (decided exactly).

        A k-d tree over boundary samples (spacing at most ``spacing``) settles most points: the
        distance to the nearest sample is at least the distance to the boundary and at most
        half a spacing more (every boundary point has a sample within half a spacing). Points
        it cannot settle get the exact distance.
        """
        if self._tree is None:
            self._sample()
        out = ~self.contains(p)
        near = self._tree.query(p[out])[0]
        lower = near - self._slack
        sure, unsure = lower > bound[out], (lower <= bound[out]) & (near > bound[out])
        idx = np.flatnonzero(out)
        decided = sure.copy()
        if unsure.any():
            decided[unsure] = self.distance(p[idx[unsure]]) > bound[out][unsure]
        out[idx] = decided
        return out

    def _sample(self) -> None:
        from scipy.spatial import cKDTree

        size = float(np.max(self.vertices.max(0) - self.vertices.min(0)))
        spacing = max(size, 1e-300) * SAMPLE_SPACING
        length = np.linalg.norm(self.b - self.a, axis=1)
        n = np.ceil(length / spacing).astype(np.int64) + 1
        u = np.concatenate([np.linspace(0.0, 1.0, k) for k in n])
        seg = np.repeat(np.arange(len(n)), n)
        pts = self.a[seg] + u[:, None] * (self.b - self.a)[seg]
        self._tree = cKDTree(pts)
        self._slack = 0.5 * spacing * (1 + 1e-9) + 1e-12 * size


def rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def quaternion(face: int, v: np.ndarray) -> np.ndarray:
    q = np.insert(np.asarray(v, dtype=np.float64), face, 1.0)
    return q / np.linalg.norm(q)


def cell_angle(face: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre quaternion and covering angle (largest over the 8 corners, plus 1e-12), radians."""
    q0 = quaternion(face, 0.5 * (lo + hi))
    worst = 0.0
    for c in range(8):
        corner = [hi[j] if (c >> (2 - j)) & 1 else lo[j] for j in range(3)]
        worst = max(worst, float(np.linalg.norm(quaternion(face, corner) - q0)))
    return q0, 2.0 * math.asin(min(1.0, worst / 2.0)) + 1e-12


def _rotation_partials(q: np.ndarray) -> list[np.ndarray]:
    """dM/dq_a (a = w, x, y, z) of the homogeneous rotation formula M(q) (:func:`rotation` for
    unit q), each a 3 x 3 matrix linear in q."""
    w, x, y, z = q
    return [
        2.0 * np.array([[w, -z, y], [z, w, -x], [-y, x, w]]),
        2.0 * np.array([[x, y, z], [y, -x, -w], [z, w, -x]]),
        2.0 * np.array([[-y, x, w], [x, y, z], [-w, z, -y]]),
        2.0 * np.array([[-z, -w, x], [w, -z, y], [x, y, z]]),
    ]


def first_order_bounds(
    face: int, lo: np.ndarray, hi: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Projections at the cell's centre and a bound on every point's displacement over the cell.

    q(v) = u / |u| with u = v and 1 in slot ``face``; J's column j is P (dR/dv_j) p with
    dR/dv_j = sum_a dM/dq_a (q0) dq_a/dv_j and dq/dv_j = (e_j - q0 q0_j) / |u_c|. The bound is
    (D_c max_corners |J delta| + |h|^2 (|p| + |P R0 p|)) / D_min (D = |u|^2, h the half-widths;
    docs/certify.md), times 1 + 1e-9 for rounding.

    Parameters
    ----------
    face : int
    lo, hi : (3,) ndarray
        The cell's box in face coordinates.
    points : (k, 3) ndarray
        Scene units.

    Returns
    -------
    proj : (k, 2) ndarray
    bound : (k,) ndarray
        Scene units.
    """
    vc, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    uc = np.insert(vc, face, 1.0)
    norm = float(np.linalg.norm(uc))
    q0 = uc / norm
    partials = _rotation_partials(q0)
    slots = [a for a in range(4) if a != face]
    proj = points @ rotation(q0)[:2].T
    columns = []
    for j, slot in enumerate(slots):
        dq = -q0 * q0[slot]
        dq[slot] += 1.0
        dq /= norm
        d_rot = sum(dq[a] * partials[a] for a in range(4))
        columns.append(h[j] * (points @ d_rot[:2].T))
    lin = np.zeros(len(points))
    for sy in (1.0, -1.0):
        for sz in (1.0, -1.0):
            d = columns[0] + sy * columns[1] + sz * columns[2]
            lin = np.maximum(lin, np.hypot(d[:, 0], d[:, 1]))
    nearest = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    d_min = 1.0 + float(nearest @ nearest)
    second = float(h @ h) * (np.linalg.norm(points, axis=1) + np.hypot(proj[:, 0], proj[:, 1]))
    return proj, (norm * norm * lin + second) / d_min * (1.0 + 1e-9)


def no_translation(hole: Hole, proj: np.ndarray, radii: np.ndarray, resolve: float) -> bool:
    """True if no t puts every proj_i + t within radii_i of H (quadtree over t, exact distances)."""
    lo = hole.vertices.min(0) - radii[0] - proj[0]
    hi = hole.vertices.max(0) + radii[0] - proj[0]
    half = 0.5 * float(np.max(hi - lo))
    centres = (0.5 * (lo + hi))[None, :]
    while len(centres):
        e = half * math.sqrt(2.0)
        if len(centres) > MAX_BOXES or e < 0.25 * resolve:
            return False
        placed = (centres[:, None, :] + proj[None]).reshape(-1, 2)
        bound = np.broadcast_to(radii[None] + e, (len(centres), len(proj))).reshape(-1)
        far = hole.beyond(placed, bound).reshape(len(centres), -1)
        centres, half = centres[~far.any(axis=1)], 0.5 * half
        offsets = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]) * half
        centres = (centres[:, None, :] + offsets[None]).reshape(-1, 2)
    return True


def disk_never_fits(hole: Hole, rho: float) -> bool:
    """True if no disk of radius ``rho`` fits in H (quadtree over disk centres)."""
    lo, hi = hole.vertices.min(0), hole.vertices.max(0)
    half = 0.5 * float(np.max(hi - lo))
    centres = (0.5 * (lo + hi))[None, :]
    while len(centres):
        e = half * math.sqrt(2.0)
        if len(centres) > MAX_BOXES:
            return False
        d, ins = hole.distance(centres), hole.contains(centres)
        if np.any(ins & (d >= rho)):
            return False
        settled = (d + e < rho * (1 - 1e-9)) | (~ins & (d > e * (1 + 1e-9)))
        centres, half = centres[~settled], 0.5 * half
        offsets = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]) * half
        centres = (centres[:, None, :] + offsets[None]).reshape(-1, 2)
    return True


class Replay:
    """State of one replay: the certificate, the hole, and the problems found."""

    def __init__(self, cert: dict):
        self.cert = cert
        self.errors: list[str] = []
        shape = cert["shape"]
        self.vertices = np.asarray(shape["vertices"], dtype=np.float64)
        self.faces = np.asarray(shape["faces"], dtype=np.int64)
        self.points = np.asarray(shape["points"], dtype=np.float64).reshape(-1, 3)
        self.hole = Hole(cert["hole"])
        self.radius = float(np.linalg.norm(self.vertices[np.unique(self.faces)], axis=1).max())
        self.kappa = float(cert["settings"]["kappa"])
        self.bound = cert["settings"].get("bound", "isotropic")
        if self.bound not in ("isotropic", "first-order"):
            self.errors.append(f"settings.bound: unknown displacement bound {self.bound!r}")
        m = int(cert["settings"]["directions"])
        a = np.pi * np.arange(m) / m
        self.dirs = np.column_stack([np.cos(a), np.sin(a)])
        self.leaves = self.open = 0
        self._edges = None

    def check_mesh(self) -> None:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices).tobytes())
        h.update(np.ascontiguousarray(self.faces).tobytes())
        if h.hexdigest() != self.cert["shape"]["sha256"]:
            self.errors.append("shape.sha256: does not match the stored mesh (vertices, faces)")
        path = self.cert["shape"].get("path", "")
        if path and os.path.isfile(path):
            s = self._load_mesh(path)
            if s is not None and not (
                np.array_equal(s.vertices, self.vertices) and np.array_equal(s.faces, self.faces)
            ):
                self.errors.append(f"shape.path: {path} differs from the certificate's mesh")
        known = {tuple(v) for v in self.vertices[np.unique(self.faces)]}
        refs = self.cert["shape"].get("on_edge") or [None] * len(self.points)
        if len(refs) != len(self.points):
            self.errors.append("shape.on_edge: not one entry per point")
            return
        bad = [
            i
            for i, (p, r) in enumerate(zip(self.points, refs))
            if not self._on_mesh(i, p, r, known)
        ]
        if bad:
            self.errors.append(
                f"shape.points: points {bad[:5]} are neither vertices nor on edges of the mesh"
            )

    def _load_mesh(self, path: str):
        """The mesh file the certificate names, or None (and an error) when it cannot be read."""
        from sieve_mi.geometry.meshes import load_shape

        try:
            return load_shape(path, scale=float(self.cert["shape"].get("scale", 1.0)))
        except SieveError as exc:
            self.errors.append(f"shape.path: {exc}")
            return None

    def _on_mesh(self, k: int, p: np.ndarray, ref, known: set) -> bool:
        """Whether point k is a vertex, or lies on the mesh edge ``ref`` = [i, j, lam] (then its
        coordinates are recomputed here from the edge and used by the replay)."""
        if ref is None:
            return tuple(p) in known
        i, j, lam = int(ref[0]), int(ref[1]), float(ref[2])
        if self._edges is None:
            f = np.sort(self.faces, axis=1)
            self._edges = {
                tuple(e) for e in np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])
            }
        if (min(i, j), max(i, j)) not in self._edges or not 0.0 <= lam <= 1.0:
            return False
        a, b = self.vertices[i], self.vertices[j]
        self.points[k] = a + lam * (b - a)
        return True

    def check_symmetry(self) -> tuple[list[int], float]:
        """Verify the claimed group; the domain's faces and half-width."""
        group = self.cert["symmetry"]
        turns = {
            "klein": [np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])],
            "octahedral": [
                np.diag([1.0, -1, -1]),
                np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
                np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
                np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
            ],
        }
        if group not in ("none", "klein", "octahedral"):
            self.errors.append(f"symmetry: unknown group {group!r}")
            return [0, 1, 2, 3], 1.0
        verts = self.vertices[np.unique(self.faces)]
        known = set(map(tuple, verts))
        for m in turns.get(group, []):
            if set(map(tuple, verts @ m.T)) != known:
                self.errors.append(
                    f"symmetry: the mesh is not symmetric under the claimed {group} group"
                )
                break
        if group == "none":
            return [0, 1, 2, 3], 1.0
        if any(r is not None for r in self.cert["shape"].get("on_edge") or []):
            self._check_edge_symmetry(turns[group])
        return [0], (1.0 if group == "klein" else 0.41422)

    def _check_edge_symmetry(self, generators: list) -> None:
        """Evidence on an edge needs that edge in a set of edges the group maps onto itself:
        the largest set closed under the generators, computed here."""
        f = self.faces
        ends = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])
        v = self.vertices
        closed = {frozenset((tuple(v[i]), tuple(v[j]))) for i, j in ends}
        while True:
            out = {
                e
                for e in closed
                for m in generators
                if frozenset(tuple(m @ np.array(p)) for p in e) not in closed
            }
            if not out:
                break
            closed -= out
        for ref in self.cert["shape"].get("on_edge") or []:
            if ref is not None:
                e = frozenset((tuple(v[int(ref[0])]), tuple(v[int(ref[1])])))
                if e not in closed:
                    self.errors.append(
                        "shape.on_edge: a point on an edge the symmetry does not preserve"
                    )
                    return

    def check_leaf(self, face: int, lo: np.ndarray, hi: np.ndarray, ev: dict) -> bool:
        """Re-prove one excluded cell from its evidence."""
        if not isinstance(ev, dict) or not isinstance(ev.get("points"), list):
            return False
        idx = np.asarray(ev.get("points", []), dtype=np.int64)
        if len(idx) == 0 or idx.min() < 0 or idx.max() >= len(self.points):
            return False
        q0, theta = cell_angle(face, lo, hi)
        p = self.points[idx]
        proj = p @ rotation(q0)[:2].T
        radii = 2.0 * math.sin(theta) * np.linalg.norm(p, axis=1)
        if self.bound == "first-order":
            proj, first = first_order_bounds(face, lo, hi, p)
            radii = np.minimum(radii, first)
        elif self.bound != "isotropic":
            return False
        if ev.get("kind") == "width":
            u = self.dirs[int(ev["direction"]) % len(self.dirs)]
            dots = proj @ u
            hv = self.hole.vertices @ u
            spread = (dots - radii).max() - (dots + radii).min()
            return bool(spread > (hv.max() - hv.min()) * (1 + 1e-12) + 1e-12)
        if ev.get("kind") == "translations":
            resolve = self.kappa * 2.0 * math.sin(theta) * self.radius
            return no_translation(self.hole, proj, radii, resolve)
        return False

    def walk(self, node: dict, face: int, lo: np.ndarray, hi: np.ndarray, depth: int = 0) -> None:
        """Check a subtree: split nodes have 8 children, leaves re-proved, open leaves counted.

        Stops once :data:`MAX_ERRORS` problems are known: the certificate is invalid then, and a
        tampered one (every leaf failing, each failure slower than a success) ends in seconds.
        """
        if len(self.errors) >= MAX_ERRORS:
            return
        if not isinstance(node, dict):
            self.errors.append(f"tree: a node at depth {depth} is not an object")
        elif depth > 60:
            self.errors.append("tree: deeper than 60 levels")
        elif "c" in node:
            kids = node["c"]
            if not isinstance(kids, list) or len(kids) != 8:
                n = len(kids) if isinstance(kids, list) else "no list of"
                self.errors.append(f"tree: a split cell at depth {depth} has {n} children, not 8")
                return
            mid = 0.5 * (lo + hi)
            for c, kid in enumerate(kids):
                upper = np.array([(c >> (2 - j)) & 1 for j in range(3)], dtype=bool)
                self.walk(kid, face, np.where(upper, mid, lo), np.where(upper, hi, mid), depth + 1)
        elif "e" in node:
            self.leaves += 1
            if not self.check_leaf(face, lo, hi, node["e"]):
                self.errors.append(
                    f"tree: leaf face {face} box {lo.tolist()}..{hi.tolist()}: evidence does not hold"
                )
        else:
            self.open += 1

    def check_ball(self, root: dict) -> None:
        """A ball inside the closed mesh, and no disk of its radius inside H."""
        import trimesh

        mesh = trimesh.Trimesh(self.vertices, self.faces, process=False)
        centre, rho = np.asarray(root["centre"], dtype=np.float64), float(root["radius"])
        if not (mesh.is_watertight and mesh.is_winding_consistent):
            self.errors.append("root: ball evidence needs a closed, consistently oriented mesh")
            return
        tri = self.vertices[self.faces]
        foot = trimesh.triangles.closest_point(tri, np.repeat(centre[None], len(tri), axis=0))
        if not np.linalg.norm(foot - centre, axis=1).min() >= rho:
            self.errors.append(f"root.radius: the ball of radius {rho} is not inside the mesh")
        a = self.vertices[self.faces] - centre
        la, lb, lc = np.linalg.norm(a, axis=2).T
        triple = np.einsum("ij,ij->i", a[:, 0], np.cross(a[:, 1], a[:, 2]))
        den = la * lb * lc + lc * (a[:, 0] * a[:, 1]).sum(1)
        den += la * (a[:, 1] * a[:, 2]).sum(1) + lb * (a[:, 2] * a[:, 0]).sum(1)
        if abs(np.arctan2(triple, den).sum() / (2 * np.pi)) < 0.5:
            self.errors.append("root.centre: the ball's centre is not enclosed by the mesh")
        if not disk_never_fits(self.hole, rho):
            self.errors.append(f"root.radius: a disk of radius {rho} may fit in the hole")

    def check_passage(self, passage: dict) -> None:
        """The pose puts the exact projection inside H."""
        q = np.asarray(passage["quaternion"], dtype=np.float64)
        t = np.asarray(passage["translation"], dtype=np.float64)
        p = self.vertices @ rotation(q)[:2].T + t
        if not self.hole.contains(p[np.unique(self.faces)]).all():
            self.errors.append("passage: a vertex lies outside the hole")
            return
        edges = np.unique(
            np.sort(
                np.concatenate(
                    [self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]
                ),
                axis=1,
            ),
            axis=0,
        )
        if segments_cross(p[edges[:, 0]], p[edges[:, 1]], self.hole.a, self.hole.b):
            self.errors.append("passage: an edge of the shape crosses the hole's boundary")
        tri = p[self.faces]
        if points_in_triangles(self.hole.vertices, tri):
            self.errors.append("passage: a corner of the hole lies inside the shape's projection")


def _orient(a, b, c):
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (
        c[..., 0] - a[..., 0]
    )


def segments_cross(p0, p1, q0, q1) -> bool:
    """Whether any segment p0-p1 properly crosses any segment q0-q1."""
    for s in range(0, len(p0), 256):
        a, b = p0[s : s + 256, None], p1[s : s + 256, None]
        c, d = q0[None], q1[None]
        o1, o2 = _orient(a, b, c), _orient(a, b, d)
        o3, o4 = _orient(c, d, a), _orient(c, d, b)
        if np.any((o1 * o2 < 0) & (o3 * o4 < 0)):
            return True
    return False


def points_in_triangles(points: np.ndarray, tri: np.ndarray) -> bool:
    """Whether any point lies strictly inside any (non-degenerate) triangle."""
    for s in range(0, len(tri), 256):
        t = tri[s : s + 256, None]
        x = points[None]
        o = [_orient(t[..., i, :], t[..., (i + 1) % 3, :], x) for i in range(3)]
        if np.any(((o[0] > 0) & (o[1] > 0) & (o[2] > 0)) | ((o[0] < 0) & (o[1] < 0) & (o[2] < 0))):
            return True
    return False


#: Problems after which a replay stops (the first ones are reported; the verdict is "invalid").
MAX_ERRORS = 10


#: The claims a certificate can make.
STATUSES = ("proved", "passage", "undecided")


def replay(source) -> dict:
    """Re-check a certificate (a path or the loaded dict) independently of the search.

    Every claimed field is re-derived from the evidence: the mesh from its hash (and the file at
    ``shape.path``), the symmetry from the mesh, each leaf, the ball and the passage by their own
    tests, and the ``status`` from what the evidence shows (a ball proof or a complete tree of
    excluded cells: proved; a passage that fits: passage; open cells and no passage: undecided).
    A claim the evidence does not support makes the certificate invalid, with an error naming the
    field; an invalid certificate always has at least one error.

    Returns
    -------
    dict
        ``valid`` (every check passed and the claimed status is the one the evidence shows),
        ``proved`` (valid and proved), ``status`` claimed, ``leaves`` re-proved, ``open`` cells,
        ``errors`` (the first 10 problems) and ``seconds``.

    Raises
    ------
    SieveError
        If ``source`` is not a path or a dict, the file cannot be read, or it is not a
        well-formed sieve-mi certificate (a missing key, a wrong type, a number that is not
        finite or is out of range); one line naming the field.
    """
    t0 = time.perf_counter()
    where = _where(source)
    cert = _load(source, where)
    check_structure(cert, where)
    try:
        r = _run_checks(cert)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError, AttributeError) as exc:
        raise SieveError(f"{where}: malformed certificate ({type(exc).__name__}: {exc})") from None
    except RecursionError:
        raise SieveError(f"{where}: malformed certificate (nested too deeply)") from None
    status = cert["status"]
    r.errors[:0] = _status_errors(cert, r)  # first, so that they are among those reported
    return {
        "valid": not r.errors,
        "proved": not r.errors and status == "proved",
        "status": status,
        "leaves": r.leaves,
        "open": r.open,
        "errors": r.errors[:MAX_ERRORS],
        "seconds": time.perf_counter() - t0,
    }


def _run_checks(cert: dict) -> Replay:
    """Every check of the evidence (module docstring, steps 1-5); the problems in ``errors``."""
    r = Replay(cert)
    r.check_mesh()
    faces, half = r.check_symmetry()
    if cert["root"]:
        r.check_ball(cert["root"])
        if cert["tree"]:
            r.errors.append("tree: a ball proof (root) has no cell tree")
    elif len(cert["tree"]) != len(faces):
        r.errors.append(
            f"tree: {len(cert['tree'])} roots, the {cert['symmetry']} domain has {len(faces)}"
        )
    else:
        for face, node in zip(faces, cert["tree"]):
            r.walk(node, face, np.full(3, -half), np.full(3, half))
    if cert["passage"]:
        r.check_passage(cert["passage"])
    return r


def _status_errors(cert: dict, r: Replay) -> list[str]:
    """The claimed ``status`` against the one the evidence shows, and claims that contradict.

    Evidence shows: a ball root, proved; else a passage, passage; else open cells, undecided;
    else (every cell of the domain excluded), proved. Open cells are counted only by a walk
    without errors, so with other errors only the claims themselves are compared.
    """
    claim, errors = cert["status"], []
    if claim not in STATUSES:
        errors.append(f"status: {claim!r} is not one of {', '.join(STATUSES)}")
    if cert["root"] and cert["passage"]:
        errors.append("passage: a ball proof (root) and a passage contradict each other")
    if errors or r.errors:
        return errors
    if cert["passage"] and not r.open:
        return ["passage: every cell of the tree is excluded, yet a passage is claimed"]
    if cert["root"]:
        shown, why = "proved", "a ball proof at the root"
    elif cert["passage"]:
        shown, why = "passage", "a passage pose that fits"
    elif r.open:
        shown, why = "undecided", f"open cells: {r.open}, and no passage"
    else:
        shown, why = "proved", "every cell of the domain excluded"
    if claim != shown:
        errors.append(f"status: claims {claim}, but the evidence shows {shown} ({why})")
    return errors


#: Largest magnitude of a coordinate, radius or translation in a certificate (scene units).
MAX_COORDINATE = 1e12
#: Most width directions a certificate may name (the search uses 36).
MAX_DIRECTIONS = 100_000


def _where(source) -> str:
    if isinstance(source, dict):
        return "certificate"
    if isinstance(source, (str, os.PathLike)):
        return os.fspath(source)
    raise SieveError(f"certificate: expected a file path or a dict, got {type(source).__name__}")


def _load(source, where: str) -> dict:
    """The certificate as a dict; SieveError unless it is a sieve-mi certificate (parsed)."""
    from sieve_mi.certify.certificate import FORMAT, is_certificate

    if isinstance(source, dict):
        cert = source
    else:
        cert = _read_json(where)
    if not is_certificate(cert):
        if isinstance(cert, dict) and cert.get("format") == FORMAT:
            missing = _missing_key(cert)
            raise SieveError(f"{where}: not a sieve-mi certificate ({missing})")
        raise SieveError(
            f'{where}: not a sieve-mi certificate (a JSON object whose "format" is {FORMAT!r})'
        )
    return cert


def _read_json(path: str):
    if not os.path.exists(path):
        raise SieveError(f"{path}: certificate not found")
    if not os.path.isfile(path):
        raise SieveError(f"{path}: is not a regular file; name a certificate file")
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except RecursionError:
        raise SieveError(f"{path}: not a readable JSON certificate (nested too deeply)") from None
    except (OSError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "integer string conversion" in first:
            first = "an integer with too many digits"
        raise SieveError(f"{path}: not a readable JSON certificate ({first})") from None


def _missing_key(cert: dict) -> str:
    from sieve_mi.certify.certificate import REQUIRED

    for part, keys in REQUIRED.items():
        block = cert if not part else cert.get(part)
        if not isinstance(block, dict):
            return f"{part} is not an object"
        for k in keys:
            if k not in block:
                return f"no key {(part + '.' if part else '') + k!r}"
    return "hole and tree must be lists"


def check_structure(cert: dict, where: str = "certificate") -> None:
    """Types, shapes and ranges of every field the replay reads (before any geometry).

    Raises
    ------
    SieveError
        One line naming the field: not a string, not an array of the right shape, a number not
        finite or above :data:`MAX_COORDINATE`, an index out of range.
    """
    shape, settings = cert["shape"], cert["settings"]
    for key, value in (("status", cert["status"]), ("symmetry", cert["symmetry"]),
                       ("shape.sha256", shape["sha256"])):  # fmt: skip
        if not isinstance(value, str):
            raise SieveError(f"{where}: {key} must be a string, not {type(value).__name__}")
    for key in ("path", "name"):
        if not isinstance(shape.get(key, ""), str):
            raise SieveError(f"{where}: shape.{key} must be a string")
    vertices = _numbers(shape["vertices"], "shape.vertices", (-1, 3), where)
    faces = _indices(shape["faces"], "shape.faces", (-1, 3), len(vertices), where)
    if len(vertices) == 0 or len(faces) == 0:
        raise SieveError(f"{where}: shape: the mesh has no vertices or no faces")
    _numbers(shape["points"], "shape.points", (-1, 3), where, allow_empty=True)
    _check_on_edge(shape.get("on_edge"), len(vertices), where)
    if "scale" in shape:
        _positive(shape["scale"], "shape.scale", where)
    if not cert["hole"]:
        raise SieveError(f"{where}: hole: no contour")
    for i, c in enumerate(cert["hole"]):
        if len(_numbers(c, f"hole[{i}]", (-1, 2), where)) < 3:
            raise SieveError(f"{where}: hole[{i}]: a contour needs at least 3 points")
    _positive(settings["kappa"], "settings.kappa", where)
    d = settings["directions"]
    if isinstance(d, bool) or not isinstance(d, int) or not 1 <= d <= MAX_DIRECTIONS:
        raise SieveError(f"{where}: settings.directions must be an integer in 1..{MAX_DIRECTIONS}")
    if not isinstance(settings.get("bound", "isotropic"), str):
        raise SieveError(f"{where}: settings.bound must be a string")
    _check_root_and_passage(cert, where)


def _check_root_and_passage(cert: dict, where: str) -> None:
    root, passage = cert["root"], cert["passage"]
    if root is not None and not isinstance(root, dict):
        raise SieveError(f"{where}: root must be null or an object")
    if root:
        if root.get("kind", "ball") != "ball":
            raise SieveError(f"{where}: root.kind {root.get('kind')!r}: only 'ball' is known")
        _numbers(root.get("centre"), "root.centre", (3,), where)
        _positive(root.get("radius"), "root.radius", where)
    if passage is not None and not isinstance(passage, dict):
        raise SieveError(f"{where}: passage must be null or an object")
    if passage:
        q = _numbers(passage.get("quaternion"), "passage.quaternion", (4,), where)
        _numbers(passage.get("translation"), "passage.translation", (2,), where)
        if not np.linalg.norm(q) > 1e-12:
            raise SieveError(f"{where}: passage.quaternion is zero, not a rotation")


def _check_on_edge(refs, n_vertices: int, where: str) -> None:
    if refs is None:
        return
    if not isinstance(refs, list):
        raise SieveError(f"{where}: shape.on_edge must be a list")
    for k, ref in enumerate(refs):
        if ref is None:
            continue
        ok = isinstance(ref, list) and len(ref) == 3
        ok = ok and all(isinstance(i, int) and not isinstance(i, bool) for i in ref[:2])
        ok = ok and all(0 <= i < n_vertices for i in ref[:2])
        ok = ok and isinstance(ref[2], (int, float)) and abs(ref[2]) <= MAX_COORDINATE
        if not ok:
            raise SieveError(
                f"{where}: shape.on_edge[{k}] must be null or [i, j, lam] with vertex indices i, j"
            )


def _numbers(value, key: str, shape: tuple, where: str, allow_empty: bool = False) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (-1: any length), finite and bounded."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise SieveError(f"{where}: {key} must be an array of numbers") from None
    if allow_empty and a.size == 0:
        return a.reshape(0, *shape[1:])
    if a.ndim != len(shape) or any(n != -1 and n != m for n, m in zip(shape, a.shape)):
        want = " x ".join("n" if n == -1 else str(n) for n in shape)
        raise SieveError(f"{where}: {key} must be an array of {want} numbers")
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > MAX_COORDINATE):
        raise SieveError(
            f"{where}: {key} holds a number that is not finite or exceeds {MAX_COORDINATE:g}"
        )
    return a


def _indices(value, key: str, shape: tuple, n: int, where: str) -> np.ndarray:
    """``value`` as an int64 array of ``shape``, every entry in [0, n)."""
    try:
        a = np.asarray(value)
        ok = a.dtype.kind in "iu" and a.ndim == len(shape) and a.shape[1:] == shape[1:]
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise SieveError(f"{where}: {key} must be an array of n x 3 integer indices")
    if a.size and (a.min() < 0 or a.max() >= n):
        raise SieveError(f"{where}: {key}: an index is outside 0..{n - 1}")
    return a.astype(np.int64)


def _positive(value, key: str, where: str) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not (ok and 0 < value <= MAX_COORDINATE):  # NaN fails; no float() of a huge int
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        raise SieveError(f"{where}: {key} must be a positive finite number, not {shown}")
    return float(value)
