"""Exact verdicts: poses scored against the printed polygon, answers argued on paper."""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.api import solve
from sieve_mi.errors import SieveError
from sieve_mi.game import exact
from sieve_mi.geometry import outline
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import from_axis_angle
from sieve_mi.scene import load_scene
from sieve_mi.testing.shapes import box

EDGE_ON = "[1, 0, 0, 0]"


def _peg():
    return shape_from_trimesh(box(1.0, 1.0, 1.0), name="peg")


def _square_hole(side: float):
    h = manifold3d.CrossSection.square([side, side], center=True)
    return h, outline.Boundary(h)


def test_square_peg_turned_45_degrees_sticks_out_at_four_corners():
    # A unit square turned 45° reaches sqrt(2)/2 from the centre; the 1.2 hole ends at 0.6, so
    # each corner sticks out by d = sqrt(2)/2 - 0.6 and cuts off a right isosceles tip of area d².
    hole, b = _square_hole(1.2)
    q = from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi / 4)
    sc = exact.score(_peg(), q, [0.0, 0.0], hole, b, closed=True)
    d = np.sqrt(2) / 2 - 0.6
    assert sc.protrusion == pytest.approx(d, rel=1e-6)
    assert sc.beta == pytest.approx(4 * d * d, rel=1e-6)
    assert not sc.fits


def test_square_peg_shifted_sticks_out_by_the_shift():
    hole, b = _square_hole(1.2)
    sc = exact.score(_peg(), [1.0, 0, 0, 0], [0.25, 0.0], hole, b, closed=True)
    # x from -0.25 to 0.75 against the hole's 0.6: a 0.15 x 1 strip outside.
    assert sc.protrusion == pytest.approx(0.15, rel=1e-6)
    assert sc.beta == pytest.approx(0.15, rel=1e-6)
    assert exact.score(_peg(), [1.0, 0, 0, 0], [0.1, 0.05], hole, b, closed=True).fits


def test_polish_slides_a_turned_peg_into_a_hole_with_sub_pixel_clearance():
    # 0.01 of clearance on each side: a fifth of a pixel of a 256² raster over 3 units.
    hole, b = _square_hole(1.02)
    q = from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.3)
    assert not exact.score(_peg(), q, [0.05, -0.03], hole, b, closed=True).fits
    qq, tt = exact.polish(_peg(), q, [0.05, -0.03], b, closed=True)
    assert exact.score(_peg(), qq, tt, hole, b, closed=True).fits
    # ... and never into a hole smaller than the peg's smallest width.
    small, bs = _square_hole(0.98)
    qq, tt = exact.polish(_peg(), q, [0.0, 0.0], bs, closed=True)
    sc = exact.score(_peg(), qq, tt, small, bs, closed=True)
    assert sc.protrusion >= 0.01 - 1e-6


def test_signed_distance_of_a_square_is_exact():
    _, b = _square_hole(2.0)
    pts = np.array([[0.0, 0.0], [1.5, 0.0], [2.0, 2.0], [0.9, 0.2]])
    np.testing.assert_allclose(b.signed(pts), [-1.0, 0.5, np.sqrt(2), -0.1], atol=1e-9)
    np.testing.assert_allclose(b.approx_signed(pts), b.signed(pts), atol=b.spacing)


def test_a_slot_thinner_than_a_pixel_stays_in_the_raster():
    # 0.05 wide, a sixth of a pixel: pixel centres miss it, the conservative mask does not.
    slot = manifold3d.CrossSection.square([4.0, 0.05], center=True).translate([0.0, 0.1])
    frame = Frame(resolution=64, half_extent=5.0)
    hole = Hole.from_outline(slot, frame)
    assert hole.mask.any()
    assert hole.outside.min() < frame.pixel_size / 2  # the exact distance, not a pixel's


def _coin(diameter: float, thickness: float) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=diameter / 2, height=thickness, sections=96)


def _edge_on_scene(
    write_scene, a_mesh, b_mesh, tolerance, resolution=160, margin=0.0, starts=24, steps=200
):
    body = f"""
[[pass]]
mesh = "meshes/a.stl"
rotation = {EDGE_ON}
[[block]]
mesh = "meshes/b.stl"
[fabrication]
tolerance = {tolerance}
block_margin = {margin}
[verdict]
starts = {starts}
steps = {steps}
resolution = {resolution}
"""
    # Turn the coin so that it is seen edge-on along z: its axis along y.
    a_mesh = a_mesh.copy()
    a_mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    return load_scene(write_scene(body, {"a.stl": a_mesh, "b.stl": b_mesh}))


COIN_CASES = [
    (res, 1.77 + sign * margin, "A" if sign > 0 else "B")
    for res, margins in ((64, (0.02, 0.05)), (128, (0.05,)), (256, (0.05,)), (512, (0.02, 0.05)))
    for margin in margins
    for sign in (-1, 1)
]


@pytest.mark.slow
@pytest.mark.parametrize("resolution, thickness, winner", COIN_CASES)
def test_coin_slot_decides_by_hundredths(write_scene, resolution, thickness, winner):
    # A 5-cent coin (21.25 x 1.67 mm) edge-on, tolerance 0.05: the printed slot is 1.77 mm wide.
    # A 19.75 mm disk 0.02 or 0.05 thinner than the slot passes; as much thicker is blocked, at
    # every resolution from 64 to 512 (a pixel is 0.35 mm at 64, 0.045 mm at 512).
    scene = _edge_on_scene(
        write_scene, _coin(21.25, 1.67), _coin(19.75, thickness), 0.05, resolution
    )
    r = solve(scene, progress=False)
    assert r.winner == winner
    if winner == "A":
        # Its smallest width is its thickness: it sticks out of the slot by at least half the excess
        # (less the outline's 0.3 % of the tolerance).
        assert r.attack.protrusion[0, 0] >= (thickness - 1.77) / 2 - 2e-4
    else:
        assert r.attack.protrusion[0, 0] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("b_mesh, winner", [("pin", "B"), ("disk", "A")])
def test_edge_on_card_makes_a_real_slot(write_scene, b_mesh, winner):
    # A 0.05 mm card edge-on with tolerance 1: a 32 x 2.05 mm slot (empty at pixel centres).
    card = box(30.0, 10.0, 0.05)  # thin along z; the scene turns it edge-on
    b = {
        "pin": trimesh.creation.cylinder(radius=0.25, height=8.0),
        "disk": trimesh.creation.cylinder(radius=5.0, height=3.0, sections=64),
    }[b_mesh]
    r = solve(_edge_on_scene(write_scene, card, b, 1.0), progress=False)
    # The 30 x 0.05 rectangle grown by 1: its area, two 1-wide strips and a unit disk.
    assert r.outline.area() == pytest.approx(30 * 0.05 + 2 * 30.05 + np.pi, rel=0.005)
    assert r.winner == winner
    if winner == "A":  # the disk's smallest width, 3, against 2.05
        assert r.attack.protrusion[0, 0] >= (3.0 - 2.05) / 2 - 1e-2


@pytest.mark.slow
def test_needle_thinner_than_a_pixel_passes_a_wide_hole(write_scene):
    ball = trimesh.creation.icosphere(3, radius=6.0)
    needle = trimesh.creation.cylinder(radius=0.02, height=8.0, sections=12)
    r = solve(_edge_on_scene(write_scene, ball, needle, 0.1), progress=False)
    assert r.winner == "B"
    assert r.attack.beta[0, 0] == 0.0


def test_zero_area_hole_is_an_error(write_scene):
    sheet = trimesh.Trimesh(
        vertices=[[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], faces=[[0, 1, 2], [0, 2, 3]]
    )
    scene = _edge_on_scene(write_scene, sheet, box(1.0, 1.0, 1.0), 0, starts=2, steps=2)
    with pytest.raises(SieveError, match="zero area"):
        solve(scene, progress=False)


def test_verdict_starts_from_the_search_memory(write_scene):
    # A 20 mm cube face-on with tolerance 1 makes a 22 mm square hole; a 21 x 21 x 1 plate
    # fits only when it lies almost flat. Two starts and no Adam steps: a random rotation does not
    # fit, the remembered flat pose does.
    from sieve_mi.game.attack import Attack, AttackMemory
    from sieve_mi.game.solver import load_shapes
    from sieve_mi.game.verdict import judge

    body = """
[[pass]]
mesh = "meshes/a.stl"
rotation = [1, 0, 0, 0]
[[block]]
mesh = "meshes/b.stl"
[verdict]
starts = 2
steps = 0
"""
    scene = load_scene(write_scene(body, {"a.stl": box(20, 20, 20), "b.stl": box(21, 21, 1)}))
    passes, blocks = load_shapes(scene)
    q, t = np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2))

    def verdict(memory):
        return judge(scene, passes, blocks, q, t, np.random.default_rng(0), memory=memory)

    assert verdict(None).winner == "A"
    memory = AttackMemory(1, size=1)
    flat = Attack(
        beta=np.zeros((1, 1)),
        protrusion=np.zeros((1, 1)),
        quats=np.array([[[1.0, 0, 0, 0]]]),
        trans=np.array([[[0.1, -0.2]]]),
        fits=np.ones((1, 1), int),
    )
    memory.update(flat)
    v = verdict(memory)
    assert v.winner == "B" and v.attack.beta[0, 0] == 0.0


def test_square_plate_sticks_out_of_the_rounded_corners_of_a_cube_hole():
    # The 20 mm cube's hole grown by 1 mm has corner arcs of radius 1 about (±10, ±10). A centred
    # 21.5 mm square's corner (10.75, 10.75) is 0.75 sqrt(2) from the arc's centre: it sticks out
    # by 0.75 sqrt(2) - 1 = 0.061 mm although the hole is 22 mm wide.
    from sieve_mi.geometry.outline import hole_outline

    cube = shape_from_trimesh(box(20, 20, 20), name="cube")
    hole = hole_outline([cube], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 1.0, closed=[True])
    b = outline.Boundary(hole)
    plate = shape_from_trimesh(box(21.5, 21.5, 1), name="plate")
    sc = exact.score(plate, [1.0, 0, 0, 0], [0.0, 0.0], hole, b, closed=True)
    # the outline lies at most 0.3 % of the tolerance outside the exact dilation
    assert 0.75 * np.sqrt(2) - 1 - 0.003 <= sc.protrusion <= 0.75 * np.sqrt(2) - 1 + 1e-6
    assert exact.score(
        shape_from_trimesh(box(21, 21, 1), name="p"), [1.0, 0, 0, 0], [0, 0], hole, b
    ).fits


def test_a_sheet_seen_edge_on_makes_a_stadium_slot():
    # A 20 x 20 sheet of zero thickness seen edge-on projects to a 20 mm segment; grown by 1 mm
    # it is a stadium 22 x 2 mm of area 20 * 2 + pi (not "zero area").
    from sieve_mi.geometry.outline import hole_outline

    sheet = trimesh.Trimesh(
        [[-10, 0, -10], [10, 0, -10], [10, 0, 10], [-10, 0, 10]], [[0, 1, 2], [0, 2, 3]]
    )
    s = shape_from_trimesh(sheet, name="sheet")
    hole = hole_outline([s], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 1.0)
    assert hole.area() == pytest.approx(40 + np.pi, rel=0.004)
    lo, hi = np.asarray(hole.bounds()[:2]), np.asarray(hole.bounds()[2:])
    np.testing.assert_allclose(hi - lo, [22.0, 2.0], rtol=0.003)


def test_the_reported_margin_is_the_smallest_protrusion(tmp_path):
    """A 10 cent coin (19.75 x 1.93 mm, a 96-gon rim) against a 22 x 1.87 mm slot: edge-on and
    centred it sticks out by (1.93 - 1.87) / 2 = 0.03 mm on each side, and any tilt widens its
    projection (1.93 cos θ + 19.75 sin θ). A sum-of-squares polish stopped at 0.046 mm, off-centre
    and tilted; the minimax polish reaches the true margin."""
    from sieve_mi.game.check import CheckSettings, check
    from sieve_mi.testing import shapes

    plate = manifold3d.Manifold.cube([60, 60, 30]).translate([-30, -30, -30])
    slot = manifold3d.Manifold.cube([22, 1.87, 40], center=True).translate([0, 0, -15])
    m = (plate - slot).to_mesh()
    path = str(tmp_path / "slot.stl")
    trimesh.Trimesh(m.vert_properties[:, :3], m.tri_verts).export(path)
    coin = shapes.coin(19.75, 1.93)
    rep = check(coin, sieve=path, settings=CheckSettings(fit=False, thin_budget=1.0))
    assert not rep.result.passes
    assert rep.result.protrusion == pytest.approx(0.03, abs=1e-3)
