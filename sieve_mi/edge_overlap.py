"""The paper's overlap loss (eq. 12) for all poses at once, differentiated by edge sampling.

For a pose (R, t) of a shape B with silhouette S, the loss is the fraction of S outside the hole,

    beta = area(S \\ H) / area(S) = 1 - area(S ∩ H) / area(S),

with H the union of the hole raster's pixel cells whose centre lies in H (outside distance 0).
Both areas and their derivatives are integrals over B's *visible outline* ∂S, which lies on B's
silhouette edges (:class:`sieve_mi.clearance.ClearanceObjective` samples them): a sample on a
silhouette edge is on ∂S iff exactly one of two points just beside it (a hundredth of a pixel
either way along the projected edge's normal) is covered by B (one batched any-hit ``ray_test``
each, in B's frame as in :mod:`sieve_mi.silhouettes`), and the outward normal n points to the
uncovered one. With samples at most a pixel apart (weight dl, the sample's share of its segment's
projected length):

* **Area** (Green's theorem): area(S) = ∮_∂S x n_x dl, exact on straight segments.
* **Area inside H**: ∂(S ∩ H) is the part of ∂S inside H plus the part of ∂H inside S, so
  area(S ∩ H) = ∮_∂S 1_H x n_x dl + Σ_e 1_S(e) x_e n_e h, the second sum over the vertical
  pixel-cell edges e of ∂H (horizontal ones have n_x = 0), each tested for cover at its midpoint
  by one more ray. Both are exact when S lies entirely inside or entirely outside H; near a
  crossing of ∂S and ∂H they are off by a fraction of a pixel's area.
* **Gradient** (Reynolds transport; what Mitsuba's projective integrators estimate): with v the
  velocity of an outline point under a change of (R, t),
  d area(S)/dθ = ∮_∂S (v·n) dl and d area(S \\ H)/dθ = ∮_∂S 1_out (v·n) dl, and
  dβ/dθ = (d area(S \\ H) - β d area(S)) / area(S). The outline point is
  x = R_{0,:} p + t_x, y = R_{1,:} p + t_y for its mesh-frame point p, so v·n is linear in the
  first two rows of R and in t; the 16 per-pose sums of n_x, n_y, n_x p and n_y p (with and without
  1_out) are added in a fixed order (:func:`sieve_mi.clearance.pose_sums`) and chained to the
  quaternion by per-pose arithmetic, as for the clearance loss.

Cost per step: two rays per sample on a silhouette edge (3 % of the sphere's edges) and one per
pose and vertical boundary edge of its hole (about the hole's height in pixels, times two), instead
of one Mitsuba render and BVH rebuild per pose (:mod:`sieve_mi.overlap`, ``"overlap-mitsuba"``).
"""

from __future__ import annotations

import numpy as np

from sieve_mi.clearance import ClearanceObjective, pose_sums
from sieve_mi.hole import HoleStack
from sieve_mi.meshes import Shape
from sieve_mi.raster import Frame
from sieve_mi.rotations import quat_rows

#: The two side points of an outline sample are this many pixels from it.
SIDE_OFFSET = 0.01
#: Per-pose sums of :meth:`EdgeOverlapObjective._outline_sums`: area, area inside H, the 8 sums
#: of d area, the 8 sums of d area outside H.
OUTLINE_SUMS = 18


def _scene(shape: Shape):
    """A Mitsuba scene holding ``shape`` in its own (centred) frame, for ray tests."""
    import mitsuba as mi

    mesh = mi.Mesh(
        shape.name or "shape", len(shape.vertices), len(shape.faces), has_vertex_normals=False
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(shape.vertices.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(shape.faces.astype(np.uint32).ravel())
    params.update()
    return mi.load_dict({"type": "scene", "shape": mesh})


def hole_edges(inside: np.ndarray, frame: Frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The vertical pixel-cell edges of a hole raster's boundary.

    Parameters
    ----------
    inside : (N, N) ndarray of bool
        Pixel cells in H (row 0 at the top).
    frame : Frame

    Returns
    -------
    x, y : (E,) ndarrays
        Edge midpoints, scene units.
    nx : (E,) ndarray
        x component of H's outward normal, +1 (H to the left of the edge) or -1.
    """
    n, h, r = frame.resolution, frame.pixel_size, frame.half_extent
    padded = np.pad(np.asarray(inside, dtype=bool), ((0, 0), (1, 1)))
    left, right = padded[:, :-1], padded[:, 1:]  # the cells on either side of edge column c
    row, col = np.nonzero(left != right)
    x = -r + col * h
    y = r - (row + 0.5) * h
    return x, y, np.where(left[row, col], 1.0, -1.0)


class EdgeOverlapObjective(ClearanceObjective):
    """Overlap loss β (paper eq. 12) of several shapes for many poses at once, by edge sampling.

    An :class:`~sieve_mi.objective.Objective` (see there for :meth:`bind` and :meth:`loss`); the
    method is in the module docstring. It shares the clearance objective's edge segments and its
    silhouette-edge test.

    Parameters
    ----------
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
        The hole's raster frame; samples are at most a pixel apart.
    samples_per_segment : int, optional
        As for :class:`~sieve_mi.clearance.ClearanceObjective`.
    """

    def __init__(self, shapes: list[Shape], frame: Frame, samples_per_segment: int | None = None):
        super().__init__(shapes, frame, samples_per_segment)
        mi = self.mi
        self._scenes = [_scene(s) for s in shapes]
        h = frame.pixel_size
        # Ray origins sit this far below the shape's centre (as in SilhouetteRenderer.trace).
        self._reach = [s.radius * 1.01 + h for s in shapes]
        self._radius = mi.Float(np.array([s.radius + 2 * h for s in shapes], dtype=np.float32))
        self._hole_cache = None

    def bind(self, pose_shape: np.ndarray) -> None:
        """Fix which shape each pose belongs to.

        Parameters
        ----------
        pose_shape : (K,) ndarray of int
            Index into ``shapes`` for every pose.
        """
        super().bind(pose_shape)
        self._pose_shape_np = np.asarray(pose_shape, dtype=np.int64)
        self._pose_shape = self.mi.UInt32(self._pose_shape_np.astype(np.uint32))
        self._hole_cache = None

    def loss(self, q, t, holes: HoleStack, pose_hole):
        """Total and per-pose overlap loss β (fraction of each silhouette outside its hole).

        Parameters
        ----------
        q : tuple of 4 mi.Float
            Quaternions (w, x, y, z), one entry per pose, possibly with gradients enabled.
        t : tuple of 2 mi.Float
            Translations in scene units.
        holes : HoleStack
        pose_hole : mi.UInt32
            Which hole of the stack each pose is tested against.

        Returns
        -------
        total : mi.Float
            Sum of β over all poses; its gradient with respect to ``q`` and ``t`` is the
            edge-sampled one (module docstring).
        per_pose : mi.Float
            β of each pose (detached), in [0, 1]; 1 for a pose whose outline has no length.
        """
        dr, mi = self.dr, self.mi
        if holes.frame != self.frame:
            raise ValueError("the hole stack's frame differs from the objective's frame")
        rows = quat_rows(*q)
        with dr.suspend_grad():
            r = [dr.detach(x) for x in rows]
            td = (dr.detach(t[0]), dr.detach(t[1]))
            s = self._outline_sums(self._active_pairs(rows), r, td, holes, pose_hole)
            inner = self._hole_edge_sums(r, td, holes, pose_hole)
            area = s[0]
            ok = area > 1e-3 * self.frame.pixel_size**2
            safe = dr.select(ok, area, 1.0)
            raw = (area - s[1] - inner) / safe
            per_pose = dr.select(ok, dr.clip(raw, 0.0, 1.0), 1.0)
            coef = [dr.select(ok, (s[10 + i] - raw * s[2 + i]) / safe, 0.0) for i in range(8)]
        total = dr.sum(per_pose)
        if dr.grad_enabled(q, t):
            link = t[0] * coef[0] + t[1] * coef[1]
            for i in range(6):
                link = link + rows[i] * coef[2 + i]
            link = dr.sum(link)
            total = total + (link - dr.detach(link))
        return total, per_pose

    def _covered(self, x, y, g, shape, active=True):
        """Whether world points (x, y) are covered by their pose's shape (one ray each).

        ``g`` holds the pose's 9 rotation entries and 2 translations (gathered per lane),
        ``shape`` its shape index.
        """
        dr, mi = self.dr, self.mi
        dx, dy = x - g[9], y - g[10]
        direction = mi.Vector3f(g[6], g[7], g[8])
        hit = mi.Bool(False)
        for i, scene in enumerate(self._scenes):
            reach = self._reach[i]
            origin = mi.Point3f(
                dx * g[0] + dy * g[3] - reach * g[6],
                dx * g[1] + dy * g[4] - reach * g[7],
                dx * g[2] + dy * g[5] - reach * g[8],
            )
            ray = mi.Ray3f(origin, direction)
            ray.maxt = mi.Float(2.0 * reach)
            mask = active if len(self._scenes) == 1 else (shape == i) & active
            hit |= scene.ray_test(ray, mask)
        return hit

    def _in_hole(self, x, y, holes: HoleStack, hole):
        """Whether world points (x, y) lie in a pixel cell of their hole."""
        dr, mi = self.dr, self.mi
        f = holes.frame
        inv_h = 1.0 / f.pixel_size
        col = mi.Int32(dr.floor((x + f.half_extent) * inv_h))
        row = mi.Int32(dr.floor((f.half_extent - y) * inv_h))
        n = f.resolution
        on = (col >= 0) & (col < n) & (row >= 0) & (row < n)
        d = holes.gather(hole, mi.UInt32(dr.maximum(row, 0)), mi.UInt32(dr.maximum(col, 0)), on)
        return on & (d <= 0)

    def _context(self, rows, t, pose_hole):
        """``prepare`` for :func:`pose_sums`: the pose's 11 numbers, its hole and its shape."""
        dr, mi = self.dr, self.mi

        def prepare(pose):
            g = [dr.gather(mi.Float, x, pose) for x in list(rows) + list(t)]
            return (
                g,
                dr.gather(mi.UInt32, pose_hole, pose),
                dr.gather(mi.UInt32, self._pose_shape, pose),
            )

        return prepare

    def _outline_sums(self, active, rows, t, holes: HoleStack, pose_hole) -> list:
        """The 18 per-pose sums over the outline samples of the active (pose, segment) pairs.

        Returns
        -------
        list of 18 mi.Float, each (K,)
            area(S); the part of ∮ x n_x dl inside H; ∮ (n_x, n_y, n_x p, n_y p) dl (8: the
            derivatives of area(S) with respect to t and the first two rows of R); the same 8
            restricted to outline points outside H. Scene units.
        """
        dr, mi = self.dr, self.mi
        fracs = [(j + 0.5) / self.samples for j in range(self.samples)]
        off = SIDE_OFFSET * self.frame.pixel_size

        def accumulate(pair, ctx, acc):
            g, hole, shape = ctx
            seg = dr.gather(mi.UInt32, self._pairs[1], pair)
            a, d = dr.gather(mi.Vector3f, self.a, seg), dr.gather(mi.Vector3f, self.d, seg)
            ex = g[0] * d.x + g[1] * d.y + g[2] * d.z
            ey = g[3] * d.x + g[4] * d.y + g[5] * d.z
            length = dr.sqrt(ex * ex + ey * ey)
            inv = dr.select(length > 0, dr.rcp(length), 0.0)
            nx, ny = ey * inv, -ex * inv  # a unit normal of the projected segment
            for frac in fracs:
                p = a + d * frac
                x = g[0] * p.x + g[1] * p.y + g[2] * p.z + g[9]
                y = g[3] * p.x + g[4] * p.y + g[5] * p.z + g[10]
                plus = self._covered(x + off * nx, y + off * ny, g, shape)
                minus = self._covered(x - off * nx, y - off * ny, g, shape)
                # On the outline iff exactly one side is covered; n points to the other one.
                w = dr.select(plus ^ minus, dr.select(minus, 1.0, -1.0) * length, 0.0)
                wx, wy = w * (nx / self.samples), w * (ny / self.samples)
                inside = self._in_hole(x, y, holes, hole)
                area = wx * (x - g[9])
                d_all = (wx, wy, wx * p.x, wx * p.y, wx * p.z, wy * p.x, wy * p.y, wy * p.z)
                d_out = tuple(dr.select(inside, 0.0, v) for v in d_all)
                terms = (area, dr.select(inside, area, 0.0)) + d_all + d_out
                acc = [s + v for s, v in zip(acc, terms)]
            return acc

        return pose_sums(
            active,
            self._pairs[0],
            self.pose_count,
            OUTLINE_SUMS,
            self._context(rows, t, pose_hole),
            accumulate,
            "overlap outline",
        )

    def _hole_pairs(self, holes: HoleStack, pose_hole):
        """(pose, hole edge) pairs, pose-major, with each pair's edge (cached per stack)."""
        mi = self.mi
        cache = self._hole_cache
        if cache is not None and cache[0] is holes and cache[1] is pose_hole:
            return cache[2]
        n = self.frame.resolution
        inside = np.asarray(holes.texture, dtype=np.float32).reshape(holes.count, n, n) <= 0
        edges = [hole_edges(m, self.frame) for m in inside]
        which = np.asarray(pose_hole, dtype=np.int64)
        counts = np.array([len(e[0]) for e in edges], dtype=np.int64)[which]
        pair_pose = np.repeat(np.arange(len(which)), counts)
        x, y, nx = (
            np.concatenate([edges[h][i] for h in which]) if len(which) else np.zeros(0)
            for i in range(3)
        )
        pairs = (
            mi.UInt32(pair_pose.astype(np.uint32)),
            mi.Float(x.astype(np.float32)),
            mi.Float(y.astype(np.float32)),
            mi.Float((nx * self.frame.pixel_size).astype(np.float32)),
        )
        self._hole_cache = (holes, pose_hole, pairs)
        return pairs

    def _hole_edge_sums(self, rows, t, holes: HoleStack, pose_hole):
        """Per pose, Σ over its hole's vertical boundary edges inside S of (x - t_x) n_x h, (K,)."""
        dr, mi = self.dr, self.mi
        pair_pose, ex, ey, enh = self._hole_pairs(holes, pose_hole)
        prepare = self._context(rows, t, pose_hole)

        def accumulate(pair, ctx, acc):
            g, _, shape = ctx
            x, y = dr.gather(mi.Float, ex, pair), dr.gather(mi.Float, ey, pair)
            dx, dy = x - g[9], y - g[10]
            near = dx * dx + dy * dy <= dr.square(dr.gather(mi.Float, self._radius, shape))
            hit = self._covered(x, y, g, shape, near)
            return [acc[0] + dr.select(hit, dx * dr.gather(mi.Float, enh, pair), 0.0)]

        active = dr.arange(mi.UInt32, dr.width(pair_pose))
        return pose_sums(
            active, pair_pose, self.pose_count, 1, prepare, accumulate, "overlap hole edges"
        )[0]
