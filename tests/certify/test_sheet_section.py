"""A slab-section proof made for a perforated sheet carries its holes (``section.hole``), and the
replay re-proves it against them: the ring of certify's docstring (20 mm across, 2 mm wire) is
proved on a 1 mm plate with one 9 mm hole, and the same proof does not hold once a second hole
lies 20 mm away (the ring stood on edge meets the plate in two blobs 20 mm apart)."""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.certify import certify, replay, thin_plate_proof
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import shape_from_trimesh


@pytest.fixture(scope="module")
def ring_proof():
    ring = shape_from_trimesh(trimesh.creation.torus(10, 1), name="ring")
    hole = manifold3d.CrossSection.circle(4.5, 32)
    c = certify(ring, [hole], budget_s=20)
    c = thin_plate_proof(c, ring, [hole], 1.0, 20)
    assert c.section["status"] == "proved"
    return c, hole


def _with_section_hole(cert: dict, section: manifold3d.CrossSection) -> dict:
    contours = [np.asarray(x).tolist() for x in section.to_polygons()]
    return {**cert, "section": {**cert["section"], "hole": contours}}


def test_the_replay_reproves_the_section_against_its_own_holes(ring_proof):
    c, hole = ring_proof
    assert replay(_with_section_hole(c.certificate, hole))["valid"]
    two = hole + hole.translate([20.0, 0.0])
    r = replay(_with_section_hole(c.certificate, two))
    assert not r["valid"] and any("section" in e for e in r["errors"])


def test_a_section_hole_without_contours_is_refused(ring_proof):
    c, _ = ring_proof
    with pytest.raises(SieveError, match=r"section\.hole: no contour$"):
        replay({**c.certificate, "section": {**c.certificate["section"], "hole": []}})


def test_a_section_search_on_several_holes_spreads_points_inside_the_section():
    # a section that falls apart can put its extreme points in two holes and its inner points on
    # the web between them, so on a hole of several regions the turn test gets inner points too
    from sieve_mi.certify import section

    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    one = manifold3d.CrossSection.circle(4.5, 32)
    two = one + one.translate([12.0, 0.0])
    assert section.SectionSearch(pts, one, 1.0).inner == section.INNER_POINTS
    assert (
        section.SectionSearch(pts, two, 1.0).inner
        == max(section.INNER_POINTS, section.SHEET_INNER_POINTS)
        > 0
    )
