"""The clearance objective: zero iff the shape fits, gradients match finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import sphere

from sieve_mi.clearance import ClearanceObjective
from sieve_mi.hole import HoleStack, build_hole
from sieve_mi.raster import Frame
from sieve_mi.silhouettes import SilhouetteRenderer


def _setup(cube20, radius=8.0):
    f = Frame.covering(cube20.radius + 1.0, 128)
    hole = build_hole([SilhouetteRenderer(cube20).frame_mask([1, 0, 0, 0], [0, 0], f)], f, 1.0)
    b = sphere(radius, 2)
    obj = ClearanceObjective([b], f)
    return f, hole, obj


def _loss(mi, dr, obj, hole, q, t, grad=False):
    qa = [mi.Float(np.float32(v)) for v in q]
    ta = [mi.Float(np.float32(v)) for v in t]
    if grad:
        for a in qa + ta:
            dr.enable_grad(a)
    total, per = obj.loss(tuple(qa), tuple(ta), HoleStack([hole]), mi.UInt32(0))
    if grad:
        dr.backward(total)
        return float(total[0]), [float(dr.grad(a)[0]) for a in qa + ta]
    return float(total[0])


def test_clearance_is_zero_inside_and_positive_outside(mi, cube20):
    import drjit as dr

    f, hole, obj = _setup(cube20)
    obj.bind(np.zeros(1, int))
    # Zero up to float32 rounding of the bilinear weights (CUDA's FMA leaves ~1e-17 mm^2, i.e. a
    # distance of ~1e-9 mm); a 6 mm shift sticks out by millimetres.
    assert _loss(mi, dr, obj, hole, [1, 0, 0, 0], [0, 0]) <= 1e-12
    assert _loss(mi, dr, obj, hole, [1, 0, 0, 0], [6.0, 0]) > 1e-3
    far = _loss(mi, dr, obj, hole, [1, 0, 0, 0], [40.0, 0])  # beyond the frame: still growing
    assert far > _loss(mi, dr, obj, hole, [1, 0, 0, 0], [25.0, 0]) > 0


def test_clearance_gradient_matches_finite_differences(mi, cube20):
    import drjit as dr
    import trimesh

    from sieve_mi.meshes import shape_from_trimesh

    f, hole, _ = _setup(cube20)
    # A box in a generic orientation: its set of silhouette edges does not change under the small
    # perturbations below (on a finely tessellated shape it would, and the loss jumps there).
    obj = ClearanceObjective([shape_from_trimesh(trimesh.creation.box((14, 10, 6)), name="box")], f)
    obj.bind(np.zeros(1, int))
    q = np.array([0.9, 0.3, -0.2, 0.25])
    q /= np.linalg.norm(q)
    t = np.array([6.0, -4.0])  # the box sticks out of the 22 mm hole
    value, grad = _loss(mi, dr, obj, hole, q, t, grad=True)
    assert value > 0
    x0 = np.concatenate([q, t])
    for i, eps in zip(range(6), [1e-3] * 4 + [1e-2] * 2):
        xp, xm = x0.copy(), x0.copy()
        xp[i] += eps
        xm[i] -= eps
        fd = (
            _loss(mi, dr, obj, hole, xp[:4], xp[4:]) - _loss(mi, dr, obj, hole, xm[:4], xm[4:])
        ) / (2 * eps)
        # The loss is piecewise smooth (bilinear distance lookups, float32): a few percent agreement.
        assert grad[i] == pytest.approx(fd, rel=0.05, abs=1e-3 * abs(value)), f"parameter {i}"


def test_clearance_uses_only_silhouette_edges(mi, cube20):
    f, hole, obj = _setup(cube20)
    obj.bind(np.zeros(1, int))
    # A sphere's silhouette edges are a thin band: far fewer than all its edge segments.
    import drjit as dr

    pair_pose, pair_seg = obj._pairs
    r3 = mi.Vector3f(0, 0, 1)
    s1 = dr.dot(dr.gather(mi.Vector3f, obj.m1, pair_seg), r3)
    s2 = dr.dot(dr.gather(mi.Vector3f, obj.m2, pair_seg), r3)
    active = int(dr.count((s1 * s2 >= 0) | dr.gather(mi.Bool, obj.always, pair_seg))[0])
    assert 0 < active < 0.25 * obj.segment_count
