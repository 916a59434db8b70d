"""A slab-section proof counts without a straight proof (Thin plates, proved).

Known answer, argued on paper: the 20-cent euro coin (22.25 x 2.14 mm, here a 96-sided cylinder)
cannot pass a round hole 20.25 mm across (a 128-gon inscribed in that circle), on a plate of any
thickness. Pin the coin's centre. A passage carries it through the plate's mid-plane; at that
moment the plane through it parallel to the plate cuts the coin's mid-plane polygon along a line
through its centre: a segment from rim to rim of length at least 2 R cos(pi / 96) = 22.238 mm
(R = 11.125 mm), lying in that plane, so inside every slab section (any t > 0) and projected onto
the plate at full length. Every chord of the hole is at most 20.25 mm: no section fits, and the
coin is blocked by any rigid motion (a straight passage included). A straight search given a
fraction of a second leaves its cells open; the section proof alone then proves the block.
"""

from __future__ import annotations

import copy
from types import SimpleNamespace

import manifold3d
import numpy as np
import pytest

from sieve_mi.certify import replay
from sieve_mi.certify.blocks import certify_blocks
from sieve_mi.certify.certificate import SECTION_PLATES
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.testing import shapes

HOLE = manifold3d.CrossSection.circle(20.25 / 2, 128)


def _coin():
    return shape_from_trimesh(shapes.coin(22.25, 2.14, 96), name="20c")


def _scene(thickness, low: float = 1.2) -> SimpleNamespace:
    """What certify_blocks reads of a scene: a straight budget too small to finish (0.2 s)."""
    verdict = SimpleNamespace(certify_budget=0.2, section_budget=30.0)
    fab = SimpleNamespace(thickness=thickness, min_thickness=low, block_margin=0.0)
    return SimpleNamespace(verdict=verdict, fabrication=fab, units="mm")


def _certified(thickness, low: float = 1.2):
    lines: list[str] = []
    (c,) = certify_blocks(_scene(thickness, low), HOLE, [_coin()], np.array([True]), lines.append,
                          workers=1)  # fmt: skip
    return c, lines


@pytest.fixture(scope="module")
def on_2_mm():
    # the straight search first (its section-first try off), then the section after open cells
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("sieve_mi.certify.blocks.FIRST_SHARE", 0.0)
        return _certified(2.0)


def test_a_given_thin_plate_is_proved_by_its_section_before_any_straight_search():
    c, lines = _certified(2.0)
    assert c.status == "proved" and c.by_section and c.cells_examined == 0
    assert c.section["thickness"] == 2.0 and c.holds_for == SECTION_PLATES
    assert "no straight search needed" in lines[0]
    rep = replay(c.certificate)
    assert rep["valid"] and rep["proved"] and rep["holds_for"] == SECTION_PLATES, rep["errors"]


def test_a_section_proves_the_coin_where_the_straight_search_left_cells_open(on_2_mm):
    c, lines = on_2_mm
    assert c.straight == "undecided" and c.cells_open > 0 and c.excluded_fraction < 1.0
    assert c.status == "proved" and c.by_section and c.holds_for == SECTION_PLATES
    assert c.section["status"] == "proved" and c.section["thickness"] == 2.0
    assert c.section["pin"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert c.on_plate(2.0).status == "proved" and c.on_plate(2.0).covers_plate
    assert c.on_plate(1.0).status == "undecided"  # thinner than the section proved
    assert c.excluded_percent() != "100.00" and "100" not in lines[0]
    assert lines[0].startswith(
        "certify 20c: proved by its slab section on plates at least 2 mm thick"
    )
    assert "proved by the section alone" in c.scope_line()
    assert c.to_dict()["status"] == "proved" and c.to_dict()["straight"] == "undecided"
    assert c.certificate["status"] == "proved"
    assert c.certificate["plate"]["holds_for"] == SECTION_PLATES


def test_the_certificate_with_open_cells_replays_as_proved_by_its_section(on_2_mm):
    rep = replay(on_2_mm[0].certificate)
    assert rep["valid"] and rep["proved"] and rep["open"] > 0, rep["errors"]
    assert rep["holds_for"] == SECTION_PLATES and rep["section_thickness"] == 2.0


def test_open_cells_without_a_valid_section_are_rejected(on_2_mm):
    cert = on_2_mm[0].certificate
    gone = copy.deepcopy(cert)
    del gone["section"]  # "proved" with open cells and no section
    rep = replay(gone)
    assert not rep["valid"] and any(e.startswith("status: claims proved") for e in rep["errors"])
    thinner = copy.deepcopy(cert)
    thinner["section"]["thickness"], thinner["section"]["band"] = 0.02, 0.01
    assert not replay(thinner)["valid"]  # the band no longer holds the evidence's points
    wider = copy.deepcopy(cert)
    wider["hole"] = (np.asarray(wider["hole"]) * 1.2).tolist()  # 24.3 mm: the coin fits flat
    assert not replay(wider)["valid"]


def test_the_thinnest_plate_tries_the_printable_minimum_first():
    c, _ = _certified(None, low=2.0)
    assert c.status == "proved" and c.straight == "undecided"
    assert c.section["bracket"] == {"proved": 2.0, "unproved": None}


def test_the_plate_and_the_reports_rest_on_the_section(on_2_mm):
    from sieve_mi.game.sheet import proof_thickness
    from sieve_mi.motion import each_thin_plate
    from sieve_mi.outputs.console import certified_word

    c, coin = on_2_mm[0], _coin()
    assert proof_thickness(coin, c) == 2.0  # not the coin's 22.35 mm diameter
    ((_, thin),) = each_thin_plate([coin], HOLE, 2.0, budget_s=0.0, sections=[c.proved_section])
    assert thin.status == "safe" and thin.to_dict()["by"] == "section"
    assert certified_word({"certified": "proved", "certification": c.to_dict()}) == (
        "proved by section"
    )


def test_a_section_proved_coin_gets_its_margin_and_the_replay_reproves_it():
    # the rim-to-rim segment through the pinned centre is >= 22.238 mm long in every section
    # (module docstring); the hole grown by m = 0.8 is 20.25 + 1.6 = 21.85 mm across (the
    # polygon offset a hair more): still shorter, so the section proof holds at m = 0.8,
    # the one bisection step between 0 and 1.6
    from sieve_mi.certify.blocks import section_margin

    m, cert, ran = section_margin(_coin(), HOLE, 2.0, 1.6, 30.0, steps=1)
    assert (m, ran) == (0.8, 1)
    extent = np.abs(np.concatenate([np.asarray(c) for c in cert["hole"]])).max(axis=0)
    assert extent == pytest.approx([20.25 / 2 + 0.8] * 2, abs=0.01)  # against the grown hole
    rep = replay(cert)
    assert rep["valid"] and rep["proved"], rep["errors"]
    assert rep["holds_for"] == SECTION_PLATES and rep["section_thickness"] == 2.0
