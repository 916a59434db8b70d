"""A turning window: the hole that admits every A at each turn about the vertical within ±δ.

A part shaken on a sieve lies in its pass pose only up to a turn about the vertical; a hole cut
for one turn admits it only when that turn is met to within the tolerance. The windowed hole is
the union, over every turn ψ in [-δ, δ] about each A's own place, of A's exact projection turned
by ψ, dilated by the tolerance.

The union over a continuum of turns is taken over samples ψ_k at most ``step`` apart, dilated by
the tolerance plus the *chord bound* g = 2 sin(step / 4) R (R: the largest distance of A's
vertices from its centre). Every turn ψ lies within step / 2 of a sample, where each point of the
projection is at most 2 sin(|ψ - ψ_k| / 2) R <= g from its sampled place; so A turned by ψ and
grown by the tolerance lies inside the sample's projection grown by tolerance + g, inside the hole.
The hole is therefore a superset of the exact window's (by at most g), which only makes it easier
for A to pass; B's verdict and proofs are made on this very polygon.

Examples
--------
A 20 mm square (a cube seen face-on) turned within ±30°, grown by 1 mm: the hole holds the disk of
radius 11 / cos 30° ≈ 12.7 about the centre (the corner of the turned face's flat side), more
than the 11 of the square alone.

>>> import numpy as np, trimesh
>>> from sieve_mi.geometry.meshes import shape_from_trimesh
>>> cube = shape_from_trimesh(trimesh.creation.box([20, 20, 20]), name="cube")
>>> hole, w = windowed_hole([cube], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 1.0,
...                         np.radians(30))
>>> w.samples > 10 and w.grow <= 0.05
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import manifold3d
import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import hole_outline

__all__ = ["GROWTH", "Window", "turn_samples", "windowed_hole"]

#: The chord bound g between sampled turns, as a fraction of the tolerance (at least 1e-4 of R).
GROWTH = 0.05


@dataclass(frozen=True)
class Window:
    """How a windowed hole was made.

    Attributes
    ----------
    degrees : float
        δ: every A passes at each turn within ±δ of its pass pose.
    samples : int
        Turns sampled over [-δ, δ].
    grow : float
        The chord bound g added to the tolerance, scene units.
    """

    degrees: float
    samples: int
    grow: float

    def to_dict(self) -> dict:
        """report.json's ``fabrication.window`` (without the bisection)."""
        return {"degrees": self.degrees, "samples": self.samples, "chord_bound": self.grow}


def turn_samples(radius: float, window: float, tolerance: float) -> tuple[np.ndarray, float]:
    """Turns sampled over [-window, window] and their chord bound.

    Parameters
    ----------
    radius : float
        R, the largest distance of a vertex from its shape's centre, scene units.
    window : float
        δ, radians (0: the pose alone).
    tolerance : float
        Scene units; the chord bound is kept to :data:`GROWTH` of it.

    Returns
    -------
    turns : (k,) ndarray
        Radians, evenly spaced, both ends included.
    grow : float
        g = 2 sin(step / 4) R, scene units (0 for no window).
    """
    if window <= 0 or radius <= 0:
        return np.zeros(1), 0.0
    target = max(GROWTH * tolerance, 1e-4 * radius)
    most = 4.0 * math.asin(min(1.0, target / (2.0 * radius)))
    steps = max(1, math.ceil(2.0 * window / most))
    grow = 2.0 * math.sin(2.0 * window / steps / 4.0) * radius
    return np.linspace(-window, window, steps + 1), grow


def windowed_hole(
    shapes: list[Shape],
    quats: np.ndarray,
    trans: np.ndarray,
    tolerance: float,
    window: float,
    fill_holes: bool = True,
    closed: list[bool] | None = None,
) -> tuple[manifold3d.CrossSection, Window]:
    """The hole that admits every A at each turn within ±``window`` (module docstring).

    Parameters
    ----------
    shapes, quats, trans, tolerance, fill_holes, closed
        As :func:`sieve_mi.geometry.outline.hole_outline`.
    window : float
        δ, radians.

    Returns
    -------
    (manifold3d.CrossSection, Window)
    """
    radius = max(float(s.radius) for s in shapes)
    turns, grow = turn_samples(radius, window, tolerance)
    hole = hole_outline(shapes, quats, trans, tolerance + grow, fill_holes, closed, turns)
    return hole, Window(math.degrees(window), len(turns), grow)
