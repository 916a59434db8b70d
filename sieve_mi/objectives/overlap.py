"""The paper's overlap loss (eq. 12) for all poses at once, differentiated by edge sampling.

For a pose (R, t) of a shape B with silhouette S, the loss is the fraction of S outside the hole,

    beta = area(S \\ H) / area(S) = 1 - area(S ∩ H) / area(S),

with H the union of the hole raster's pixel cells whose centre lies in H (outside distance 0).
Both areas and their derivatives are integrals over B's *visible outline* ∂S, which lies on B's
silhouette edges (:class:`sieve_mi.objectives.edges.EdgeSampledObjective` cuts them into segments of at most
``samples_per_segment`` pixels and samples them at most a pixel apart; dl is a sample's share of
its segment's projected length).

* **Visibility.** A segment is on ∂S iff the point a hundredth of a pixel beside its midpoint, on
  the side away from its two faces, is not covered by B (one batched any-hit ``ray_test`` in B's
  frame, as in :mod:`sieve_mi.geometry.silhouettes`); the outward normal n points there. Boundary and
  non-manifold edges have no "inner" side: both sides are tested and exactly one must be covered.
  Near a junction where the outline passes from one edge to another, a segment is thus counted
  whole or not at all (an error of a fraction of a segment's length).
* **Area** (Green's theorem): area(S) = ∮_∂S (x - t_x) n_x dl, exact on straight segments.
* **Area outside H**: area(S \\ H) = ∮_∂S P n_x dl with P(x, y) the length outside H in y's
  pixel row between t_x and x (signed), read from a per-row prefix sum of the cells outside H;
  ∂P/∂x = 1_out, which is all Green's theorem needs. Where the horizontal chord from t_x to the
  outline point lies in H (B inside H and star-shaped about its centre), P = 0 and β = 0 exactly;
  where it misses H, P = x - t_x. Elsewhere P jumps between pixel rows by the change of H's
  boundary from one row to the next, which costs a fraction of a pixel's area per row crossing.
* **Gradient** (Reynolds transport; what Mitsuba's projective integrators estimate): with v the
  velocity of an outline point under a change of (R, t),
  d area(S)/dθ = ∮_∂S (v·n) dl and d area(S \\ H)/dθ = ∮_∂S 1_out (v·n) dl, and
  dβ/dθ = (d area(S \\ H) - β d area(S)) / area(S). The outline point is
  x = R_{0,:} p + t_x, y = R_{1,:} p + t_y for its mesh-frame point p, so v·n is linear in the
  first two rows of R and in t; the 16 per-pose sums of n_x, n_y, n_x p and n_y p (with and
  without 1_out) are added in a fixed order (:func:`sieve_mi.objectives.pairs.pose_sums`) and chained to
  the quaternion by per-pose arithmetic, as for the clearance loss: the results are reproducible
  bit for bit.

Cost per step: one ray per silhouette-edge segment (3 % of the sphere's edges for a random
rotation) and a few texture reads per sample, instead of one Mitsuba render and BVH rebuild per
pose (:mod:`sieve_mi.objectives.overlap_mitsuba`, ``"overlap-mitsuba"``). Coincident silhouette edges of separate
parts (two boxes sharing a face plane) are counted once each, so such meshes get too large an
outline there; the raster scores that decide results are not affected.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.hole import HoleStack
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import quat_rows
from sieve_mi.geometry.silhouettes import mesh_scene
from sieve_mi.objectives.edges import EdgeSampledObjective
from sieve_mi.objectives.pairs import pose_sums

__all__ = ["EdgeOverlapObjective", "OUTLINE_SUMS", "SIDE_OFFSET"]

#: The two side points of an outline sample are this many pixels from it.
SIDE_OFFSET = 0.01
#: Per-pose sums of :meth:`EdgeOverlapObjective._outline_sums`: area, area inside H, the 8 sums
#: of d area, the 8 sums of d area outside H.
OUTLINE_SUMS = 18


class EdgeOverlapObjective(EdgeSampledObjective):
    """Overlap loss β (paper eq. 12) of several shapes for many poses at once, by edge sampling.

    An :class:`~sieve_mi.objectives.Objective` (see there for :meth:`bind` and :meth:`loss`); the
    method is in the module docstring. Its edge segments, (pose, segment) pairs and
    silhouette-edge test are those of the clearance objective (:class:`EdgeSampledObjective`).

    Parameters
    ----------
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
        The hole's raster frame; samples are at most a pixel apart.
    samples_per_segment : int, optional
        As for :class:`~sieve_mi.objectives.edges.EdgeSampledObjective`.
    """

    def __init__(self, shapes: list[Shape], frame: Frame, samples_per_segment: int | None = None):
        super().__init__(shapes, frame, samples_per_segment)
        h = frame.pixel_size
        # Ray origins sit this far below the shape's centre (as in SilhouetteRenderer.trace).
        self._reach = np.array([s.radius * 1.01 + h for s in shapes])
        self._scene, offsets = _shelf_scene(shapes, 3.0 * float(self._reach.max()))
        # On the device once: arrays made inside a symbolic loop's body would not outlive it.
        self._reach_dev = self.mi.Float(self._reach.astype(np.float32))
        self._sites = self.mi.Point3f(offsets.astype(np.float32).T)
        self._prefix_cache = None

    def bind(self, pose_shape: np.ndarray) -> None:
        """See :meth:`sieve_mi.objectives.Objective.bind`.

        Also keeps each pose's shape index on the device, for the visibility rays.
        """
        super().bind(pose_shape)
        self._pose_shape = self.mi.UInt32(np.asarray(pose_shape).astype(np.uint32))

    def loss(self, q, t, holes: HoleStack, pose_hole, live=None):
        """See :meth:`sieve_mi.objectives.Objective.loss` (no ``fit_loss``: ``live`` is refused).

        ``per_pose`` is β, the fraction of each silhouette outside its hole, in [0, 1]; 1 for a
        pose whose outline has no length. The gradient of ``total`` with respect to ``q`` and
        ``t`` is the edge-sampled one (module docstring). Raises ValueError when ``holes`` is on
        another frame.
        """
        dr = self.dr
        self._no_live(live)
        if holes.frame != self.frame:
            raise ValueError("the hole stack's frame differs from the objective's frame")
        rows = quat_rows(*q)
        with dr.suspend_grad():
            r = [dr.detach(x) for x in rows]
            td = (dr.detach(t[0]), dr.detach(t[1]))
            s = self._outline_sums(self._active_pairs(rows), r, td, holes, pose_hole)
            area = s[0]
            ok = area > 1e-3 * self.frame.pixel_size**2
            safe = dr.select(ok, area, 1.0)
            raw = s[1] / safe
            per_pose = dr.select(ok, dr.clip(raw, 0.0, 1.0), 1.0)
            coef = [dr.select(ok, (s[10 + i] - raw * s[2 + i]) / safe, 0.0) for i in range(8)]
        return self._link(dr.sum(per_pose), q, t, rows, coef), per_pose

    def _covered(self, x, y, g, shape, active=True):
        """Whether world points (x, y) are covered by their pose's shape (one ray each).

        ``g`` holds the pose's 9 rotation entries and 2 translations (gathered per lane),
        ``shape`` its shape index. Every shape lies in one scene, each at its own place
        (:func:`_shelf_scene`): one ray test per point, against one BVH.
        """
        mi, dr = self.mi, self.dr
        dx, dy = x - g[9], y - g[10]
        reach = dr.gather(mi.Float, self._reach_dev, shape)
        place = dr.gather(mi.Point3f, self._sites, shape)
        origin = mi.Point3f(
            dx * g[0] + dy * g[3] - reach * g[6],
            dx * g[1] + dy * g[4] - reach * g[7],
            dx * g[2] + dy * g[5] - reach * g[8],
        )
        ray = mi.Ray3f(origin + place, mi.Vector3f(g[6], g[7], g[8]))
        ray.maxt = 2.0 * reach
        return self._scene.ray_test(ray, active)

    def _prefix(self, holes: HoleStack):
        """Per hole and pixel row, the length outside H left of each cell edge: (count N (N + 1),).

        Entry ``(k N + row) (N + 1) + c`` is h times the number of cells of row ``row`` of hole
        ``k`` left of column ``c`` that are not in H. Cached for the last stack.
        """
        if self._prefix_cache is not None and self._prefix_cache[0] is holes:
            return self._prefix_cache[1]
        n = self.frame.resolution
        outside = np.asarray(holes.texture, dtype=np.float32).reshape(holes.count, n, n) > 0
        prefix = np.zeros((holes.count, n, n + 1), dtype=np.float64)
        np.cumsum(outside, axis=2, out=prefix[:, :, 1:])
        prefix = self.mi.Float((prefix * self.frame.pixel_size).astype(np.float32).ravel())
        self._prefix_cache = (holes, prefix)
        return prefix

    def _cell(self, x, y):
        """Lattice column and row (mi.Int32) of the pixel cells holding world points (x, y)."""
        dr, mi = self.dr, self.mi
        f = self.frame
        inv_h = 1.0 / f.pixel_size
        return (
            mi.Int32(dr.floor((x + f.half_extent) * inv_h)),
            mi.Int32(dr.floor((f.half_extent - y) * inv_h)),
        )

    def _in_hole(self, col, row, holes: HoleStack, hole):
        """Whether pixel cells (col, row) of the lattice lie in their hole (beyond the frame: no)."""
        dr, mi = self.dr, self.mi
        n = self.frame.resolution
        on = (col >= 0) & (col < n) & (row >= 0) & (row < n)
        d = holes.gather(hole, mi.UInt32(dr.maximum(row, 0)), mi.UInt32(dr.maximum(col, 0)), on)
        return on & (d <= 0)

    def _outside_left_of(self, x, row, holes: HoleStack, hole, prefix):
        """Length outside H in pixel row ``row`` left of x, from the frame's left edge (scene
        units; negative left of the frame, all outside beyond the frame)."""
        dr, mi = self.dr, self.mi
        f = self.frame
        n, h = f.resolution, f.pixel_size
        u = (x + f.half_extent) / h
        uc = dr.clip(u, 0.0, float(n))
        col = dr.minimum(mi.Int32(dr.floor(uc)), n - 1)
        row_on = (row >= 0) & (row < n)
        base = (mi.UInt32(hole) * n + mi.UInt32(dr.maximum(row, 0))) * (n + 1)
        left = dr.gather(mi.Float, prefix, base + mi.UInt32(col), row_on)
        cell = dr.select(self._in_hole(col, row, holes, hole), 0.0, h)
        return dr.select(row_on, left + (uc - mi.Float(col)) * cell + (u - uc) * h, u * h)

    def _outline_sums(self, active, rows, t, holes: HoleStack, pose_hole) -> list:
        """The 18 per-pose sums over the outline samples of the active (pose, segment) pairs.

        Returns
        -------
        list of 18 mi.Float, each (K,)
            area(S); area(S \\ H); ∮ (n_x, n_y, n_x p, n_y p) dl (8: the
            derivatives of area(S) with respect to t and the first two rows of R); the same 8
            restricted to outline points outside H. Scene units.
        """
        dr, mi = self.dr, self.mi
        fracs = self._fractions()
        off = SIDE_OFFSET * self.frame.pixel_size
        prefix = self._prefix(holes)

        def accumulate(pair, ctx, acc):
            g, hole, shape = ctx
            seg, a, d = self._segment(pair)
            ex = g[0] * d.x + g[1] * d.y + g[2] * d.z
            ey = g[3] * d.x + g[4] * d.y + g[5] * d.z
            length = dr.sqrt(ex * ex + ey * ey)
            inv = dr.select(length > 0, dr.rcp(length), 0.0)
            nx, ny = ey * inv, -ex * inv  # a unit normal of the projected segment
            # Both faces of a manifold silhouette edge project to its inner side: the face to the
            # left of the projected segment when r3 . m1 > 0 (m2 if the first face is edge-on).
            # That side is covered; only the other one needs a ray. Others get both.
            always = dr.gather(mi.Bool, self.always, seg)
            r3 = mi.Vector3f(g[6], g[7], g[8])
            s1 = dr.dot(r3, dr.gather(mi.Vector3f, self.m1, seg))
            s1 = dr.select(s1 == 0, dr.dot(r3, dr.gather(mi.Vector3f, self.m2, seg)), s1)
            left_in, right_in = ~always & (s1 > 0), ~always & (s1 <= 0)
            # The segment (at most samples_per_segment pixels long) is on the outline iff its
            # midpoint is: exactly one side covered; n points to the other one.
            mid = a + d * 0.5
            x = g[0] * mid.x + g[1] * mid.y + g[2] * mid.z + g[9]
            y = g[3] * mid.x + g[4] * mid.y + g[5] * mid.z + g[10]
            plus = right_in | self._covered(x + off * nx, y + off * ny, g, shape, ~right_in)
            minus = left_in | self._covered(x - off * nx, y - off * ny, g, shape, ~left_in)
            w = dr.select(plus ^ minus, dr.select(minus, 1.0, -1.0) * length, 0.0)
            wx, wy = w * (nx / self.samples), w * (ny / self.samples)
            for frac in fracs:
                p = a + d * frac
                x = g[0] * p.x + g[1] * p.y + g[2] * p.z + g[9]
                y = g[3] * p.x + g[4] * p.y + g[5] * p.z + g[10]
                col, row = self._cell(x, y)
                inside = self._in_hole(col, row, holes, hole)
                area = wx * (x - g[9])
                # The length outside H in this row between the pose's centre and the point
                # (Green's theorem for the area of S \\ H, see the module docstring).
                out_h = self._outside_left_of(x, row, holes, hole, prefix)
                out_h = out_h - self._outside_left_of(g[9], row, holes, hole, prefix)
                d_all = (wx, wy, wx * p.x, wx * p.y, wx * p.z, wy * p.x, wy * p.y, wy * p.z)
                d_out = tuple(dr.select(inside, 0.0, v) for v in d_all)
                terms = (area, wx * out_h) + d_all + d_out
                acc = [s + v for s, v in zip(acc, terms)]
            return acc

        return pose_sums(
            active,
            self._pairs[0],
            self.pose_count,
            OUTLINE_SUMS,
            self._context(rows, t, pose_hole, self._pose_shape),
            accumulate,
            "overlap outline",
        )


def _shelf_scene(shapes: list[Shape], spacing: float):
    """One Mitsuba scene holding every shape, each moved to its own lattice site.

    On ``cuda_ad_mono`` a kernel may trace rays against one scene only (OptiX takes one
    pipeline and one shader binding table per kernel and silently disables the others' ray
    tests), so the visibility rays of all shapes go to one BVH; on the CPU it is one BVH too.
    Shape ``k`` sits at ``offsets[k]``, sites of a cubic lattice ``spacing`` apart: a visibility
    ray of shape k stays within about 1.42 reach of its site (its points are within the
    silhouette's pixel band, its segment 2 reach long), so with ``spacing`` = 3 x the largest
    reach it never meets another shape.

    Parameters
    ----------
    shapes : list of Shape
        Centred meshes, mm.
    spacing : float
        Distance between neighbouring sites, mm.

    Returns
    -------
    scene : mitsuba.Scene
    offsets : (K, 3) ndarray of float
        Each shape's site, mm.
    """
    side = max(1, int(np.ceil(len(shapes) ** (1.0 / 3.0) - 1e-9)))
    k = np.arange(len(shapes))
    offsets = spacing * np.column_stack([k % side, (k // side) % side, k // (side * side)])
    offsets = offsets.astype(np.float64)
    counts = np.cumsum([0] + [len(s.vertices) for s in shapes])
    vertices = np.vstack([s.vertices + o for s, o in zip(shapes, offsets)])
    faces = np.vstack([s.faces + c for s, c in zip(shapes, counts)])
    return mesh_scene(vertices, faces, "shapes"), offsets
