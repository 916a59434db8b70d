"""(pose, item) pairs on the device: built from ranges, read as packets, summed in a fixed order.

The edge-sampled objectives (:mod:`sieve_mi.objectives.edges`) evaluate every (pose, segment)
pair of many poses in one kernel. What they need of Dr.Jit, apart from the geometry:

* pairs from per-pose ranges, built on the device by one scan (:func:`expand_ranges`,
  :func:`pose_ranges`): pose j gets items ``start[j], ..., start[j] + length[j] - 1``;
* tables of 8 floats per item in Dr.Jit's own (aligned) memory (:func:`packet_table`), so that
  one packet gather (:func:`packet_type`) reads an item's row instead of eight gathers;
* per-pose sums over the active pairs added in an order fixed by the inputs (:func:`pose_sums`:
  chunks of :data:`CHUNK` pairs, then each pose's chunks in order), so the objectives built on
  them are reproducible bit for bit, whatever the thread count or scheduling.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CHUNK", "expand_ranges", "packet_table", "packet_type", "pose_ranges", "pose_sums"]

#: Active (pose, segment) pairs that one thread sums in the first level of the per-pose reduction
#: (:func:`pose_sums`). Fixed, so results do not depend on the machine.
CHUNK = 16


def packet_table(rows: np.ndarray):
    """``rows`` ((N, 8) float) as a flat mi.Float (8N) in Dr.Jit's own memory, which is aligned.

    Dr.Jit reads a row of it as one packet only from aligned memory. An array made from a
    NumPy array on the CPU uses NumPy's memory, aligned or not by chance (and then every read
    falls back to 8 gathers; copies and identity gathers keep the same memory): a scatter into
    a new array is what makes it Dr.Jit's.
    """
    import drjit as dr
    import mitsuba as mi

    host = mi.Float(np.ascontiguousarray(rows, dtype=np.float32).ravel())
    table = dr.zeros(mi.Float, dr.width(host))
    dr.scatter(table, host, dr.arange(mi.UInt32, dr.width(host)))
    dr.eval(table)
    return table


def packet_type():
    """Dr.Jit's ArrayXf of the active Mitsuba variant's backend: the type of packet gathers of
    8 consecutive floats (``dr.gather(packet_type(), flat, index, shape=(8, n))``)."""
    import drjit as dr
    import mitsuba as mi

    return (dr.cuda.ad if mi.variant().startswith("cuda") else dr.llvm.ad).ArrayXf


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
