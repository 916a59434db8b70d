"""The thin-plate verdict of one shape: safe by its diameter, a verified passage, or none found.

Each shape's search runs in a forked worker process (in parallel over shapes): the planner's
bindings stay out of the calling process, and a worker ends without the interpreter's teardown.
A single shape (:func:`thin_plate`, as ``check`` asks) gets its slab-section proof in the calling
process first, so a shape that proof makes safe starts no worker.
"""

from __future__ import annotations

import math
import numbers
import os
import time
from collections.abc import Iterator
from concurrent.futures import as_completed
from dataclasses import dataclass, field

import manifold3d
import numpy as np

from sieve_mi.certify.bounds import contour_segments, inscribed_ball, no_disk_fits
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.plate import LENGTH_SLACK, diameter
from sieve_mi.workers import worker_pool

__all__ = [
    "BALL_ARGUMENT",
    "INTERPOLATION",
    "SAFE_ARGUMENT",
    "SECTION_ARGUMENT",
    "SECTION_MAX_S",
    "ThinPlate",
    "each_thin_plate",
    "thin_plate",
    "thin_plates",
]

#: How a reported motion moves between consecutive poses.
INTERPOLATION = "centre along straight segments, rotation along the shortest arc (slerp)"

#: Why a plate at least as thick as a shape's diameter needs no motion search.
SAFE_ARGUMENT = (
    "diameter <= thickness: when the shape's highest point enters the plate's top face, every "
    "point of the shape lies within its diameter below it, inside the plate's slab, so the shape "
    "is wholly inside the hole's prism and its projection must fit H"
)

#: Why a shape proved blocked by an inscribed ball needs no motion search on any plate.
BALL_ARGUMENT = (
    "a ball certified inside the shape is wider than any disk the hole holds: the ball's centre "
    "must cross the plate's slab, and there the horizontal disk through it lies in the slab, so "
    "it would have to fit H (any thickness)"
)

#: Why a shape proved by its slab section needs no motion search on a plate at least that thick.
SECTION_ARGUMENT = (
    "a point pinned in the shape must cross the plate's mid-plane, and then every point of the "
    "shape inside the plate's slab must lie in the hole's prism; for no direction, turn and offset "
    "does that slab section fit the hole (a certified branch and bound over directions: "
    "docs/certify.md, 'Thin plates'), so no rigid motion passes this plate or a thicker one"
)

#: Most seconds of a shape's own section proof before its motion search (half its budget).
SECTION_MAX_S = 15.0

#: The planner, as reported.
PLANNER = "OMPL RRTConnect on SE(3), seeded straight descents and crossing poses"


@dataclass
class ThinPlate:
    """One shape against a plate of a given thickness.

    Attributes
    ----------
    name : str
    thickness, diameter : float
        Scene units.
    status : {"safe", "passage", "no passage found", "not covered"}
        ``"not covered"``: the argument behind "safe" does not reach this plate (a B of several
        bodies on a perforated sheet, its verdict against one hole; ``note`` says why).
    poses : (k, 7) float
        A found motion: rows (w, x, y, z, tx, ty, tz), the shape's rotation about its centre and
        the centre's position (plate top at z = 0, hole in the xy-plane); empty otherwise.
    min_clearance : float
        Smallest distance from the shape to the plate along the verified motion, scene units.
    verified_poses : int
        Poses of the continuous re-check (the motion subdivided until every segment passed).
    method : str
        What found the motion.
    seconds, budget_s : float
    checks, plans, crossings : int
        Collision/distance queries, planner runs and crossing poses sampled.
    argument : str
        Why a "safe" answer holds.
    verified_on : str
        ``"plate mesh"`` when the motion was re-checked against the plate's own mesh (a plate
        that is not a uniform slab); empty when the slab is the plate.
    note : str
        Why a motion found through the slab was dropped (it met the plate's other material).
    section : dict or None
        The slab-section proof behind a ``"safe"`` answer by :data:`SECTION_ARGUMENT`: its
        ``thickness`` (at most this plate's), ``pin``, cells and seconds.
    """

    name: str
    thickness: float
    diameter: float
    status: str
    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    min_clearance: float = float("nan")
    verified_poses: int = 0
    method: str = ""
    seconds: float = 0.0
    budget_s: float = 0.0
    checks: int = 0
    plans: int = 0
    crossings: int = 0
    argument: str = SAFE_ARGUMENT
    verified_on: str = ""
    note: str = ""
    section: dict | None = None

    def to_dict(self) -> dict:
        """The ``thin_plate`` entry of report.json and of ``check --json``."""
        out = {
            "thickness": self.thickness,
            "status": self.status,
            "diameter": self.diameter,
        }
        if self.status == "not covered":
            out["note"] = self.note
            return out
        if self.status == "safe":
            by = {BALL_ARGUMENT: "ball", SECTION_ARGUMENT: "section"}
            out["by"] = by.get(self.argument, "diameter")
            out["argument"] = self.argument
            if self.section is not None:
                out["section"] = self.section
            return out
        out.update(planner=PLANNER, seconds=self.seconds, budget_s=self.budget_s)
        out.update(checks=self.checks, plans=self.plans, crossings=self.crossings)
        if self.status == "passage":
            out.update(method=self.method, min_clearance=self.min_clearance)
            out.update(verified_poses=self.verified_poses, interpolation=INTERPOLATION)
            if self.verified_on:
                out["verified_on"] = self.verified_on
            out["poses"] = [[float(v) for v in row] for row in self.poses]
        else:
            out["note"] = "a heuristic search within the budget, not a proof that no motion exists"
            if self.note:
                out["note"] += f"; {self.note}"
        return out


def _ball_proves(shape: Shape, segs: np.ndarray) -> bool:
    """Whether a ball certified inside the shape is wider than every disk in the hole
    (:data:`BALL_ARGUMENT`; certify's root-level test)."""
    ball = inscribed_ball(shape)
    return ball is not None and no_disk_fits(segs, ball[1])


def _polygons(outline: manifold3d.CrossSection) -> list:
    return [np.asarray(c, dtype=np.float64) for c in outline.to_polygons()]


def _section_first(shape: Shape, outline, thickness: float, budget_s: float) -> ThinPlate | None:
    """ "safe" by a slab-section proof at ``thickness`` within ``budget_s`` (None when it fails)."""
    from sieve_mi.certify.search import Settings
    from sieve_mi.certify.section import prove_section

    found, _ = prove_section(shape, outline, thickness, budget_s, Settings())
    if found.status != "proved":
        return None
    record = {"thickness": float(thickness), "pin": [float(c) for c in found.pin],
              "seconds": found.seconds, "cells_examined": found.examined,
              "cells_excluded": found.excluded}  # fmt: skip
    return ThinPlate(shape.name, float(thickness), diameter(shape.hull), "safe",
                     argument=SECTION_ARGUMENT, seconds=found.seconds, section=record)  # fmt: skip


def _search(shape: Shape, polygons: list, thickness: float, budget_s: float, seeds, seed: int,
            plate=None, section_s: float = 0.0):  # fmt: skip
    """Worker: the section proof (``section_s`` seconds of the budget) then the motion search
    for one shape (see :func:`thin_plate`)."""
    from sieve_mi.motion.collide import PlateWorld
    from sieve_mi.motion.planner import search_passage

    outline = manifold3d.CrossSection(polygons)
    if section_s > 0:
        t0 = time.perf_counter()
        safe = _section_first(shape, outline, thickness, section_s)
        if safe is not None:
            return safe
        budget_s = max(0.0, budget_s - (time.perf_counter() - t0))
    world = PlateWorld(shape, outline, thickness)
    found = search_passage(world, outline, seeds, budget_s, seed)
    d = diameter(shape.hull)
    out = ThinPlate(shape.name, float(thickness), d, "no passage found", seconds=found.seconds,
                    budget_s=float(budget_s), checks=found.checks, plans=found.plans,
                    crossings=found.crossings)  # fmt: skip
    passage, poses = found.passage, found.poses
    if passage is not None and plate is not None:
        passage, poses = _on_mesh(shape, plate, poses)
        out.verified_on = "plate mesh"
        if not passage.ok:
            out.note = (
                f"a motion through the slab ({thickness:.4g} thick) met the plate's other "
                "material (a rim, post or boss) and was dropped"
            )
    if passage is not None and passage.ok:
        out.status, out.method = "passage", found.method
        out.poses = np.array([np.concatenate([q, t]) for q, t in poses])
        out.min_clearance = passage.min_clearance
        out.verified_poses = len(passage.poses)
    return out


def _on_mesh(shape: Shape, plate, poses: list):
    """Re-check a motion found through the slab model against the plate's own mesh.

    The motion is first lengthened straight up from its start and straight down from its end
    until the shape clears the whole plate (posts and rims included), then re-checked
    continuously (:func:`sieve_mi.motion.path.verify`).

    Parameters
    ----------
    shape : Shape
    plate : (vertices (V, 3) float, faces (F, 3) int)
        The plate's mesh in the slab's frame (the slab's top at z = 0), scene units.
    poses : list of (quat, trans)

    Returns
    -------
    (Verified, list of (quat, trans))
    """
    from sieve_mi.motion.collide import MeshWorld
    from sieve_mi.motion.path import verify

    vertices, faces = plate
    world = MeshWorld(shape, vertices, faces)
    gap = max(0.05 * world.radius, 1e-3)
    (q0, t0), (q1, t1) = poses[0], poses[-1]
    top = float(np.max(vertices[:, 2])) + world.radius + gap
    bottom = float(np.min(vertices[:, 2])) - world.radius - gap
    path = list(poses)
    if t0[2] < top:
        path.insert(0, (q0, np.array([t0[0], t0[1], top])))
    if t1[2] > bottom:
        path.append((q1, np.array([t1[0], t1[1], bottom])))
    return verify(world, path), path


def _safe_at_once(shapes: list, outline, ts: list, sections: list | None) -> list:
    """Per shape, a ``"safe"`` ThinPlate that needs no search (a ball, its diameter, a section
    proof that covers its plate), else None."""
    out: list = [None] * len(shapes)
    segs = contour_segments([np.asarray(c, float) for c in outline.to_polygons()])
    for j, shape in enumerate(shapes):
        d, t = diameter(shape.hull), ts[j]
        if _ball_proves(shape, segs):  # the stronger proof: safe on any plate
            out[j] = ThinPlate(shape.name, t, d, "safe", argument=BALL_ARGUMENT)
        elif d <= t + LENGTH_SLACK:
            out[j] = ThinPlate(shape.name, t, d, "safe")
        elif sections and sections[j] and sections[j]["thickness"] <= t + LENGTH_SLACK:
            out[j] = ThinPlate(shape.name, t, d, "safe",
                               argument=SECTION_ARGUMENT, section=sections[j])  # fmt: skip
    return out


def _per_shape(thickness, n: int) -> list:
    """``thickness`` (one number, or one per shape) as a list of ``n``.

    Raises
    ------
    SieveError
        A list of another length.
    """
    if not isinstance(thickness, (list, tuple, np.ndarray)):
        return [thickness] * n
    if len(thickness) != n:
        raise SieveError(f"thin plate: {len(thickness)} thicknesses for {n} shapes; give one each")
    return list(thickness)


def _checked(outline: manifold3d.CrossSection, thickness, budget_s) -> None:
    """Refuse what would crash a worker: a thickness or budget that is not a positive finite
    number (a flat plate), an empty hole.

    Raises
    ------
    SieveError
    """
    t = float(thickness) if isinstance(thickness, numbers.Real) else math.nan
    x0, y0, x1, y1 = outline.bounds() if not outline.is_empty() else (0.0, 0.0, 0.0, 0.0)
    size = max(1.0, x1 - x0, y1 - y0)
    if not (math.isfinite(t) and t > 1e-6 * size):
        raise SieveError(
            f"thin plate: thickness {thickness!s:.40}: must be a positive number of scene units "
            "(a flat plate has none); give a plate with thickness"
        )
    b = float(budget_s) if isinstance(budget_s, numbers.Real) else math.nan
    if not (math.isfinite(b) and b >= 0):
        raise SieveError(f"thin plate: budget {budget_s!s:.40}: must be seconds, 0 or more")
    if outline.is_empty() or not outline.area() > 0:
        raise SieveError("thin plate: the hole outline is empty; give the plate's hole")


def thin_plate(
    shape: Shape,
    outline: manifold3d.CrossSection,
    thickness: float,
    *,
    budget_s: float = 10.0,
    seeds=(),
    seed: int = 0,
    plate=None,
) -> ThinPlate:
    """Can ``shape`` pass a plate of this thickness with the hole ``outline`` by any rigid motion?

    Parameters
    ----------
    shape : Shape
    outline : manifold3d.CrossSection
        The hole H, scene units.
    thickness : float
        Plate thickness, scene units.
    budget_s : float
        Seconds for the motion search (none when the shape's diameter is at most ``thickness``).
    seeds : sequence of (quat, xy)
        Poses to try first: rotations (w, x, y, z) and positions in the hole's plane.
    seed : int
        Seeds the search's random numbers.
    plate : (vertices (V, 3) float, faces (F, 3) int), optional
        The plate's own mesh, in the slab's frame (its top at z = 0), when the plate is more
        than the slab of ``thickness`` (a post, a raised rim): a motion found through the slab
        counts only once re-checked against it (``verified_on``), lengthened until the shape
        clears the whole mesh. ``thickness`` must then be a lower bound of the plate's material
        around the hole (:func:`sieve_mi.geometry.sieve.read_plate`), so "safe" holds.

    Returns
    -------
    ThinPlate

    Raises
    ------
    SieveError
        A thickness that is not a positive finite number, or an empty hole (before any worker).

    Examples
    --------
    A 20 mm cube passes a 22 mm square hole in any plate, straight down:

    >>> import manifold3d, trimesh
    >>> from sieve_mi.geometry.meshes import shape_from_trimesh
    >>> cube = shape_from_trimesh(trimesh.creation.box([20, 20, 20]), name="cube")
    >>> hole = manifold3d.CrossSection.square([22, 22], center=True)
    >>> thin_plate(cube, hole, 2.0, budget_s=5).status
    'passage'
    """
    _checked(outline, thickness, budget_s)
    t0, t = time.perf_counter(), float(thickness)
    safe = _safe_at_once([shape], outline, [t], None)[0]
    if safe is None and budget_s > 0:  # its section proof here: no worker to start when it holds
        safe = _section_first(shape, outline, t, min(0.5 * budget_s, SECTION_MAX_S))
    if safe is not None:
        return safe
    left = max(0.0, budget_s - (time.perf_counter() - t0))
    return thin_plates([shape], outline, t, budget_s=left, seeds=[seeds], seed=seed,
                       plate=plate, sections=[None])[0]  # fmt: skip


def thin_plates(
    shapes: list[Shape],
    outline: manifold3d.CrossSection,
    thickness: float | list,
    *,
    budget_s: float = 10.0,
    seeds: list | None = None,
    seed: int = 0,
    plate=None,
    sections: list | None = None,
) -> list[ThinPlate]:
    """:func:`each_thin_plate`'s answers as a list, one :class:`ThinPlate` per shape (parameters,
    errors and workers as there)."""
    out: list = [None] * len(shapes)
    for j, answer in each_thin_plate(shapes, outline, thickness, budget_s=budget_s, seeds=seeds,
                                     seed=seed, plate=plate, sections=sections):  # fmt: skip
        out[j] = answer
    return out


def each_thin_plate(
    shapes: list[Shape],
    outline: manifold3d.CrossSection,
    thickness: float | list,
    *,
    budget_s: float = 10.0,
    seeds: list | None = None,
    seed: int = 0,
    plate=None,
    sections: list | None = None,
) -> Iterator[tuple[int, ThinPlate]]:
    """:func:`thin_plate` for several shapes, searched in parallel worker processes: yields
    ``(index, ThinPlate)`` per shape as its answer is known (the safe ones first, then each
    search as it ends), so a caller can show progress (:func:`thin_plates` collects them).

    A shape is ``"safe"`` without a search when a ball certified inside it is wider than every
    disk in the hole (:data:`BALL_ARGUMENT`, on any plate), or when its diameter is at most the
    thickness.

    Parameters
    ----------
    shapes : list of Shape
    outline, budget_s, seed, plate
        As :func:`thin_plate` (shape j's search is seeded with ``seed + j``).
    thickness : float or list of float
        As :func:`thin_plate`, or one per shape (each searched against its own plate).
    seeds : list of sequences of (quat, xy), optional
        Per shape, poses to try first.
    sections : list of dict or None, optional
        Per shape, a slab-section proof already made (certify's ``section`` record) or None:
        ``"safe"`` when it covers ``thickness``. Without the list, each shape thicker than the
        plate first gets a section proof of its own, with half its ``budget_s`` (at most
        :data:`SECTION_MAX_S`; :data:`SECTION_ARGUMENT`).

    Yields
    ------
    (int, ThinPlate)

    Raises
    ------
    SieveError
        As :func:`thin_plate`.
    """
    ts = _per_shape(thickness, len(shapes))
    for t in ts:
        _checked(outline, t, budget_s)
    ts = [float(t) for t in ts]
    seeds = seeds or [()] * len(shapes)
    safe = _safe_at_once(shapes, outline, ts, sections)
    yield from ((j, o) for j, o in enumerate(safe) if o is not None)
    todo = [j for j, o in enumerate(safe) if o is None]
    if not todo:
        return
    polygons = _polygons(outline)
    n = max(1, min(len(todo), os.cpu_count() or 1))  # one worker per core, at most one per shape
    with worker_pool(n, what="thin-plate search") as pool:
        jobs = {
            pool.submit(
                _search,
                shapes[j],
                polygons,
                ts[j],
                budget_s,
                [(np.asarray(q, float), np.asarray(t, float)) for q, t in seeds[j]],
                seed + j,
                plate,
                0.0 if sections is not None else min(0.5 * budget_s, SECTION_MAX_S),
            ): j  # fmt: skip
            for j in todo
        }
        for job in as_completed(jobs):
            yield jobs[job], job.result()
