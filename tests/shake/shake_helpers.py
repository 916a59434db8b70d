"""Plates, parts and settings for the shake tests (millimetres)."""

from __future__ import annotations

import manifold3d
import trimesh

from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.testing.shapes import from_manifold


def round_hole(diameter: float = 22.0) -> manifold3d.CrossSection:
    """A round hole of ``diameter`` mm (a 96-gon with its vertices on the circle)."""
    return manifold3d.CrossSection.circle(diameter / 2, 96)


def square_hole(side: float = 22.0) -> manifold3d.CrossSection:
    return manifold3d.CrossSection.square([side, side], center=True)


def ball(diameter: float):
    """A ball of ``diameter`` mm: an icosphere whose faces all lie within 0.13 % of the radius."""
    return trimesh.creation.icosphere(subdivisions=3, radius=diameter / 2)


def plate_mesh(hole: manifold3d.CrossSection, margin: float, thickness: float):
    """The plate as a mesh: the hole's bounding box grown by ``margin``, minus the hole, extruded
    over z in [-thickness, 0]."""
    x0, y0, x1, y1 = hole.bounds()
    rect = manifold3d.CrossSection.square([x1 - x0 + 2 * margin, y1 - y0 + 2 * margin])
    region = rect.translate([x0 - margin, y0 - margin]) - hole
    solid = manifold3d.Manifold.extrude(region, thickness).translate([0, 0, -thickness])
    return from_manifold(solid)


def quick(**kw) -> ShakeSettings:
    """Settings for a test: one worker (no process start-up), the rest as given."""
    return ShakeSettings(**{"workers": 1, **kw})


__all__ = ["ball", "plate_mesh", "quick", "round_hole", "square_hole"]
