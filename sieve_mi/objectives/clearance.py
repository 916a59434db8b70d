"""The clearance objective: a containment loss on B's silhouette edges (Dr.Jit, batched).

When H is simply connected (or a disjoint union of simply connected pieces), proj(B) lies in H iff
every *silhouette edge* of B projects into H: the outline of a union of triangles is made of such
edges, and a bounded region whose outline lies in H cannot contain a point outside H, because the
complement of H is connected and unbounded. So

    L(R, t) = sum over samples s on silhouette edges of  d_H(P(R s) + t)^2,

with d_H the distance to H (bilinear in H's distance transform, in pixels), is zero iff B fits (up to
the raster), and has useful gradients even when B is far outside H.

All poses are evaluated at once, on the active (pose, segment) pairs only, with per-pose sums in a
fixed order: the machinery it shares with the overlap objective (:mod:`sieve_mi.objectives.edges`).
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.hole import HoleStack
from sieve_mi.geometry.rotations import quat_rows
from sieve_mi.objectives.edges import EdgeSampledObjective
from sieve_mi.objectives.pairs import CHUNK, pose_sums

__all__ = ["ClearanceObjective"]


class ClearanceObjective(EdgeSampledObjective):
    """Clearance loss of several shapes, for many poses at once (an :class:`~sieve_mi.objectives.Objective`).

    Parameters
    ----------
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
        The hole's raster frame; its pixel size sets the sample spacing.
    samples_per_segment : int, optional
        As for :class:`~sieve_mi.objectives.edges.EdgeSampledObjective`: samples per edge
        segment, by default from the edge lengths (1 to 4).
    """

    #: :meth:`loss_fixed` computes this loss, so player B may freeze its steps (:mod:`sieve_mi.game.frozen`).
    freezable = True
    #: A pose whose loss is at most this (pixels squared) fits: every sample on its silhouette
    #: edges lies inside H, where one sample a thousandth of a pixel outside already adds 1e-6.
    #: Player B stops descending the other starts of a hole that a pose fits
    #: (:meth:`sieve_mi.game.player_b.PlayerB.attack`'s ``settle``); ``live`` below masks them.
    fit_loss = 1e-6
    #: :meth:`hole_distance` reads its holes' four corners at once: stacks for this loss are
    #: built with :attr:`~sieve_mi.geometry.hole.HoleStack.corners`.
    hole_corners = True
    #: The Dr.Jit arrays a frozen function (:func:`drjit.freeze`) must see as its inputs.
    DRJIT_STRUCT = {
        "ends": object,
        "_pairs": object,
        "_pose_ends": object,
        "tests": object,
        "e_tests": object,
        "_edge_pairs": object,
        "_edge_pose_ends": object,
    }

    def loss(self, q, t, holes: HoleStack, pose_hole, live=None):
        """See :meth:`sieve_mi.objectives.Objective.loss`; with ``live`` (mi.Bool, K) the other
        poses sum nothing (their loss and gradient are 0, and they cost no work).

        ``per_pose`` is the clearance loss in pixels squared. Every sum runs in an order that
        depends only on the inputs, never on thread scheduling, so the same inputs give the same
        bits on every run (see :meth:`_pose_sums`). The gradient with respect to ``q`` and ``t``
        is the loss' exact gradient, reduced per pose the same way and attached to the AD graph
        through per-pose (element-wise) operations only.
        """
        return self._loss(q, t, holes, pose_hole, live=live)[:2]

    def loss_fixed(self, q, t, holes: HoleStack, pose_hole, capacity: int, live=None):
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
        return self._loss(q, t, holes, pose_hole, capacity, live)

    def capacity(self, q) -> int:
        """A buffer size for :meth:`loss_fixed` at poses near quaternions ``q`` (4 mi.Float).

        Twice the active pairs at ``q``, rounded up to a power of two (at least 1024), so that
        attacks of the same size share one recording of a frozen step.
        """
        dr = self.dr
        active = self.active_count(q)
        total = dr.width(self._pairs[0])
        return int(min(max(1024, 1 << int(np.ceil(np.log2(max(2 * active, 1))))), max(total, 1)))

    def _loss(self, q, t, holes: HoleStack, pose_hole, capacity: int | None = None, live=None):
        """:meth:`loss` (``capacity`` None) or :meth:`loss_fixed`: total, per_pose, overflow."""
        dr, mi = self.dr, self.mi
        rows = quat_rows(*q)
        with dr.suspend_grad():
            r = [dr.detach(x) for x in rows[:6]]
            td = (dr.detach(t[0]), dr.detach(t[1]))
            if capacity is None:
                active, layout, overflow = self._active_pairs(rows, live), None, mi.Bool(False)
            else:
                active, count, overflow = self._active_fixed(rows, capacity, live)
                layout = (count, capacity // CHUNK + self.pose_count)
            sums = self._pose_sums(active, r, td, holes, pose_hole, layout)
        per_pose = sums[0]
        total = self._link(dr.sum(per_pose), q, t, rows, sums[1:])
        return total, per_pose, overflow

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
        fracs = self._fractions()

        def accumulate(pair, ctx, acc):
            g, hole = ctx
            _, a, d = self._segment(pair)
            for frac in fracs:
                p = a + d * frac
                x = g[0] * p.x + g[1] * p.y + g[2] * p.z + g[6]
                y = g[3] * p.x + g[4] * p.y + g[5] * p.z + g[7]
                dist, ddx, ddy = self.hole_distance(x, y, holes, hole)
                gx, gy = 2 * dist * ddx, 2 * dist * ddy
                terms = (dist * dist, gx, gy, gx * p.x, gx * p.y, gx * p.z, gy * p.x, gy * p.y)
                acc = [s + v for s, v in zip(acc, terms + (gy * p.z,))]
            return acc

        return pose_sums(
            active,
            self._pairs[0],
            self.pose_count,
            9,
            self._context(rows, t, pose_hole),
            accumulate,
            "clearance chunks",
            layout,
        )

    def hole_distance(self, x, y, holes: HoleStack, hole_index):
        """Distance to H in pixels at world points (x, y), and its derivatives (pixels per unit).

        Bilinear in the distance texture inside the frame, extended outside it by the distance to
        the frame, ``sqrt(e^2 + 1e-6) - 1e-3`` with ``e`` the distance to the frame in pixels.
        What the loss squares at every sample.

        Parameters
        ----------
        x, y : mi.Float
            World points in the hole plane, scene units (P entries).
        holes : HoleStack
            The holes, on this objective's frame.
        hole_index : mi.UInt32
            Which hole of the stack each point is measured against (P entries, or one).

        Returns
        -------
        d, dd_dx, dd_dy : mi.Float
            The distance (pixels; 0 inside H, up to rounding) and its derivatives with respect
            to x and y (pixels per scene unit), P entries each.
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
        d00, d01, d10, d11 = holes.gather_corners(hole_index, iv, iu)
        top, bottom = dr.lerp(d00, d01, fu), dr.lerp(d10, d11, fu)
        d = dr.lerp(top, bottom, fv) + root - 1e-3
        # Inside the frame the bilinear part varies with u, v; outside, the extension does.
        dd_du = dr.select((u > 0) & (u < n - 1), dr.lerp(d01 - d00, d11 - d10, fv), 0.0)
        dd_dv = dr.select((v > 0) & (v < n - 1), bottom - top, 0.0)
        dd_du += (u - uc) / root
        dd_dv += (v - vc) / root
        return d, dd_du * inv_h, -dd_dv * inv_h
