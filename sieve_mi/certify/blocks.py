"""Certify a solve's blocks: each blocked B against the exact hole that gets printed."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from concurrent.futures import as_completed
from typing import NamedTuple

import manifold3d
import numpy as np

from sieve_mi.certify.certificate import Certification
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import dilated, is_closed
from sieve_mi.geometry.window import windowed_hole
from sieve_mi.scene import Scene
from sieve_mi.workers import worker_pool

__all__ = [
    "Budgets",
    "MARGIN_FACTOR",
    "BALL_BOXES",
    "BALL_STEPS",
    "MARGIN_MIN_S",
    "SECTION_MARGIN_STEPS",
    "ball_margin",
    "certify_blocks",
    "margin_by_ball",
    "on_sheet",
    "printed_hole",
    "progress_words",
    "prove_margin",
    "section_margin",
    "sheet_holes",
]

#: The margin bisection after a proof gets at most this many times the proof's time ...
MARGIN_FACTOR = 4.0
#: ... and at least this many seconds (when the budget has them left).
MARGIN_MIN_S = 2.0
#: Bisection steps of a section-proved block's margin (:func:`section_margin`).
SECTION_MARGIN_STEPS = 5
#: Bisection steps of a ball-proved block's margin (within found / 2^steps of the ball's best) ...
BALL_STEPS = 8
#: ... each giving up (not proved) past this many boxes of the disk test.
BALL_BOXES = 20_000


def ball_margin(
    radius: float, hole, *, steps: int = 24, upper: float | None = None, max_boxes: int = 200_000
) -> float:
    """A proved lower bound on how far a shape holding a ball of ``radius`` sticks out of ``hole``.

    If no disk of that radius fits in H grown by m, every pose sticks out by more than m (a pose
    sticking out by at most m lies in H ⊕ m, and so would the projection of the ball's disk).
    Bisection on m over :func:`sieve_mi.geometry.outline.dilated` (which contains the exact
    dilation, so a disk that fits neither fits the exact one) with certify's proved
    ``no_disk_fits``.

    Parameters
    ----------
    radius : float
        Radius of a ball certified inside the shape (a ball proof's), scene units.
    hole : manifold3d.CrossSection
        The exact hole H.
    steps : int
        Bisection steps (the bound is within upper / 2^steps of the best this test can prove).
    upper : float, optional
        Upper end of the bisection (default ``radius``), e.g. the overhang of a pose found: no
        proof goes past it.
    max_boxes : int
        Boxes the disk test may refine before it gives up on a step (counted as not proved:
        near the bound the test needs ever smaller boxes).

    Returns
    -------
    float
        m >= 0 (0 when no disk test proves anything).
    """
    from sieve_mi.certify.bounds import contour_segments, no_disk_fits

    def holds(m: float) -> bool:
        grown = dilated(hole, m) if m > 0 else hole
        segs = contour_segments([np.asarray(c, float) for c in grown.to_polygons()])
        return no_disk_fits(segs, radius, max_boxes=max_boxes)

    if not holds(0.0):
        return 0.0
    lo, hi = 0.0, float(radius if upper is None else min(radius, upper))
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if holds(mid) else (lo, mid)
    return lo


def on_sheet(certified: list, thickness: float) -> list:
    """Each B's certification judged on the plate as made (:meth:`Certification.on_plate`).

    A cell-tree proof holds only for straight passage, or a plate at least as thick as the B's
    diameter: on a thinner plate (``[fabrication] thickness``, or ``"thinnest"``) its status
    becomes ``"undecided"`` (``straight`` stays ``"proved"``), so report.json never says
    "proved" where a tilted passage is not excluded. Ball proofs and passages hold on any plate.

    Parameters
    ----------
    certified : list of Certification or None
        Per B (None where none ran); may be empty.
    thickness : float
        The plate's thickness, scene units.

    Returns
    -------
    list of Certification or None
    """
    return [None if c is None else c.on_plate(thickness) for c in certified]


def printed_hole(scene: Scene, pass_shapes: list[Shape], quats: np.ndarray, trans: np.ndarray,
                 outline=None):  # fmt: skip
    """The hole a block's proof is against: the exact outline the plate is cut from, grown by the
    block margin.

    That outline is :func:`sieve_mi.geometry.window.windowed_hole` of A's placed projections
    (dilated by ``[fabrication] tolerance``, gaps filled as ``fill_holes`` says), grown by
    ``[fabrication] block_margin`` when there is one, so a proof covers the printed plate and the
    margin the scene asks for.

    Parameters
    ----------
    scene : Scene
        Its ``[fabrication]`` table.
    pass_shapes : list of Shape
    quats : (m, 4) ndarray
        A's rotations.
    trans : (m, 2) ndarray
        A's translations, scene units.
    outline : manifold3d.CrossSection, optional
        The verdict's exact hole (:attr:`sieve_mi.game.verdict.Judgement.outline`), used as it
        is where given: separate holes, each at its own tolerance and with the mirrored holes
        (:mod:`sieve_mi.game.holes`), are the verdict's to lay out.

    Returns
    -------
    manifold3d.CrossSection
    """
    fab = scene.fabrication
    closed = [is_closed(s) for s in pass_shapes]
    hole = outline
    if hole is None:
        hole, _ = windowed_hole(pass_shapes, quats, trans, fab.tolerance,
                                math.radians(fab.window), fab.fill_holes, closed)  # fmt: skip
    if fab.block_margin > 0:
        hole = dilated(hole, fab.block_margin)
    return hole


def certify_blocks(
    scene: Scene,
    hole,
    block_shapes: list[Shape],
    blocked: np.ndarray,
    progress: Callable[[str], None] | None = None,
    workers: int | None = None,
    found: np.ndarray | None = None,
    pattern=None,
) -> list[Certification | None]:
    """Try to prove, for every B the verdict found blocked, that it cannot pass in any pose.

    The proofs run in parallel, one forked worker process per B (at most ``workers`` at once),
    each with ``[verdict] certify_budget`` seconds.

    Parameters
    ----------
    scene : Scene
        ``[verdict] certify_budget`` gives each proof's budget.
    hole : manifold3d.CrossSection
        The hole to prove against: :func:`printed_hole` of A's placement, so a proof covers the
        printed plate and the block margin.
    block_shapes : list of Shape
    blocked : (n,) ndarray of bool
        The verdict's answer per B; only blocked B are certified.
    progress : callable, optional
        Called with one line per proof as it ends: its status, seconds and the share of
        rotations excluded.
    workers : int, optional
        Worker processes (default: the machine's CPU count); 1 runs the proofs here, one by one.
    found : (n,) ndarray, optional
        Per B, the protrusion of the best pose found (scene units): the upper end of the margin
        bisection that follows a proof (:func:`prove_margin`, within the same budget).
    pattern : sieve_mi.geometry.pattern.Pattern, optional
        The perforated sheet ``hole`` is repeated on (:func:`sheet_holes`): a B of several bodies
        is proved against the copies within its reach, and every slab-section proof is.

    Returns
    -------
    list of Certification or None
        Per B, its certification, or None where the verdict already let it through.
    """
    todo = [j for j, b in enumerate(blocked) if b]
    budget = Budgets(scene.verdict.certify_budget, scene.verdict.section_budget,
                     scene.fabrication.thickness, scene.fabrication.min_thickness)  # fmt: skip
    out: list[Certification | None] = [None] * len(block_shapes)
    tops = [None if found is None else float(found[j]) for j in todo]
    merged = pattern is not None and 2.0 * scene.fabrication.block_margin >= pattern.least_gap
    holes = [sheet_holes(hole, block_shapes[j], pattern, tops[k], merged)
             for k, j in enumerate(todo)]  # fmt: skip
    for j, c in _proofs([block_shapes[j] for j in todo], holes, budget, workers, tops):
        out[todo[j]] = c
        if progress is not None:
            progress(f"certify {block_shapes[todo[j]].name}: {progress_words(c, scene.units)}")
    return out


def progress_words(c: Certification, units: str = "mm") -> str:
    """What a proof's progress line says after the B's name: ``proved (2.1 s, 100.0 % of
    rotations excluded)``, or for a proof by its slab section alone (the straight search left
    cells open, :attr:`Certification.by_section`) ``proved by its slab section on plates at
    least 2 mm thick (12.3 s; the straight search excluded 0.0 % of rotations)``."""
    if c.by_section and not c.cells_examined:  # proved first: no straight search ran
        return (f"proved by its slab section on plates at least {c.section['thickness']:g} "
                f"{units} thick ({c.seconds:.1f} s; no straight search needed: the section "
                "excludes straight passage too)")  # fmt: skip
    if c.by_section:
        return (f"proved by its slab section on plates at least {c.section['thickness']:g} "
                f"{units} thick ({c.seconds:.1f} s; the straight search excluded "
                f"{c.excluded_percent(1)} % of rotations)")  # fmt: skip
    return f"{c.status} ({c.seconds:.1f} s, {c.excluded_percent(1)} % of rotations excluded)"


class Budgets(NamedTuple):
    """What each block's proof may spend, and the plate it is for.

    Attributes
    ----------
    proof_s : float
        Seconds of the straight proof and its margin (``[verdict] certify_budget``).
    section_s : float
        Seconds of the slab-section proofs after it (``[verdict] section_budget``).
    thickness : float, str or None
        ``[fabrication] thickness``: None or "thinnest" bisects the thinnest proved plate from
        ``low`` up; a number is proved at that thickness (when thinner than the shape).
    low : float
        ``[fabrication] min_thickness``, scene units.
    """

    proof_s: float
    section_s: float
    thickness: object
    low: float


def sheet_holes(hole, shape: Shape, pattern, found: float | None = None,
                merged: bool = False) -> tuple:  # fmt: skip
    """The holes one B's proofs are against: (straight, section), each a list of contours.

    On a single hole both are ``hole``. On a perforated sheet (``pattern``), a B of one body is
    proved straight against ``hole`` (its projection is connected, so it fits the copies' union
    iff it fits one copy: :mod:`sieve_mi.geometry.pattern`), a B of several bodies against the
    copies within its reach (:meth:`~sieve_mi.geometry.pattern.Pattern.window` of its diameter,
    plus twice ``found`` for the margin bisection's grown holes), and every slab-section proof
    against the groups of copies a set of its diameter can touch together
    (:meth:`~sieve_mi.geometry.pattern.Pattern.patches`; a section of a connected B may fall
    apart), except
    for a convex solid (:func:`~sieve_mi.geometry.meshes.convex_solid`: its sections are convex,
    so connected, and one copy decides them). ``section`` is None where it is ``straight``.

    Parameters
    ----------
    hole : manifold3d.CrossSection
        :func:`printed_hole` (H grown by the block margin).
    shape : Shape
    pattern : Pattern or None
    found : float, optional
        The protrusion of B's best pose found, scene units.
    merged : bool
        Whether ``hole``'s copies may meet (a block margin of at least half the web): then a B
        of one body is proved straight against the copies within its reach too.
    """
    from sieve_mi.geometry.meshes import bodies, convex_solid
    from sieve_mi.geometry.plate import diameter

    def contours(section) -> list:
        return [np.asarray(c, dtype=np.float64) for c in section.to_polygons()]

    if pattern is None:
        return contours(hole), None
    d = diameter(shape.hull)
    # a convex solid's slab sections are convex, hence connected: one copy decides them too
    window = None if convex_solid(shape) else contours(pattern.patches(d, hole))
    if merged or bodies(shape) > 1:
        return contours(pattern.window(d + 2.0 * max(found or 0.0, 0.0), hole)), window
    return contours(hole), window


def _proofs(shapes: list[Shape], holes: list, budget_s: Budgets, workers, tops: list):
    """Yield ``(index, Certification)`` for each shape as its proof ends (forked workers)."""
    n = max(1, min(len(shapes), workers or os.cpu_count() or 1))
    if n == 1:
        for j, shape in enumerate(shapes):
            yield j, _prove(shape, holes[j], budget_s, tops[j])
        return
    with worker_pool(n, what="certify") as pool:
        jobs = {
            pool.submit(_prove, shape, holes[j], budget_s, tops[j]): j
            for j, shape in enumerate(shapes)
        }
        for job in as_completed(jobs):
            yield jobs[job], job.result()


def _prove(shape: Shape, holes: tuple, budget: Budgets, found: float | None) -> Certification:
    """Worker: certify one shape against the hole given by its contours, then bracket its
    margin (:func:`prove_margin`) with what is left of the budget, but at most
    :data:`MARGIN_FACTOR` times the proof's own time (at least :data:`MARGIN_MIN_S`): a step
    that takes much longer than the proof is near the true margin and would mostly end
    undecided. A search by cells, proved or left with open cells (no passage), then gets the
    slab-section proofs of the plate within ``[verdict] section_budget``
    (:func:`sieve_mi.certify.thinnest_proved`, or :func:`~sieve_mi.certify.thin_plate_proof` at a
    given thickness, see :func:`_section_thickness`): a section proof at t excludes every rigid
    motion through a plate at least t thick, straight passage included (a straight passage
    passes every plate), so it completes an undecided tree as well as a proved one. ``holes``:
    the straight proof's and the section proofs' contours
    (:func:`sieve_mi.certify.blocks.sheet_holes`; None: the same)."""
    from sieve_mi.certify import thin_plate_proof, thinnest_proved

    hole = manifold3d.CrossSection(holes[0])
    section = hole if holes[1] is None else manifold3d.CrossSection(holes[1])
    first = _section_first(shape, hole, section, budget, found)
    if first is not None:
        return first if holes[1] is None else _against_sheet(first, holes[1])
    c = _straight(shape, hole, budget, found)
    if c.status not in ("proved", "undecided") or c.method != "cells" or c.diameter is None:
        return c
    t0 = time.perf_counter()
    if budget.thickness in (None, "thinnest"):
        c = thinnest_proved(c, shape, [section], budget.low, budget.section_s)
    elif (t := _section_thickness(c, budget.thickness)) is not None:
        c = thin_plate_proof(c, shape, [section], t, budget.section_s)
    if c.by_section and not c.margin:  # no straight proof to bisect: the section's margin
        margin = _section_margin(c, shape, section, found, budget, t0)
        c.margin, c.margin_certificate, c.margin_steps = margin
    return c if holes[1] is None else _against_sheet(c, holes[1])


#: A given plate thinner than the B first gets its section proof alone, with this share of
#: ``[verdict] section_budget``: proved, no straight search is needed (it excludes straight
#: passage too); failed, the straight search and the sections after it run as before.
FIRST_SHARE = 0.3


def _section_first(shape: Shape, hole, section, budget: Budgets,
                   found: float | None) -> Certification | None:  # fmt: skip
    """A B on a given plate thinner than it, proved by its slab section at the plate's thickness
    before any straight search (:func:`sieve_mi.certify.section_only`, :data:`FIRST_SHARE` of
    ``[verdict] section_budget``), with its section margin; None when the plate is not such a
    plate, when a ball inside the B already proves it on any plate (the straight proof's root
    test, kept first), or when the section is not proved in that time."""
    from sieve_mi.certify import proving_ball, section_only
    from sieve_mi.geometry.plate import diameter as points_diameter

    t = _given(budget.thickness)
    if t is None or t <= 0 or FIRST_SHARE <= 0 or t >= points_diameter(shape.hull):
        return None
    if proving_ball(shape, [np.asarray(c, dtype=np.float64) for c in hole.to_polygons()]):
        return None  # the ball proof (any plate) comes from the straight proof
    t0 = time.perf_counter()
    c = section_only(shape, [section], float(t), FIRST_SHARE * budget.section_s)
    if not c.by_section:
        return None
    c.margin, c.margin_certificate, c.margin_steps = _section_margin(
        c, shape, section, found, budget, t0
    )
    return c


def _section_margin(c: Certification, shape: Shape, hole, found, budget: Budgets, t0: float):
    """:func:`section_margin` of a block proved by its section, with what is left of
    ``[verdict] section_budget`` (counted from ``t0``), but at most :data:`SECTION_MARGIN_STEPS`
    times twice the section proof's own time (at least :data:`MARGIN_MIN_S`), each step at least
    that twice."""
    proof_s = float(c.section["seconds"])
    spare = min(budget.section_s - (time.perf_counter() - t0),
                max(MARGIN_MIN_S, 2.0 * SECTION_MARGIN_STEPS * proof_s))  # fmt: skip
    return section_margin(shape, hole, c.section["thickness"], found, spare,
                          steps=SECTION_MARGIN_STEPS, step_s=2.0 * proof_s)  # fmt: skip


def _section_thickness(c: Certification, given) -> float | None:
    """The thickness a given plate (``[fabrication] thickness``, a number) gets its section
    proof at, scene units, or None for none: the plate's own when it is thinner than the shape
    (a straight proof by cells does not cover it); after open cells also a thicker plate, at
    the diameter (the section there covers every thicker plate)."""
    given = _given(given)
    if given is None:
        return None
    d = float(c.diameter)
    if given < d:
        return given
    return d if c.straight == "undecided" else None


def _given(thickness) -> float | None:
    """``[fabrication] thickness`` as a number of scene units, or None when it is not one
    (unset, or ``"thinnest"``)."""
    if not isinstance(thickness, float | int) or isinstance(thickness, bool):
        return None
    return float(thickness)


def _against_sheet(c: Certification, contours: list) -> Certification:
    """A certification whose section proofs were against a sheet's copies: its certificate's
    ``section`` carries them as ``hole`` (the replay re-proves it against them), and report.json's
    ``section`` says how many contours they have."""
    if c.section is not None:
        c.section = {**c.section, "sheet_contours": len(contours)}
    entry = (c.certificate or {}).get("section")
    if entry is not None:
        c.certificate = {
            **c.certificate,
            "section": {**entry, "hole": [x.tolist() for x in contours]},
        }
    return c


def _straight(shape: Shape, hole, budget: Budgets, found: float | None) -> Certification:
    """The straight proof against ``hole`` and its margin bisection (:func:`_prove`)."""
    from sieve_mi.certify import certify

    c = certify(shape, [hole], budget_s=budget.proof_s)
    if c.status == "proved" and c.method == "ball":
        c.margin, c.margin_certificate, c.margin_steps = _ball_margin(shape, c, hole, found)
    elif c.status == "proved":
        spare = min(budget.proof_s - c.seconds, max(MARGIN_MIN_S, MARGIN_FACTOR * c.seconds))
        c.margin, c.margin_certificate, c.margin_steps = prove_margin(shape, hole, found, spare)
    return c


def margin_by_ball(radius: float, hole, found: float | None) -> float:
    """:func:`ball_margin` of a ball of ``radius`` up to ``found``, the overhang of a pose found
    (no proof goes past it), in :data:`BALL_STEPS` steps of at most :data:`BALL_BOXES` boxes;
    0 when nothing sticks out (``found`` None or <= 0)."""
    if not found or found <= 0.0:
        return 0.0
    return ball_margin(radius, hole, steps=BALL_STEPS, upper=float(found), max_boxes=BALL_BOXES)


def _ball_margin(shape: Shape, c, hole, found: float | None) -> tuple[float, dict, int]:
    """The margin of a block proved by its ball (:func:`prove_margin`'s answer, without its
    bisection of whole proofs): :func:`ball_margin` of that ball, capped by ``found`` (no proof
    can go past a pose that sticks out that much), proved again by one certify call against H
    grown by it, which gives the margin's certificate (the same ball test)."""
    from sieve_mi.certify import certify

    m = margin_by_ball(float(c.certificate["root"]["radius"]), hole, found)
    if m <= 0.0:
        return 0.0, {}, 0
    again = certify(shape, [dilated(hole, m)], budget_s=1.0)
    return (m, again.certificate, 1) if again.status == "proved" else (0.0, {}, 1)


def prove_margin(
    shape: Shape, hole, found: float | None, budget_s: float, *, steps: int = 5
) -> tuple[float, dict, int]:
    """The largest m (of a bisection) for which ``shape`` is proved blocked by ``hole`` grown by m.

    A proof against H grown by m (:func:`sieve_mi.geometry.outline.dilated`, which contains the
    exact dilation) means every pose puts some point of the shape further than m from H. The
    bisection runs between 0 (already proved) and ``found``, the protrusion of the best pose
    found (the true margin is at most that), each step with an equal share of the budget left;
    a step that ends undecided or with a passage counts as not proved.

    Parameters
    ----------
    shape : Shape
    hole : manifold3d.CrossSection
        The hole the shape is already proved blocked by.
    found : float or None
        Upper end, scene units; None or <= 0 skips the bisection.
    budget_s : float
        Seconds for all steps together.
    steps : int

    Returns
    -------
    (float, dict, int)
        m >= 0, the certificate of the proof at m (empty for m = 0) and the number of steps that
        ran (0: not bisected, e.g. no budget left or ``found`` <= 0).
    """
    from sieve_mi.certify import certify

    def proved(grown, seconds: float) -> dict | None:
        c = certify(shape, [grown], budget_s=seconds)
        return c.certificate if c.status == "proved" else None

    return _bisect(proved, hole, found, budget_s, steps)


def section_margin(shape: Shape, hole, thickness: float, found: float | None, budget_s: float,
                   *, steps: int = 5, step_s: float = 0.0) -> tuple[float, dict, int]:  # fmt: skip
    """The largest m (of a bisection) for which the slab-section proof at ``thickness`` holds
    against ``hole`` grown by m: the margin of a block proved by its section
    (:attr:`~sieve_mi.certify.certificate.Certification.by_section`), as :func:`prove_margin` is
    a straight proof's.

    Each step is :func:`sieve_mi.certify.section_only` against H grown by m
    (:func:`sieve_mi.geometry.outline.dilated`, which contains the exact dilation). Proved, it
    means: on a plate at least ``thickness`` thick, by any motion, the section's projection (a
    part of the silhouette) sticks out of H by more than m at the moment the pin crosses the
    mid-plane; so every straight pose sticks out by more than m too. The certificate is that
    proof's (a section beside open roots), which the replay re-proves against the grown hole.

    Parameters
    ----------
    shape : Shape
    hole : manifold3d.CrossSection
        The hole the section proof held against (the sheet's copies on a perforated sheet).
    thickness : float
        The proved section's thickness, scene units.
    found, budget_s, steps
        As :func:`prove_margin`.
    step_s : float
        Seconds each step gets at least (while the budget has them): a step cut short by its
        share counts as not proved, so a step is given about what the proof at m = 0 took.

    Returns
    -------
    (float, dict, int)
        As :func:`prove_margin`.
    """
    from sieve_mi.certify import section_only

    def proved(grown, seconds: float) -> dict | None:
        c = section_only(shape, [grown], thickness, seconds)
        return c.certificate if c.proved_section is not None else None

    return _bisect(proved, hole, found, budget_s, steps, step_s)


def _bisect(proved: Callable, hole, found: float | None, budget_s: float, steps: int,
            least: float = 0.0):  # fmt: skip
    """The margin bisection of :func:`prove_margin` and :func:`section_margin`: between 0 and
    ``found``, each step ``proved(H grown by m, seconds)`` (a certificate, or None) with an
    equal share of what is left of ``budget_s`` (at least ``least`` seconds while that is
    left); steps stop when under 0.5 s is left."""
    t0 = time.perf_counter()
    lo, hi, cert, ran = 0.0, float(found or 0.0), {}, 0
    for k in range(steps if hi > 0 else 0):
        left = budget_s - (time.perf_counter() - t0)
        if left < 0.5:
            break
        mid, ran = 0.5 * (lo + hi), ran + 1
        got = proved(dilated(hole, mid), min(left, max(left / (steps - k), least)))
        if got is not None:
            lo, cert = mid, got
        else:
            hi = mid
    return lo, cert, ran
