"""The clearance objective: a containment loss on B's silhouette edges (Dr.Jit, batched).

When H is simply connected (or a disjoint union of simply connected pieces), proj(B) lies in H iff
every *silhouette edge* of B projects into H: the outline of a union of triangles is made of such
edges, and a bounded region whose outline lies in H cannot contain a point outside H, because the
complement of H is connected and unbounded. So

    L(R, t) = sum over samples s on silhouette edges of  d_H(P(R s) + t)^2,

with d_H the distance to H (bilinear in H's distance transform, in pixels), is zero iff B fits (up to
the raster), and has useful gradients even when B is far outside H.

All poses of all shapes (particles x shapes x starts) are evaluated in one kernel per step: per step
the silhouette test runs over every (pose, segment) pair, :func:`drjit.compress` keeps the active
ones, and the loss is evaluated on their samples only.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.hole import Hole
from sieve_mi.meshes import Shape, segments
from sieve_mi.raster import Frame


def _quat_rows(dr, mi, qw, qx, qy, qz):
    """Rotation matrix entries (row-major, 9 arrays) of the normalised quaternion (qw, qx, qy, qz)."""
    n = dr.rsqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, x, y, z = qw * n, qx * n, qy * n, qz * n
    return (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )


def auto_samples(shapes: list[Shape], spacing: float, most: int = 4) -> int:
    """Samples per segment from the median edge length (in units of ``spacing``), in [1, most]."""
    from sieve_mi.meshes import edge_topology

    lengths = []
    for s in shapes:
        edges = edge_topology(s.vertices, s.faces)[0]
        lengths.append(np.linalg.norm(s.vertices[edges[:, 0]] - s.vertices[edges[:, 1]], axis=1))
    median = float(np.median(np.concatenate(lengths))) / spacing
    return int(np.clip(np.ceil(median), 1, most))


class HoleStack:
    """Several holes on one frame, as one flat Dr.Jit array of outside distances in pixels.

    Parameters
    ----------
    holes : list of Hole
        All on the same frame.
    """

    def __init__(self, holes: list[Hole]):
        import mitsuba as mi

        frame = holes[0].frame
        if any(h.frame != frame for h in holes):
            raise ValueError("all holes of a stack must share one frame")
        self.frame = frame
        self.count = len(holes)
        stack = np.stack([h.outside for h in holes]) / frame.pixel_size
        self.texture = mi.Float(stack.astype(np.float32).ravel())


class ClearanceObjective:
    """Clearance loss of several shapes, for many poses at once.

    Parameters
    ----------
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
        The hole's raster frame; its pixel size sets the sample spacing.
    samples_per_segment : int, optional
        Samples per edge segment (segments are at most this many pixels long). By default it is
        chosen from the edge lengths: the median edge length in pixels, between 1 and 4, so that
        meshes whose edges are shorter than a pixel get one sample per edge instead of four.
    """

    def __init__(self, shapes: list[Shape], frame: Frame, samples_per_segment: int | None = None):
        import drjit as dr
        import mitsuba as mi

        self.dr, self.mi = dr, mi
        self.frame = frame
        if samples_per_segment is None:
            samples_per_segment = auto_samples(shapes, frame.pixel_size)
        self.samples = int(samples_per_segment)
        segs = [segments(s, frame.pixel_size, self.samples) for s in shapes]
        self.counts = np.array([len(s) for s in segs], dtype=np.int64)
        self.offsets = np.concatenate([[0], np.cumsum(self.counts)[:-1]])

        def cat(attr):
            a = np.concatenate([getattr(s, attr) for s in segs]).astype(np.float32)
            return mi.Vector3f(a[:, 0], a[:, 1], a[:, 2])

        self.a = cat("a")
        d = np.concatenate([s.b - s.a for s in segs]).astype(np.float32)
        self.d = mi.Vector3f(d[:, 0], d[:, 1], d[:, 2])
        self.m1, self.m2 = cat("m1"), cat("m2")
        self.always = mi.Bool(np.concatenate([s.always for s in segs]))
        self._pairs = None

    @property
    def segment_count(self) -> int:
        return int(self.counts.sum())

    def bind(self, pose_shape: np.ndarray) -> None:
        """Fix which shape each pose belongs to (builds the (pose, segment) pair list).

        Parameters
        ----------
        pose_shape : (K,) ndarray of int
            Index into ``shapes`` for every pose.
        """
        mi = self.mi
        pose_shape = np.asarray(pose_shape, dtype=np.int64)
        n = self.counts[pose_shape]
        pair_pose = np.repeat(np.arange(len(pose_shape)), n)
        start = np.repeat(self.offsets[pose_shape] - (np.cumsum(n) - n), n)
        pair_seg = np.arange(int(n.sum())) + start
        self._pairs = (
            mi.UInt32(pair_pose.astype(np.uint32)),
            mi.UInt32(pair_seg.astype(np.uint32)),
        )
        self.pose_count = len(pose_shape)

    def loss(self, q, t, holes: HoleStack, pose_hole):
        """Total and per-pose clearance loss (pixels squared).

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
            Sum over all poses (differentiable).
        per_pose : mi.Float
            Loss of each pose (detached).
        """
        dr, mi = self.dr, self.mi
        pair_pose, pair_seg = self._pairs
        rows = _quat_rows(dr, mi, *q)
        with dr.suspend_grad():
            r3 = mi.Vector3f(dr.detach(rows[6]), dr.detach(rows[7]), dr.detach(rows[8]))
            r3p = dr.gather(mi.Vector3f, r3, pair_pose)
            s1 = dr.dot(r3p, dr.gather(mi.Vector3f, self.m1, pair_seg))
            s2 = dr.dot(r3p, dr.gather(mi.Vector3f, self.m2, pair_seg))
            flag = (s1 * s2 >= 0) | dr.gather(mi.Bool, self.always, pair_seg)
            active = dr.compress(flag)
        n_active = dr.width(active)
        if n_active == 0:
            zero = dr.zeros(mi.Float, self.pose_count)
            return dr.sum(zero), zero
        idx = dr.arange(mi.UInt32, n_active * self.samples)
        pair = dr.gather(mi.UInt32, active, idx // self.samples)
        frac = (mi.Float(idx % self.samples) + 0.5) / self.samples
        pose = dr.gather(mi.UInt32, pair_pose, pair)
        seg = dr.gather(mi.UInt32, pair_seg, pair)
        p = dr.gather(mi.Vector3f, self.a, seg) + dr.gather(mi.Vector3f, self.d, seg) * frac
        g = [dr.gather(mi.Float, r, pose) for r in rows[:6]]
        x = g[0] * p.x + g[1] * p.y + g[2] * p.z + dr.gather(mi.Float, t[0], pose)
        y = g[3] * p.x + g[4] * p.y + g[5] * p.z + dr.gather(mi.Float, t[1], pose)
        dist = self._lookup(x, y, holes, dr.gather(mi.UInt32, pose_hole, pose))
        value = dist * dist
        per_pose = dr.zeros(mi.Float, self.pose_count)
        dr.scatter_reduce(dr.ReduceOp.Add, per_pose, dr.detach(value), pose)
        return dr.sum(value), per_pose

    def _lookup(self, x, y, holes: HoleStack, hole_index):
        """Distance to H in pixels at world points (x, y): bilinear inside the frame, extended outside."""
        dr, mi = self.dr, self.mi
        f = holes.frame
        n = f.resolution
        inv_h = 1.0 / f.pixel_size
        u = (x + f.half_extent) * inv_h - 0.5
        v = (f.half_extent - y) * inv_h - 0.5
        uc = dr.clip(u, 0.0, n - 1.0)
        vc = dr.clip(v, 0.0, n - 1.0)
        e2 = dr.square(u - uc) + dr.square(v - vc)
        extra = dr.sqrt(e2 + 1e-6) - 1e-3
        iu = dr.minimum(mi.UInt32(dr.floor(dr.detach(uc))), n - 2)
        iv = dr.minimum(mi.UInt32(dr.floor(dr.detach(vc))), n - 2)
        fu, fv = uc - mi.Float(iu), vc - mi.Float(iv)
        base = hole_index * (n * n) + iv * n + iu
        tex = holes.texture
        d00 = dr.gather(mi.Float, tex, base)
        d01 = dr.gather(mi.Float, tex, base + 1)
        d10 = dr.gather(mi.Float, tex, base + n)
        d11 = dr.gather(mi.Float, tex, base + n + 1)
        d = dr.lerp(dr.lerp(d00, d01, fu), dr.lerp(d10, d11, fu), fv)
        return d + extra
