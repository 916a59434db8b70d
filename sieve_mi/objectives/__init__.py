"""Player B's differentiable losses: the interface every objective implements, and the factory.
Rule: an objective scores poses against holes; it knows the geometry, not the game.

An *objective* scores many poses of B's shapes against a stack of holes in one call. Player B
(:class:`sieve_mi.game.player_b.PlayerB`) binds it once to the list of poses (which shape each pose is),
then calls :meth:`Objective.loss` once per Adam step with all poses' quaternions and translations
as Dr.Jit arrays, and differentiates the returned total.

Three objectives exist:

``"clearance"`` (:class:`sieve_mi.objectives.clearance.ClearanceObjective`)
    Squared distance to H summed over samples on B's silhouette edges; zero iff B fits. The default:
    one kernel for all poses, reproducible bit for bit.
``"overlap"`` (:class:`sieve_mi.objectives.overlap.EdgeOverlapObjective`)
    The paper's eq. 12: the fraction of B's silhouette outside H, from integrals over B's visible
    outline (edge sampling), all poses at once; reproducible bit for bit.
``"overlap-mitsuba"`` (:class:`sieve_mi.objectives.overlap_mitsuba.OverlapObjective`)
    The same loss on an anti-aliased silhouette, differentiated by Mitsuba's projective sampling,
    one render per pose (the reference for ``"overlap"``; orders of magnitude slower).

The first two share their edge segments, (pose, segment) pairs, silhouette-edge test and fixed-order
per-pose sums (:class:`sieve_mi.objectives.edges.EdgeSampledObjective`, built on the device's pair
machinery of :mod:`sieve_mi.objectives.pairs`). Everything player B reads of an objective
(:class:`~sieve_mi.objectives.base.Objective`: :meth:`~Objective.bind`, :meth:`~Objective.loss`, ``fit_loss``, ``freezable``, ...)
is documented here once; each implementation adds only what is its own.

Neither decides a winner: the verdict scores poses on the hole itself (:mod:`sieve_mi.game.scoring`).

Modules
-------
base
    The ``Objective`` base class: what player B reads of a loss, documented once.
edges
    The edge sampling that the clearance and overlap objectives share.
pairs
    (pose, item) pairs on the device: built from ranges, read as packets, summed in a fixed order.
clearance
    ``"clearance"``: squared distance to H on B's silhouette edges.
overlap
    ``"overlap"``: the paper's eq. 12 by edge sampling.
overlap_mitsuba
    ``"overlap-mitsuba"``: eq. 8 by Mitsuba's projective sampling.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sieve_mi.objectives.base import Objective

if TYPE_CHECKING:  # kept light: scene.py reads OBJECTIVES from here
    from sieve_mi.geometry.meshes import Shape
    from sieve_mi.geometry.raster import Frame

__all__ = ["OBJECTIVES", "Objective", "make_objective"]

#: Names of the objectives, as ``[solver] objective`` accepts them.
OBJECTIVES = ("clearance", "overlap", "overlap-mitsuba")


def make_objective(
    name: str, shapes: list[Shape], frame: Frame, samples_per_segment: int | None = None
) -> Objective:
    """The objective called ``name`` for ``shapes`` on ``frame``.

    Parameters
    ----------
    name : {"clearance", "overlap", "overlap-mitsuba"}
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
    samples_per_segment : int, optional
        Clearance and overlap: edge samples per segment (default: from the edge lengths).

    Examples
    --------
    >>> from sieve_mi.geometry.meshes import shape_from_trimesh
    >>> from sieve_mi.geometry.raster import Frame
    >>> from sieve_mi.testing.shapes import sphere
    >>> ball = shape_from_trimesh(sphere(5.0, 2), name="ball")
    >>> loss = make_objective("clearance", [ball], Frame(16, 8.0))
    >>> type(loss).__name__
    'ClearanceObjective'
    """
    if name == "clearance":
        from sieve_mi.objectives.clearance import ClearanceObjective

        return ClearanceObjective(shapes, frame, samples_per_segment)
    if name == "overlap":
        from sieve_mi.objectives.overlap import EdgeOverlapObjective

        return EdgeOverlapObjective(shapes, frame, samples_per_segment)
    if name == "overlap-mitsuba":
        from sieve_mi.objectives.overlap_mitsuba import OverlapObjective

        return OverlapObjective(shapes, frame)
    raise ValueError(f"unknown objective {name!r}; use one of {OBJECTIVES}")
