"""The clearance objective: zero iff the shape fits, gradients match finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import sphere

from sieve_mi.geometry.hole import HoleStack, build_hole
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.objectives.clearance import ClearanceObjective


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

    from sieve_mi.geometry.meshes import shape_from_trimesh

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


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clearance_uses_exactly_the_silhouette_edges(mi, seed):
    # For a convex polyhedron seen in a general direction, the silhouette edges project onto the
    # boundary of the projection's convex hull and add up to its perimeter; any other edge would
    # add length. So the segments the loss keeps must sum to the hull's perimeter, lie on the
    # hull's boundary, and be a thin band (a small fraction of all segments).
    import drjit as dr
    from scipy.spatial import ConvexHull

    from sieve_mi.geometry.rotations import random_uniform, to_matrix

    b = sphere(8.0, 2)
    obj = ClearanceObjective([b], Frame.covering(9.0, 128))
    obj.bind(np.zeros(1, int))
    q = random_uniform(1, np.random.default_rng(seed))[0]
    qa = tuple(mi.Float(float(v)) for v in q)
    keep = dr.gather(mi.UInt32, obj.pairs[1], obj.active_pairs(qa)).numpy()
    r = to_matrix(q)[:2]
    a = np.stack([c.numpy() for c in (obj.a.x, obj.a.y, obj.a.z)], 1)[keep] @ r.T
    d = np.stack([c.numpy() for c in (obj.d.x, obj.d.y, obj.d.z)], 1)[keep] @ r.T
    hull = ConvexHull(b.vertices @ r.T)
    assert np.linalg.norm(d, axis=1).sum() == pytest.approx(hull.area, rel=1e-4)  # 2D: perimeter
    eq = hull.equations  # n . x + c = 0 on each boundary line, n a unit vector
    for p in (a, a + d):
        assert np.abs(p @ eq[:, :2].T + eq[:, 2]).min(axis=1).max() < 1e-4
    assert 0 < len(keep) < 0.25 * obj.segment_count


def test_expand_ranges_lists_every_range_in_order(mi):
    from sieve_mi.objectives.pairs import expand_ranges

    out = expand_ranges(mi.UInt32([3, 10, 20]), mi.UInt32([2, 3, 1]))
    assert np.array(out).tolist() == [3, 4, 10, 11, 12, 20]
    assert len(np.array(expand_ranges(mi.UInt32([]), mi.UInt32([])))) == 0


def test_pose_ranges_lists_each_poses_items_in_order(mi):
    from sieve_mi.objectives.pairs import pose_ranges

    pose, item = pose_ranges(np.array([3, 10, 7, 0]), np.array([2, 0, 3, 1]))
    assert np.array(pose).tolist() == [0, 0, 2, 2, 2, 3]
    assert np.array(item).tolist() == [3, 4, 7, 8, 9, 0]
    empty = pose_ranges(np.array([5]), np.array([0]))
    assert len(np.array(empty[0])) == len(np.array(empty[1])) == 0


def test_bound_pairs_are_every_poses_segments_and_edges(mi, cube20):
    # bind() builds the pairs on the device; they must be, entry for entry, each pose's segments
    # (and edges, with each edge's first segment pair and segment count) in pose order, for a
    # mix of shapes: the definition, written out here with NumPy.
    import trimesh

    from sieve_mi.geometry.meshes import shape_from_trimesh

    torus = shape_from_trimesh(trimesh.creation.torus(8.0, 2.5), name="torus")
    shapes = [cube20, sphere(12.0), torus]
    obj = ClearanceObjective(shapes, Frame(128, 20.0))
    pose_shape = np.array([2, 0, 0, 1, 2, 1, 0])
    obj.bind(pose_shape)
    e = obj.edge_table
    want_pose, want_seg, want_epose, want_edge, want_first, want_pieces = [], [], [], [], [], []
    first_pair = 0
    for k, sh in enumerate(pose_shape):
        segs = np.arange(obj.offsets[sh], obj.offsets[sh] + obj.counts[sh])
        edges = np.arange(e["offset"][sh], e["offset"][sh] + e["count"][sh])
        want_pose += [k] * len(segs)
        want_seg += segs.tolist()
        want_epose += [k] * len(edges)
        want_edge += edges.tolist()
        want_first += (first_pair + e["first_local"][edges]).tolist()
        want_pieces += e["pieces"][edges].tolist()
        first_pair += len(segs)
    got = [np.array(a).tolist() for a in (*obj.pairs, *obj.edge_pairs)]
    want = [want_pose, want_seg, want_epose, want_edge, want_first, want_pieces]
    for g, w in zip(got, want):
        assert g == w
    assert obj.pair_count == first_pair > 1000


def test_per_edge_silhouette_test_keeps_exactly_the_per_segment_pairs(mi, cube20):
    # The silhouette test runs per (pose, edge) and expands the active edges into their
    # segments; it must give the very list that testing every (pose, segment) gives, for closed,
    # open (boundary edges: always candidates) and several shapes bound together.
    import trimesh

    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.geometry.rotations import normalize

    torus = shape_from_trimesh(trimesh.creation.torus(8.0, 2.5), name="torus")
    open_box = trimesh.creation.box((10.0, 6.0, 4.0))
    open_box.update_faces(np.arange(len(open_box.faces)) > 1)  # one face removed: a hole
    opened = shape_from_trimesh(open_box, name="open")
    shapes = [cube20, sphere(12.0), torus, opened]
    obj = ClearanceObjective(shapes, Frame(128, 20.0))
    assert obj.per_edge  # 4 samples a segment at this pixel size: edges have several segments
    rng = np.random.default_rng(3)
    pose_shape = rng.integers(0, len(shapes), size=300)
    obj.bind(pose_shape)
    q = normalize(rng.normal(size=(300, 4)))
    qa = tuple(mi.Float(q[:, i].astype(np.float32)) for i in range(4))
    fast = np.array(obj.active_pairs(qa))
    slow = np.array(mi.UInt32(__import__("drjit").compress(obj.silhouette_flags(qa))))
    assert len(fast) > 1000 and np.array_equal(fast, slow)
    # the count that sizes a frozen step's buffer, without the list, both ways of testing
    assert obj.active_count(qa) == len(fast)
    obj.per_edge = False
    assert obj.active_count(qa) == len(fast)


def test_packet_tables_hold_each_segments_ends_and_each_items_test(mi, cube20):
    # The losses read a segment's ends and an item's silhouette test as one packet of 8 floats:
    # the tables must hold, row for row, the segments' (a, b - a) and the (m1, m2, always) of
    # every segment and every edge, for a mix of shapes with an open one (always-tested edges).
    import trimesh

    from sieve_mi.geometry.meshes import segments, shape_from_trimesh

    open_box = trimesh.creation.box((10.0, 6.0, 4.0))
    open_box.update_faces(np.arange(len(open_box.faces)) > 1)
    shapes = [cube20, sphere(12.0), shape_from_trimesh(open_box, name="open")]
    frame = Frame(128, 20.0)
    obj = ClearanceObjective(shapes, frame)
    segs = [segments(s, frame.pixel_size, obj.samples) for s in shapes]

    def cat(attr):
        return np.concatenate([getattr(s, attr) for s in segs]).astype(np.float32)

    ends = np.asarray(obj.ends).reshape(-1, 8)
    d = np.concatenate([s.b - s.a for s in segs]).astype(np.float32)
    np.testing.assert_array_equal(ends[:, :3], cat("a"))
    np.testing.assert_array_equal(ends[:, 3:6], d)
    tests = np.asarray(obj.tests).reshape(-1, 8)
    np.testing.assert_array_equal(tests[:, :3], cat("m1"))
    np.testing.assert_array_equal(tests[:, 3:6], cat("m2"))
    np.testing.assert_array_equal(tests[:, 6], cat("always"))
    e = obj.edge_table
    edge_tests = np.asarray(obj.e_tests).reshape(-1, 8)
    np.testing.assert_array_equal(edge_tests[:, :3], e["m1"])
    np.testing.assert_array_equal(edge_tests[:, 3:6], e["m2"])
    np.testing.assert_array_equal(edge_tests[:, 6], e["always"])
    assert e["always"].any() and not e["always"].all()  # the open box's rim, and the rest
    assert not ends[:, 6:].any() and not tests[:, 7].any()


def test_corner_table_holds_each_pixels_four_neighbours(mi):
    # The clearance loss reads a pixel's distance and its right, lower and lower-right
    # neighbours' as one packet: the same numbers as four single reads, for two holes, every
    # pixel up to row and column N - 2 (the last row and column repeat themselves).
    from sieve_mi.geometry.hole import Hole

    n = 24
    frame = Frame(n, 10.0)
    yy, xx = np.mgrid[0:n, 0:n]
    holes = [
        Hole.from_mask((xx - 11) ** 2 + (yy - 12) ** 2 < 30, frame),
        Hole.from_mask((np.abs(xx - 6) < 4) & (np.abs(yy - 15) < 6), frame),
    ]
    stack = HoleStack(holes)
    h, r, c = (a.ravel().astype(np.uint32) for a in np.mgrid[0:2, 0 : n - 1, 0 : n - 1])
    got = np.array(stack.gather_corners(mi.UInt32(h), mi.UInt32(r), mi.UInt32(c)))
    dist = np.stack([hole.outside for hole in holes]).astype(np.float32) / frame.pixel_size
    want = [dist[h, r, c], dist[h, r, c + 1], dist[h, r + 1, c], dist[h, r + 1, c + 1]]
    np.testing.assert_array_equal(got, np.array(want, dtype=np.float32))
    assert (got > 0).any() and (got == 0).any()  # outside and inside pixels both read
    last = np.asarray(stack.corners).reshape(2, n, n, 4)[:, n - 1, n - 1]
    np.testing.assert_array_equal(last, np.repeat(dist[:, n - 1, n - 1, None], 4, axis=1))
    assert HoleStack(holes, corners=False).corners is None
