"""The clearance objective: a containment loss on B's silhouette edges (Dr.Jit, batched).

When H is simply connected (or a disjoint union of simply connected pieces), proj(B) lies in H iff
every *silhouette edge* of B projects into H: the outline of a union of triangles is made of such
edges, and a bounded region whose outline lies in H cannot contain a point outside H, because the
complement of H is connected and unbounded. So

    L(R, t) = sum over samples s on silhouette edges of  d_H(P(R s) + t)^2,

with d_H the distance to H (bilinear in H's distance transform, in pixels), is zero iff B fits (up to
the raster), and has useful gradients even when B is far outside H.

All poses of all shapes (particles x shapes x starts) are evaluated in one kernel per step: per step
the silhouette test runs over every (pose, edge) pair (it depends on the edge only),
:func:`drjit.compress` keeps the active ones, they are expanded into their segments' (pose,
segment) pairs (:func:`expand_ranges`), and the loss is evaluated on their samples only. Where
edges are about one segment long, the test runs per (pose, segment) directly.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.hole import HoleStack
from sieve_mi.geometry.meshes import Shape, segments
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import quat_rows

__all__ = [
    "CHUNK",
    "ClearanceObjective",
    "PER_EDGE_RATIO",
    "auto_samples",
    "expand_ranges",
    "pose_ranges",
    "pose_sums",
]

#: Active (pose, segment) pairs that one thread sums in the first level of the per-pose reduction
#: (:meth:`ClearanceObjective._pose_sums`). Fixed, so results do not depend on the machine.
CHUNK = 16
#: Segments per edge from which the silhouette test runs per (pose, edge), not per segment.
PER_EDGE_RATIO = 1.5


def _edge_table(segs: list) -> dict:
    """Per edge of every shape (concatenated): the silhouette-test vectors and its segments.

    Returns
    -------
    dict
        ``m1``, ``m2`` ((E, 3) float32), ``always`` ((E,) bool), ``pieces`` (segments per edge),
        ``first_local`` (its first segment's index within its shape), ``count`` (edges per
        shape) and ``offset`` (each shape's first edge).
    """
    m1, m2, always, pieces, first_local, count = [], [], [], [], [], []
    for s in segs:
        k = np.bincount(s.parent, minlength=int(s.parent[-1]) + 1 if len(s.parent) else 0)
        start = np.cumsum(k) - k
        m1.append(s.m1[start])
        m2.append(s.m2[start])
        always.append(s.always[start])
        pieces.append(k)
        first_local.append(start)
        count.append(len(k))
    count = np.array(count, dtype=np.int64)
    return {
        "m1": np.concatenate(m1).astype(np.float32),
        "m2": np.concatenate(m2).astype(np.float32),
        "always": np.concatenate(always),
        "pieces": np.concatenate(pieces),
        "first_local": np.concatenate(first_local),
        "count": count,
        "offset": np.cumsum(count) - count,
    }


def expand_ranges(start, length):
    """The integers ``start[j], ..., start[j] + length[j] - 1`` for every j, in order (mi.UInt32).

    ``length`` must be positive. Reads back the total length (one synchronisation).

    Examples
    --------
    start (3, 10), length (2, 3) -> (3, 4, 10, 11, 12).
    """
    import drjit as dr
    import mitsuba as mi

    if dr.width(start) == 0:
        return dr.zeros(mi.UInt32, 0)
    return _ranges(start, length, int(dr.sum(length)[0]))[1]


def _ranges(start, length, total: int):
    """:func:`expand_ranges` with its ``total`` given: (range index j, integer) of every entry."""
    import drjit as dr
    import mitsuba as mi

    offset = dr.prefix_sum(length)  # exclusive
    marks = dr.zeros(mi.UInt32, total)
    dr.scatter(marks, mi.UInt32(1), offset, offset > 0)
    entry = dr.cumsum(marks)  # inclusive
    i = dr.arange(mi.UInt32, total)
    return entry, dr.gather(mi.UInt32, start, entry) + (i - dr.gather(mi.UInt32, offset, entry))


def pose_ranges(start: np.ndarray, length: np.ndarray):
    """Pose-major pairs: pose j gets the items ``start[j], ..., start[j] + length[j] - 1``.

    Built on the device (:func:`expand_ranges`' scan); poses with no items get none.

    Parameters
    ----------
    start, length : (K,) ndarrays of int
        Each pose's first item and item count (``length`` >= 0).

    Returns
    -------
    pose, item : mi.UInt32
        ``sum(length)`` entries each, pose-major.

    Examples
    --------
    start (3, 10, 7), length (2, 0, 3) -> pose (0, 0, 2, 2, 2), item (3, 4, 7, 8, 9).
    """
    import drjit as dr
    import mitsuba as mi

    start, length = np.asarray(start, dtype=np.int64), np.asarray(length, dtype=np.int64)
    some = np.flatnonzero(length > 0)
    if len(some) == 0:
        return dr.zeros(mi.UInt32, 0), dr.zeros(mi.UInt32, 0)
    entry, item = _ranges(
        mi.UInt32(start[some].astype(np.uint32)),
        mi.UInt32(length[some].astype(np.uint32)),
        int(length[some].sum()),
    )
    pose = dr.gather(mi.UInt32, mi.UInt32(some.astype(np.uint32)), entry)
    dr.eval(pose, item)
    return pose, item


def auto_samples(shapes: list[Shape], spacing: float, most: int = 4) -> int:
    """Samples per segment from the median edge length (in units of ``spacing``), in [1, most]."""
    from sieve_mi.geometry.meshes import edge_topology

    lengths = []
    for s in shapes:
        edges = edge_topology(s.vertices, s.faces)[0]
        lengths.append(np.linalg.norm(s.vertices[edges[:, 0]] - s.vertices[edges[:, 1]], axis=1))
    median = float(np.median(np.concatenate(lengths))) / spacing
    return int(np.clip(np.ceil(median), 1, most))


class ClearanceObjective:
    """Clearance loss of several shapes, for many poses at once (an :class:`~sieve_mi.objectives.Objective`).

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

    #: :meth:`loss_fixed` computes this loss, so player B may freeze its steps (:mod:`sieve_mi.game.frozen`).
    freezable = True
    #: The Dr.Jit arrays a frozen function (:func:`drjit.freeze`) must see as its inputs.
    DRJIT_STRUCT = {
        "a": object,
        "d": object,
        "m1": object,
        "m2": object,
        "always": object,
        "_pairs": object,
        "_pose_ends": object,
        "e_m1": object,
        "e_m2": object,
        "e_always": object,
        "_edge_pairs": object,
        "_edge_pose_ends": object,
    }

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
        self._edges = _edge_table(segs)
        self.e_m1, self.e_m2 = (mi.Vector3f(*self._edges[k].T) for k in ("m1", "m2"))
        self.e_always = mi.Bool(self._edges["always"])
        # testing per edge pays where edges are cut into several segments (not for fine meshes)
        self.per_edge = self.segment_count >= PER_EDGE_RATIO * len(self._edges["pieces"])
        self._pairs = None
        self._pose_ends = None
        self._edge_pairs = None
        self._edge_pose_ends = None

    @property
    def segment_count(self) -> int:
        return int(self.counts.sum())

    @property
    def pair_count(self) -> int:
        """Number of (pose, segment) pairs of the bound poses."""
        return 0 if self._pairs is None else self.dr.width(self._pairs[0])

    def bind(self, pose_shape: np.ndarray) -> None:
        """Fix which shape each pose belongs to (builds the (pose, segment) pair list).

        The pair lists are built on the device (:func:`pose_ranges`): only per-pose numbers go
        through NumPy, so binding 100 poses of a 70k-face mesh takes milliseconds and no host
        copies of the K x S pairs.

        Parameters
        ----------
        pose_shape : (K,) ndarray of int
            Index into ``shapes`` for every pose.
        """
        mi = self.mi
        pose_shape = np.asarray(pose_shape, dtype=np.int64)
        n = self.counts[pose_shape]
        self._pairs = pose_ranges(self.offsets[pose_shape], n)
        # Each pose's first pair and one past its last (pairs are pose-major).
        ends = np.cumsum(n)
        self._pose_ends = (
            mi.UInt32((ends - n).astype(np.uint32)),
            mi.UInt32(ends.astype(np.uint32)),
        )
        self.pose_count = len(pose_shape)
        self._bind_edges(pose_shape, ends - n)

    def _bind_edges(self, pose_shape: np.ndarray, pose_first_pair: np.ndarray) -> None:
        """The (pose, edge) pairs, each with its first (pose, segment) pair and segment count."""
        dr, mi, e = self.dr, self.mi, self._edges
        n = e["count"][pose_shape]
        pair_pose, pair_edge = pose_ranges(e["offset"][pose_shape], n)
        first = dr.gather(
            mi.UInt32, mi.UInt32(pose_first_pair.astype(np.uint32)), pair_pose
        ) + dr.gather(mi.UInt32, mi.UInt32(e["first_local"].astype(np.uint32)), pair_edge)
        pieces = dr.gather(mi.UInt32, mi.UInt32(e["pieces"].astype(np.uint32)), pair_edge)
        # Each pose's first (pose, edge) pair and one past its last (pose-major, as for segments).
        ends = np.cumsum(n)
        self._edge_pose_ends = (
            mi.UInt32((ends - n).astype(np.uint32)),
            mi.UInt32(ends.astype(np.uint32)),
        )
        self._edge_pairs = (pair_pose, pair_edge, first, pieces)
        dr.eval(self._edge_pairs)

    def loss(self, q, t, holes: HoleStack, pose_hole):
        """Total and per-pose clearance loss (pixels squared), summed in a fixed order.

        Every sum runs in an order that depends only on the inputs, never on thread scheduling,
        so the same inputs give the same bits on every run (see :meth:`_pose_sums`). The gradient
        with respect to ``q`` and ``t`` is the loss' exact gradient, reduced per pose the same way
        and attached to the AD graph through per-pose (element-wise) operations only.

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
            Sum over all poses (differentiable with respect to ``q`` and ``t``).
        per_pose : mi.Float
            Loss of each pose (detached).
        """
        return self._loss(q, t, holes, pose_hole)[:2]

    def loss_fixed(self, q, t, holes: HoleStack, pose_hole, capacity: int):
        """:meth:`loss` without data-dependent sizes or reads, for :func:`drjit.freeze`.

        The active pairs go into a buffer of ``capacity`` entries (in the same ascending order as
        :meth:`_active_pairs`), so the sums, and the results, are the same as :meth:`loss`'s as
        long as no more than ``capacity`` pairs are active.

        Returns
        -------
        total, per_pose : mi.Float
            As for :meth:`loss`.
        overflow : mi.Bool
            One entry: more than ``capacity`` pairs were active (the results are then wrong).
        """
        return self._loss(q, t, holes, pose_hole, capacity)

    def capacity(self, q) -> int:
        """A buffer size for :meth:`loss_fixed` at poses near quaternions ``q`` (4 mi.Float).

        Twice the active pairs at ``q``, rounded up to a power of two (at least 1024), so that
        attacks of the same size share one recording of a frozen step.
        """
        dr = self.dr
        with dr.suspend_grad():
            active = dr.width(self._active_pairs(quat_rows(*[dr.detach(x) for x in q])))
        total = dr.width(self._pairs[0])
        return int(min(max(1024, 1 << int(np.ceil(np.log2(max(2 * active, 1))))), max(total, 1)))

    def _loss(self, q, t, holes: HoleStack, pose_hole, capacity: int | None = None):
        """:meth:`loss` (``capacity`` None) or :meth:`loss_fixed`: total, per_pose, overflow."""
        dr, mi = self.dr, self.mi
        rows = quat_rows(*q)
        with dr.suspend_grad():
            r = [dr.detach(x) for x in rows[:6]]
            td = (dr.detach(t[0]), dr.detach(t[1]))
            if capacity is None:
                active, layout, overflow = self._active_pairs(rows), None, mi.Bool(False)
            else:
                active, count, overflow = self._active_fixed(rows, capacity)
                layout = (count, capacity // CHUNK + self.pose_count)
            sums = self._pose_sums(active, r, td, holes, pose_hole, layout)
        per_pose = sums[0]
        total = dr.sum(per_pose)
        if dr.grad_enabled(q, t):
            # d total / d(q, t) = sum over rows of (d row / d(q, t)) * (d L / d row): per pose.
            link = t[0] * sums[1] + t[1] * sums[2]
            for i in range(6):
                link = link + rows[i] * sums[3 + i]
            link = dr.sum(link)
            total = total + (link - dr.detach(link))
        return total, per_pose, overflow

    def _silhouette_flags(self, rows):
        """Whether each (pose, segment) pair's segment is on the silhouette (mi.Bool)."""
        pair_pose, pair_seg = self._pairs
        return self._flags(rows, pair_pose, pair_seg, self.m1, self.m2, self.always)

    def _flags(self, rows, pose, item, m1, m2, always):
        """The silhouette test ``(r3 . m1)(r3 . m2) >= 0 or always`` of (pose, item) pairs, where
        items are segments or edges (``m1``, ``m2``, ``always`` indexed by ``item``)."""
        dr, mi = self.dr, self.mi
        with dr.suspend_grad():
            r3 = mi.Vector3f(dr.detach(rows[6]), dr.detach(rows[7]), dr.detach(rows[8]))
            r3p = dr.gather(mi.Vector3f, r3, pose)
            s1 = dr.dot(r3p, dr.gather(mi.Vector3f, m1, item))
            s2 = dr.dot(r3p, dr.gather(mi.Vector3f, m2, item))
            return (s1 * s2 >= 0) | dr.gather(mi.Bool, always, item)

    def _active_fixed(self, rows, capacity: int):
        """:meth:`_active_pairs` in a buffer of fixed size, without reading anything back.

        Per (pose, edge) pair where :attr:`per_edge` holds (as :meth:`_active_pairs`): each active
        edge's segments get consecutive buffer slots from an exclusive prefix sum of their
        counts; each edge writes its index at its first slot, and an inclusive running maximum
        over the buffer tells every slot its edge (slots grow with the edge index). Otherwise
        per (pose, segment) pair, each active pair writing itself at its slot.

        Returns
        -------
        active : mi.UInt32
            ``capacity`` entries: the active pair indices, ascending, then zeros.
        count : mi.UInt32
            Active pairs per pose (K,).
        overflow : mi.Bool
            One entry: more than ``capacity`` pairs are active.
        """
        dr, mi = self.dr, self.mi
        if self.per_edge:
            pair_pose, pair_edge, first, pieces = self._edge_pairs
            flag = self._flags(rows, pair_pose, pair_edge, self.e_m1, self.e_m2, self.e_always)
            size, ends = dr.select(flag, pieces, 0), self._edge_pose_ends
        else:
            flag = self._silhouette_flags(rows)
            size, ends, first = dr.select(flag, mi.UInt32(1), mi.UInt32(0)), self._pose_ends, None
        slot = dr.prefix_sum(size)  # exclusive: the buffer slot of each item's first pair
        upto = slot + size
        n = dr.width(flag)
        total = dr.gather(mi.UInt32, upto, mi.UInt32(n - 1))
        item = dr.arange(mi.UInt32, n)
        owner = dr.zeros(mi.UInt32, capacity)  # 1 + the item that starts at each slot, else 0
        # size > 0, not flag: flag is not evaluated, the test would run again in this kernel
        dr.scatter(owner, item + 1, slot, (size > 0) & (slot < capacity))
        i = dr.arange(mi.UInt32, capacity)
        if first is None:  # one pair per item: the slot's item is its pair
            active = owner - 1
        else:
            owner = dr.prefix_reduce(dr.ReduceOp.Max, owner, exclusive=False)
            edge = dr.maximum(owner, 1) - 1
            active = dr.gather(mi.UInt32, first, edge) + (i - dr.gather(mi.UInt32, slot, edge))
        active = dr.select(i < total, active, 0)
        start, end = ends
        before = dr.gather(mi.UInt32, upto, start - 1, start > 0)
        count = dr.select(end > start, dr.gather(mi.UInt32, upto, end - 1, end > start) - before, 0)
        overflow = total > capacity
        # Past the buffer there is nothing to read: sum nothing (the caller discards the results).
        return active, dr.select(overflow, 0, count), overflow

    def _active_pairs(self, rows):
        """Indices (ascending) of the (pose, segment) pairs whose segment is on the silhouette.

        The silhouette test depends on the parent edge only, so it runs once per (pose, edge)
        pair (about four times fewer tests than per segment); the active edges are then expanded
        into their consecutive segment pairs. The result equals
        ``dr.compress(self._silhouette_flags(rows))`` entry for entry, which is what runs where
        edges have few segments (:attr:`per_edge` False).
        """
        dr, mi = self.dr, self.mi
        if not self.per_edge:
            return dr.compress(self._silhouette_flags(rows))
        pair_pose, pair_edge, first, pieces = self._edge_pairs
        flag = self._flags(rows, pair_pose, pair_edge, self.e_m1, self.e_m2, self.e_always)
        with dr.suspend_grad():
            edges = dr.compress(flag)
            return expand_ranges(
                dr.gather(mi.UInt32, first, edges), dr.gather(mi.UInt32, pieces, edges)
            )

    def _pose_sums(self, active, rows, t, holes: HoleStack, pose_hole, layout=None) -> list:
        """Per-pose sums of the loss and of its derivatives, in an order fixed by the inputs.

        See :func:`pose_sums` for the two-level order.

        Parameters
        ----------
        active : mi.UInt32
            Active pair indices, ascending (from :meth:`_active_pairs`).
        rows : list of 6 mi.Float
            First two rows of each pose's rotation matrix, row-major (detached).
        t : tuple of 2 mi.Float
            Translations, scene units (detached).
        holes : HoleStack
        pose_hole : mi.UInt32
        layout : tuple, optional
            Fixed-size mode (:meth:`loss_fixed`): see :func:`pose_sums`.

        Returns
        -------
        list of 9 mi.Float, each (K,)
            L, dL/dt_x, dL/dt_y, dL/d(row 0) (3), dL/d(row 1) (3), L in pixels squared and t
            in scene units.
        """
        dr, mi = self.dr, self.mi
        fracs = [(j + 0.5) / self.samples for j in range(self.samples)]

        def prepare(pose):
            g = [dr.gather(mi.Float, x, pose) for x in list(rows) + list(t)]
            return g, dr.gather(mi.UInt32, pose_hole, pose)

        def accumulate(pair, ctx, acc):
            g, hole = ctx
            seg = dr.gather(mi.UInt32, self._pairs[1], pair)
            a, d = dr.gather(mi.Vector3f, self.a, seg), dr.gather(mi.Vector3f, self.d, seg)
            for frac in fracs:
                p = a + d * frac
                x = g[0] * p.x + g[1] * p.y + g[2] * p.z + g[6]
                y = g[3] * p.x + g[4] * p.y + g[5] * p.z + g[7]
                dist, ddx, ddy = self._lookup(x, y, holes, hole)
                gx, gy = 2 * dist * ddx, 2 * dist * ddy
                terms = (dist * dist, gx, gy, gx * p.x, gx * p.y, gx * p.z, gy * p.x, gy * p.y)
                acc = [s + v for s, v in zip(acc, terms + (gy * p.z,))]
            return acc

        return pose_sums(
            active,
            self._pairs[0],
            self.pose_count,
            9,
            prepare,
            accumulate,
            "clearance chunks",
            layout,
        )

    def _lookup(self, x, y, holes: HoleStack, hole_index):
        """Distance to H in pixels at world points (x, y), and its derivatives (pixels per unit).

        Bilinear in the distance texture inside the frame, extended outside it by the distance to
        the frame, ``sqrt(e^2 + 1e-6) - 1e-3`` with ``e`` the distance to the frame in pixels.

        Returns
        -------
        d, dd_dx, dd_dy : mi.Float
            The distance (pixels) and its derivatives with respect to x and y (per scene unit).
        """
        dr, mi = self.dr, self.mi
        f = holes.frame
        n = f.resolution
        inv_h = 1.0 / f.pixel_size
        u = (x + f.half_extent) * inv_h - 0.5
        v = (f.half_extent - y) * inv_h - 0.5
        uc = dr.clip(u, 0.0, n - 1.0)
        vc = dr.clip(v, 0.0, n - 1.0)
        root = dr.sqrt(dr.square(u - uc) + dr.square(v - vc) + 1e-6)
        iu = dr.minimum(mi.UInt32(dr.floor(uc)), n - 2)
        iv = dr.minimum(mi.UInt32(dr.floor(vc)), n - 2)
        fu, fv = uc - mi.Float(iu), vc - mi.Float(iv)
        d00 = holes.gather(hole_index, iv, iu)
        d01 = holes.gather(hole_index, iv, iu + 1)
        d10 = holes.gather(hole_index, iv + 1, iu)
        d11 = holes.gather(hole_index, iv + 1, iu + 1)
        top, bottom = dr.lerp(d00, d01, fu), dr.lerp(d10, d11, fu)
        d = dr.lerp(top, bottom, fv) + root - 1e-3
        # Inside the frame the bilinear part varies with u, v; outside, the extension does.
        dd_du = dr.select((u > 0) & (u < n - 1), dr.lerp(d01 - d00, d11 - d10, fv), 0.0)
        dd_dv = dr.select((v > 0) & (v < n - 1), bottom - top, 0.0)
        dd_du += (u - uc) / root
        dd_dv += (v - vc) / root
        return d, dd_du * inv_h, -dd_dv * inv_h


def pose_sums(
    active, pair_pose, pose_count: int, sums: int, prepare, accumulate, label: str, layout=None
):
    """Per-pose sums over (pose, item) pairs, added in an order fixed by the inputs.

    Two levels, both sequential loops over contiguous ranges: each thread sums the terms of at
    most :data:`CHUNK` consecutive active pairs of one pose (``active`` is ascending and the pairs
    are pose-major, so a pose's pairs are contiguous), then one thread per pose sums its chunks in
    order. The result depends on neither the thread count nor the scheduling (atomic
    scatter-adds do).

    Parameters
    ----------
    active : mi.UInt32
        Indices of the pairs to sum, ascending.
    pair_pose : mi.UInt32
        Pose of every pair, non-decreasing.
    pose_count : int
        K, the number of poses.
    sums : int
        Number of sums per pose.
    prepare : callable
        ``prepare(pose) -> ctx``: per-thread data gathered once per chunk (pose is mi.UInt32).
    accumulate : callable
        ``accumulate(pair, ctx, acc) -> acc``: adds pair ``pair``'s terms to the ``sums``
        running sums ``acc`` (a list of mi.Float); called inside a symbolic loop.
    label : str
        Name of the loop (in Dr.Jit's kernel history).
    layout : tuple (count, threads), optional
        Fixed-size mode, which reads nothing back (for :func:`drjit.freeze`): ``count`` (mi.UInt32,
        K) holds the active pairs of each pose (``active`` may have unused entries after them) and
        ``threads`` (int) is at least the number of chunks; the extra threads sum nothing. The
        sums are the same as without it.

    Returns
    -------
    list of ``sums`` mi.Float, each (K,)
    """
    import drjit as dr
    import mitsuba as mi

    k = pose_count
    if layout is None:
        if dr.width(active) == 0:
            return [dr.zeros(mi.Float, k) for _ in range(sums)]
        count = dr.zeros(mi.UInt32, k)  # integer sums are exact: order does not matter
        dr.scatter_reduce(dr.ReduceOp.Add, count, 1, dr.gather(mi.UInt32, pair_pose, active))
    else:
        count, n_chunks = layout
    chunks = (count + (CHUNK - 1)) // CHUNK
    first_pair, first_chunk = dr.prefix_sum(count), dr.prefix_sum(chunks)
    if layout is None:
        dr.eval(count, chunks, first_pair, first_chunk)
        n_chunks = int(dr.sum(chunks)[0])
    c = dr.arange(mi.UInt32, n_chunks)
    # The pose of chunk c: the last pose whose first chunk is <= c.
    r = dr.binary_search(0, k - 1, lambda i: dr.gather(mi.UInt32, first_chunk, i) <= c)
    pose = dr.select(dr.gather(mi.UInt32, first_chunk, r) <= c, r, r - 1)
    begin = dr.gather(mi.UInt32, first_pair, pose)
    lo = begin + (c - dr.gather(mi.UInt32, first_chunk, pose)) * CHUNK
    hi = dr.minimum(lo + CHUNK, begin + dr.gather(mi.UInt32, count, pose))
    ctx = prepare(pose)

    def body(i, *acc):
        return (i + 1, *accumulate(dr.gather(mi.UInt32, active, i), ctx, list(acc)))

    zero = [dr.zeros(mi.Float, n_chunks) for _ in range(sums)]
    partial = dr.while_loop((lo, *zero), lambda i, *_: i < hi, body, label=label)[1:]
    return _sum_chunks(list(partial), chunks, first_chunk, k)


def _sum_chunks(partial, chunks, first_chunk, k: int) -> list:
    """Second level of :func:`pose_sums`: each pose sums its chunks in order, (K,) each."""
    import drjit as dr
    import mitsuba as mi

    dr.eval(partial)
    end = first_chunk + chunks

    def body(j, *acc):
        return (j + 1, *[s + dr.gather(mi.Float, p, j) for s, p in zip(acc, partial)])

    zero = [dr.zeros(mi.Float, k) for _ in range(len(partial))]
    out = dr.while_loop((mi.UInt32(first_chunk), *zero), lambda j, *_: j < end, body)
    return list(out[1:])
