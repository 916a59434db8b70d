"""A perforated sheet (sieve_mi.geometry.pattern): counts, open fractions and the web, argued on
paper and measured independently of the code under test (manifold3d's exact gap between solids).

On paper: 10 mm squares at pitch 12 (web 2) on a 100 x 100 plate with a 5 mm border. A row of n
squares with 2 mm between them spans 12 n - 2 mm and must fit the 90 mm inside the border:
n = 7 (82 mm; 8 would need 94). So 7 x 7 = 49 holes of 100 mm^2 on 10,000 mm^2: 49 % open.
"""

from __future__ import annotations

import itertools
import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import bodies, shape_from_trimesh
from sieve_mi.geometry.pattern import gap, lay_out


def _copies(p) -> list:
    return [p.copy(int(i), int(j)) for i, j in p.sites]


def _least_gap_by_solids(copies: list, within: float) -> float:
    """The least distance between copies, by manifold3d's ``min_gap`` of their extrusions (an
    implementation other than :func:`gap`)."""
    solids = [manifold3d.Manifold.extrude(c, 1.0) for c in copies]
    centres = [np.mean(np.asarray(c.bounds()).reshape(2, 2), axis=0) for c in copies]
    reach = max(np.ptp(np.asarray(c.bounds()).reshape(2, 2), axis=0).max() for c in copies)
    best = math.inf
    for u, v in itertools.combinations(range(len(copies)), 2):
        if np.linalg.norm(centres[u] - centres[v]) <= reach + within:
            best = min(best, solids[u].min_gap(solids[v], within))
    return best


def _inside(p, border: float) -> bool:
    (x0, y0), (x1, y1) = p.plate
    b = np.asarray(p.holes().bounds())
    return (
        b[0] >= x0 + border - 1e-9
        and b[1] >= y0 + border - 1e-9
        and (b[2] <= x1 - border + 1e-9 and b[3] <= y1 - border + 1e-9)
    )


def test_square_pattern_of_squares_matches_the_paper_count():
    square = manifold3d.CrossSection.square([10.0, 10.0])
    p = lay_out(square, "square", (100.0, 100.0), 5.0, 2.0)
    assert p.count == 49
    assert np.linalg.norm(p.a1) == pytest.approx(12.0) and np.linalg.norm(p.a2) == pytest.approx(
        12.0
    )
    assert p.open_fraction == pytest.approx(0.49)
    assert p.holes().area() == pytest.approx(4900.0)
    assert _inside(p, 5.0)
    assert p.to_dict()["count"] == 49 and p.to_dict()["plate_size"] == [100.0, 100.0]


def test_hex_pattern_keeps_the_web_between_every_pair():
    disc = manifold3d.CrossSection.circle(5.0, 64)
    p = lay_out(disc, "hex", (100.0, 100.0), 5.0, 1.2)
    # denser than a square lattice of the same disks (8 x 8 = 64 at pitch 11.2)
    assert p.count > 64 and _inside(p, 5.0)
    least = _least_gap_by_solids(_copies(p), 3.0)
    assert least >= 1.2 - 1e-6
    assert least == pytest.approx(1.2, abs=0.02)  # tight: the rows are packed, not just apart


def test_turned_copies_keep_the_web():
    bar = manifold3d.CrossSection.square([12.0, 4.0], center=True)
    p = lay_out(bar, "hex", (80.0, 80.0), 5.0, 1.2, turns=[0, 60, 120])
    assert {p.turn(int(i), int(j)) for i, j in p.sites} == {0.0, 60.0, 120.0}
    assert _least_gap_by_solids(_copies(p), 3.0) >= 1.2 - 1e-6
    assert p.copy(0, 0) is bar  # H itself is one copy: a pose found for H is over the sheet


def test_gap_is_exact_for_squares_side_by_side_and_diagonal():
    sq = manifold3d.CrossSection.square([10.0, 10.0])
    assert gap(sq, sq.translate([12.0, 0.0]), 5.0) == pytest.approx(2.0, abs=1e-12)
    assert gap(sq, sq.translate([12.0, 12.0]), 5.0) == pytest.approx(2 * math.sqrt(2), abs=1e-12)
    assert gap(sq, sq.translate([5.0, 5.0]), 5.0) == 0.0  # overlapping


def test_window_holds_every_copy_within_reach():
    disc = manifold3d.CrossSection.circle(5.0, 32)
    p = lay_out(disc, "square", (200.0, 200.0), 5.0, 1.2)
    # pitch 11.2: a set 30 mm across touching H reaches the copies whose centres lie within
    # 30 + 2 x 5 = 40 mm, 4 pitches along an axis (44.8 mm is out)
    w = p.window(30.0)
    assert w.decompose() and len(w.decompose()) == sum(
        1 for i in range(-4, 5) for j in range(-4, 5) if math.hypot(i, j) * 11.2 <= 40.0
    )


def _centres(region) -> np.ndarray:
    return np.array([np.mean(np.asarray(r.bounds()).reshape(2, 2), axis=0)
                     for r in region.decompose()])  # fmt: skip


def test_patches_of_a_hex_sheet_of_discs_are_one_triangle():
    # discs of radius 4.357 (the M4 nut's hole) 5 mm apart: pitch 13.714. A set 10.36 mm across
    # (the M5 nut) can touch two copies only if their centres are within 10.36 + 2 r = 19.07 mm:
    # the six nearest (13.714), not the next ring (sqrt(3) x 13.714 = 23.75). Three copies touched
    # together are then a triangle, and a disc is its own half turn: one group of three.
    disc = manifold3d.CrossSection.circle(4.357, 64)
    p = lay_out(disc, "hex", (100.0, 100.0), 5.0, 5.0)
    assert np.linalg.norm(p.a1) == pytest.approx(2 * 4.357 + 5.0, rel=1e-6)
    group = p.patches(10.36)
    c = _centres(group)
    assert len(c) == 3
    sides = sorted(np.linalg.norm(c[u] - c[v]) for u, v in itertools.combinations(range(3), 2))
    # (the 64-gon's flats let the rows pack up to r (1 - cos(pi / 64)) closer than discs would)
    assert sides == pytest.approx([13.714] * 3, abs=0.02)
    assert group.area() == pytest.approx(3 * disc.area(), rel=1e-9)
    # the window (every copy such a set touching H could reach) holds H and its six neighbours
    assert len(p.window(10.36).decompose()) == 7


def test_patches_keep_every_group_and_lay_them_apart():
    # a notched disc is not its own half turn: the up and down triangles are two groups, each
    # laid more than the set's 10.36 mm from the other, so that no set of that size touches both
    notched = manifold3d.CrossSection.circle(4.357, 64) - manifold3d.CrossSection.square(
        [1.0, 1.0]
    ).translate([3.8, -0.5])
    p = lay_out(notched, "hex", (100.0, 100.0), 5.0, 5.0)
    groups = p.patches(10.36)
    parts = groups.decompose()
    assert len(parts) == 6
    order = np.argsort(_centres(groups)[:, 0])
    left = manifold3d.CrossSection.batch_boolean([parts[k] for k in order[:3]],
                                                 manifold3d.OpType.Add)  # fmt: skip
    right = manifold3d.CrossSection.batch_boolean([parts[k] for k in order[3:]],
                                                  manifold3d.OpType.Add)  # fmt: skip
    assert gap(left, right, 100.0) > 10.36
    # a narrower web joins the next ring too (sqrt(3) x 9.914 - 8.714 = 8.46 < 10.36): bigger groups
    wide = lay_out(manifold3d.CrossSection.circle(4.357, 64), "hex", (100.0, 100.0), 5.0, 1.2)
    assert len(wide.patches(10.36).decompose()) > 3


@pytest.mark.parametrize(
    "kind, size, web, turns, key",
    [
        ("hex", (100.0, 100.0), 1.2, [30, 60], "fabrication.turns"),
        ("square", (12.0, 12.0), 1.2, None, "fabrication.plate_size"),
    ],
)
def test_bad_patterns_are_one_line_errors_naming_the_key(kind, size, web, turns, key):
    square = manifold3d.CrossSection.square([10.0, 10.0])
    with pytest.raises(SieveError) as exc:
        lay_out(square, kind, size, 5.0, web, turns)
    assert str(exc.value).startswith(key) and "\n" not in str(exc.value)


def test_bodies_counts_separate_parts():
    one = trimesh.creation.box((2, 2, 2))
    two = trimesh.util.concatenate([one, one.copy().apply_translation((5, 0, 0))])
    assert bodies(shape_from_trimesh(one, name="one")) == 1
    assert bodies(shape_from_trimesh(two, name="two")) == 2


def test_mirrored_copies_alternate_keep_the_web_and_are_in_the_window():
    """An L (arms 10 and 6 mm, 2 mm wide) is chiral: lying upside down it shows a J, which no
    turn of the L covers. With ``mirror`` every other site class holds the L reflected in the
    vertical line through its centre (x -> 10 - x), computed here from the points by hand."""
    pts = [(0.0, 0.0), (10.0, 0.0), (10.0, 2.0), (2.0, 2.0), (2.0, 6.0), (0.0, 6.0)]
    ell = manifold3d.CrossSection([pts])
    p = lay_out(ell, "hex", (60.0, 60.0), 2.0, 1.2, mirror=True)
    centre = np.array([5.0, 3.0])
    flips = 0
    for i, j in p.sites:
        site = p.centre + i * p.a1 + j * p.a2
        flipped = (i + j) % 2 == 1  # one turn: classes plain, mirrored, plain, ...
        want = [(10.0 - x, y) for x, y in pts[::-1]] if flipped else pts  # counter-clockwise
        want = manifold3d.CrossSection([[tuple(np.add(q, site - centre)) for q in want]])
        got = p.copy(int(i), int(j))
        assert (got - want).area() < 1e-9 and (want - got).area() < 1e-9
        flips += flipped
    assert 0 < flips < p.count and p.to_dict()["mirror"] is True
    assert p.least_gap >= 1.2 * (1 - 1e-9)
    assert _least_gap_by_solids(_copies(p), 2.4) >= 1.2 - 1e-6
    mirrored_here = manifold3d.CrossSection([[(10.0 - x, y) for x, y in pts[::-1]]])
    assert abs(mirrored_here.area() - 28.0) < 1e-9  # 10 x 2 + 2 x 4
    assert (mirrored_here - p.window(0.0)).area() < 1e-9  # the proofs' window holds the J too


def test_patches_of_a_mirrored_sheet_hold_the_mirrored_copies():
    # with mirror, neighbouring copies are an L and a J: no lattice move takes one to the other,
    # so the groups (all copies H translated) do not apply and the section proofs get the window,
    # which holds a J at H's own site
    pts = [(0.0, 0.0), (10.0, 0.0), (10.0, 2.0), (2.0, 2.0), (2.0, 6.0), (0.0, 6.0)]
    ell = manifold3d.CrossSection([pts])
    jay = manifold3d.CrossSection([[(10.0 - x, y) for x, y in pts[::-1]]])
    p = lay_out(ell, "hex", (60.0, 60.0), 2.0, 1.2, mirror=True)
    region = p.patches(12.0)
    assert (jay - region).area() < 1e-9
    assert region.area() == pytest.approx(p.window(12.0).area(), rel=1e-12)
