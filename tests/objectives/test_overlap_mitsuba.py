"""The overlap objective: Mitsuba's projective-sampling silhouettes on the hole's pixel grid.

Checks that the rendered silhouette is the orthographic projection on the right pixels, that the
loss is the fraction outside the hole, and that its gradients (from Mitsuba's silhouette-edge
sampling) match finite differences and reach the right pose.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from helpers import rng

from sieve_mi.geometry.hole import Hole, HoleStack
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import random_uniform
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.objectives.overlap_mitsuba import OverlapObjective

FRAME = Frame(64, 1.0)  # pixel size h = 1/32


def _box(x, y, z, name="box"):
    return shape_from_trimesh(trimesh.creation.box((x, y, z)), name=name)


def _rect_hole(x0, x1, y0, y1, frame=FRAME):
    xc, yc = frame.centres()
    xx, yy = np.meshgrid(xc, yc)
    return Hole.from_mask((xx > x0) & (xx < x1) & (yy > y0) & (yy < y1), frame)


def _arrays(mi, dr, q, t, grad=False):
    q = np.atleast_2d(np.asarray(q, float))
    t = np.atleast_2d(np.asarray(t, float))
    qa = [mi.Float(q[:, i].astype(np.float32)) for i in range(4)]
    ta = [mi.Float(t[:, i].astype(np.float32)) for i in range(2)]
    if grad:
        for a in qa + ta:
            dr.enable_grad(a)
    return qa, ta


def _loss(mi, dr, obj, holes, q, t, seed, pose_hole=None):
    """Per-pose losses (ndarray) without gradients."""
    qa, ta = _arrays(mi, dr, q, t)
    ph = mi.UInt32(
        np.zeros(len(qa[0]), np.uint32) if pose_hole is None else np.asarray(pose_hole, np.uint32)
    )
    _, per = obj.loss(tuple(qa), tuple(ta), holes, ph, seed=seed)
    return per.numpy().astype(float)


def _grad(mi, dr, obj, holes, q, t, seed, pose_hole=None):
    """Per-pose losses and d(total)/d(q, t) as a (K, 6) array, through the caller's dr.backward."""
    qa, ta = _arrays(mi, dr, q, t, grad=True)
    ph = mi.UInt32(
        np.zeros(len(qa[0]), np.uint32) if pose_hole is None else np.asarray(pose_hole, np.uint32)
    )
    total, per = obj.loss(tuple(qa), tuple(ta), holes, ph, seed=seed)
    dr.backward(total)
    return per.numpy().astype(float), np.stack(
        [dr.grad(a).numpy() for a in qa + ta], axis=1
    ).astype(float)


def _iou(a, b):
    return float(np.minimum(a, b).sum() / np.maximum(a, b).sum())


@pytest.fixture(scope="module")
def box_obj(mi):
    obj = OverlapObjective([_box(0.8, 0.6, 0.4)], FRAME, spp=64)
    obj.bind(np.zeros(1, int))
    return obj


def test_face_on_box_has_the_exact_area_and_lands_on_the_right_pixels(mi, box_obj):
    import drjit as dr

    h = FRAME.pixel_size
    qa, ta = _arrays(mi, dr, [1, 0, 0, 0], [0, 0])
    img = box_obj.silhouette(tuple(qa), tuple(ta)).numpy()
    assert img.shape == (64, 64) and img.min() >= 0 and img.max() <= 1
    # The camera is perspective but the vertices are pre-warped, so the projection is exact: the
    # 0.8 x 0.6 face covers 0.48 (about 492 pixels) up to Monte Carlo noise at the edge pixels.
    assert abs(img.sum() * h * h - 0.48) < h * h

    # Offset in +x and +y: +x is to the right (larger columns), +y is up (smaller rows).
    t = np.array([0.3, 0.2])
    qa, ta = _arrays(mi, dr, [1, 0, 0, 0], t)
    img = box_obj.silhouette(tuple(qa), tuple(ta)).numpy()
    ref = SilhouetteRenderer(_box(0.8, 0.6, 0.4)).frame_mask(np.array([1.0, 0, 0, 0]), t, FRAME)
    assert _iou(img, ref) > 0.95
    rows, cols = np.indices(img.shape)
    centre_col = (img * cols).sum() / img.sum()
    centre_row = (img * rows).sum() / img.sum()
    expect_col, expect_row = FRAME.to_pixel(t)
    assert abs(centre_col - expect_col) < 0.1 and abs(centre_row - expect_row) < 0.1
    assert expect_col > 32 and expect_row < 32  # right of and above the frame's centre


def test_rotated_asymmetric_shape_matches_the_ray_cast_silhouette(mi):
    import drjit as dr

    # An L-shaped block (two overlapping boxes): no symmetry hides a wrong rotation convention.
    a = trimesh.creation.box((0.9, 0.25, 0.3))
    b = trimesh.creation.box((0.25, 0.7, 0.3))
    b.apply_translation((-0.325, 0.225, 0.0))
    shape = shape_from_trimesh(trimesh.util.concatenate([a, b]), name="L")
    obj = OverlapObjective([shape], FRAME, spp=16)
    obj.bind(np.zeros(1, int))
    ref_renderer = SilhouetteRenderer(shape)
    for q in random_uniform(3, rng(3)):
        t = np.array([-0.15, 0.1])
        qa, ta = _arrays(mi, dr, q, t)
        img = obj.silhouette(tuple(qa), tuple(ta)).numpy()
        ref = ref_renderer.frame_mask(q, t, FRAME)
        assert _iou(img, ref) > 0.9


def test_loss_is_the_fraction_outside_the_hole(mi, box_obj):
    import drjit as dr

    big = _rect_hole(-0.9, 0.9, -0.9, 0.9)
    small = _rect_hole(-0.2, 0.2, -0.2, 0.2)
    half = _rect_hole(-0.9, 0.0, -0.9, 0.9)  # the left half of the frame
    stack = HoleStack([big, small, half])
    q = np.tile([1.0, 0, 0, 0], (3, 1))
    t = np.array([[0.0, 0.0], [0.6, 0.6], [0.0, 0.0]])
    box_obj.bind(np.zeros(3, int))
    try:
        per = _loss(mi, dr, box_obj, stack, q, t, seed=1, pose_hole=[0, 1, 2])
    finally:
        box_obj.bind(np.zeros(1, int))
    assert per[0] < 1e-6  # well inside the big hole
    assert per[1] > 1 - 1e-6  # entirely outside the small one
    assert abs(per[2] - 0.5) < 0.02  # the box straddles x = 0


def _quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def test_gradient_matches_finite_differences(mi):
    import drjit as dr

    # A box in a generic orientation sticking out of the right and top of a square hole, so the
    # silhouette's outline crosses the hole's boundary and every parameter moves the loss.
    obj = OverlapObjective([_box(0.8, 0.5, 0.3)], FRAME, spp=64, spp_grad=16)
    obj.bind(np.zeros(1, int))
    stack = HoleStack([_rect_hole(-0.45, 0.45, -0.45, 0.45)])
    q0 = np.array([0.95, 0.1, -0.05, 0.2])
    t0 = np.array([0.25, 0.1])
    grads = np.array([_grad(mi, dr, obj, stack, q0, t0, seed=s)[1][0] for s in range(2)]).mean(0)

    # Central differences with common random numbers (same seed on both sides), averaged over
    # seeds. The loss is a Monte Carlo estimate over fixed sample positions, piecewise constant at
    # the scale of the samples: steps of 0.02 (about 0.6 pixel at the outline) flip enough samples
    # (64 per pixel) for the difference quotient to average out, while being small enough that the
    # loss is close to linear. What remains is a few percent of sample noise in the differences and
    # a percent or two in the edge-sampled gradient, hence the 10-15 % tolerances.
    eps = 0.02
    x0 = np.concatenate([q0, t0])

    def fd(direction):
        diffs = [
            (
                _loss(mi, dr, obj, stack, *np.split(x0 + eps * direction, [4]), seed=s)[0]
                - _loss(mi, dr, obj, stack, *np.split(x0 - eps * direction, [4]), seed=s)[0]
            )
            / (2 * eps)
            for s in range(4)
        ]
        return float(np.mean(diffs))

    numeric = np.array([fd(np.eye(6)[i]) for i in range(6)])
    # Translations: each derivative on its own.
    for i in (4, 5):
        assert abs(grads[i] - numeric[i]) < 0.1 * abs(numeric[i]), (i, grads[i], numeric[i])
    # Quaternion: d/dw and d/dz are small here (the loss only depends on q/|q|), so compare the
    # 4-vector as a whole.
    assert np.linalg.norm(grads[:4] - numeric[:4]) < 0.15 * np.linalg.norm(numeric[:4]), (
        grads[:4],
        numeric[:4],
    )
    # The in-plane rotation (about z, in world space) as a directional derivative.
    dq = 0.5 * _quat_mul([0, 0, 0, 1], q0)
    direction = np.concatenate([dq, [0, 0]])
    assert abs(grads @ direction - fd(direction)) < 0.15 * abs(fd(direction)) + 1e-3


def test_each_pose_gets_its_own_gradient(mi):
    """Poses rendered one after another in one scene: every gradient belongs to its own pose."""
    import drjit as dr

    shapes = [_box(0.8, 0.5, 0.3), _box(0.5, 0.5, 0.5, name="cube")]
    obj = OverlapObjective(shapes, FRAME, spp=4, spp_grad=4)
    stack = HoleStack([_rect_hole(-0.45, 0.45, -0.45, 0.45), _rect_hole(-0.6, 0.3, -0.3, 0.6)])
    q = random_uniform(3, rng(5))
    t = np.array([[0.25, 0.1], [-0.3, 0.2], [0.1, -0.35]])
    pose_shape, pose_hole = np.array([0, 1, 0]), np.array([0, 1, 1])
    obj.bind(pose_shape)
    per, grads = _grad(mi, dr, obj, stack, q, t, seed=7, pose_hole=pose_hole)
    assert np.all(np.abs(grads[:, 4:]) > 0.05)
    for k in range(3):
        obj.bind(pose_shape[k : k + 1])
        per_k, grad_k = _grad(
            mi, dr, obj, stack, q[k], t[k], seed=7, pose_hole=pose_hole[k : k + 1]
        )
        assert per_k[0] == pytest.approx(per[k], abs=1e-6)
        np.testing.assert_allclose(grad_k[0], grads[k], rtol=1e-3, atol=1e-5)


def test_stock_direct_projective_gives_the_same_images_and_gradients(mi):
    import drjit as dr

    stack = HoleStack([_rect_hole(-0.45, 0.45, -0.45, 0.45)])
    q, t = np.array([0.95, 0.1, -0.05, 0.2]), np.array([0.25, 0.1])
    out = []
    for integrator in ("silhouette", "direct_projective"):
        obj = OverlapObjective(
            [_box(0.8, 0.5, 0.3)], FRAME, spp=4, spp_grad=4, integrator=integrator
        )
        obj.bind(np.zeros(1, int))
        out.append(_grad(mi, dr, obj, stack, q, t, seed=3))
    assert out[0][0] == pytest.approx(out[1][0], abs=1e-4)
    np.testing.assert_allclose(out[0][1], out[1][1], rtol=1e-2, atol=1e-4)


def test_margin_sees_the_part_outside_the_frame(mi):
    import drjit as dr

    shape = _box(0.8, 0.6, 0.4)
    stack = HoleStack([_rect_hole(-0.9, 0.9, -0.9, 0.9)])
    q, t = (
        np.array([1.0, 0, 0, 0]),
        np.array([0.8, 0.0]),
    )  # x from 0.4 to 1.2: a quarter past the frame
    plain = OverlapObjective([shape], FRAME, spp=16)
    wide = OverlapObjective([shape], FRAME, spp=16, margin=16)
    for obj in (plain, wide):
        obj.bind(np.zeros(1, int))
    qa, ta = _arrays(mi, dr, q, t)
    h = FRAME.pixel_size
    assert wide.silhouette(tuple(qa), tuple(ta)).numpy().shape == (96, 96)
    assert wide.silhouette(tuple(qa), tuple(ta)).numpy().sum() * h * h == pytest.approx(
        0.48, abs=h * h
    )
    seen = _loss(mi, dr, plain, stack, q, t, seed=0)[0]  # only the part on the frame: x in [0.4, 1]
    full = _loss(mi, dr, wide, stack, q, t, seed=0)[0]
    assert seen == pytest.approx(0.1 / 0.6, abs=0.02)  # [0.9, 1.0] of [0.4, 1.0] is outside H
    assert full == pytest.approx(0.3 / 0.8, abs=0.02)  # [0.9, 1.2] of [0.4, 1.2]


def test_player_b_fits_a_box_with_the_overlap_objective(mi):
    """Adam on the overlap loss moves a box that sticks out into an off-centre hole."""
    from sieve_mi.game.player_b import PlayerB

    hole = _rect_hole(0.0, 0.8, -0.5, 0.5)  # the box (half diagonal 0.2) starts near x = 0
    player = PlayerB([_box(0.3, 0.2, 0.2)], FRAME, objective="overlap-mitsuba")
    attack = player.attack([hole], starts=2, steps=40, learning_rate=0.05, rng=rng(1))
    assert attack.beta.shape == (1, 1)
    assert attack.beta[0, 0] == 0.0 and attack.fits[0, 0] >= 1
