"""Certified blocks: prove that a shape cannot pass a hole in any pose, or find a pose that passes.
Rule: certify works on exact polygons and meshes only; it never trusts a raster or the game.

Under the paper's model (the shape moves by translation along z through a thick plate), a shape B
passes the hole H iff some rotation R and in-plane translation t put proj(R B) + t inside H.
:func:`certify` decides this with rigorous bounds (docs/certify.md):

1. root level, rotation-free: a ball of radius rho inside B projects to a disk of radius rho in
   every pose; if no such disk fits in H, B is blocked (``method = "ball"``);
2. otherwise a branch and bound over rotation space (:mod:`sieve_mi.certify.search`) excludes
   cells of rotations, finds a passage, or runs out of budget.

That answer is about straight passage. A ball proof and a passage hold on a plate of any
thickness; a cell-tree proof only on a plate at least as thick as the shape's diameter (the
thick-plate argument): given a plate's ``thickness``, a thinner one turns it into "undecided"
(:meth:`Certification.on_plate`; the result's ``holds_for``, ``diameter`` and ``thickness`` say
so). On such a plate, the slab-section proof (:mod:`sieve_mi.certify.section`, from what is left
of the budget) can still prove it: then it holds on plates at least that thick.

:func:`replay` re-checks a certificate file with an independent implementation.

Modules
-------
search
    The branch and bound over rotation space (:class:`~sieve_mi.certify.search.CellSearch`).
cells
    Rotation-space cells on the faces of the quaternion cube, and their covering radii.
bounds
    Exclusion tests: rigorous reasons why no rotation of a cell lets the shape through H.
symmetry
    Rotational symmetries of a shape that shrink the search's domain.
certificate
    The result of a certification and its certificate file (JSON).
record
    A certificate's dictionary, assembled from what a search found.
structure
    A certificate's form, checked before any geometry.
replay
    The independent replay of a certificate.
replay_geometry
    The replay's own exact geometry.
section
    The slab-section proof: no rigid motion passes a plate of a given thickness.
turns
    The section proof's batched turn test: a quadtree of proved bounds over in-plane turns.
chain
    The section proof's chain test on a sheet: a section too wide for any one copy of the hole.
link
    The section proof's link test: a ring's loops keep it from straddling a web of the sheet.
replay_section
    The independent replay of a slab-section proof.
svg
    A hole outline read exactly from an SVG file.
blocks
    A solve's blocked B certified against the exact hole that gets printed.
"""

from __future__ import annotations

import numbers
import time

import manifold3d
import numpy as np

from sieve_mi.certify import bounds, cells, symmetry
from sieve_mi.certify.certificate import Certification, scope
from sieve_mi.certify.record import Evidence, build
from sieve_mi.certify.replay import replay
from sieve_mi.certify.search import CellSearch, Settings
from sieve_mi.certify.svg import read_svg_hole
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.plate import diameter as points_diameter

__all__ = [
    "Certification",
    "Settings",
    "certify",
    "proving_ball",
    "read_svg_hole",
    "replay",
    "section_only",
    "thin_plate_proof",
    "thinnest_proved",
]


def union_of_holes(holes: list[manifold3d.CrossSection]) -> manifold3d.CrossSection:
    """All holes as one region (a shape may use several holes at once if it is disconnected)."""
    if not holes:
        raise SieveError("no hole to certify against")
    hole = (
        manifold3d.CrossSection.batch_boolean(list(holes), manifold3d.OpType.Add)
        if len(holes) > 1
        else holes[0]
    )
    if hole.is_empty() or hole.area() <= 0:
        raise SieveError("the hole is empty")
    return hole


def _check_arguments(shape, holes, budget_s, settings=None, thickness=None) -> None:
    """One-line SieveErrors for arguments of the wrong kind (as the CLI refuses them)."""
    if settings is not None and not isinstance(settings, Settings):
        raise SieveError(
            "certify: settings must be a sieve_mi.certify.search.Settings (or None), "
            f"not {type(settings).__name__}"
        )
    if not isinstance(shape, Shape):
        raise SieveError(
            f"certify: shape must be a Shape (sieve_mi.load_shape), not {type(shape).__name__}"
        )
    if not isinstance(holes, (list, tuple)) or not all(
        isinstance(h, manifold3d.CrossSection) for h in holes
    ):
        raise SieveError("certify: holes must be a list of manifold3d.CrossSection")
    number = isinstance(budget_s, numbers.Real) and not isinstance(budget_s, (bool, np.bool_))
    if not (number and 0 < budget_s < float("inf")):
        raise SieveError(f"budget {budget_s!r}: must be a positive number of seconds")
    real = isinstance(thickness, numbers.Real) and not isinstance(thickness, (bool, np.bool_))
    if thickness is not None and not (real and 0 <= thickness < float("inf")):
        raise SieveError(f"thickness {thickness!r}: must be None or a number >= 0 (scene units)")


def certify(
    shape: Shape,
    holes: list[manifold3d.CrossSection],
    *,
    budget_s: float = 30.0,
    settings: Settings | None = None,
    scale: float = 1.0,
    use_symmetry: bool = True,
    thickness: float | None = None,
) -> Certification:
    """Prove that ``shape`` cannot pass through ``holes``, find a pose that passes, or give up.

    Parameters
    ----------
    shape : Shape
        The shape (vertices centred, scene units); rotations act about its centre.
    holes : list of manifold3d.CrossSection
        The through-holes of the sieve, in the hole plane's coordinates, scene units.
    budget_s : float
        Wall-clock budget, seconds (overrides ``settings.budget_s``).
    settings : Settings, optional
        Search settings; the defaults otherwise.
    scale : float
        The scale the shape was loaded with (recorded in the certificate for the replay).
    use_symmetry : bool
        Shrink the rotation domain by the shape's detected symmetry group.
    thickness : float, optional
        The plate's thickness where the holes are, scene units. None (the default): the holes
        are an outline without a plate, and the answer is for straight passage (a cell-tree
        proof then also holds for plates at least the shape's diameter thick). Given, a plate
        that the straight answer does not settle (thinner than the shape, or cells left open)
        gets the slab-section proof at its thickness (capped at the diameter) from what is left
        of the budget; on a plate thinner than the shape the straight search gets
        :data:`STRAIGHT_SHARE` of it.

    Returns
    -------
    Certification
        ``status`` "proved", "passage" or "undecided" (also a straight proof that does not hold
        on a plate of ``thickness``), ``straight`` the answer for straight passage, ``holds_for``
        what it covers, timings, cell counts, the excluded fraction, the passage pose if any,
        and the certificate (``write_certificate``).
    """
    _check_arguments(shape, holes, budget_s, settings, thickness)
    thin = thickness is not None and 0 < thickness < points_diameter(shape.hull)
    straight_s = STRAIGHT_SHARE * budget_s if thin else budget_s
    result = _certify(shape, holes, straight_s, settings, scale, use_symmetry)
    if thickness is None:
        return result
    result = result.on_plate(thickness)
    left = budget_s - result.seconds
    if _needs_section(result) and thickness > 0 and left > 0:
        t = min(float(thickness), float(result.diameter))  # at the diameter: every plate above
        result = thin_plate_proof(result, shape, holes, t, left, settings)
    return result


#: On a plate thinner than the shape, the straight search gets this share of ``certify``'s
#: budget: only a section proof decides such a plate, and it gets the rest.
STRAIGHT_SHARE = 0.5


def _needs_section(result: Certification) -> bool:
    """Whether a slab-section proof could still decide ``result`` on its plate: a straight proof
    by cells that does not cover the plate, or a straight search that left cells open (a
    section proof excludes straight passage too, :attr:`Certification.proved_section`)."""
    if result.method != "cells" or result.diameter is None or result.straight == "passage":
        return False
    return result.straight == "undecided" or not result.covers_plate


def thin_plate_proof(result: Certification, shape: Shape, holes: list, thickness: float,
                     budget_s: float, settings: Settings | None = None) -> Certification:  # fmt: skip
    """``result`` (a straight proof) completed by the slab-section proof at ``thickness``
    (:func:`sieve_mi.certify.section.prove_section`, within ``budget_s`` seconds): proved on
    plates at least that thick when it succeeds (:meth:`Certification.with_section`).

    Examples
    --------
    A closed wire ring (centre circle 20 mm across, wire 2 mm) cannot pass a 9 mm hole in a
    1 mm plate: any plane through its centre meets the ring at two points 20 mm apart.

    >>> import manifold3d, trimesh
    >>> from sieve_mi.geometry.meshes import shape_from_trimesh
    >>> ring = shape_from_trimesh(trimesh.creation.torus(10, 1), name="ring")
    >>> hole = manifold3d.CrossSection.circle(4.5, 64)
    >>> c = certify(ring, [hole], budget_s=60, thickness=1.0)
    >>> c.status, c.holds_for, c.section["thickness"]
    ('proved', "plates at least the section's thickness thick", 1.0)
    """
    from sieve_mi.certify.section import prove_section

    settings = settings or Settings()
    outcome, entry = prove_section(shape, union_of_holes(list(holes)), float(thickness),
                                   budget_s, settings)  # fmt: skip
    return result.with_section(outcome, entry)


def section_only(shape: Shape, holes: list, thickness: float, budget_s: float,
                 settings: Settings | None = None) -> Certification:  # fmt: skip
    """The slab-section proof at ``thickness`` without a straight search: a cell tree whose
    roots are all left open (no symmetry), completed by :func:`thin_plate_proof` within
    ``budget_s`` seconds. Proved (:attr:`Certification.proved_section`), it holds on plates at
    least ``thickness`` thick; its certificate replays as any proof by a section beside open
    cells. Used for a section-proved block's margin
    (:func:`sieve_mi.certify.blocks.section_margin`).
    """
    from sieve_mi.certify.search import Node, Outcome

    t0 = time.perf_counter()
    settings = settings or Settings()
    hole = union_of_holes(list(holes))
    contours = [np.asarray(c, dtype=np.float64) for c in hole.to_polygons()]
    roots = cells.roots(*symmetry.domain("none"))
    nodes = [Node(int(f), lo, hi) for f, lo, hi in zip(roots.face, roots.lo, roots.hi)]
    outcome = Outcome(roots=nodes, candidates=shape.vertices[np.unique(shape.faces)])
    diameter = points_diameter(shape.hull)
    evidence = Evidence("none", None, outcome)
    cert = build(shape, contours, "undecided", evidence, settings, 1.0, diameter)
    result = Certification("undecided", time.perf_counter() - t0, "cells", cells_open=len(nodes),
                           certificate=cert, straight="undecided", diameter=diameter)  # fmt: skip
    left = budget_s - (time.perf_counter() - t0)
    return thin_plate_proof(result, shape, [hole], thickness, max(left, 1e-3), settings)


#: :func:`thinnest_proved` tries this fraction of the diameter first after a straight proof.
TOP_TRY = 0.95
#: After a straight search that left cells open, :func:`thinnest_proved` tries ``low`` first,
#: with this share of its budget, then the diameter with this share of what is left.
LOW_SHARE = 0.5


def thinnest_proved(result: Certification, shape: Shape, holes: list, low: float,
                    budget_s: float, steps: int = 5) -> Certification:  # fmt: skip
    """The thinnest plate (of a bisection between ``low`` and the shape's diameter) on which
    ``result`` (a straight search by cells) is completed by a section proof.

    After a straight proof, :data:`TOP_TRY` of the diameter is tried first (when that fails,
    nothing thinner is tried: plates at least the diameter thick are proved already), then
    ``low`` (a printable minimum), then the bisection, each step with an equal share of the
    budget left. After a straight search that left cells open, nothing is proved yet, and a
    section proof is a complete proof (:attr:`Certification.proved_section`): ``low`` is tried
    first with :data:`LOW_SHARE` of the budget (a shape a section proves is often proved
    there), then the diameter itself with that share of what is left (when that fails,
    nothing thinner is tried), then the bisection. A section proof at t holds on every thicker plate
    (its band holds more of the shape), so the bracket is sound.

    Parameters
    ----------
    result : Certification
        A search by cells (``straight`` "proved" or "undecided"); a ball proof, a passage or
        anything else is returned as it is.
    shape : Shape
    holes : list of manifold3d.CrossSection
    low : float
        The thinnest plate worth proving, scene units.
    budget_s : float
        Seconds for all steps.
    steps : int
        Bisection steps after the first two tries.

    Returns
    -------
    Certification
        With :attr:`~Certification.section` the thinnest proved (the last tried when none was)
        and ``section["bracket"]``: ``proved`` (the thinnest thickness proved, or None) and
        ``unproved`` (the thickest tried that was not), with ``unproved_left``: that try's caps
        of directions ``open`` and ``examined`` and its ``seconds`` (why it is not proved);
        after open cells with nothing proved, no bracket (nothing to bracket).
    """
    if result.straight not in ("proved", "undecided") or result.method != "cells":
        return result
    if result.diameter is None:
        return result
    t0, best, unproved, last = time.perf_counter(), None, None, None
    hi, straight = float(result.diameter), result.straight == "proved"
    lo = float(low) if straight else min(float(low), hi)  # a shape thinner than low: at hi
    # after a straight proof first just below the diameter: a shape no section proves there is
    # left at once; after open cells, the printable minimum first, then the diameter
    top = round(TOP_TRY * hi, 4) if straight else hi
    tries = ([top, lo] if straight else [lo, top]) + [None] * steps
    for k, t in enumerate(tries):
        left = budget_s - (time.perf_counter() - t0)
        narrow = t is None and hi - lo <= 1e-3 * hi
        if left < 0.5 or narrow or not _worth(t, lo, hi, straight or best):
            break
        t = t if t is not None else round(0.5 * (lo + hi), 4)
        share = LOW_SHARE if (k <= 1 and not straight) else 1.0 / (len(tries) - k)
        c = thin_plate_proof(result, shape, holes, t, left * share)
        if c.section["status"] == "proved":
            best, hi = c, t
            if t == lo:
                break
        else:
            unproved, lo, last = t, t, c
            if t == top:
                break
    out = best or last or result  # an attempt that failed is recorded too
    if out is not result:  # every try's seconds, not only the one kept
        out.seconds = result.seconds + (time.perf_counter() - t0)
    if out.section is not None and (straight or best):
        bracket = {"proved": hi if best else None, "unproved": unproved}
        if last is not None:  # why the thickest unproved plate is not proved: caps left open
            bracket["unproved_left"] = {k: last.section[f"cells_{k}"] for k in ("open", "examined")}
            bracket["unproved_left"]["seconds"] = last.section["seconds"]
        out.section = {**out.section, "bracket": bracket}
    return out


def _worth(t: float | None, lo: float, hi: float, hi_proved) -> bool:
    """Whether a try at ``t`` (None: the bisection's middle) is inside the bracket: at least
    ``lo``, below ``hi`` (or at it, while nothing proves ``hi``)."""
    return t is None or lo <= t < hi or (t == hi and not hi_proved)


def proving_ball(shape: Shape, contours: list) -> tuple | None:
    """The ball certified inside ``shape`` (:func:`~sieve_mi.certify.bounds.inscribed_ball`:
    ``(centre (3,), radius)``) when no disk of its radius fits the hole given by ``contours``
    ((k, 2) float each): then no pose passes, on a plate of any thickness. None otherwise."""
    ball = bounds.inscribed_ball(shape)
    if ball is not None and bounds.no_disk_fits(bounds.contour_segments(contours), ball[1]):
        return ball
    return None


def _certify(shape, holes, budget_s, settings, scale, use_symmetry) -> Certification:
    """:func:`certify` for straight passage (the paper's model), arguments checked."""
    t0 = time.perf_counter()
    settings = Settings(**{**(settings or Settings()).__dict__, "budget_s": budget_s})
    if settings.bound not in ("first-order", "isotropic"):
        raise SieveError(f"bound {settings.bound!r}: must be 'first-order' or 'isotropic'")
    hole = union_of_holes(holes)
    contours = [np.asarray(c, dtype=np.float64) for c in hole.to_polygons()]
    diameter = points_diameter(shape.hull)
    ball = proving_ball(shape, contours)
    if ball is not None:
        root = {"kind": "ball", "centre": ball[0].tolist(), "radius": ball[1]}
        evidence = Evidence("none", root, None)
        cert = build(shape, contours, "proved", evidence, settings, scale, diameter)
        return Certification(
            "proved",
            time.perf_counter() - t0,
            "ball",
            excluded_fraction=1.0,
            certificate=cert,
            straight="proved",
            holds_for=scope("proved", "ball"),
            diameter=diameter,
        )
    group = symmetry.detect(shape) if use_symmetry else "none"
    faces, half = symmetry.domain(group)
    roots = cells.roots(faces, half)
    outcome = CellSearch(shape, hole, settings, group).run(roots)
    status = (
        "passage" if outcome.passage else ("proved" if outcome.open_cells == 0 else "undecided")
    )
    total = float(cells.volumes(roots).sum())
    cert = build(shape, contours, status, Evidence(group, None, outcome), settings, scale, diameter)
    return Certification(
        status,
        time.perf_counter() - t0,
        "cells",
        cells_examined=outcome.examined,
        cells_excluded=outcome.excluded,
        cells_open=outcome.open_cells,
        excluded_fraction=outcome.excluded_volume / total,
        depth=outcome.depth,
        symmetry=group,
        passage=outcome.passage,
        certificate=cert,
        straight=status,
        holds_for=scope(status, "cells"),
        diameter=diameter,
    )
