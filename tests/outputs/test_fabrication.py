"""Known-answer tests for the exact hole outline and the printable plate (sieve_mi.outputs.fabrication).

Areas are argued on paper: a cube of side a projects to an a x a square face-on and to a regular
hexagon of area sqrt(3) a^2 along its body diagonal; a square of side s grown by r has area
s^2 + 4 s r + pi r^2; a plate of W x D x T with a hole of area A has volume (W D - A) T.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.geometry import outline
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import align, from_axis_angle
from sieve_mi.outputs import fabrication as fab
from sieve_mi.testing.mesh_io import read_3mf
from sieve_mi.testing.shapes import to_manifold


def sym_diff(a: manifold3d.CrossSection, b: manifold3d.CrossSection) -> float:
    """Area of the symmetric difference (manifold3d's ``^`` is the intersection)."""
    return (a - b).area() + (b - a).area()


def cube_shape(a: float = 10.0):
    return shape_from_trimesh(trimesh.creation.box((a, a, a)), name="cube")


def test_projection_of_a_cube_face_on_and_along_its_diagonal():
    a = 10.0
    cube = cube_shape(a)
    face = outline.projection(outline.placed_vertices(cube, [1, 0, 0, 0], [0, 0]), cube.faces)
    assert face.area() == pytest.approx(a * a, rel=1e-9)
    # body diagonal (1, 1, 1) turned onto z: a regular hexagon of area sqrt(3) a^2
    q = align(np.array([1.0, 1.0, 1.0]) / math.sqrt(3), np.array([0.0, 0.0, 1.0]))
    hexagon = outline.projection(outline.placed_vertices(cube, q, [0, 0]), cube.faces)
    assert hexagon.area() == pytest.approx(math.sqrt(3) * a * a, rel=1e-9)
    assert hexagon.num_vert() == 6
    # the front-facing shortcut for closed meshes gives the same region
    closed = outline.projection(outline.placed_vertices(cube, q, [0, 0]), cube.faces, closed=True)
    assert sym_diff(closed, hexagon) == pytest.approx(0.0, abs=1e-9)


def test_projection_of_a_triangle_soup_with_mixed_winding_is_the_union():
    # two unit right triangles forming the unit square, wound opposite ways, plus an edge-on one
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1]], dtype=float)
    f = np.array([[0, 1, 2], [0, 3, 2], [0, 1, 5]])
    sec = outline.projection(v, f)
    assert sec.area() == pytest.approx(1.0, rel=1e-12)
    # overlapping triangles: union, not sum (two copies of the same triangle)
    f2 = np.array([[0, 1, 2], [2, 1, 0]])
    assert outline.projection(v, f2).area() == pytest.approx(0.5, rel=1e-12)
    # everything edge-on: empty
    assert outline.projection(v, np.array([[0, 1, 5]])).is_empty()


def test_dilation_contains_the_exact_offset_and_stays_close():
    s, r = 10.0, 1.0
    square = manifold3d.CrossSection.square([s, s], center=True)
    grown = outline.dilated(square, r)
    exact = s * s + 4 * s * r + math.pi * r * r
    assert (
        exact
        <= grown.area()
        <= exact * 1.0
        + (outline.ARC_ERROR * 1.1 + 2 * outline.SIMPLIFY) * r * (4 * s + 2 * math.pi * r)
    )
    pts = np.vstack(grown.to_polygons())
    # every vertex lies at distance >= r from the square (never inward of the exact dilation) ...
    dx = np.maximum(np.abs(pts[:, 0]) - s / 2, 0)
    dy = np.maximum(np.abs(pts[:, 1]) - s / 2, 0)
    dist = np.hypot(dx, dy)
    assert dist.min() >= r - 1e-9
    # ... and within a few per cent of the tolerance from it
    assert dist.max() <= r * (1 + outline.ARC_ERROR * 1.1 + 2 * outline.SIMPLIFY)
    assert outline.dilated(square, 0.0).area() == pytest.approx(s * s)


def test_filled_removes_enclosed_gaps():
    ring = manifold3d.CrossSection.circle(10.0, 128) - manifold3d.CrossSection.circle(5.0, 128)
    disk = outline.filled(ring)
    assert disk.area() == pytest.approx(manifold3d.CrossSection.circle(10.0, 128).area(), rel=1e-9)
    assert len(disk.to_polygons()) == 1


def test_hole_outline_of_two_cubes_is_their_dilated_union():
    a, r = 10.0, 0.5
    cube = cube_shape(a)
    quats = np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]])
    trans = np.array([[0.0, 0.0], [a, 0.0]])  # side by side: a 2a x a rectangle
    out = outline.hole_outline([cube, cube], quats, trans, r)
    exact = 2 * a * a + 2 * (3 * a) * r + math.pi * r * r
    assert out.area() == pytest.approx(exact, rel=0.01)
    assert out.area() >= exact
    assert len(out.to_polygons()) == 1


def test_outline_agrees_with_a_raster_of_it():
    cube = cube_shape(10.0)
    q = from_axis_angle(np.array([0.3, 1.0, 0.2]), 0.7)
    out = outline.hole_outline([cube], q[None], np.zeros((1, 2)), 1.0)
    frame = Frame.covering(12.0, 256)
    mask = outline.rasterize(out, frame)
    agree = outline.raster_agreement(out, mask, frame)
    # same region sampled at pixel centres: areas agree to within the boundary's pixels
    perimeter = 60.0
    assert abs(agree["polygon_area"] - agree["raster_area"]) < perimeter * frame.pixel_size
    assert agree["pixels_only_raster"] == 0 and agree["pixels_only_polygon"] == 0


def _holes_of(mesh: trimesh.Trimesh, z: float) -> manifold3d.CrossSection:
    """Holes of the plate's cross-section at height z: filled outline minus material."""
    body = to_manifold(mesh)
    section = body.slice(z)
    return outline.filled(section) - section


def test_plate_is_one_watertight_body_with_the_hole_through_it():
    a, r, t, border = 10.0, 1.0, 18.0, 6.0
    cube = cube_shape(a)
    q = from_axis_angle(np.array([1.0, 2.0, 0.5]), 0.9)
    H = outline.hole_outline([cube], q[None], np.zeros((1, 2)), r)
    plate = fab.plate(H, t, border)
    m = plate.mesh
    assert m.is_watertight and m.is_winding_consistent and m.is_volume
    assert len(m.split(only_watertight=False)) == 1
    (x0, y0, z0), (x1, y1, z1) = m.bounds
    assert z0 == pytest.approx(-t) and z1 == pytest.approx(0.0, abs=1e-9)
    (ox0, oy0), (ox1, oy1) = fab._bounds(H)
    assert x1 - x0 == pytest.approx(ox1 - ox0 + 2 * border, rel=1e-6)
    assert m.volume == pytest.approx(((x1 - x0) * (y1 - y0) - H.area()) * t, rel=1e-6)
    # the hole at several depths is H itself
    for z in (-0.1, -t / 2, -t + 0.1):
        holes = _holes_of(m, z)
        assert holes.area() == pytest.approx(H.area(), rel=1e-6)
        assert sym_diff(holes, H) < 1e-6 * H.area()
    assert plate.warnings == []


def test_thin_plate_warns_about_wriggling():
    outline = manifold3d.CrossSection.square([10, 10], center=True)
    plate = fab.plate(outline, 5.0, 3.0, required_thickness=17.4)
    assert len(plate.warnings) == 1
    assert "17.4" in plate.warnings[0] and "motion search" in plate.warnings[0]


def test_3mf_round_trip(tmp_path):
    outline = manifold3d.CrossSection.circle(5.0, 32)
    mesh = fab.plate(outline, 4.0, 2.0).mesh
    path = str(tmp_path / "p.3mf")
    fab.write_3mf(path, mesh)
    back = read_3mf(path)
    np.testing.assert_allclose(back.vertices, mesh.vertices, rtol=1e-8, atol=1e-8)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    assert back.is_watertight


def test_svg_outline_is_written(tmp_path):
    outline = manifold3d.CrossSection.square([10, 4], center=True)
    path = tmp_path / "h.svg"
    fab.write_svg(str(path), outline, "mm")
    text = path.read_text()
    assert 'width="11mm"' in text and 'fill-rule="evenodd"' in text
    assert text.count("M ") == 1


def test_shape_mesh_is_lifted_above_the_plate():
    cube = cube_shape(10.0)
    q = from_axis_angle(np.array([1.0, 1.0, 0.0]), 0.5)
    m = fab.shape_mesh(cube, q, np.array([3.0, -2.0]), 2.5)
    assert m.bounds[0, 2] == pytest.approx(2.5)
    assert m.volume == pytest.approx(1000.0)
    c = 0.5 * (m.bounds[0] + m.bounds[1])
    assert c[:2] == pytest.approx([3.0, -2.0])


def test_shapes_beside_the_plate_stand_on_its_ground_without_touching_it():
    from sieve_mi.outputs.fabrication import beside_plate

    plate = trimesh.creation.box(extents=(40.0, 30.0, 10.0))
    plate.apply_translation((0.0, 0.0, -5.0))  # top at z = 0, bottom at z = -10
    a = trimesh.creation.icosphere(radius=3.0)
    a.apply_translation((0.0, 0.0, 50.0))
    b = trimesh.creation.box(extents=(4.0, 4.0, 4.0))
    moved = beside_plate(plate, [a, b], gap=2.0)
    assert [m.bounds[0, 2] for m in moved] == pytest.approx([-10.0, -10.0])
    assert moved[0].bounds[0, 0] == pytest.approx(22.0)  # plate ends at x = 20, then the gap
    assert moved[1].bounds[0, 0] == pytest.approx(moved[0].bounds[1, 0] + 2.0)
    assert moved[0].bounds[:, 1].mean() == pytest.approx(0.0, abs=1e-9)


def test_several_a_are_stacked_in_the_figure_not_overlapping():
    """Three 20 mm cubes over one hole: the first stays, each next one sits 2 mm above the one
    before, all over the same xy (the hole)."""
    cubes = [trimesh.creation.box([20, 20, 20]).apply_translation([1, 2, 15]) for _ in range(3)]
    out = fab.stacked(cubes, 2.0)
    lows = [m.bounds[0, 2] for m in out]
    assert lows == pytest.approx([5.0, 27.0, 49.0])
    assert all(np.allclose(m.bounds[:, :2], cubes[0].bounds[:, :2]) for m in out)
    assert cubes[1].bounds[0, 2] == pytest.approx(5.0)  # the inputs are left as they were
