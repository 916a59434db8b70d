"""Separate holes, each its own: a tolerance per A, and a mirrored hole for a chiral A.

With ``[layout] mode = "separate"`` every A has a hole of its own, and a B passes the sieve when
it passes any one of them. Two things then need not be shared:

* **A tolerance per A** (``[[pass]] tolerance``): A_i's hole is its silhouette dilated by its
  own tolerance t_i (``[fabrication] tolerance`` where the entry gives none). One number for
  every hole is bound by the hole that holds B least (the letters' I: a B on its side is a bar
  12 mm wide, the I's hole 7.73 + 2t wide), while the others could grow further
  (:func:`sieve_mi.game.tolerance.widest_tolerances` bisects each hole's own).
* **Mirrored holes** (``[layout] mirrored = true``): a flat part lying face up shows the mirror
  image of its face-down silhouette, which no turn of its hole admits when the part is *chiral*
  (an S, a G). Each chiral A then gets one more hole, its own hole mirrored, beside it on the
  same plate. Turning a B over mirrors its projection, so a B passes the mirrored hole exactly
  when it passes the hole: the verdict, certify and the overhangs see every hole anyway. An A
  is chiral when its hole and the hole's mirror image are not the same polygon up to a turn and
  a shift (:func:`sieve_mi.geometry.pose_words.same_silhouette`, on the exact outline).

The holes lie in a row (:func:`sieve_mi.game.frames.separate_layout`), each mirrored hole right
after its A's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.game.frames import separate_layout
from sieve_mi.geometry.outline import is_closed
from sieve_mi.geometry.pose_words import same_silhouette
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.window import GROWTH, windowed_hole

__all__ = ["SeparateHoles", "hole_tolerances", "is_chiral", "separate_holes"]


def hole_tolerances(scene) -> np.ndarray:
    """Each A's tolerance: its ``[[pass]] tolerance``, else ``[fabrication] tolerance``.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    (m,) ndarray
        Scene units.

    Raises
    ------
    SieveError
        When several A share one merged hole and their tolerances differ (one hole, one
        dilation).
    """
    fab = scene.fabrication
    out = np.array([fab.tolerance if e.tolerance is None else e.tolerance for e in scene.passes],
                   dtype=np.float64)  # fmt: skip
    if len(out) > 1 and scene.layout.mode != "separate" and np.ptp(out) > 0:
        i = next(i for i, e in enumerate(scene.passes) if e.tolerance is not None)
        raise SieveError(
            f"{scene.path}: pass[{i}].tolerance: a tolerance per A needs [layout] mode = "
            '"separate" (a merged hole has one tolerance); set [fabrication] tolerance instead'
        )
    return out


def is_chiral(outline) -> bool:
    """Whether a hole is not its own mirror image up to a turn and a shift.

    Parameters
    ----------
    outline : manifold3d.CrossSection
        Scene units.

    Returns
    -------
    bool
        False for a square, a disk or a bar; True for an S or a G.
    """
    return not same_silhouette(outline, outline.mirror([1.0, 0.0]))


@dataclass
class SeparateHoles:
    """The separate layout's holes.

    Attributes
    ----------
    trans : (m, 2) ndarray
        Each A's place, scene units.
    frame : Frame
        The verdict's raster frame over every hole.
    outlines : list of manifold3d.CrossSection
        Every hole, A's in order, each mirrored one right after its A's; scene units.
    places : (m + k, 2) ndarray
        Each A's place, then each of the k mirrored holes' centres, scene units.
    groups : list of list of int
        Per hole, the row of ``places`` where its verdict starts are centred.
    mirrored : list of dict
        One per mirrored hole: ``of`` (the A's index), ``name`` and ``translation``.
    tolerances : (m,) ndarray
        Each A's tolerance, scene units.
    """

    trans: np.ndarray
    frame: Frame
    outlines: list
    places: np.ndarray
    groups: list
    mirrored: list
    tolerances: np.ndarray


def _own_hole(shape, quat, place, tolerance: float, fab):
    """One A's exact hole at ``place`` (its window as ``[fabrication] window`` says)."""
    o, _ = windowed_hole([shape], np.asarray(quat)[None], np.asarray(place, float)[None],
                         tolerance, math.radians(fab.window), fab.fill_holes,
                         closed=[is_closed(shape)])  # fmt: skip
    if o.is_empty() or o.area() <= 0:
        raise SieveError(
            f"the hole of {shape.name} has zero area: the shape is seen edge-on and its "
            "tolerance is 0; set a positive tolerance or another rotation"
        )
    return o


def separate_holes(scene, passes: list, quats: np.ndarray, resolution: int) -> SeparateHoles:
    """Every A's own hole (at its own tolerance) and, with ``[layout] mirrored``, each chiral A's
    mirrored hole, laid in a row with ``[fabrication] border`` between neighbours.

    Parameters
    ----------
    scene : Scene
        Its ``[fabrication]`` (tolerance, window, fill_holes, border), ``[layout] mirrored`` and
        each ``[[pass]] tolerance``.
    passes : list of Shape
    quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z).
    resolution : int
        Pixels per side of the largest single hole's frame.

    Returns
    -------
    SeparateHoles
    """
    fab, quats = scene.fabrication, np.asarray(quats, dtype=np.float64)
    tols = hole_tolerances(scene)
    reach = tols * (1 + GROWTH) if fab.window else tols  # a window's chord bound
    origin, zipped = np.zeros(2), list(zip(passes, quats, tols))
    centred = (
        [_own_hole(p, q, origin, t, fab) for p, q, t in zipped] if scene.layout.mirrored else []
    )
    mirror = [is_chiral(o) for o in centred] or [False] * len(passes)
    owner = [i for i in range(len(passes)) for _ in range(1 + mirror[i])]  # each hole's A
    radii = [passes[i].radius for i in owner]
    places, frame = separate_layout(radii, reach[owner], fab.border, resolution)
    first = [owner.index(i) for i in range(len(passes))]
    trans = places[first]
    outlines, groups, mirrored = [], [], []
    for k, i in enumerate(owner):
        if k == first[i]:
            outlines.append(_own_hole(passes[i], quats[i], trans[i], tols[i], fab))
            groups.append([i])
            continue
        outlines.append(centred[i].mirror([1.0, 0.0]).translate(places[k].tolist()))
        groups.append([len(passes) + len(mirrored)])
        mirrored.append({"of": i, "name": passes[i].name,
                         "translation": [float(x) for x in places[k]]})  # fmt: skip
    where = np.vstack([trans, [m["translation"] for m in mirrored]]) if mirrored else trans
    return SeparateHoles(trans, frame, outlines, where, groups, mirrored, tols)
