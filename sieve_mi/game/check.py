"""``sieve-mi check``: does a shape pass a given sieve, and by how much?

Works on any sieve, not only those sieve-mi made:

* ``--sieve plate.stl``: the through-holes of a plate along an axis (z by default) are found
  exactly: a straight line along the axis is free iff it misses every triangle, so the free region
  is the plate's filled outline minus the union of its projected triangles (manifold3d). Each
  connected free region is one hole; this is exact for any plate, also for holes that narrow
  inside the plate (a shape moving straight along the axis must clear the narrowest part).
  :func:`sieve_mi.geometry.sieve.read_plate_holes` reads them, once.
* ``--hole hole.png [--pixel-size MM]``: a binary image (white or opaque = hole), square pixels of the
  given size in scene units, +y up (:func:`sieve_mi.geometry.hole_image.read_image_holes`).

Player B then tries to fit the shape through each hole from many random starts (the same batched
Adam as the verdict of ``solve``); the answer is *passes* when some pose has beta = 0 (binary
masks; on a plate's exact polygons, :mod:`sieve_mi.game.exact`). The pose of that attempt is
named in words (:func:`pass_pose`: end on, on its side, face down, and how far from a resting
pose). The *fit scale* is the largest uniform scale of the shape that still passes
(:mod:`sieve_mi.game.fit`): above 1 it says by how much a passing shape could grow, below 1 how
far a blocked shape must shrink to get through, i.e. how much margin a block has.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field, replace

import manifold3d
import numpy as np

from sieve_mi.backend import ensure_variant
from sieve_mi.errors import SieveError
from sieve_mi.game.attack import AttackMemory, Starts
from sieve_mi.game.check_settings import AXIS_NAMES, CheckInputs, CheckSettings
from sieve_mi.game.exact import CANDIDATES, exact_rescore
from sieve_mi.game.fit import fit_scale, grown_scale, probe_starts, scaled
from sieve_mi.game.verdict import REACH
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.hole_image import image_size, read_image_holes
from sieve_mi.geometry.meshes import Shape, edge_length
from sieve_mi.geometry.outline import placed_vertices, projection, union
from sieve_mi.geometry.pixels import image_pixel_size
from sieve_mi.geometry.sieve import PlateReading, SieveHoles, read_plate_holes
from sieve_mi.settings import read_value, shown

__all__ = [
    "AXES",
    "CheckReport",
    "CheckSettings",  # sieve_mi.game.check_settings's, imported from here (docs/api.md)
    "ShapeCheck",
    "as_shape",
    "attempt",
    "check",
    "check_part_size",
    "fit_scale",  # sieve_mi.game.fit's, imported from here (tests, docs/api.md)
    "grown_scale",
    "pass_pose",
    "probe_starts",
    "scaled",
]

#: The index of each plate axis (``--axis``) among x, y, z.
AXES = {name: i for i, name in enumerate(AXIS_NAMES)}


@dataclass
class ShapeCheck:
    """One shape against one sieve at one scale."""

    scale: float
    passes: bool
    beta: float
    protrusion: float
    rotation: list
    translation: list
    hole: int
    fitting_starts: int
    exact_outside_area: float | None = None


@dataclass
class CheckReport:
    """What ``sieve-mi check`` reports (``--json`` prints it as a dict)."""

    shape: str
    sieve: str
    units: str
    holes: list
    pixel_size: float
    result: ShapeCheck
    #: The pose of ``result`` in words and angles (:func:`pass_pose`): ``of`` ("pass" or "best
    #: attempt"), ``position``, ``words``, ``tilt_deg``, ``rest_deg``, ``quaternion``, ...
    pose: dict | None = None
    fit_scale: float | None = None
    fit_bracket: list | None = None
    evaluations: list = field(default_factory=list)
    seconds: float = 0.0
    #: With a plate mesh: the thin-plate answer at the plate's measured thickness
    #: (:meth:`sieve_mi.motion.ThinPlate.to_dict`).
    thin_plate: dict | None = None
    #: The sieve's holes as the check read them (for its page); not part of :meth:`to_dict`.
    sieve_holes: SieveHoles | None = field(default=None, repr=False, compare=False)

    @property
    def passes(self) -> bool:
        """Whether the part passes at scale 1: the exact verdict on a plate's holes, or a
        verified motion through a plate thinner than the part's diameter."""
        thin = self.thin_plate is not None and self.thin_plate["status"] == "passage"
        return self.result.passes or thin

    def to_dict(self) -> dict:
        d = asdict(replace(self, sieve_holes=None))
        del d["sieve_holes"]
        d["passes"] = self.passes
        return d


# ------------------------------------------------------------------------------------------------
# Player B against fixed holes
# ------------------------------------------------------------------------------------------------


def attempt(
    shape: Shape,
    holes: list[Hole],
    settings: CheckSettings,
    s: float,
    outlines: list[manifold3d.CrossSection] | None = None,
    indices: list[int] | None = None,
    *,
    memory: AttackMemory | None = None,
    probe: bool = False,
) -> ShapeCheck:
    """Player B's best attempt to pass ``shape`` scaled by ``s`` through any of ``holes``.

    Parameters
    ----------
    shape : Shape
    holes : list of Hole
        The sieve's holes on one raster (scene units, centred on the holes).
    settings : CheckSettings
        The attack's budget (``starts``, ``steps``, ``learning_rate``, ``seed``).
    s : float
        The shape's scale.
    outlines : list of manifold3d.CrossSection, optional
        The holes' exact polygons (a plate): they decide. None for a hole image (pixels decide).
    indices : list of int, optional
        The plate's hole numbers ``outlines`` have, for the report (default their order).
    memory : AttackMemory, optional
        Poses remembered from earlier attempts (the fit-scale probes): the first starts begin
        there, and the memory is updated.
    probe : bool
        A fit-scale probe, which only needs to know whether the shape fits: it runs
        :func:`probe_starts` starts (the first from ``memory``), they stop descending as soon as
        one of them fits the raster (``settle="shape"``), and a blocked
        pose is not slid to where it sticks out least (its protrusion is then not the least).
        The verdict at scale 1 is no probe: every start runs (their fitting count is reported)
        and its margin is the least found.
    """
    from sieve_mi.game.player_b import PlayerB

    b = scaled(shape, s)
    player = PlayerB([b], holes[0].frame)
    rng = np.random.default_rng(settings.seed)
    keep = CANDIDATES if outlines is not None else 0
    att = player.attack(
        holes,
        Starts(
            probe_starts(settings.starts) if probe else settings.starts,
            centres=_centres(holes),
            memory=memory,
        ),  # fmt: skip
        settings.steps,
        settings.learning_rate,
        rng,
        keep=keep,
        settle="shape" if probe else None,
    )
    if outlines is None:  # a hole image: its pixels are the truth
        k = int(np.lexsort((att.protrusion[:, 0], att.beta[:, 0]))[0])
        best, row, fits = att, k, int(att.fits[k, 0])
    else:  # the plate's exact holes decide (any of them may let it through)
        hole = union(outlines)
        reach = REACH * holes[0].frame.pixel_size
        best = exact_rescore(att, [b], hole, reach=reach, least_margin=not probe)
        row, fits = 0, int(att.fits.sum())
        k = _hole_of(best.trans[0, 0], outlines)
        k = k if indices is None else int(indices[k])
    v = ShapeCheck(
        scale=float(s),
        passes=bool(best.beta[row, 0] == 0),
        beta=float(best.beta[row, 0]),
        protrusion=float(best.protrusion[row, 0]),
        rotation=[float(x) for x in best.quats[row, 0]],
        translation=[float(x) for x in best.trans[row, 0]],
        hole=k,
        fitting_starts=fits,
    )
    if outlines is not None:
        proj = projection(placed_vertices(b, best.quats[0, 0], best.trans[0, 0]), b.faces)
        v.exact_outside_area = float((proj - hole).area())
    return v


def _centres(holes: list[Hole]) -> np.ndarray:
    """Each hole's starts centred on its own pixels (scene units), (H, 2)."""
    out = []
    for h in holes:
        rows, cols = np.nonzero(h.mask)
        x, y = h.frame.centres()
        out.append([x[cols].mean(), y[rows].mean()] if len(rows) else [0.0, 0.0])
    return np.array(out)


def _hole_of(xy: np.ndarray, outlines: list) -> int:
    """Index of the outline nearest to point ``xy`` (the hole a pose is in)."""
    from sieve_mi.geometry.outline import Boundary

    d = [Boundary(o).signed(np.atleast_2d(xy))[0] for o in outlines]
    return int(np.argmin(d))


def check(
    shape,
    *,
    sieve: str | None = None,
    axis: str = "z",
    image: str | None = None,
    pixel_size: float | None = None,
    units: str = "mm",
    settings: CheckSettings | None = None,
    progress=None,
) -> CheckReport:
    """Test a shape against a sieve (a plate mesh or a hole image).

    The Mitsuba variant is the one in effect (``sieve_mi.backend.use_variant``, ``--variant``),
    else the default (``$SIEVE_MI_VARIANT`` or "llvm_ad_mono"), selected here, so ``check``
    works first thing in a fresh process.

    Parameters
    ----------
    shape : Shape, trimesh.Trimesh or str
        The part, in scene units: a loaded Shape, a trimesh mesh, or a mesh file's path.
    sieve : str, optional
        Plate mesh file; its holes are taken along ``axis``.
    image : str, optional
        Hole image (white = hole), with ``pixel_size`` in scene units.
    pixel_size : float, optional
        The image's pixel size; default the size it records (PNG ``pHYs`` or sieve-mi's text
        chunk, :func:`sieve_mi.geometry.pixels.image_pixel_size`, as ``hole.png`` has).
    units : str
        Label for reports.
    settings : CheckSettings, optional
    progress : callable, optional
        Called with each :class:`ShapeCheck` as it is computed.

    Returns
    -------
    CheckReport

    Raises
    ------
    SieveError
        One line, before any work: a bad argument (as ``sieve-mi check`` refuses its options), an
        unreadable or oversized hole image, a part too large for the raster (:func:`check_part_size`).
    """
    sieve, image, axis, pixel_size, units, settings = _arguments(
        sieve, image, axis, pixel_size, units, settings, progress
    )
    shape = as_shape(shape)
    ensure_variant()
    t0 = time.perf_counter()
    given = _sieve_holes(shape, sieve, image, axis, pixel_size, units, settings)
    holes, outlines, centre = given.holes, given.outlines, given.centre
    played, drawn = _played(given)
    # Poses are reported in the sieve's own coordinates.
    evaluations: list[ShapeCheck] = []
    memory = AttackMemory.for_starts(1, probe_starts(settings.starts))  # the probes start there

    def evaluate(s: float, probe: bool = True) -> ShapeCheck:
        v = attempt(shape, holes, settings, s, drawn, played, memory=memory, probe=probe)
        v.translation = [v.translation[0] + float(centre[0]), v.translation[1] + float(centre[1])]
        evaluations.append(v)
        if progress:
            progress(v)
        return v

    first = evaluate(1.0, probe=False)
    rep = CheckReport(shape=shape.path or shape.name, sieve=given.source, units=units,
                      holes=given.info, pixel_size=given.frame.pixel_size, result=first,
                      pose=pass_pose(shape, first), sieve_holes=given)  # fmt: skip
    if given.plate is not None:
        rep.thin_plate = _thin_plate(shape, given.plate, outlines, centre, first, settings, units)
    if settings.fit:
        grow = _grower(shape, outlines, centre, settings)
        rep.fit_scale, rep.fit_bracket = fit_scale(
            evaluate, first, settings.fit_tolerance, grow=grow
        )
    rep.evaluations = evaluations
    rep.seconds = time.perf_counter() - t0
    return rep


def _grower(shape: Shape, outlines: list | None, centre: np.ndarray, settings: CheckSettings):
    """``grow(v)`` for :func:`fit_scale`: :func:`grown_scale` of the pose of ``v`` (reported in
    the sieve's coordinates, ``centre`` off the holes' own) in the exact holes ``outlines``, to a
    quarter of the fit tolerance; None for a hole image (no exact holes)."""
    if outlines is None:
        return None
    hole = union(outlines)

    def grow(v: ShapeCheck) -> float:
        trans = np.asarray(v.translation, dtype=np.float64) - centre[:2]
        return grown_scale(shape, v.rotation, trans, hole, v.scale, settings.fit_tolerance / 4)

    return grow


def pass_pose(shape: Shape, v: ShapeCheck) -> dict:
    """The pose of the attempt ``v`` in words and angles (:func:`~sieve_mi.geometry.pose_words.
    describe_pose`), with ``"of"``: "pass" when it passes, else "best attempt"."""
    from sieve_mi.geometry.pose_words import describe_pose

    return {
        "of": "pass" if v.passes else "best attempt",
        **describe_pose(shape, v.rotation).to_dict(),
    }


def _sieve_holes(shape, sieve, image, axis, pixel_size, units, settings) -> SieveHoles:
    """The holes of the plate ``sieve`` (along ``axis``) or of the hole ``image``, on their
    raster; the part's size checked against its pixel (:func:`check_part_size`)."""
    if sieve is not None:
        given = read_plate_holes(sieve, axis, settings.resolution)
    else:
        given = read_image_holes(image, pixel_size)
    check_part_size(shape, given.frame.pixel_size, given.source, units, sieve is not None)
    return given


#: Most samples along a part's edges the search takes (:func:`check_part_size`): the edges are
#: sampled one pixel of the sieve's raster apart, and each sample costs about 60 bytes while the
#: objective is built (30 million: under 2 GB; a 1 m part against a 22 mm hole at the default
#: resolution needs well under a million).
EDGE_SAMPLES_MAX = 30_000_000


def check_part_size(
    shape: Shape, pixel_size: float, sieve: str, units: str = "mm", plate: bool = True
) -> None:
    """Refuse, before any work, a part whose edges would need more than
    :data:`EDGE_SAMPLES_MAX` samples on the sieve's raster: a part of absurd size against its
    holes (mostly the wrong units or scale: a 2e9 mm part against a 22 mm hole wanted 2 TiB).

    Parameters
    ----------
    shape : Shape
        The part, scene units.
    pixel_size : float
        The raster's pixel, scene units (the holes' frame: ``resolution`` pixels across the
        holes of a plate, the image's own pixels).
    sieve : str
        The plate or image, for the message.
    units : str
        The scene's units, for the message.
    plate : bool
        The raster is a plate's (its pixel follows ``resolution``), not a hole image's.

    Raises
    ------
    SieveError
        One line naming the part's file, its size, the pixel and the bound.
    """
    samples = edge_length(shape) / pixel_size
    if samples <= EDGE_SAMPLES_MAX:
        return
    across = float(np.ptp(shape.vertices, axis=0).max())
    other = "a lower resolution" if plate else "an image of larger pixels"
    raise SieveError(
        f"{shape.path or shape.name}: the part is {across:.4g} {units} across, "
        f"{across / pixel_size:,.0f} pixels of {sieve}'s raster ({pixel_size:.3g} {units} each): "
        f"its edges would need {samples:.3g} samples, check takes at most "
        f"{EDGE_SAMPLES_MAX:,}; check the part's scale and units (or use {other})"
    )


def _arguments(sieve, image, axis, pixel_size, units, settings, progress) -> tuple:
    """:func:`check`'s arguments checked as ``sieve-mi check`` checks its options, in the API's
    words (``axis``, not ``--axis``): one-line SieveError before any work. A hole image's size
    is checked from its header (:func:`~sieve_mi.geometry.hole_image.image_size`) and, without
    ``pixel_size``, its recorded pixel size read.

    Returns
    -------
    tuple
        ``(sieve, image, axis, pixel_size, units, settings)``: paths as str, ``pixel_size`` a
        float (None with a sieve), ``settings`` a :class:`CheckSettings` (the default one for
        None).
    """
    if sieve is None and image is None:
        raise SieveError("check: give sieve=PLATE (a plate mesh) or image=HOLE with pixel_size=MM")
    if sieve is not None and image is not None:
        raise SieveError("check: give sieve=PLATE (a plate mesh) or image=HOLE (a hole image), not both")  # fmt: skip
    what = "sieve" if sieve is not None else "image"
    path = sieve if sieve is not None else image
    if isinstance(path, os.PathLike):
        path = os.fspath(path)
    if not isinstance(path, str) or not path.strip():
        raise SieveError(f"check: {what}: expected a file path (str), got {shown(path)}")
    axis = read_value(CheckInputs, "axis", axis, "check")
    units = read_value(CheckInputs, "units", units, "check")
    if pixel_size is not None:
        pixel_size = read_value(CheckInputs, "pixel_size", pixel_size, "check")
    if settings is None:
        settings = CheckSettings()
    if not isinstance(settings, CheckSettings):
        raise SieveError(f"check: settings: expected a CheckSettings (sieve_mi.game.check."
                         f"CheckSettings(starts=...)), got {shown(settings)}")  # fmt: skip
    if progress is not None and not callable(progress):
        raise SieveError(f"check: progress: expected a function or None, got {shown(progress)}")
    if what == "image":
        image_size(path)  # a missing, unreadable or oversized image: one line, nothing decoded
        if pixel_size is None:
            pixel_size = image_pixel_size(path, units)  # a PNG's pHYs, as hole.png has
        if pixel_size is None:
            raise SieveError(
                "check: image= needs pixel_size= (scene units per pixel); the image records none"
            )
    sieve, image = (path, None) if what == "sieve" else (None, path)
    return sieve, image, axis, pixel_size, units, settings


def _thin_plate(
    shape: Shape, plate: PlateReading, outlines, centre, first, settings, units
) -> dict:
    """The part against the plate at its measured thickness (:func:`sieve_mi.motion.thin_plate`),
    seeded with the check's best pose; poses in the sieve's own coordinates.

    The slab's thickness is a lower bound, so a "safe" answer holds on the real plate. On a plate
    that is not a uniform slab a motion found through the slab is re-checked against the plate's
    own mesh (its posts and rims), and the answer says what the plate is.
    """
    from sieve_mi.motion import thin_plate

    seeds = [(np.asarray(first.rotation, float), np.asarray(first.translation, float) - centre)]
    top = np.array([centre[0], centre[1], plate.slab[1]])
    real = None if plate.uniform else (plate.vertices - top, plate.faces)
    found = thin_plate(shape, union(outlines), plate.thickness, budget_s=settings.thin_budget,
                       seeds=seeds, seed=settings.seed, plate=real)  # fmt: skip
    found.poses[:, 4:6] += centre
    out = found.to_dict()
    out["plate"] = plate.to_dict()
    if not plate.uniform:
        out["plate"]["note"] = f"{plate.describe(units)}; proofs use {plate.thickness:.4g} {units}"
    return out


def as_shape(part) -> Shape:
    """A Shape from a Shape, a trimesh mesh or a mesh file's path (scene units).

    Raises
    ------
    SieveError
        Anything else (None, a list of numbers, a ``trimesh.Scene``): one line naming what was
        given; a mesh that is not a usable triangle mesh (:func:`~sieve_mi.geometry.meshes.
        shape_from_arrays`).
    """
    import trimesh

    from sieve_mi.geometry.meshes import load_shape, shape_from_trimesh

    if isinstance(part, Shape):
        return part
    if isinstance(part, (str, os.PathLike)):
        return load_shape(os.fspath(part))
    if not isinstance(part, trimesh.Trimesh):
        hint = " (a trimesh.Scene: give scene.to_mesh())" if isinstance(part, trimesh.Scene) else ""
        raise SieveError(
            f"check: expected a mesh file path, a trimesh.Trimesh or a Shape, got "
            f"{shown(part)}{hint}"
        )
    name = part.metadata.get("name") if isinstance(part.metadata, dict) else None
    return shape_from_trimesh(part, name=name if isinstance(name, str) and name else "part")


def _played(given: SieveHoles) -> tuple:
    """The indices of the plate's holes that are played (one of each group of translates: a
    sheet's copies, :func:`sieve_mi.geometry.sieve.distinct_holes`) and their outlines (None
    for an image)."""
    outlines = given.outlines
    played = given.played if given.played is not None else list(range(len(outlines or ())))
    return played, (None if outlines is None else [outlines[k] for k in played])
