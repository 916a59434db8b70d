"""Rotations, raster frames, mesh preparation, silhouettes and holes: known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from helpers import sphere
from scipy.spatial import ConvexHull

from sieve_mi.geometry.hole import build_hole
from sieve_mi.geometry.meshes import edge_topology, load_shape, segments, shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import (
    align,
    from_axis_angle,
    from_matrix,
    from_rotvec,
    random_uniform,
    to_matrix,
)
from sieve_mi.geometry.silhouettes import SilhouetteRenderer


def test_quaternion_matrix_round_trip():
    q = random_uniform(50, np.random.default_rng(1))
    m = to_matrix(q)
    assert np.allclose(np.einsum("kij,kil->kjl", m, m), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(m), 1.0)
    back = np.array([from_matrix(x) for x in m])
    assert np.allclose(np.abs(np.einsum("ki,ki->k", back, q)), 1.0)


def test_quaternion_conventions():
    # 90 degrees about z takes x to y (rotation acts on points, right-handed).
    assert np.allclose(
        to_matrix(from_axis_angle([0, 0, 1], np.pi / 2)) @ [1, 0, 0], [0, 1, 0], atol=1e-12
    )
    assert np.allclose(
        to_matrix(align([1, 1, 1], [0, 0, 1])) @ (np.ones(3) / np.sqrt(3)), [0, 0, 1], atol=1e-12
    )
    assert np.allclose(
        to_matrix(from_rotvec([0, np.pi / 2, 0])), to_matrix(from_axis_angle([0, 1, 0], np.pi / 2))
    )


def test_frame_pixel_centres_and_lookup():
    f = Frame(8, 4.0)
    x, y = f.centres()
    assert f.pixel_size == 1.0
    assert np.allclose(x, np.arange(8) - 3.5) and np.allclose(y, 3.5 - np.arange(8))
    assert np.allclose(f.to_pixel(np.array([x[2], y[5]])), [2, 5])
    big = Frame.covering(10.0, 100, margin_px=5)
    assert big.half_extent * (1 - 10 / 100) == pytest.approx(10.0)


def test_stl_vertices_are_welded(tmp_path):
    path = tmp_path / "s.stl"
    trimesh.creation.icosphere(2, 5.0).export(str(path))
    s = load_shape(str(path))
    _, _, _, always = edge_topology(s.vertices, s.faces)
    assert not always.any(), "a closed sphere read from STL must have no boundary edges"


def _projected_silhouette_length(shape, q):
    edges, m1, m2, always = edge_topology(shape.vertices, shape.faces)
    r = to_matrix(q)
    sil = always | ((m1 @ r[2]) * (m2 @ r[2]) >= 0)
    p = shape.vertices @ r[:2].T
    return np.linalg.norm(p[edges[sil, 0]] - p[edges[sil, 1]], axis=1).sum(), p


@pytest.mark.parametrize(
    "mesh", [trimesh.creation.box((20, 10, 6)), trimesh.creation.icosphere(2, 7.0)]
)
def test_silhouette_edges_trace_the_outline_of_convex_shapes(mesh):
    # For a convex polyhedron in general position the silhouette edges project onto the boundary
    # of the convex hull of the projection: their projected lengths add up to its perimeter.
    shape = shape_from_trimesh(mesh, name="convex")
    for q in random_uniform(5, np.random.default_rng(3)):
        total, p = _projected_silhouette_length(shape, q)
        hull = ConvexHull(p)
        assert total == pytest.approx(
            hull.area, rel=1e-6
        )  # in 2D, ConvexHull.area is the perimeter


def test_silhouette_test_ignores_face_orientation():
    mesh = trimesh.creation.icosphere(2, 7.0)
    flipped = mesh.faces.copy()
    flipped[::2] = flipped[::2, ::-1]  # a polygon soup with inconsistent orientation
    a = shape_from_trimesh(mesh, name="a")
    b = shape_from_trimesh(trimesh.Trimesh(mesh.vertices, flipped, process=False), name="b")
    q = random_uniform(1, np.random.default_rng(5))[0]
    assert _projected_silhouette_length(a, q)[0] == pytest.approx(
        _projected_silhouette_length(b, q)[0]
    )


def test_segments_respect_spacing():
    s = shape_from_trimesh(trimesh.creation.box((20, 20, 20)), name="cube")
    seg = segments(s, spacing=0.5, samples_per_segment=4)
    lengths = np.linalg.norm(seg.b - seg.a, axis=1)
    assert lengths.max() <= 4 * 0.5 + 1e-9
    # 12 edges of 20 mm and 6 face diagonals of 20*sqrt(2) mm, cut into pieces of at most 2 mm.
    assert len(seg) == 12 * 10 + 6 * int(np.ceil(20 * np.sqrt(2) / 2))


def test_cube_silhouette_area_and_position(cube20):
    f = Frame.covering(cube20.radius, 256)
    r = SilhouetteRenderer(cube20)
    h = f.pixel_size
    m = r.frame_mask([1, 0, 0, 0], [5.0, -3.0], f)
    x, y = f.centres()
    xx, yy = np.meshgrid(x, y)
    area = m.sum() * h * h
    assert (
        abs(area - 400.0) <= 80.0 * h
    )  # pixel-centre sampling: at most a pixel along the perimeter
    assert xx[m].mean() == pytest.approx(5.0, abs=h) and yy[m].mean() == pytest.approx(-3.0, abs=h)


def test_rotation_convention_of_silhouettes():
    # A 30 x 10 x 10 bar along x, rotated 90 degrees about z, must lie along y.
    bar = shape_from_trimesh(trimesh.creation.box((30, 10, 10)), name="bar")
    f = Frame.covering(bar.radius, 128)
    r = SilhouetteRenderer(bar)
    x, y = f.centres()
    xx, yy = np.meshgrid(x, y)
    m0 = r.frame_mask([1, 0, 0, 0], [0, 0], f)
    m1 = r.frame_mask(from_axis_angle([0, 0, 1], np.pi / 2), [0, 0], f)
    assert np.ptp(xx[m0]) > 2.5 * np.ptp(yy[m0])
    assert np.ptp(yy[m1]) > 2.5 * np.ptp(xx[m1])


def test_sphere_silhouette_is_a_disk_in_every_orientation():
    s = sphere(10.0, 4)
    f = Frame.covering(s.radius, 200)
    r = SilhouetteRenderer(s)
    q = random_uniform(8, np.random.default_rng(2))
    masks = r.masks(q, np.zeros((8, 2)), f, np.zeros(8, int), np.zeros(8, int), 200)
    areas = masks.sum((1, 2)) * f.pixel_size**2
    # An icosphere is inscribed in its sphere: area a little below pi r^2, the same in every orientation.
    assert np.all(areas < np.pi * 100 * 1.01) and np.all(areas > np.pi * 100 * 0.97)
    assert np.ptp(areas) < 0.01 * areas.mean()


def test_flat_and_open_meshes_have_silhouettes():
    # A single flat square (zero thickness, open): its silhouette face-on is the square, edge-on nothing.
    v = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float)
    s = shape_from_trimesh(trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False), name="flat")
    f = Frame.covering(s.radius, 128)
    r = SilhouetteRenderer(s)
    area = r.frame_mask([1, 0, 0, 0], [0, 0], f).sum() * f.pixel_size**2
    assert area == pytest.approx(100.0, abs=40 * f.pixel_size)
    edge_on = r.frame_mask(from_axis_angle([1, 0, 0], np.pi / 2), [0, 0], f).sum()
    assert edge_on <= 128


def test_hole_dilation_and_filling(cube20):
    f = Frame.covering(cube20.radius + 2.0, 400)
    h = f.pixel_size
    a = SilhouetteRenderer(cube20).frame_mask([1, 0, 0, 0], [0, 0], f)
    hole = build_hole([a], f, tolerance=2.0)
    # Minkowski sum of a square and a disk: (s + 2t)^2 - (4 - pi) t^2.
    assert hole.area == pytest.approx((20 + 4) ** 2 - (4 - np.pi) * 4, abs=2 * 96 * h)
    # A ring's silhouette has a hole; filling makes it a disk.
    ring = trimesh.creation.annulus(r_min=4.0, r_max=8.0, height=2.0)
    rs = shape_from_trimesh(ring, name="ring")
    fr = Frame.covering(rs.radius, 200)
    m = SilhouetteRenderer(rs).frame_mask([1, 0, 0, 0], [0, 0], fr)
    filled = build_hole([m], fr, 0.0, fill_holes=True)
    open_ = build_hole([m], fr, 0.0, fill_holes=False)
    assert filled.area == pytest.approx(np.pi * 64, rel=0.03)
    assert open_.area == pytest.approx(np.pi * (64 - 16), rel=0.04)
    # Outside distance: zero inside, about the gap outside.
    assert hole.outside_distance(np.array([[0.0, 0.0]]))[0] == 0.0
    assert hole.outside_distance(np.array([[15.0, 0.0]]))[0] == pytest.approx(3.0, abs=1.5 * h)


def test_dilation_of_one_pixel_is_the_lattice_disk_and_crops_change_nothing():
    # One pixel dilated by t covers the lattice points within t + h/2 of it (Gauss's circle
    # count); a shape touching the frame's corner dilates as the whole frame's transform does.
    from scipy import ndimage

    from sieve_mi.geometry.hole import dilate

    f = Frame(64, 8.0)
    h = f.pixel_size
    dot = np.zeros((64, 64), dtype=bool)
    dot[30, 33] = True
    t = 7.3 * h
    i, j = np.mgrid[-20:21, -20:21]
    assert dilate(dot, f, t).sum() == ((i**2 + j**2) * h**2 <= (t + h / 2) ** 2).sum()
    rng = np.random.default_rng(5)
    for _ in range(5):
        blob = ndimage.binary_opening(rng.random((64, 64)) < 0.45) & (rng.random((64, 64)) < 0.2)
        blob[:, 40:] = False
        blob[0, 0] = True
        whole = ndimage.distance_transform_edt(~blob) * h <= t + h / 2
        np.testing.assert_array_equal(dilate(blob, f, t), whole)


def test_filling_closes_what_a_4_connected_path_cannot_leave():
    # A square ring is filled; a ring with a one-pixel door is not; a diamond drawn with
    # diagonal steps only is filled (the empty pixels inside cannot step diagonally out);
    # random masks are filled exactly as scipy's binary_fill_holes fills them.
    from scipy import ndimage

    from sieve_mi.geometry.hole import fill_gaps

    ring = np.zeros((20, 20), dtype=bool)
    ring[4:15, 4:15] = True
    ring[6:13, 6:13] = False
    assert fill_gaps(ring).sum() == 11 * 11
    door = ring.copy()
    door[9, 4:6] = False
    np.testing.assert_array_equal(fill_gaps(door), door)
    diamond = np.zeros((20, 20), dtype=bool)
    for k in range(5):
        diamond[[10 - k, 10 + k, 5 + k, 15 - k], [5 + k, 15 - k, 10 + k, 10 - k]] = True
    inside = ((np.abs(np.arange(20)[:, None] - 10) + np.abs(np.arange(20)[None] - 10)) <= 5).sum()
    assert fill_gaps(diamond).sum() == inside
    rng = np.random.default_rng(2)
    for p in (0.3, 0.5, 0.7):
        m = rng.random((40, 40)) < p
        np.testing.assert_array_equal(fill_gaps(m), ndimage.binary_fill_holes(m))
        # away from the frame's edges, at one edge, in a corner (filled on the mask's box)
        for rows, cols in ((slice(8, 30), slice(5, 25)), (slice(0, 20), slice(12, 33)),
                           (slice(25, 40), slice(28, 40))):  # fmt: skip
            part = np.zeros_like(m)
            part[rows, cols] = m[rows, cols]
            np.testing.assert_array_equal(fill_gaps(part), ndimage.binary_fill_holes(part))
    assert not fill_gaps(np.zeros((5, 5), dtype=bool)).any()


def test_sensor_rays_are_the_pixel_centres():
    # Mitsuba's orthographic sensor framing the raster gives, at film position ((i + 0.5) / N,
    # (j + 0.5) / N), the ray through pixel (j, i)'s centre, also beyond the frame.
    import drjit as dr  # noqa: F401
    import mitsuba as mi

    from sieve_mi.geometry.raster import Frame

    frame = Frame(resolution=64, half_extent=12.5)
    j, i = np.meshgrid(np.arange(-10, 74), np.arange(-10, 74), indexing="ij")
    film = mi.Point2f(
        mi.Float(((i + 0.5) / 64).ravel().astype(np.float32)),
        mi.Float(((j + 0.5) / 64).ravel().astype(np.float32)),
    )
    ray, _ = frame.sensor().sample_ray(0.0, 0.5, film, mi.Point2f(0.5, 0.5))
    h = frame.pixel_size
    np.testing.assert_allclose(np.array(ray.o.x), (-12.5 + (i + 0.5) * h).ravel(), atol=1e-5)
    np.testing.assert_allclose(np.array(ray.o.y), (12.5 - (j + 0.5) * h).ravel(), atol=1e-5)
    np.testing.assert_allclose(np.array(ray.d.z), -1.0)


@pytest.mark.parametrize("mesh", ["box", "sphere", "torus"])
def test_silhouette_masks_match_an_independent_ray_caster(mesh):
    # The sensor-built masks against an independent point-in-projected-triangle test at the same
    # pixel centres, for a generic pose (no pixel centre on an edge), pixel for pixel.
    import trimesh

    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.geometry.raster import Frame
    from sieve_mi.geometry.rotations import random_uniform, to_matrix
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    m = {
        "box": lambda: trimesh.creation.box((14.0, 9.0, 5.0)),
        "sphere": lambda: trimesh.creation.icosphere(2, 7.0),
        "torus": lambda: trimesh.creation.torus(6.0, 2.0),
    }[mesh]()
    shape = shape_from_trimesh(m, name=mesh)
    q = random_uniform(1, np.random.default_rng(3))[0]
    t = np.array([0.37, -0.81])
    frame = Frame(resolution=48, half_extent=11.0)
    got = SilhouetteRenderer(shape).frame_mask(q, t, frame)
    x, y = frame.centres()
    xx, yy = np.meshgrid(x, y)
    # a vertical ray hits the mesh iff its (x, y) lies in some projected triangle
    tri = (shape.vertices @ to_matrix(q).T)[shape.faces][:, :, :2] + t
    p = np.column_stack([xx.ravel(), yy.ravel()])[:, None, :]
    a, b, c = tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    d1, d2, d3 = cross(b - a, p - a), cross(c - b, p - b), cross(a - c, p - c)
    inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
    hits = inside.any(axis=1).reshape(got.shape)
    assert got.any() and np.array_equal(got, hits)


@pytest.mark.parametrize("which", ["box", "sphere", "torus"])
def test_rendered_masks_equal_the_traced_ones(which):
    # mi.render with the silhouette integrator under the lattice's orthographic sensors gives the
    # masks that batched ray_test gives, pixel for pixel: on the whole frame and on windows that
    # reach beyond it, for random poses of three meshes.
    import trimesh

    from sieve_mi.geometry.meshes import shape_from_trimesh
    from sieve_mi.geometry.raster import Frame
    from sieve_mi.geometry.rotations import normalize
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    mesh = {
        "box": trimesh.creation.box([10.0, 14.0, 6.0]),
        "sphere": trimesh.creation.icosphere(3, 9.0),
        "torus": trimesh.creation.torus(8.0, 2.5),
    }[which]
    renderer = SilhouetteRenderer(shape_from_trimesh(mesh, name=which))
    frame = Frame(96, 15.0)
    rng = np.random.default_rng(7)
    covered = 0
    for _ in range(3):
        q, t = normalize(rng.normal(size=4)), rng.normal(size=2) * 3.0
        whole = renderer.render(q, t, frame)
        assert np.array_equal(whole, renderer.frame_mask(q, t, frame))
        covered += whole.sum()
        row0, col0 = rng.integers(-20, 60, size=2)
        window = renderer.render(q, t, frame, int(row0), int(col0), 50)
        traced = renderer.masks(q[None], t[None], frame, np.array([row0]), np.array([col0]), 50)
        assert np.array_equal(window, traced[0])
    assert covered > 1000  # the shapes are really on the film


def test_scoring_casts_each_ray_once_and_counts_pixels(cube20):
    # score_poses reduces one ray-casting pass three ways (area, outside, worst distance): one
    # thread per window row walks its pixels, casting each ray once, in one kernel; one more
    # kernel sums the rows per pose. A 12 mm sphere centred in a 40 mm square hole has no pixel
    # outside it (beta 0); moved 43 mm aside, beyond the frame's edge, it lies wholly outside the
    # hole (beta 1).
    import drjit as dr

    from sieve_mi.game.scoring import projection_windows, score_poses
    from sieve_mi.geometry.hole import Hole

    frame = Frame(96, 30.0)
    xc, yc = frame.centres()
    xx, yy = np.meshgrid(xc, yc)
    hole = Hole.from_mask((np.abs(xx) < 20) & (np.abs(yy) < 20), frame)
    renderer = SilhouetteRenderer(sphere(12.0, 4))
    quats = np.tile([1.0, 0, 0, 0], (2, 1))
    trans = np.array([[0.0, 0.0], [30.0 + 12.0 + 1.0, 0.0]])
    score_poses(renderer, hole, quats, trans)  # compile
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        scores = score_poses(renderer, hole, quats, trans)
        history = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    _, _, rows, cols = projection_windows(frame, *renderer.projected_extent(quats, trans))
    jit = [k for k in history if str(k["type"]).endswith("JIT")]
    walks = [k for k in jit if "rows" in k["ir"].getvalue()]  # the loop's label
    # one kernel walks the rows (one thread each) and casts; one more sums them and casts nothing
    assert len(walks) == 1 and walks[0]["size"] == int(rows.sum())
    # the one other kernel sums (scatter-reduces) the walk's results: LLVM IR and CUDA's PTX alike
    sums = [k for k in jit if k is not walks[0]]
    assert len(sums) == 1 and "reduce" in sums[0]["ir"].getvalue().lower()
    np.testing.assert_array_equal(scores.beta, [0.0, 1.0])
    assert scores.protrusion[0] == 0 and scores.protrusion[1] > 0


def _rectangles(frame, half_sides):
    """Holes on ``frame``: the centred rectangles |x| < a, |y| < b for each (a, b), scene units."""
    from sieve_mi.geometry.hole import Hole

    xx, yy = np.meshgrid(*frame.centres())
    return [Hole.from_mask((np.abs(xx) < a) & (np.abs(yy) < b), frame) for a, b in half_sides]


def test_projection_windows_score_like_the_bounding_disk_squares():
    # A 40 x 30 x 4 mm slab at random poses against three rectangular holes: windows around each
    # projection's bounding box see the same covered pixels as the squares around the bounding
    # disk (side 2 x 25.2 mm), so beta and protrusion agree to the bit, with fewer rays: seen
    # face-on the box is 40 x 30 mm, edge-on 40 x 4 mm.
    from sieve_mi.game.scoring import projection_windows, score_poses, window_for
    from sieve_mi.geometry.rotations import random_uniform

    slab = shape_from_trimesh(trimesh.creation.box((40.0, 30.0, 4.0)), name="slab")
    renderer = SilhouetteRenderer(slab)
    frame = Frame(128, 30.0)
    holes = _rectangles(frame, [(21.0, 16.0), (21.0, 3.0), (5.0, 5.0)])
    rng = np.random.default_rng(3)
    quats = np.vstack([[1.0, 0, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0, 0], random_uniform(60, rng)])
    trans = np.vstack([[0.0, 0.0], [0.0, 0.0], rng.uniform(-3.0, 3.0, (60, 2))])
    which = np.concatenate([[0, 1], rng.integers(0, 3, 60)])
    got = score_poses(renderer, holes, quats, trans, pose_hole=which)
    want, _ = score_poses(renderer, holes, quats, trans, pose_hole=which, return_masks=True)
    np.testing.assert_array_equal(got.beta, want.beta)
    np.testing.assert_array_equal(got.protrusion, want.protrusion)
    assert got.beta[0] == 0 and got.beta[1] == 0 and (got.beta[2:] > 0).any()
    _, _, rows, cols = projection_windows(frame, *renderer.projected_extent(quats, trans))
    side = window_for(renderer, frame, trans)[2]
    h = frame.pixel_size
    # each window is its box plus at most two pixels on either side
    for got_side, box_side in [(rows[0], 30.0), (cols[0], 40.0), (rows[1], 4.0), (cols[1], 40.0)]:
        assert box_side <= got_side * h <= box_side + 5 * h
    assert (rows * cols).sum() < 0.7 * len(quats) * side * side


@pytest.mark.parametrize("sizes", ["mixed", "with empty windows", "all one pixel"])
def test_trace_numbers_every_window_pixel(sizes):
    # Each traced entry's pose, row and column, against NumPy's expansion of the windows: pose k's
    # rows[k] x cols[k] pixels from (row0[k], col0[k]), row by row, after the earlier windows'.
    # The pose comes from a table of buckets no longer than the smallest window (an entry's
    # window is its bucket's first or the next), so windows of 1 pixel, of none and of 37 x 250
    # are mixed here.
    rng = np.random.default_rng(4)
    k = 40
    rows, cols = rng.integers(1, 40, k), rng.integers(1, 260, k)
    if sizes == "with empty windows":
        rows[[3, 4, 17]] = 0
    if sizes == "all one pixel":
        rows[:], cols[:] = 1, 1
    row0, col0 = rng.integers(-20, 100, k), rng.integers(-20, 100, k)
    renderer = SilhouetteRenderer(sphere(5.0, 2))
    quats = np.tile([1.0, 0, 0, 0], (k, 1))
    _, pose, row, col = renderer.trace(
        quats, np.zeros((k, 2)), Frame(64, 10.0), row0, col0, rows, cols
    )
    want_pose = np.repeat(np.arange(k), rows * cols)
    local = np.concatenate([np.arange(r * c) for r, c in zip(rows, cols)])
    width = cols[want_pose]
    np.testing.assert_array_equal(np.asarray(pose), want_pose)
    np.testing.assert_array_equal(np.asarray(row), row0[want_pose] + local // width)
    np.testing.assert_array_equal(np.asarray(col), col0[want_pose] + local % width)


def _sphere_and_cube():
    """A 20 mm ball at the origin and a 6 mm cube 20 mm to its right (two closed parts): the
    shape's centre (its box's) lies off the ball's, so the core is off-centre."""
    ball = trimesh.creation.icosphere(4, 10.0)
    cube = trimesh.creation.box((6.0, 6.0, 6.0))
    cube.apply_translation([20.0, 0.0, 0.0])
    return shape_from_trimesh(trimesh.util.concatenate([ball, cube]), name="ball+cube")


@pytest.mark.parametrize("which", ["sphere", "box", "ball+cube"])
def test_a_core_scores_every_pose_like_the_rays(which):
    # A ray through the shadow of a ball inside the closed solid enters the ball, so it hits:
    # with that ball as the renderer's core no ray is cast there, and every pose scores to the
    # same bit against three holes (120 random poses). The shapes: a 24 mm icosphere (its ball,
    # radius > 11.9 mm, covers nearly every covered pixel), a 20 x 20 x 14 mm box (ball radius 7)
    # and a ball with a cube beside it (the core off the shape's centre). A ball that is too big
    # (30 mm) is no core: it changes the scores, so the comparison can fail.
    from sieve_mi.certify.bounds import inscribed_ball
    from sieve_mi.game.scoring import core_ball, score_poses
    from sieve_mi.geometry.rotations import random_uniform

    shape = {
        "sphere": lambda: sphere(12.0, 4),
        "box": lambda: shape_from_trimesh(trimesh.creation.box((20.0, 20.0, 14.0)), name="box"),
        "ball+cube": _sphere_and_cube,
    }[which]()
    ball = inscribed_ball(shape)
    assert ball is not None
    frame = Frame(128, 30.0)
    holes = _rectangles(frame, [(11.5, 11.5), (13.0, 9.0), (20.0, 20.0)])
    rng = np.random.default_rng(11)
    quats = random_uniform(120, rng)
    trans = rng.uniform(-4.0, 4.0, (120, 2))
    which_hole = rng.integers(0, 3, 120)
    plain = SilhouetteRenderer(shape)
    want = score_poses(plain, holes, quats, trans, pose_hole=which_hole)
    cored = SilhouetteRenderer(shape)
    cored.core = ball
    got = score_poses(cored, holes, quats, trans, pose_hole=which_hole)
    np.testing.assert_array_equal(got.beta, want.beta)
    np.testing.assert_array_equal(got.protrusion, want.protrusion)
    assert 0 < (want.beta > 0).sum() < len(quats)
    cored.core = (ball[0], 30.0)
    assert (score_poses(cored, holes, quats, trans, pose_hole=which_hole).beta > want.beta).any()
    if which == "sphere":  # the icosphere's inscribed ball is nearly the sphere: a core
        assert 11.9 < ball[1] <= 12.0 and core_ball(shape) is not None
    if which == "box":  # radius 7 of a 15.8 mm radius: too small to pay, no core by default
        assert abs(ball[1] - 7.0) < 0.5 and core_ball(shape) is None


def _union_of_triangles(vertices, faces):
    """Ground truth for a projection: shapely's union of the projected triangles."""
    import shapely

    tris = [shapely.Polygon(t[:, :2]) for t in np.asarray(vertices)[faces]]
    return shapely.union_all([t for t in tris if t.area > 1e-15])


@pytest.mark.parametrize("closed", [True, False])
def test_projection_from_boundary_loops_is_the_union_of_the_triangles(closed):
    # A closed sphere at an odd rotation: its front faces' boundary is its silhouette, a disk of
    # radius 12 (up to the polygonal outline); with every triangle (closed=False) the front and
    # back faces' boundaries both remain and still fill exactly the same region.
    from sieve_mi.geometry.outline import placed_vertices, projection

    s = sphere(12.0)
    v = placed_vertices(
        s, np.array([0.9, 0.3, -0.2, 0.1]) / np.linalg.norm([0.9, 0.3, -0.2, 0.1]), [3.0, -1.0]
    )
    got = projection(v, s.faces, closed=closed)
    want = _union_of_triangles(v, s.faces)
    assert got.area() == pytest.approx(want.area, rel=1e-9)
    assert got.area() == pytest.approx(np.pi * 12.0**2, rel=0.01)


def test_projection_counts_overlapping_folds_once():
    # Two unit squares (two triangles each) that overlap by half and share no vertex, plus a
    # triangle folded back over the first square: the union is 1.5 (a 1 x 1.5 rectangle), which
    # a boundary chain with multiplicities must reproduce.
    from sieve_mi.geometry.outline import boundary_loops, projection

    v = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
         [0, 0.5, 0], [1, 0.5, 0], [1, 1.5, 0], [0, 1.5, 0], [0.5, 0.5, 1.0]],
        dtype=float,
    )  # fmt: skip
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [0, 8, 1]])
    assert projection(v, f).area() == pytest.approx(1.5, rel=1e-12)
    # The first square's two triangles share their diagonal, which cancels: one loop of 4.
    assert sorted(len(loop) for loop in boundary_loops(f[:2], np.zeros(2, bool))) == [4]
