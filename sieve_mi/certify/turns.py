"""The turn test of the slab-section proof, batched over cells and intervals of turns.

A cell of directions that neither the diameter nor the width test excludes keeps a few band
points x_i (plane coordinates at the cell's centre direction) with displacement bounds r_i
(:class:`~sieve_mi.certify.section.Plane`, slack included). The section's projection is those
points turned by some psi and shifted by some t; an interval of turns [lo, hi] is excluded when
no t puts every point, turned by the interval's middle, within r_i + 2 sin(h / 2) |x_i| of H
(h the interval's half-width: a turn within h moves x_i by at most that).

Every cell starts with eight intervals of 2 pi / 8, halved down to ``depth`` levels. Each level
runs, for all intervals of all cells at once:

1. a quadtree over translations on proved lower bounds of the distance to H
   (:class:`~sieve_mi.certify.bounds.LowerDistance`), as the cell tree's
   :func:`~sieve_mi.certify.bounds.translation_quadtree`: an interval is excluded when no square
   is left;
2. a *fit* check on the squares left: a square centre c with every c + x_i (turned by the
   interval's middle) inside H (exact even-odd) shows that these points fit H at that turn, so
   no subinterval of it is ever excluded with these points (its test grows each bound by at
   least the turn back to the middle): the cell is given up at once (a choice, not a claim);
3. from level ``exact_from`` on, the exact test
   (:func:`~sieve_mi.certify.bounds.translations_left`) on the intervals the quadtree left.

What is left at the last level leaves the cell undecided. The certificate's tree of turns is the
same as the one-by-one search wrote (``{"roots": [8 nodes]}``, a node ``{"e": true}`` or
``{"c": [2 nodes]}``), and the replay re-proves every leaf with its own quadtree.
"""

from __future__ import annotations

import math
import time

import numpy as np

from sieve_mi.certify import bounds

__all__ = ["EXACT_FROM", "FIRST_LEVEL", "GROUP", "QUADTREE_STEPS", "TurnTest", "quadtree", "spread"]

#: Level of the turn tree from which intervals the quadtree leaves get the exact test.
EXACT_FROM = 6
#: First level of the turn tree that is tested (coarser intervals turn the points too far).
FIRST_LEVEL = 3
#: Cells whose trees of turns are built together, and intervals per quadtree call / 16 (memory:
#: intervals x points x squares).
GROUP = 128
#: Refinements of the quadtree over translations per interval.
QUADTREE_STEPS = 6
#: Relative margin on the turn's displacement bound (rounding).
MARGIN = 1e-9


class TurnTest:
    """The batched turn test against one hole H.

    Parameters
    ----------
    cache : bounds.OffsetCache
        H's offsets, for the exact test.
    lower : bounds.LowerDistance
        Proved lower bounds of the distance to H.
    region : object with ``contains_points((P, 2)) -> (P,) bool``
        H, even-odd (for the fit check only).
    depth : int
        Levels below the eight root intervals.
    exact_from : int
        First level with exact tests.
    """

    def __init__(self, cache, lower, region, depth: int, exact_from: int = EXACT_FROM):
        self.cache, self.lower, self.region = cache, lower, region
        self.depth, self.exact_from = int(depth), int(exact_from)
        #: Counts, for progress and measurement: intervals excluded by the quadtree and by the
        #: exact test, cells given up on a fit, on an interval left at the last level, or on time.
        self.stats = dict.fromkeys(("quadtree", "exact", "fits", "last", "time"), 0)
        #: The :func:`time.perf_counter` value past which cells are given up (:meth:`run`'s).
        self.deadline = math.inf

    def run(self, items: list, deadline: float) -> list:
        """The tree of turns for each item, or None where an interval is left (or the clock
        passed ``deadline``, a :func:`time.perf_counter` value).

        Parameters
        ----------
        items : list of (x, r)
            Per cell: plane coordinates (k, 2) and bounds (k,) of its points, scene units.

        Returns
        -------
        list of dict or None
            ``{"roots": [8 nodes]}`` per item.
        """
        out, self.deadline = [], deadline
        for s in range(0, len(items), GROUP):
            out += self._group(items[s : s + GROUP], deadline)
        return out

    def _group(self, items: list, deadline: float) -> list:
        """:meth:`run` for at most :data:`GROUP` items."""
        if not items:
            return []
        x, r = _padded(items)
        roots = [[{} for _ in range(8)] for _ in items]
        failed = np.zeros(len(items), dtype=bool)
        cell = np.repeat(np.arange(len(items)), 8)
        step = 2.0 * math.pi / 8
        lo = np.tile(np.arange(8) * step, len(items))
        nodes = [n for tree in roots for n in tree]
        for level in range(self.depth + 1):
            if not len(cell):
                break
            if time.perf_counter() > deadline:
                self.stats["time"] += len(np.unique(cell))
                failed[cell] = True
                break
            left = np.ones(len(cell), dtype=bool)
            if level >= FIRST_LEVEL:
                left = self._level(x, r, [len(i[0]) for i in items], failed, cell, lo, step, level)
                for k in np.flatnonzero(~left):
                    nodes[k]["e"] = True
            keep = left & ~failed[cell]
            if level == self.depth:
                failed[cell[keep]] = True
                break
            cell, lo, nodes = _halve(cell[keep], lo[keep], [nodes[k] for k in np.flatnonzero(keep)],
                                     step)  # fmt: skip
            step *= 0.5
        return [None if failed[i] else {"roots": roots[i]} for i in range(len(items))]

    def _level(self, x, r, counts, failed, cell, lo, step: float, level: int) -> np.ndarray:
        """Per interval: whether it is left (not excluded); a cell with an interval whose
        points fit H at its middle is given up (``failed``)."""
        mid, half = lo + 0.5 * step, 0.5 * step
        placed = _turned(x[cell], mid)
        grow = 2.0 * math.sin(0.5 * half) * np.linalg.norm(x[cell], axis=-1) * (1 + MARGIN)
        radii = r[cell] + grow
        left = np.empty(len(cell), dtype=bool)
        witness = np.empty((len(cell), 2))
        for s in range(0, len(cell), GROUP * 16):
            if time.perf_counter() > self.deadline:  # given up on time, within the level
                self.stats["time"] += int((~failed[np.unique(cell)]).sum())
                failed[cell] = True
                return np.ones(len(cell), dtype=bool)
            sl = slice(s, s + GROUP * 16)
            left[sl], witness[sl] = quadtree(self.lower, self.region, placed[sl], radii[sl])
        self.stats["quadtree"] += int((~left).sum())
        fit = np.unique(cell[np.isfinite(witness[:, 0])])
        self.stats["fits"] += int((~failed[fit]).sum())
        failed[fit] = True
        if level >= self.exact_from:
            for k in np.flatnonzero(left & ~failed[cell]):
                i = cell[k]
                if failed[i]:
                    continue  # an interval of this cell was left at the last level
                if time.perf_counter() > self.deadline:
                    self.stats["time"] += 1
                    failed[i] = True
                    continue
                n = counts[i]
                if bounds.translations_left(self.cache, placed[k, :n], radii[k, :n]).is_empty():
                    left[k] = False
                    self.stats["exact"] += 1
                elif level == self.depth:
                    self.stats["last"] += 1
                    failed[i] = True
        return left


def _turned(x: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Points x (n, k, 2) turned by psi (n,) radians."""
    c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], -1)


def _padded(items: list) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, K, 2) and bounds (n, K) of the items, each padded with copies of its first
    point (a copy adds no condition)."""
    most = max(len(x) for x, _ in items)
    x = np.empty((len(items), most, 2))
    r = np.empty((len(items), most))
    for i, (xi, ri) in enumerate(items):
        x[i, : len(xi)], x[i, len(xi) :] = xi, xi[0]
        r[i, : len(ri)], r[i, len(ri) :] = ri, ri[0]
    return x, r


def _halve(cell: np.ndarray, lo: np.ndarray, nodes: list, step: float):
    """The two halves of every interval (width ``step``), their nodes made children."""
    kids = []
    for node in nodes:
        node["c"] = [{}, {}]
        kids += node["c"]
    return np.repeat(cell, 2), (lo[:, None] + np.array([0.0, 0.5 * step])).reshape(-1), kids


def quadtree(lower, region, proj: np.ndarray, radii: np.ndarray, steps: int = QUADTREE_STEPS,
             cap: int = 64) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Which intervals some translation may leave, and a translation that puts every point
    inside H where one was met.

    :func:`~sieve_mi.certify.bounds.translation_quadtree` (a square of half-diagonal e is
    discarded when some point's lower bound exceeds r_i + e), with a fit check on every square
    left at every step: its centre puts every point inside H (exact even-odd).

    Parameters
    ----------
    lower : bounds.LowerDistance
    region : object with ``contains_points``
    proj : (n, k, 2) ndarray
    radii : (n, k) ndarray
    steps, cap : int
        As :func:`~sieve_mi.certify.bounds.translation_quadtree`.

    Returns
    -------
    left : (n,) bool ndarray
        Not excluded (a square was left, or the quadtree gave up).
    witness : (n, 2) ndarray
        A translation putting every point inside H; NaN where none was met.
    """
    n, k = radii.shape
    tlo = (lower.hlo[None, None] - radii[..., None] - proj).max(axis=1)
    thi = (lower.hhi[None, None] + radii[..., None] - proj).min(axis=1)
    left = ~(tlo > thi).any(axis=1)
    witness = np.full((n, 2), np.nan)
    cell = np.flatnonzero(left)
    centre, half = 0.5 * (tlo + thi)[cell], 0.5 * (thi - tlo).max(axis=1)[cell]
    crowded_any = np.zeros(n, dtype=bool)
    quarter = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]])
    for step in range(steps + 1):
        x = (centre[:, None, :] + proj[cell]).reshape(-1, 2)
        far = lower(x).reshape(len(cell), k) > radii[cell] + math.sqrt(2.0) * half[:, None]
        keep = ~far.any(axis=1)
        cell, centre, half, x = cell[keep], centre[keep], half[keep], x.reshape(-1, k, 2)[keep]
        if len(cell):
            inside = region.contains_points(x.reshape(-1, 2)).reshape(len(cell), k).all(axis=1)
            witness[cell[inside]] = centre[inside]
        if step == steps or not len(cell):
            break
        crowded = np.bincount(cell, minlength=n) > cap // 4
        crowded_any |= crowded
        ok = ~crowded[cell] & np.isnan(witness[cell, 0])
        cell, centre, half = cell[ok], centre[ok], 0.5 * half[ok]
        centre = (centre[:, None, :] + quarter[None] * half[:, None, None]).reshape(-1, 2)
        cell, half = np.repeat(cell, 4), np.repeat(half, 4)
    left[:] = False
    left[cell] = True
    left |= crowded_any | np.isfinite(witness[:, 0])
    return left, witness


def spread(x: np.ndarray, chosen: np.ndarray, count: int) -> np.ndarray:
    """Up to ``count`` more indices into the points ``x`` (k, 2), each the furthest from those
    chosen so far (farthest-point sampling from ``chosen``): points spread over the section,
    inside its hull too (a choice only; any points of the band are sound)."""
    d = np.min(np.linalg.norm(x[:, None] - x[chosen][None], axis=-1), axis=1)
    out: list[int] = []
    for _ in range(min(count, len(x) - len(chosen))):
        j = int(np.argmax(d))
        if d[j] <= 0.0:
            break
        out.append(j)
        d = np.minimum(d, np.linalg.norm(x - x[j], axis=1))
    return np.asarray(out, dtype=np.int64)
