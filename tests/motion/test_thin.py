"""Thin plates: known answers for motions through a plate thinner than the shape (issue "Thin sheets").

Every found passage is re-checked here independently of coal: manifold3d intersects the placed
mesh with the plate solid at poses along the motion, and the intersection must be empty.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.rotations import random_uniform, to_matrix
from sieve_mi.motion import thin_plate, thin_plates
from sieve_mi.motion.collide import PlateWorld
from sieve_mi.motion.path import interpolate, segment_reach, verify
from sieve_mi.testing import shapes

ROD = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="rod")
ROD_HOLE = manifold3d.CrossSection.circle(4.5, 64)  # a 9 mm round hole


def _placed(shape, quat, trans) -> manifold3d.Manifold:
    v = shape.vertices @ to_matrix(np.asarray(quat)).T + np.asarray(trans)
    mesh = manifold3d.Mesh(v.astype(np.float32), shape.faces.astype(np.uint32))
    return manifold3d.Manifold(mesh)


def _plate_solid(hole, thickness: float, margin: float = 60.0) -> manifold3d.Manifold:
    x0, y0, x1, y1 = hole.bounds()
    size = [x1 - x0 + 2 * margin, y1 - y0 + 2 * margin, thickness]
    block = manifold3d.Manifold.cube(size).translate([x0 - margin, y0 - margin, -thickness])
    return block - manifold3d.Manifold.extrude(hole, thickness + 2).translate(
        [0, 0, -thickness - 1]
    )


def _assert_real_passage(shape, hole, result, samples: int = 120):
    """Starts wholly above, ends wholly below, and manifold3d finds no overlap along the way."""
    poses = [(row[:4], row[4:]) for row in result.poses]
    first = shape.vertices @ to_matrix(poses[0][0]).T + poses[0][1]
    last = shape.vertices @ to_matrix(poses[-1][0]).T + poses[-1][1]
    assert first[:, 2].min() > 0 and last[:, 2].max() < -result.thickness
    plate = _plate_solid(hole, result.thickness)
    for k in range(len(poses) - 1):
        for s in np.linspace(0, 1, max(2, samples // len(poses)), endpoint=False):
            q, t = interpolate(poses[k], poses[k + 1], s)
            assert (_placed(shape, q, t) ^ plate).volume() < 1e-6
    assert result.min_clearance > 0


def test_l_rod_is_blocked_on_a_plate_as_thick_as_its_diameter():
    """The two arms are orthogonal, so the squared sines of their angles to any view direction add
    up to at least 1: one arm makes >= 45 degrees and projects >= 20 sin 45 = 14.1 mm > 9 mm. On a
    plate at least as thick as the diameter only projections count ("safe": no search)."""
    for q in random_uniform(2000, np.random.default_rng(0)):
        p = (ROD.vertices @ to_matrix(q).T)[:, :2]
        span = np.max(np.linalg.norm(p[:, None] - p[None], axis=-1))
        assert span >= 20 / math.sqrt(2) - 1e-9
    result = thin_plate(ROD, ROD_HOLE, 28.4, budget_s=1.0)
    assert result.status == "safe" and result.diameter == pytest.approx(math.sqrt(804))
    assert result.to_dict()["by"] == "diameter"


def test_l_rod_threads_through_a_thin_plate():
    """1 mm plate: the first arm goes straight down, the corner turns through the hole while the
    second arm follows; the search finds it and the motion is real (the motion search alone:
    ``sections`` given, no section proof first)."""
    (result,) = thin_plates([ROD], ROD_HOLE, 1.0, budget_s=60.0, seed=1, sections=[None])
    assert result.status == "passage", result.to_dict()
    _assert_real_passage(ROD, ROD_HOLE, result)
    d = result.to_dict()
    assert d["interpolation"] and len(d["poses"]) == len(result.poses) >= 2
    assert result.seconds < 60.0


def test_coin_cannot_pass_a_slot_narrower_than_its_chord():
    """A 19.75 x 1.93 mm disk (10 cents) and a 19.5 x 3 mm slot in a 1 mm plate: when the coin's
    centre crosses the plate's mid-plane, the horizontal plane there cuts the coin in a chord of
    at least 19.75 cos(pi/96) = 19.739 mm (the 96-gon's rim), longer than the slot's diagonal
    sqrt(19.5² + 3²) = 19.729 mm. No motion exists, and the motion search alone (no section
    proof: ``sections`` given) finds none and says it is not a proof
    (tests/certify/test_section.py proves it)."""
    coin = shape_from_trimesh(shapes.coin(19.75, 1.93), name="10c")
    slot = manifold3d.CrossSection.square([19.5, 3.0], center=True)
    assert 19.75 * math.cos(math.pi / 96) > math.hypot(19.5, 3.0)
    (result,) = thin_plates([coin], slot, 1.0, budget_s=3.0, sections=[None])
    assert result.status == "no passage found" and result.plans >= 1 and result.checks > 100
    d = result.to_dict()
    assert "not a proof" in d["note"] and d["seconds"] >= 2.9


@pytest.mark.parametrize("thickness", [1.0, 5.0, 30.0])
def test_cube_passes_a_larger_square_hole_at_every_thickness(thickness):
    """A 20 mm cube through a 22 mm square hole: straight down, face first. Its slab-section
    proof first gets half the 2 s (and must fail: the cube passes); the straight descent that
    follows takes milliseconds."""
    cube = shape_from_trimesh(shapes.cube(20.0), name="cube")
    hole = manifold3d.CrossSection.square([22, 22], center=True)
    result = thin_plate(cube, hole, thickness, budget_s=2.0)
    assert result.status == "passage" and result.method == "straight descent"
    _assert_real_passage(cube, hole, result, samples=20)
    # a 1 mm clearance on each side at best; the descent keeps at least most of it
    assert 0.5 < result.min_clearance <= 1.0 + 1e-6


@pytest.mark.parametrize("thickness", [1.0, 6.0])
def test_ball_never_passes_a_smaller_round_hole(thickness):
    """A 24 mm ball and a 22 mm hole: its centre must cross the plate, where its 24 mm equator
    disk lies in the plate's slab; no motion exists. Proved without a search: the ball certified
    inside the icosphere (radius >= 12 cos of the faces' angle, ~11.9) is wider than the hole."""
    ball = shape_from_trimesh(trimesh.creation.icosphere(3, 12.0), name="ball")
    hole = manifold3d.CrossSection.circle(11.0, 128)
    result = thin_plate(ball, hole, thickness, budget_s=1.5)
    assert result.status == "safe" and result.to_dict()["by"] == "ball" and result.plans == 0


def test_verify_rejects_a_motion_through_material():
    """Straight down through a hole its projection does not fit: the re-check finds a pose that
    meets the plate; the distance test's reach bound is |Δt| + r θ."""
    world = PlateWorld(ROD, ROD_HOLE, 1.0)
    q = np.array([1.0, 0, 0, 0])
    path = [(q, np.array([0, 0, 20.0])), (q, np.array([0, 0, -20.0]))]
    out = verify(world, path)
    assert not out.ok and out.min_clearance <= 0
    turn = np.array([math.cos(0.25), math.sin(0.25), 0, 0])  # 0.5 rad about x
    reach = segment_reach((q, np.zeros(3)), (turn, np.array([3.0, 4.0, 0])), 2.0)
    assert reach == pytest.approx(5.0 + 2.0 * 0.5)


def test_verify_accepts_a_clear_motion_without_subdividing_much():
    """Far above the plate, a short move: both distances exceed the reach, one segment."""
    world = PlateWorld(ROD, ROD_HOLE, 1.0)
    q = np.array([1.0, 0, 0, 0])
    out = verify(world, [(q, np.array([0, 0, 40.0])), (q, np.array([1.0, 0, 40.0]))])
    assert out.ok and len(out.poses) == 2 and out.min_clearance > 20


def test_two_holes_the_shape_finds_the_one_it_fits():
    """A plate with a 5 mm hole at x = -30 and a 22 mm square hole at x = +30: the cube cannot go
    straight down at the holes' common centre, but the search finds the wide hole (the motion
    search alone: ``sections`` given; a section proof first would spend 15 s failing, as the
    cube passes; the cube's section proof fails at every thickness in the test above)."""
    cube = shape_from_trimesh(shapes.cube(20.0), name="cube")
    holes = manifold3d.CrossSection.circle(2.5, 32).translate(
        [-30, 0]
    ) + manifold3d.CrossSection.square([22, 22], center=True).translate([30, 0])
    (result,) = thin_plates([cube], holes, 2.0, budget_s=30.0, seed=0, sections=[None])
    assert result.status == "passage", result.to_dict()
    _assert_real_passage(cube, holes, result, samples=60)
    # the segment that crosses the plate's mid-plane lies over the hole at x = +30
    p = result.poses
    crossing = [k for k in range(len(p) - 1) if p[k, 6] > -1.0 > p[k + 1, 6]]
    assert crossing and all(p[k, 4] > 15 and p[k + 1, 4] > 15 for k in crossing)
