"""Edge sampling, the machinery the clearance and overlap objectives share (Dr.Jit, batched).

Both objectives are sums over samples on B's *silhouette edges*: each shape's edges are cut into
segments of at most ``samples_per_segment`` pixels (:func:`sieve_mi.geometry.meshes.segments`),
each sampled ``samples_per_segment`` times at the centres of equal parts.
:class:`EdgeSampledObjective` holds those segments and, once bound to a list of poses, every
(pose, segment) pair, and finds the pairs whose segment is on the silhouette of its pose.

All poses of all shapes (particles x shapes x starts) are evaluated in one kernel per step: per step
the silhouette test runs over every (pose, edge) pair (it depends on the edge only),
:func:`drjit.compress` keeps the active ones, they are expanded into their segments' (pose,
segment) pairs, and the loss is evaluated on their samples only. Where edges are about one
segment long, the test runs per (pose, segment) directly. The per-pose sums over the active pairs
are added in an order fixed by the inputs, so the objectives built on them are reproducible bit
for bit. How pairs are built, read and summed on the device is :mod:`sieve_mi.objectives.pairs`.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.backend import aligned
from sieve_mi.geometry.meshes import Shape, segments
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import quat_rows
from sieve_mi.objectives.base import Objective
from sieve_mi.objectives.pairs import expand_ranges, packet_table, packet_type, pose_ranges

__all__ = ["EdgeSampledObjective", "PER_EDGE_RATIO", "auto_samples"]


#: Segments per edge from which the silhouette test runs per (pose, edge), not per segment.
PER_EDGE_RATIO = 1.5
#: What a silhouette test reads of its segment or edge (:func:`_test_table`).
_TEST = ("m1", "m2", "always")


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


def _test_table(m1: np.ndarray, m2: np.ndarray, always: np.ndarray):
    """The silhouette tests of N items as one flat mi.Float, 8 entries per item: ``m1`` (3),
    ``m2`` (3), ``always`` (1.0 or 0.0) and a 0 of padding, so that one packet reads an item's
    test (:meth:`EdgeSampledObjective._flags`).

    Parameters
    ----------
    m1, m2 : (N, 3) float
    always : (N,) bool
    """
    table = np.zeros((len(m1), 8), dtype=np.float32)
    table[:, 0:3], table[:, 3:6], table[:, 6] = m1, m2, always
    return packet_table(table)


def auto_samples(shapes: list[Shape], spacing: float, most: int = 4) -> int:
    """Samples per segment from the median edge length (in units of ``spacing``), in [1, most]."""
    from sieve_mi.geometry.meshes import edge_topology

    lengths = []
    for s in shapes:
        edges = edge_topology(s.vertices, s.faces)[0]
        lengths.append(np.linalg.norm(s.vertices[edges[:, 0]] - s.vertices[edges[:, 1]], axis=1))
    median = float(np.median(np.concatenate(lengths))) / spacing
    return int(np.clip(np.ceil(median), 1, most))


class EdgeSampledObjective(Objective):
    """Silhouette-edge segments of several shapes and their (pose, segment) pairs.

    The base of the edge-sampled objectives (:class:`~sieve_mi.objectives.clearance.ClearanceObjective`,
    :class:`~sieve_mi.objectives.overlap.EdgeOverlapObjective`): it implements
    :meth:`~sieve_mi.objectives.Objective.bind`, and subclasses add
    :meth:`~sieve_mi.objectives.Objective.loss`, built on :meth:`_active_pairs` and
    :func:`~sieve_mi.objectives.pairs.pose_sums`.

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

    Attributes
    ----------
    frame : Frame
        The raster frame of the holes it is evaluated against.
    samples : int
        Samples per segment.
    counts, offsets : (B,) ndarrays of int
        Segments of each shape, and each shape's first segment.
    a, d : mi.Vector3f
        First end and direction (second end minus first) of every segment (S), mesh frame.
    ends : mi.Float
        The same, 8 entries per segment (a, d, two zeros), read as one packet by the losses.
    tests, e_tests : mi.Float
        The silhouette test of every segment and of every edge, 8 entries each
        (:func:`_test_table`), read as one packet.
    per_edge : bool
        Whether the silhouette test runs per (pose, edge) pair rather than per (pose, segment).
    pose_count : int
        K, the number of bound poses (set by :meth:`bind`).
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

        ends = np.zeros((self.segment_count, 8), dtype=np.float32)
        ends[:, :3] = np.concatenate([s.a for s in segs])
        ends[:, 3:6] = np.concatenate([s.b - s.a for s in segs])
        self.ends = packet_table(ends)
        self.a, self.d = (mi.Vector3f(*ends[:, k : k + 3].T) for k in (0, 3))
        self.m1, self.m2 = cat("m1"), cat("m2")  # the overlap loss' test per segment
        self.always = mi.Bool(np.concatenate([s.always for s in segs]))
        self._edges = _edge_table(segs)
        self.tests = _test_table(*(np.concatenate([getattr(s, k) for s in segs]) for k in _TEST))
        self.e_tests = _test_table(*(self._edges[k] for k in _TEST))
        # testing per edge pays where edges are cut into several segments (not for fine meshes)
        self.per_edge = self.segment_count >= PER_EDGE_RATIO * len(self._edges["pieces"])
        self._pairs = None
        self._pose_ends = None
        self._edge_pairs = None
        self._edge_pose_ends = None

    @property
    def segment_count(self) -> int:
        """S, the number of segments of all shapes together."""
        return int(self.counts.sum())

    @property
    def pair_count(self) -> int:
        """Number of (pose, segment) pairs of the bound poses."""
        return 0 if self._pairs is None else self.dr.width(self._pairs[0])

    @property
    def pairs(self) -> tuple | None:
        """The (pose, segment) pairs of the bound poses, pose-major; None before :meth:`bind`.

        Returns
        -------
        pose, segment : mi.UInt32
            :attr:`pair_count` entries each: the pose (index into the bound poses) and the
            segment (index into :attr:`a` and :attr:`d`) of every pair. A pose's pairs are
            consecutive, its segments in ascending order.
        """
        return self._pairs

    @property
    def edge_pairs(self) -> tuple | None:
        """The (pose, edge) pairs of the bound poses, pose-major; None before :meth:`bind`.

        Returns
        -------
        pose, edge, first, pieces : mi.UInt32
            One entry per (pose, edge) pair each: the pose, the edge (index into
            :attr:`edge_table`'s rows), the pair's first (pose, segment) pair (index into
            :attr:`pairs`) and its number of segments (its (pose, segment) pairs are
            ``first, ..., first + pieces - 1``).
        """
        return self._edge_pairs

    @property
    def edge_table(self) -> dict:
        """Per edge of every shape (edges of shape 0 first, E in all): its test and segments.

        Returns
        -------
        dict of ndarrays
            ``m1``, ``m2`` ((E, 3) float32): the silhouette-test vectors (the edge is on the
            silhouette for a rotation R when ``(R_2 . m1)(R_2 . m2) >= 0``); ``always`` ((E,)
            bool): the edge is always tested as a silhouette edge (boundary or non-manifold);
            ``pieces`` ((E,) int): its segments; ``first_local`` ((E,) int): its first
            segment's index among its shape's segments; ``count`` and ``offset`` ((B,) int):
            each shape's number of edges and first edge. Host arrays; do not modify them.
        """
        return self._edges

    def bind(self, pose_shape: np.ndarray) -> None:
        """See :meth:`sieve_mi.objectives.Objective.bind`.

        Builds the (pose, segment) pairs (:attr:`pairs`) and the (pose, edge) pairs
        (:attr:`edge_pairs`) on the device (:func:`~sieve_mi.objectives.pairs.pose_ranges`): only
        per-pose numbers go through NumPy, so binding 100 poses of a 70k-face mesh takes
        milliseconds and no host copies of the K x S pairs.
        """
        mi = self.mi
        pose_shape = np.asarray(pose_shape, dtype=np.int64)
        n = self.counts[pose_shape]
        self._pairs = pose_ranges(self.offsets[pose_shape], n)
        # Each pose's first pair and one past its last (pairs are pose-major).
        ends = np.cumsum(n)
        self._pose_ends = (
            mi.UInt32(aligned(ends - n, np.uint32)),
            mi.UInt32(aligned(ends, np.uint32)),
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
            mi.UInt32(aligned(ends - n, np.uint32)),
            mi.UInt32(aligned(ends, np.uint32)),
        )
        self._edge_pairs = (pair_pose, pair_edge, first, pieces)
        dr.eval(self._edge_pairs)

    def _silhouette_flags(self, rows, live=None):
        """Whether each (pose, segment) pair's segment is on the silhouette (mi.Bool)."""
        pair_pose, pair_seg = self._pairs
        return self._flags(rows, pair_pose, pair_seg, self.tests, live)

    def _flags(self, rows, pose, item, tests, live=None):
        """The silhouette test ``(r3 . m1)(r3 . m2) >= 0 or always`` of (pose, item) pairs, where
        items are segments or edges (``tests``: their :func:`_test_table`); with ``live``
        (mi.Bool, K), pairs of the other poses are never active.

        Each pair reads its pose's third rotation row and its item's test as one packet each
        (the pose's rows are packed first, one small kernel), not as ten gathers.
        """
        dr, mi = self.dr, self.mi
        with dr.suspend_grad():
            k, n = dr.width(rows[6]), dr.width(pose)
            packed = dr.zeros(mi.Float, 4 * k)
            at = dr.arange(mi.UInt32, k) * 4
            for j in range(3):
                dr.scatter(packed, dr.detach(rows[6 + j]), at + j)
            r = dr.gather(packet_type(), packed, pose, shape=(4, n))
            e = dr.gather(packet_type(), tests, item, shape=(8, n))
            r3 = mi.Vector3f(r[0], r[1], r[2])
            s1 = dr.dot(r3, mi.Vector3f(e[0], e[1], e[2]))
            s2 = dr.dot(r3, mi.Vector3f(e[3], e[4], e[5]))
            flag = (s1 * s2 >= 0) | (e[6] != 0)
            return flag if live is None else flag & dr.gather(mi.Bool, live, pose)

    def _item_sizes(self, rows, live=None):
        """Active pairs of every tested item: per (pose, edge) pair its segments where the edge
        is on the silhouette (:attr:`per_edge`), else 1 per (pose, segment) pair on it.

        Returns
        -------
        size : mi.UInt32
            One entry per item (0 where not on the silhouette).
        ends : tuple of mi.UInt32
            Each pose's first item and one past its last.
        first : mi.UInt32 or None
            Per edge item, its first (pose, segment) pair; None for segment items.
        """
        dr, mi = self.dr, self.mi
        if self.per_edge:
            pair_pose, pair_edge, first, pieces = self._edge_pairs
            flag = self._flags(rows, pair_pose, pair_edge, self.e_tests, live)
            return dr.select(flag, pieces, 0), self._edge_pose_ends, first
        flag = self._silhouette_flags(rows, live)
        return dr.select(flag, mi.UInt32(1), mi.UInt32(0)), self._pose_ends, None

    def _active_fixed(self, rows, capacity: int, live=None):
        """:meth:`_active_pairs` in a buffer of fixed size, without reading anything back.

        Per (pose, edge) pair where :attr:`per_edge` holds (as :meth:`_active_pairs`), else per
        (pose, segment) pair: an exclusive prefix sum of the active pairs of every tested item
        gives each item its first buffer slot, and each active item writes its pairs there
        (an edge its segments' pairs, one after another). Items are in the order of the pairs,
        so the buffer holds :meth:`_active_pairs`' indices in the same order.

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
        size, ends, first = self._item_sizes(rows, live)
        slot = dr.prefix_sum(size)  # exclusive: the buffer slot of each item's first pair
        n = dr.width(size)
        last = mi.UInt32(n - 1)
        total = dr.gather(mi.UInt32, slot, last) + dr.gather(mi.UInt32, size, last)
        active = dr.zeros(mi.UInt32, capacity)
        if first is None:  # one pair per item: the item is its pair
            dr.scatter(active, dr.arange(mi.UInt32, n), slot, (size > 0) & (slot < capacity))
        else:

            def body(j):
                dr.scatter(active, first + j, slot + j, slot + j < capacity)
                return (j + 1,)

            dr.while_loop((dr.zeros(mi.UInt32, n),), lambda j: j < size, body, label="active list")
        start, end = ends
        count = dr.gather(mi.UInt32, slot, end - 1, end > start) + dr.gather(
            mi.UInt32, size, end - 1, end > start
        )
        count = dr.select(end > start, count - dr.gather(mi.UInt32, slot, start, end > start), 0)
        overflow = total > capacity
        # Past the buffer there is nothing to read: sum nothing (the caller discards the results).
        return active, dr.select(overflow, 0, count), overflow

    def _active_pairs(self, rows, live=None):
        """Indices (ascending) of the (pose, segment) pairs whose segment is on the silhouette
        (of the ``live`` poses only, where given: mi.Bool, K).

        The silhouette test depends on the parent edge only, so it runs once per (pose, edge)
        pair (about four times fewer tests than per segment); the active edges are then expanded
        into their consecutive segment pairs. The result equals
        ``dr.compress(self._silhouette_flags(rows))`` entry for entry, which is what runs where
        edges have few segments (:attr:`per_edge` False).
        """
        dr, mi = self.dr, self.mi
        if not self.per_edge:
            return dr.compress(self._silhouette_flags(rows, live))
        pair_pose, pair_edge, first, pieces = self._edge_pairs
        flag = self._flags(rows, pair_pose, pair_edge, self.e_tests, live)
        with dr.suspend_grad():
            edges = dr.compress(flag)
            return expand_ranges(
                dr.gather(mi.UInt32, first, edges), dr.gather(mi.UInt32, pieces, edges)
            )

    def silhouette_flags(self, q):
        """Whether each (pose, segment) pair's segment is a silhouette edge of its pose.

        Parameters
        ----------
        q : tuple of 4 mi.Float
            Quaternions (w, x, y, z) of the K bound poses (gradients are ignored).

        Returns
        -------
        mi.Bool
            :attr:`pair_count` entries, in the order of :attr:`pairs`.
        """
        dr = self.dr
        with dr.suspend_grad():
            return self._silhouette_flags(quat_rows(*[dr.detach(x) for x in q]))

    def active_pairs(self, q):
        """The (pose, segment) pairs whose segment is a silhouette edge of its pose.

        What the losses sum over; equal to ``dr.compress(self.silhouette_flags(q))`` entry for
        entry, however it is computed (:attr:`per_edge`).

        Parameters
        ----------
        q : tuple of 4 mi.Float
            Quaternions (w, x, y, z) of the K bound poses (gradients are ignored).

        Returns
        -------
        mi.UInt32
            Indices into :attr:`pairs`, ascending (so grouped by pose).
        """
        dr = self.dr
        with dr.suspend_grad():
            return self._active_pairs(quat_rows(*[dr.detach(x) for x in q]))

    def active_count(self, q) -> int:
        """How many entries :meth:`active_pairs` has at quaternions ``q`` (4 mi.Float), from
        one sum over the silhouette test, without building the list (one synchronisation)."""
        dr = self.dr
        if self.pair_count == 0:
            return 0
        with dr.suspend_grad():
            size = self._item_sizes(quat_rows(*[dr.detach(x) for x in q]))[0]
            return int(dr.sum(size)[0])

    def active_fixed(self, q, capacity: int):
        """:meth:`active_pairs` in a buffer of ``capacity`` entries, reading nothing back.

        What fixed-size (frozen) steps sum over.

        Parameters
        ----------
        q : tuple of 4 mi.Float
            Quaternions (w, x, y, z) of the K bound poses (gradients are ignored).
        capacity : int
            Entries of the buffer.

        Returns
        -------
        active : mi.UInt32
            ``capacity`` entries: :meth:`active_pairs`' indices, then zeros.
        count : mi.UInt32
            Active pairs of each pose (K,); zeros on overflow.
        overflow : mi.Bool
            One entry: more than ``capacity`` pairs are active.
        """
        dr = self.dr
        with dr.suspend_grad():
            return self._active_fixed(quat_rows(*[dr.detach(x) for x in q]), capacity)

    def _segment(self, pair):
        """Segment index, first end and direction (mesh frame) of (pose, segment) pairs ``pair``."""
        dr, mi = self.dr, self.mi
        seg = dr.gather(mi.UInt32, self._pairs[1], pair)
        e = dr.gather(packet_type(), self.ends, seg, shape=(8, dr.width(pair)))
        return seg, mi.Vector3f(e[0], e[1], e[2]), mi.Vector3f(e[3], e[4], e[5])

    def _fractions(self) -> list:
        """Where the samples lie along a segment, as fractions of its length (centred, ascending)."""
        return [(j + 0.5) / self.samples for j in range(self.samples)]

    def _context(self, rows, t, pose_hole, pose_shape=None):
        """``prepare`` for :func:`~sieve_mi.objectives.pairs.pose_sums`: each pose's ``rows`` and
        ``t`` entries and its hole.

        With ``pose_shape`` (mi.UInt32, K) the context also holds the pose's shape index.
        """
        dr, mi = self.dr, self.mi

        def prepare(pose):
            g = [dr.gather(mi.Float, x, pose) for x in list(rows) + list(t)]
            hole = dr.gather(mi.UInt32, pose_hole, pose)
            if pose_shape is None:
                return g, hole
            return g, hole, dr.gather(mi.UInt32, pose_shape, pose)

        return prepare

    def _link(self, total, q, t, rows, coef):
        """``total`` with the gradient ``sum_k coef_k . d(t_k, rows_k)/d(q, t)`` attached.

        ``coef`` holds 8 per-pose derivatives (with respect to t_x, t_y and the first two rows
        of R, row-major), ``rows`` the rotation rows of ``q`` (with their AD graph). The value is
        unchanged; only per-pose (element-wise) operations join the AD graph.
        """
        dr = self.dr
        if dr.grad_enabled(q, t):
            # d total / d(q, t) = sum over rows of (d row / d(q, t)) * (d L / d row): per pose.
            link = t[0] * coef[0] + t[1] * coef[1]
            for i in range(6):
                link = link + rows[i] * coef[2 + i]
            link = dr.sum(link)
            total = total + (link - dr.detach(link))
        return total
