"""What player B reads of an objective, documented once: the base class :class:`Objective`.
Rule: an attribute player B reads is declared here, with its meaning and its default.

Every objective of :mod:`sieve_mi.objectives` derives from :class:`Objective` (re-exported there as
``sieve_mi.objectives.Objective``) and overrides only what differs from the defaults.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from sieve_mi.geometry.raster import Frame

__all__ = ["Objective"]


class Objective:
    """What player B reads of a loss: the base of every objective, documenting the interface once.

    Player B (:mod:`sieve_mi.game.player_b`, :mod:`sieve_mi.game.descent`,
    :mod:`sieve_mi.game.frozen`) reads exactly what is declared here, as plain attributes; the
    class attributes below are the defaults, and an objective overrides those that differ.

    Attributes
    ----------
    frame : Frame
        The raster frame of the holes it is evaluated against (set by the objective).
    fit_loss : float or None
        A pose whose loss is at most this fits, so player B may stop descending the other starts
        of its group (:meth:`sieve_mi.game.player_b.PlayerB.attack`'s ``settle``) and pass
        ``live`` to :meth:`loss`. None (the default): the loss has no such threshold, poses never
        settle, and ``live`` is never passed.
    freezable : bool
        Whether the objective offers :meth:`loss_fixed`, :meth:`capacity` and
        :attr:`pair_count`, so that player B may freeze its steps (:mod:`sieve_mi.game.frozen`);
        its Dr.Jit arrays must then be listed in ``DRJIT_STRUCT``. False by default.
    hole_corners : bool
        Whether :meth:`loss` reads its holes' four corners at once, so that player B builds its
        hole stacks with :attr:`~sieve_mi.geometry.hole.HoleStack.corners`. False by default.
    counts : (B,) ndarray of int or None
        The edge segments of each of B's shapes, by which player B splits a large attack into
        chunks of at most ``max_pairs`` (pose, segment) pairs; None (the default): the objective
        is not edge-sampled and an attack is one chunk.
    """

    frame: Frame
    fit_loss: float | None = None
    freezable: bool = False
    hole_corners: bool = False
    counts: np.ndarray | None = None

    @property
    def pair_count(self) -> int:
        """(pose, segment) pairs of the bound poses, what a frozen step's work grows with; read
        only where :attr:`freezable` (0 here)."""
        return 0

    def bind(self, pose_shape: np.ndarray) -> None:
        """Fix which shape each pose belongs to, before any :meth:`loss` call.

        Parameters
        ----------
        pose_shape : (K,) ndarray of int
            Index into the objective's shape list for every pose.
        """
        raise NotImplementedError

    def loss(self, q: tuple, t: tuple, holes: Any, pose_hole: Any, live: Any = None) -> tuple:
        """Total and per-pose loss of all K bound poses.

        Parameters
        ----------
        q : tuple of 4 mi.Float
            Quaternions (w, x, y, z), K entries each, possibly with gradients enabled; they need
            not be normalised (the rotation uses q / |q|).
        t : tuple of 2 mi.Float
            Translations in the hole plane, scene units.
        holes : HoleStack
            The holes (:class:`sieve_mi.geometry.hole.HoleStack`), on this objective's frame.
        pose_hole : mi.UInt32
            Which hole of the stack each pose is tested against (K entries).
        live : mi.Bool, optional
            (K,): only these poses are descended; the others (settled) sum nothing. Player B
            passes it only where :attr:`fit_loss` is set; an objective without one raises
            ValueError when given it.

        Returns
        -------
        total : mi.Float
            One value, the sum over poses; ``dr.backward(total)`` gives each pose's gradient.
        per_pose : mi.Float
            K values, detached; 0 means the pose fits (up to the raster).
        """
        raise NotImplementedError

    def loss_fixed(
        self, q: tuple, t: tuple, holes: Any, pose_hole: Any, capacity: int, live: Any = None
    ) -> tuple:
        """:meth:`loss` without data-dependent sizes, for :func:`drjit.freeze`, and an overflow
        flag (mi.Bool, one entry: the buffer of ``capacity`` pairs was too small); only where
        :attr:`freezable`."""
        raise NotImplementedError

    def capacity(self, q: tuple) -> int:
        """A buffer size for :meth:`loss_fixed` at poses near quaternions ``q``; only where
        :attr:`freezable`."""
        raise NotImplementedError

    @staticmethod
    def _no_live(live: Any) -> None:
        """Raise ValueError when ``live`` is given to an objective without :attr:`fit_loss`."""
        if live is not None:
            raise ValueError("this objective has no fit_loss: its poses never settle (live)")
