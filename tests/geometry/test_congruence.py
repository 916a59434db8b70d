"""Congruent raster holes (sieve_mi.geometry.congruence).

Known answers: a cube seen face-on makes the same square whichever face and however turned
about the view (the views along x and along -x are mirror images, turned; turned by other than
a multiple of 90°, since a square drawn square to the pixels loses up to a pixel per edge to
the raster); a ball makes the same
disk in every view; an asymmetric box seen from random directions makes holes that differ by
more than a pixel. A tilt changes a face view's width by side x (cos + sin - 1): 3° widens a
20 mm cube's square by 1.0 mm, 3.6 pixels at 128 pixels over 37.5 mm, more than the test's
allowance (0.6 pixel of area per pixel of border, 1.5 pixel anywhere); 0.2° widens it by 0.07 mm,
a quarter of a pixel.
"""

from __future__ import annotations

import numpy as np
from helpers import sphere

from sieve_mi.geometry import congruence
from sieve_mi.geometry.congruence import Motion, Outline, congruent
from sieve_mi.geometry.hole import Hole, build_hole
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import from_axis_angle, quat_multiply, random_uniform
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.testing import shapes

X, Z = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


def _masks(shape, frame, quats, trans=None):
    quats = np.atleast_2d(quats)
    trans = np.zeros((len(quats), 2)) if trans is None else np.atleast_2d(trans)
    zero = np.zeros(len(quats), int)
    return SilhouetteRenderer(shape).masks(quats, trans, frame, zero, zero, frame.resolution)


def _outlines(shape, quats, resolution=128):
    frame = Frame.covering(shape.radius + 1.0, resolution)
    return [Outline.of(build_hole([m], frame, 1.0)) for m in _masks(shape, frame, quats)]


def test_a_cubes_face_views_are_congruent_and_its_tilts_are_not():
    cube = shape_from_trimesh(shapes.cube(20.0), name="cube")
    ten = from_axis_angle(Z, np.radians(10.0))
    views = [
        ten,
        from_axis_angle(Z, np.radians(40.0)),
        quat_multiply(from_axis_angle(Z, np.radians(71.0)), from_axis_angle(X, np.pi / 2)),
        quat_multiply(from_axis_angle(X, np.radians(0.2)), ten),
        quat_multiply(from_axis_angle(X, np.radians(3.0)), ten),
    ]
    ref, *others = _outlines(cube, np.array(views))
    turned = congruent(ref, others[0])
    assert turned is not None and abs(turned.shift).max() < 0.05
    # a square's turns agree modulo 90° (a mirror turns it the other way)
    angle = np.degrees(-turned.angle if turned.mirror else turned.angle)
    assert abs((angle - 30.0 + 45.0) % 90.0 - 45.0) < 0.5
    assert congruent(ref, others[1]) is not None
    assert congruent(ref, others[2]) is not None  # 0.2° of tilt: a quarter of a pixel
    assert congruent(ref, others[3]) is None  # 3° of tilt: 3.6 pixels wider


def test_a_balls_views_are_one_hole_and_an_asymmetric_boxs_are_not():
    ball = _outlines(sphere(10.0), random_uniform(4, np.random.default_rng(1)))
    for other in ball[1:]:
        motion = congruent(ball[0], other)
        assert motion is not None and abs(motion.shift).max() < 0.05  # the centred disk
    box = shape_from_trimesh(shapes.box(24.0, 25.0, 26.0), name="box")
    q = random_uniform(6, np.random.default_rng(2))
    # the same views turned 50° about the view and seen from the other side (a mirror)
    flipped = quat_multiply(from_axis_angle(X, np.pi), q[0])
    q = np.concatenate([q, [quat_multiply(from_axis_angle(Z, np.radians(50.0)), q[0])], [flipped]])
    outs = _outlines(box, q)
    for i in range(6):
        for j in range(i):
            assert congruent(outs[j], outs[i]) is None, (i, j)
    turned = congruent(outs[0], outs[6])
    assert turned is not None and not turned.mirror
    assert (
        abs((np.degrees(turned.angle) - 50.0 + 90.0) % 180.0 - 90.0) < 0.5
    )  # a box's view: point-symmetric
    assert congruent(outs[0], outs[7]).mirror


def test_poses_move_with_the_plane():
    # B's silhouette at a moved pose is its silhouette moved by the same motion, mirror included
    box = shape_from_trimesh(shapes.box(6.0, 9.0, 14.0), name="box")
    frame = Frame.covering(22.0, 128)
    q, t = random_uniform(1, np.random.default_rng(4)), np.array([[2.0, -1.0]])
    for motion in (
        Motion(0.7, False, np.array([1.5, -2.0])),
        Motion(2.1, True, np.array([-3.0, 0.5])),
    ):
        q2, t2 = motion.poses(q, t)
        a, b = (
            Outline.of(Hole.from_mask(m, frame))
            for m in _masks(box, frame, [q[0], q2[0]], [t[0], t2[0]])
        )
        assert congruence._fits(a, b, motion)
        assert not congruence._fits(a, b, Motion(motion.angle, not motion.mirror, motion.shift))


def test_an_outlines_distances_are_the_whole_frames_wherever_the_hole_lies():
    # computed on the hole's bounding box grown by a pixel: the same as on the whole frame,
    # for a hole in the middle, one cut off by the frame's edge and one filling a corner
    from scipy import ndimage

    frame = Frame.covering(10.0, 64)
    x, y = frame.centres()
    xx, yy = np.meshgrid(x, y)
    for cx, cy, r in ((0.0, 0.0, 4.0), (9.5, -3.0, 3.0), (-9.0, 9.0, 6.0)):
        mask = np.hypot(xx - cx, yy - cy) <= r
        mask &= ~((np.abs(xx - cx) < 0.6 * r) & (np.abs(yy - cy) < 0.2 * r))  # a slot
        hole = Hole.from_mask(mask, frame)
        out = Outline.of(hole)
        inside = ndimage.distance_transform_edt(mask)
        whole = np.where(mask, 0.5 - inside, hole.outside / frame.pixel_size - 0.5)
        np.testing.assert_array_equal(out.signed, whole.astype(np.float32))
        assert out.border == np.count_nonzero(mask & ~ndimage.binary_erosion(mask, border_value=0))
