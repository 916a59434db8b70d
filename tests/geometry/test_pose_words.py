"""Poses in words (sieve_mi.geometry.pose_words), with answers worked on paper.

A box of extents 8 (x) x 4 (y) x 2 (z) at rest (identity) lies face down. A quarter turn about
y stands its 8 extent along z (the passage): end on; about x, its 4 extent: on its side. Its
resting poses are its six faces, and a quasi-static drop settles on a face with the probability
of the solid angle the face subtends at the centre: a rectangle a x b seen from distance d on its
axis subtends 4 arcsin(ab / sqrt((a^2 + 4d^2)(b^2 + 4d^2))).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sieve_mi.geometry.meshes import shape_from_arrays, shape_from_trimesh
from sieve_mi.geometry.pose_words import describe_pose, pose_sentence, resting_poses
from sieve_mi.geometry.rotations import from_axis_angle, quat_multiply
from sieve_mi.testing.catalogue import brick, cell, hex_nut

X, Y, Z = np.eye(3)


def turn(axis, degrees):
    return from_axis_angle(np.asarray(axis, float), np.radians(degrees))


@pytest.fixture(scope="module")
def box():
    return shape_from_trimesh(trimesh.creation.box((8.0, 4.0, 2.0)), name="box")


def solid_angle(a, b, d):
    return 4 * np.arcsin(a * b / np.sqrt((a * a + 4 * d * d) * (b * b + 4 * d * d)))


@pytest.mark.parametrize(
    "q, position, upright",
    [
        ([1.0, 0, 0, 0], "face down", 2.0),
        (turn(Y, 90), "end on", 8.0),
        (turn(X, 90), "on its side", 4.0),
        (turn(Y, -90), "end on", 8.0),
        (quat_multiply(turn(Z, 37), turn(Y, 90)), "end on", 8.0),  # turned about z: the same
        (turn(X, 180), "face down", 2.0),  # upside down
    ],
)
def test_which_extent_of_a_box_is_upright(box, q, position, upright):
    p = describe_pose(box, q)
    assert p.position == position
    assert p.upright == pytest.approx(upright)
    assert p.extents == pytest.approx([8.0, 4.0, 2.0])
    assert p.tilt_deg == pytest.approx(0.0, abs=1e-6)
    assert p.rest_deg == pytest.approx(0.0, abs=1e-6)  # every face of a box is a resting pose
    assert p.rest_position == position


def test_end_on_box_words_angles_and_rotation(box):
    p = describe_pose(box, turn(Y, 90))
    assert p.words == "end on (standing on its short end)"
    assert p.euler_xyz_deg == pytest.approx([0.0, 90.0, 0.0], abs=1e-9)
    assert p.turn_deg == pytest.approx(90.0) and p.turn_axis == pytest.approx([0, 1, 0])
    assert p.quaternion == pytest.approx([np.sqrt(0.5), 0, np.sqrt(0.5), 0])
    d = p.to_dict()
    assert d["position"] == "end on" and d["words"] == p.words
    assert pose_sentence(d) == p.sentence() and "standing on its short end" in p.sentence()


def test_a_tilted_box_is_named_by_its_nearest_axis_and_its_tilt(box):
    # 80° about y: the 8 extent is 10° from upright, the end face 10° from flat on the plate
    p = describe_pose(box, turn(Y, 80))
    assert p.position == "end on"
    assert p.tilt_deg == pytest.approx(10.0)
    assert p.rest_deg == pytest.approx(10.0) and p.rest_position == "end on"
    assert "tilted 10.0°; 10.0° from resting end on" in p.sentence()
    # 30° about y: the 2 extent is nearest upright, 30° off; the nearest face is the bottom one
    p = describe_pose(box, turn(Y, 30))
    assert p.position == "face down" and p.tilt_deg == pytest.approx(30.0)
    assert p.rest_deg == pytest.approx(30.0) and p.rest_position == "face down"


def test_resting_shares_of_a_box_are_its_faces_solid_angles(box):
    normals, shares = resting_poses(box)
    assert len(normals) == 6 and shares.sum() == pytest.approx(1.0)
    by_axis = {i: shares[np.abs(normals[:, i]) > 0.99].sum() for i in range(3)}
    four_pi = 4 * np.pi
    assert by_axis[0] == pytest.approx(2 * solid_angle(4, 2, 4) / four_pi, rel=1e-6)  # ends
    assert by_axis[1] == pytest.approx(2 * solid_angle(8, 2, 2) / four_pi, rel=1e-6)  # sides
    assert by_axis[2] == pytest.approx(2 * solid_angle(8, 4, 1) / four_pi, rel=1e-6)  # faces
    # the share a pose names sums the position's faces: end on is about 6.9 %
    assert describe_pose(box, turn(Y, 90)).rest_share == pytest.approx(by_axis[0])


def test_equal_extents_rods_discs_and_cubes():
    aaa = shape_from_trimesh(cell(10.5, 44.5), name="AAA")  # axis along z
    assert describe_pose(aaa, [1.0, 0, 0, 0]).position == "end on"
    lying = describe_pose(aaa, quat_multiply(turn(Z, 20), turn(X, 90)))
    assert lying.position == "on its side" and lying.gloss == "lying along its length"
    # rolled about its own axis it still lies on its side, untilted
    rolled = describe_pose(aaa, quat_multiply(turn(X, 90), turn(Z, 33)))
    assert rolled.position == "on its side" and rolled.tilt_deg == pytest.approx(0, abs=1e-6)
    assert lying.rest_share > 0.9  # a cell dropped at random ends up lying down
    coin = shape_from_trimesh(cell(25.75, 2.2), name="coin")
    assert describe_pose(coin, [1.0, 0, 0, 0]).position == "face down"
    assert describe_pose(coin, turn(X, 90)).position == "on its side"
    cube = shape_from_trimesh(trimesh.creation.box((3, 3, 3)), name="cube")
    assert describe_pose(cube, turn([1, 2, 3], 50)).position == "any way up"


def test_the_toy_brick_end_on_and_studs_up():
    b = shape_from_trimesh(brick(2, 1), name="1x2")  # 15.8 x 7.8 x 11.3 with its studs
    p = describe_pose(b, turn(Y, 90))
    assert p.position == "end on" and p.upright == pytest.approx(15.8)
    # studs up, its 11.3 mm height (with the studs) is its middle extent
    assert describe_pose(b, [1.0, 0, 0, 0]).position == "on its side"
    assert describe_pose(b, turn(X, 90)).position == "face down"


def test_a_hex_nut_rests_on_its_flats_named_by_its_width_across_them():
    # ISO 4032 M3: 5.5 mm across flats (normals along x and at 60° to it), 6.35 across corners
    # (along y), 2.4 thick. On a flat its 5.5 mm width stands upright: on its side, a resting
    # pose; on a corner, 30° from the nearest flat's normal, still resting on its side.
    nut = shape_from_trimesh(hex_nut(5.5, 2.4, 3.0), name="M3")
    on_flat = describe_pose(nut, turn(Y, 90))  # body +x points down
    assert on_flat.rest_deg == pytest.approx(0.0, abs=1e-6)
    assert on_flat.rest_position == "on its side"
    on_corner = describe_pose(nut, turn(X, 90))  # body -y (a corner) points down
    assert on_corner.position == "end on" and on_corner.upright == pytest.approx(
        5.5 / np.cos(np.pi / 6)
    )
    assert on_corner.rest_deg == pytest.approx(30.0, abs=1e-6)
    assert on_corner.rest_position == "on its side"  # the flat 30° off, not its corner axis
    assert describe_pose(nut, [1.0, 0, 0, 0]).rest_position == "face down"


def test_a_flat_part_has_no_resting_pose():
    square = shape_from_arrays(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
        np.array([[0, 1, 2], [0, 2, 3]]),
        name="square",
    )
    assert resting_poses(square) is None
    p = describe_pose(square, [1.0, 0, 0, 0])
    assert p.rest_deg is None and p.position == "face down"
    assert p.sentence().endswith("a flat part has no resting pose")


def _tetromino(cells, thickness=4.0):
    """Four 10 mm squares extruded ``thickness`` along z (a flat part lying face down)."""
    from shapely.geometry import box as square
    from shapely.ops import unary_union

    outline = unary_union([square(10 * i, 10 * j, 10 * i + 10, 10 * j + 10) for i, j in cells])
    return shape_from_trimesh(trimesh.creation.extrude_polygon(outline, thickness), name="t")


def test_a_chiral_flat_part_counts_only_the_face_that_shows_its_silhouette():
    # The S tetromino face up shows the Z tetromino, its mirror image, which no turn of it gives:
    # a hole for it lying face down admits only the drops on that face (half of face down's).
    # The T tetromino is its own mirror image: both faces show the same silhouette.
    s = describe_pose(_tetromino([(1, 0), (2, 0), (0, 1), (1, 1)]), [1.0, 0, 0, 0])
    assert s.rest_position == "face down" and s.position_share > 0.5  # flat: mostly face down
    assert s.rest_share == pytest.approx(s.position_share / 2, rel=1e-9)
    assert "settle face down showing this silhouette" in s.sentence()
    t = describe_pose(_tetromino([(0, 1), (1, 1), (2, 1), (1, 0)]), turn(X, 180))  # upside down
    assert t.rest_share == pytest.approx(t.position_share, rel=1e-9)
    assert t.sentence().endswith("random drops settle face down)")


def test_same_silhouette_is_turn_and_shift_never_mirror():
    import manifold3d

    from sieve_mi.geometry.pose_words import same_silhouette

    ell = manifold3d.CrossSection([np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 2], [0, 2.0]])])
    moved = ell.rotate(73.0).translate([5.0, -2.0])
    assert same_silhouette(ell, moved)
    assert not same_silhouette(ell, ell.mirror([1.0, 0.0]).rotate(73.0))  # an L with unequal arms
    disc = manifold3d.CrossSection.circle(2.0, 7)  # a heptagon: isotropic, every degree tried
    assert same_silhouette(disc, disc.rotate(40.0).translate([1.0, 1.0]))
    assert not same_silhouette(disc, manifold3d.CrossSection.circle(2.1, 7))
