"""The slab-section proof (Thin plates, proved): known answers argued on paper, and its replay.

Each case pins a point p of the shape's hull: a passage carries p through the plate's mid-plane,
and then every point of the shape within half the thickness of p must lie in the hole's prism.
"""

from __future__ import annotations

import copy

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.certify import certify, replay
from sieve_mi.certify.search import Settings
from sieve_mi.certify.section import hull_widths, min_width, prove_section
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.motion import thin_plate
from sieve_mi.testing import shapes


def _ring(gap_degrees: float = 0.0):
    """A wire ring: centre circle 20 mm across, wire 2 mm thick; a C with a gap when asked."""
    mesh = trimesh.creation.torus(10.0, 1.0, major_sections=48, minor_sections=12)
    if gap_degrees:
        angle = np.degrees(np.arctan2(mesh.vertices[:, 1], mesh.vertices[:, 0]))
        keep = ~np.all(np.abs(angle[mesh.faces]) < 0.5 * gap_degrees, axis=1)
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[keep])
        mesh.remove_unreferenced_vertices()
    return shape_from_trimesh(mesh, name="C" if gap_degrees else "ring")


NINE_MM = manifold3d.CrossSection.circle(4.5, 64)


@pytest.fixture(scope="module")
def ring_proof():
    # Pin the ring's centre: any plane through it meets the centre circle at two opposite
    # points 20 mm apart (or holds the whole ring), so every slab section is wider than the
    # 9 mm hole, on a 1 mm plate as on any thicker one.
    return certify(_ring(), [NINE_MM], budget_s=120, thickness=1.0)


def test_a_closed_ring_cannot_pass_a_9_mm_hole_in_a_1_mm_plate(ring_proof):
    c = ring_proof
    assert c.status == "proved" and c.straight == "proved"
    assert c.section["status"] == "proved" and c.section["thickness"] == 1.0
    assert c.section["pin"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert c.holds_for == "plates at least the section's thickness thick" and c.covers_plate
    assert c.diameter == pytest.approx(22.0, rel=1e-3)  # outer diameter 20 + 2
    assert "at least 1 mm thick" in c.scope_line()
    assert c.on_plate(0.5).status == "undecided" and c.on_plate(3.0).status == "proved"


def test_the_section_certificate_replays_and_tampering_is_rejected(ring_proof):
    cert = ring_proof.certificate
    rep = replay(cert)
    assert rep["valid"] and rep["proved"] and rep["covers_plate"] is True
    assert rep["section_thickness"] == 1.0 and rep["open"] == 0
    thinner = copy.deepcopy(cert)
    thinner["section"]["thickness"], thinner["section"]["band"] = 0.25, 0.125
    assert not replay(thinner)["valid"]  # the same cells do not hold a thinner band
    outside = copy.deepcopy(cert)
    outside["section"]["pin"] = [30.0, 0.0, 0.0]
    bad = replay(outside)
    assert not bad["valid"] and any("section.pin" in e for e in bad["errors"])
    band = copy.deepcopy(cert)
    band["section"]["band"] = 2.0
    assert any("section.band" in e for e in replay(band)["errors"])
    wider = copy.deepcopy(cert)
    wider["hole"] = [[[-12.0, -12.0], [12.0, -12.0], [12.0, 12.0], [-12.0, 12.0]]]
    assert not replay(wider)["valid"]


def test_a_c_ring_is_never_proved():
    # With a 60 degree gap the C threads through the hole, turning as it sinks: no proof.
    hole = NINE_MM
    found, _ = prove_section(_ring(60.0), hole, 1.0, 4.0, Settings())
    assert found.status == "undecided" and found.open_cells > 0


def test_an_l_rod_through_a_9_mm_square_in_a_2_mm_plate_is_never_proved():
    rod = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="rod")
    hole = manifold3d.CrossSection.square([9.0, 9.0], center=True)
    found, _ = prove_section(rod, hole, 2.0, 4.0, Settings())
    assert found.status == "undecided"  # a passage exists (the thin-sheet scene finds one)


def test_a_10_cent_coin_is_safe_on_a_1_mm_plate_with_a_19_5_by_3_mm_slot(monkeypatch):
    # A plane through the coin's centre cuts a full diameter: at least 19.75 cos(pi / 256) =
    # 19.7485 mm on this 256-sided mesh, longer than the slot's diagonal sqrt(19.5² + 3²) =
    # 19.729 mm. The check path (thin_plate) proves it before any motion search. The proof
    # takes about 4 s on a quiet core; its wall-clock cap is raised so a loaded suite proves it too.
    monkeypatch.setattr("sieve_mi.motion.thin.SECTION_MAX_S", 120.0)
    coin = shape_from_trimesh(shapes.coin(19.75, 1.93, 256), name="coin")
    slot = manifold3d.CrossSection.square([19.5, 3.0], center=True)
    answer = thin_plate(coin, slot, 1.0, budget_s=240)
    out = answer.to_dict()
    assert answer.status == "safe" and out["by"] == "section"
    assert out["section"]["thickness"] == 1.0 and out["section"]["cells_excluded"] > 0


def test_a_flat_ring_falls_through_a_wider_hole():
    wide = manifold3d.CrossSection.circle(12.5, 64)  # 25 mm > the ring's 22 mm
    c = certify(_ring(), [wide], budget_s=20, thickness=1.0)
    assert c.status == "passage" and c.holds_for == "any plate"


def test_hole_widths_are_known_answers():
    slot = manifold3d.CrossSection.square([19.5, 3.0], center=True)
    diameter, width = hull_widths([np.asarray(c) for c in slot.to_polygons()])
    assert diameter == pytest.approx(np.hypot(19.5, 3.0)) and width == pytest.approx(3.0)
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, np.sqrt(3.0)]])  # side 2: width sqrt(3)
    assert min_width(tri) == pytest.approx(np.sqrt(3.0))


def test_the_console_names_the_blocks_whose_section_proof_failed():
    from sieve_mi.outputs.console import sheet_line

    def report(bracket):
        section = {"status": "undecided", "bracket": bracket}
        block = {"name": "letter_R", "certification": {"status": "proved", "section": section}}
        sheet = {"thickness": 42.2, "safe_thickness": 42.2, "mode": "safe", "proved": True}
        return {"units": "mm", "block": [block], "fabrication": {"sheet": sheet}}

    line = sheet_line(report({"proved": None, "unproved": 41.5}))
    assert line.startswith("plate: 42.2 mm thick") and "41.5 mm for letter_R" in line
    assert sheet_line(report({"proved": 14.8, "unproved": 1.2})) is None  # proved: nothing to say
