"""Known-answer tests for the generated test shapes (sieve_mi.testing.shapes) and scenes/meshes/.

Expected values are argued from geometry (volumes of prisms, spheres, trapezoids; Euler
characteristic of closed surfaces), never copied from a run of the code.
"""

from __future__ import annotations

import importlib.util
import math
import os

import numpy as np
import pytest
import trimesh
from helpers import REPO
from scipy.spatial import cKDTree

from sieve_mi.testing import catalogue, shapes

REPO = REPO
MESH_DIR = os.path.join(REPO, "scenes", "meshes")
#: Real meshes shared beside the checkout (../shared/meshes), or where $SIEVE_MI_SHARED_MESHES says.
SHARED_MESHES = os.environ.get(
    "SIEVE_MI_SHARED_MESHES", os.path.join(os.path.dirname(REPO), "shared", "meshes")
)


def shoelace(points: np.ndarray) -> float:
    """Signed area of a closed polygon (positive when counter-clockwise)."""
    x, y = np.asarray(points, dtype=float).T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def contains(mesh: trimesh.Trimesh, points) -> np.ndarray:
    """Inside test by the generalised winding number (sum of signed solid angles / 4 pi).

    Written out here so the test needs no spatial index (trimesh's ``contains`` wants rtree).
    """
    p = np.asarray(points, dtype=float)
    tri = mesh.triangles[None, :, :, :] - p[:, None, None, :]  # (P, F, 3, 3)
    a, b, c = tri[:, :, 0], tri[:, :, 1], tri[:, :, 2]
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    den = (
        la * lb * lc
        + np.einsum("pfi,pfi->pf", a, b) * lc
        + np.einsum("pfi,pfi->pf", b, c) * la
        + np.einsum("pfi,pfi->pf", c, a) * lb
    )
    winding = 2.0 * np.arctan2(det, den).sum(axis=1) / (4.0 * np.pi)
    return np.abs(winding) > 0.5


def assert_solid(mesh: trimesh.Trimesh) -> None:
    """Closed, consistently wound, positive volume, one connected body, centred."""
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.is_volume
    assert mesh.volume > 0
    assert mesh.body_count == 1
    assert len(mesh.split(only_watertight=False)) == 1
    np.testing.assert_allclose(mesh.bounds.mean(axis=0), 0.0, atol=1e-9)


def genus(mesh: trimesh.Trimesh) -> float:
    """Genus of a closed orientable surface from V - E + F = 2 - 2g."""
    return (2 - mesh.euler_number) / 2


def load_generator():
    spec = importlib.util.spec_from_file_location(
        "make_scene_meshes", os.path.join(REPO, "tools", "make_scene_meshes.py")
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --------------------------------------------------------------------------------------------
# Boxes and cubes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("side", [1.0, 20.0, 37.5])
def test_cube_volume_is_side_cubed(side):
    mesh = shapes.cube(side)
    assert_solid(mesh)
    assert len(mesh.faces) == 12 and len(mesh.vertices) == 8
    assert mesh.volume == pytest.approx(side**3, rel=1e-12)
    assert mesh.area == pytest.approx(6 * side**2, rel=1e-12)
    np.testing.assert_allclose(mesh.bounds, [[-side / 2] * 3, [side / 2] * 3], atol=1e-12)


def test_cube_default_side_is_20mm():
    np.testing.assert_allclose(shapes.cube().extents, [20, 20, 20])


def test_box_extents_and_volume():
    mesh = shapes.box(12.0, 7.0, 30.0)
    assert_solid(mesh)
    np.testing.assert_allclose(mesh.extents, [12, 7, 30], atol=1e-12)
    assert mesh.volume == pytest.approx(12 * 7 * 30, rel=1e-12)
    # every vertex is a corner (+-x/2, +-y/2, +-z/2)
    np.testing.assert_allclose(np.abs(mesh.vertices), np.tile([6.0, 3.5, 15.0], (8, 1)), atol=1e-12)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_box_rejects_non_positive_sizes(bad):
    with pytest.raises(ValueError):
        shapes.box(1.0, bad, 1.0)
    with pytest.raises(ValueError):
        shapes.cube(bad)


# --------------------------------------------------------------------------------------------
# Sphere
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("radius", [9.0, 12.0])
def test_sphere_vertices_on_radius_and_volume_just_below_ball(radius):
    mesh = shapes.sphere(radius)
    assert_solid(mesh)
    assert mesh.is_convex
    np.testing.assert_allclose(np.linalg.norm(mesh.vertices, axis=1), radius, rtol=1e-12)
    ball = 4 / 3 * math.pi * radius**3
    # inscribed polytope: strictly inside the ball, but within a few percent of it
    assert mesh.volume < ball
    assert mesh.volume > 0.97 * ball
    # and it contains the ball of radius = smallest distance from the centre to a face plane
    r_in = float(np.min(np.abs(np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles[:, 0]))))
    assert mesh.volume >= 4 / 3 * math.pi * r_in**3
    np.testing.assert_allclose(mesh.extents, 2 * radius, rtol=1e-12)


@pytest.mark.parametrize("subdivisions", [0, 1, 2, 3])
def test_sphere_face_count_quadruples_per_subdivision(subdivisions):
    # the icosahedron has 20 faces; each subdivision splits every triangle into 4
    mesh = shapes.sphere(5.0, subdivisions)
    assert len(mesh.faces) == 20 * 4**subdivisions
    assert genus(mesh) == 0


def test_sphere_default_is_small():
    mesh = shapes.sphere()
    assert len(mesh.faces) <= 2000
    np.testing.assert_allclose(np.linalg.norm(mesh.vertices, axis=1), 12.0, rtol=1e-12)


def test_sphere_converges_to_ball_volume():
    ball = 4 / 3 * math.pi
    errors = [ball - shapes.sphere(1.0, s).volume for s in range(4)]
    assert all(e > 0 for e in errors)
    assert all(b < a for a, b in zip(errors, errors[1:]))


# --------------------------------------------------------------------------------------------
# extrude_polygon
# --------------------------------------------------------------------------------------------


def test_extrude_polygon_square_either_winding():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=float)
    for pts in (square, square[::-1]):
        mesh = shapes.extrude_polygon(pts, 4.0)
        assert_solid(mesh)
        assert mesh.volume == pytest.approx(400.0, rel=1e-12)
        np.testing.assert_allclose(mesh.extents, [10, 10, 4], atol=1e-12)


def test_extrude_polygon_concave_l_shape():
    ell = np.array([[0, 0], [6, 0], [6, 2], [2, 2], [2, 5], [0, 5]], dtype=float)
    area = 6 * 2 + 2 * 3  # bottom bar plus upright
    assert abs(shoelace(ell)) == pytest.approx(area)
    mesh = shapes.extrude_polygon(ell, 3.0)
    assert_solid(mesh)
    assert genus(mesh) == 0
    assert mesh.volume == pytest.approx(area * 3.0, rel=1e-12)


def test_extrude_rejects_bad_depth_and_empty_polygon():
    tri = np.array([[0, 0], [1, 0], [0, 1]], dtype=float)
    with pytest.raises(ValueError):
        shapes.extrude_polygon(tri, 0.0)
    with pytest.raises(ValueError):
        shapes.extrude_polygon(np.array([[0, 0], [1, 0], [2, 0]], dtype=float), 1.0)


def test_manifold_round_trip_and_rejects_open_mesh():
    mesh = shapes.box(3.0, 4.0, 5.0)
    back = shapes.from_manifold(shapes.to_manifold(mesh))
    assert back.volume == pytest.approx(60.0, rel=1e-12)
    open_mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[:-1], process=False)
    with pytest.raises(ValueError):
        shapes.to_manifold(open_mesh)


# --------------------------------------------------------------------------------------------
# Bowtie
# --------------------------------------------------------------------------------------------


def test_bowtie_volume_is_two_trapezoids_times_thickness():
    w, h, t, s = 30.0, 20.0, 6.0, 6.0
    mesh = shapes.bowtie(width=w, height=h, thickness=t, waist=s)
    assert_solid(mesh)
    assert genus(mesh) == 0
    # each half is a trapezoid of width w/2 with parallel sides h and s
    trapezoids = 2 * (w / 2) * (h + s) / 2
    own_polygon = np.array(
        [
            [-w / 2, -h / 2],
            [0, -s / 2],
            [w / 2, -h / 2],
            [w / 2, h / 2],
            [0, s / 2],
            [-w / 2, h / 2],
        ]
    )
    assert abs(shoelace(own_polygon)) == pytest.approx(trapezoids)
    assert mesh.volume == pytest.approx(trapezoids * t, rel=1e-12)
    np.testing.assert_allclose(mesh.extents, [w, h, t], atol=1e-12)


def test_bowtie_is_narrow_at_the_waist():
    w, h, t, s = 30.0, 20.0, 6.0, 6.0
    mesh = shapes.bowtie(width=w, height=h, thickness=t, waist=s)
    inside = contains(
        mesh, [[0, s / 2 - 0.5, 0], [w / 2 - 0.5, h / 2 - 0.5, 0], [-w / 2 + 0.5, -h / 2 + 0.5, 0]]
    )
    outside = contains(mesh, [[0, s / 2 + 0.5, 0], [0, -s / 2 - 0.5, 0], [0, 0, t / 2 + 0.5]])
    assert inside.all()
    assert not outside.any()


def test_bowtie_rejects_waist_not_narrower_than_height():
    with pytest.raises(ValueError):
        shapes.bowtie(width=30, height=20, thickness=6, waist=20)
    with pytest.raises(ValueError):
        shapes.bowtie(width=30, height=20, thickness=6, waist=0)


# --------------------------------------------------------------------------------------------
# Arch
# --------------------------------------------------------------------------------------------


def test_arch_volume_is_polygon_area_times_depth():
    w, h, t, d, n = 30.0, 20.0, 6.0, 10.0, 16
    r = w / 2 - t
    mesh = shapes.arch(width=w, height=h, thickness=t, depth=d, segments=n)
    assert_solid(mesh)
    assert genus(mesh) == 0
    np.testing.assert_allclose(mesh.extents, [w, h, d], atol=1e-12)
    # the test's own outline: rectangle corners plus n chords on the semicircle
    ang = np.pi - np.pi * np.arange(n + 1) / n
    arc = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    own = np.vstack([[[-w / 2, 0]], arc, [[w / 2, 0], [w / 2, h], [-w / 2, h]]])
    assert mesh.volume == pytest.approx(abs(shoelace(own)) * d, rel=1e-9)
    # equivalently: rectangle minus n isosceles triangles of apex angle pi/n
    assert mesh.volume == pytest.approx(
        (w * h - n * 0.5 * r * r * math.sin(math.pi / n)) * d, rel=1e-9
    )


def test_arch_has_the_semicircle_removed():
    w, h, t, d, n = 30.0, 20.0, 6.0, 10.0, 16
    r = w / 2 - t
    mesh = shapes.arch(width=w, height=h, thickness=t, depth=d, segments=n)
    true_half_disk = math.pi * r * r / 2
    exact = (w * h - true_half_disk) * d
    # chords cut off slightly less than the half disk: a bit more volume, by under 1% of it
    assert exact < mesh.volume < exact + 0.01 * true_half_disk * d
    # far from the full rectangle
    assert mesh.volume < w * h * d - 0.99 * true_half_disk * d
    # point in the opening vs points in the crown and legs (bottom edge at y = -h/2)
    y0 = -h / 2
    assert not contains(mesh, [[0, y0 + r / 2, 0]]).any()
    assert not contains(mesh, [[0, y0 + r - 0.5, 0]]).any()
    assert contains(
        mesh, [[0, y0 + r + 0.5, 0], [w / 2 - t / 2, y0 + 0.5, 0], [-(w / 2 - t / 2), y0 + 0.5, 0]]
    ).all()


def test_arch_rejects_impossible_proportions():
    with pytest.raises(ValueError):
        shapes.arch(width=30, height=20, thickness=15, depth=10)  # no opening left
    with pytest.raises(ValueError):
        shapes.arch(width=30, height=9, thickness=6, depth=10)  # opening radius 9 >= height


# --------------------------------------------------------------------------------------------
# Letters
# --------------------------------------------------------------------------------------------

HOLES = {"S": 0, "I": 0, "G": 0, "H": 0, "R": 1, "A": 1, "P": 1}


@pytest.mark.parametrize("char", sorted(HOLES))
def test_letter_is_one_watertight_body_of_right_size_and_genus(char):
    mesh = shapes.letter(char, height=30.0, depth=8.0)
    assert_solid(mesh)
    assert mesh.extents[1] == pytest.approx(30.0, rel=0.01)
    assert mesh.extents[2] == pytest.approx(8.0, rel=1e-9)
    # one hole through the plate (A, P, R) makes a genus-1 surface: V - E + F = 0
    assert mesh.euler_number == 2 - 2 * HOLES[char]
    assert genus(mesh) == HOLES[char]


@pytest.mark.parametrize("char", sorted(HOLES))
def test_letter_volume_is_outline_area_minus_holes_times_depth(char):
    contours = shapes.glyph_contours(char)
    assert len(contours) == 1 + HOLES[char]
    # holes are wound opposite to the outer boundary in a TrueType font, so the signed areas sum
    # to outer minus holes; compare with the mesh (filling a hole would add its area)
    areas = [shoelace(c) for c in contours]
    if HOLES[char]:
        assert np.sign(areas[0]) != np.sign(areas[1])
    net = abs(sum(areas))
    assert net < sum(abs(a) for a in areas) or not HOLES[char]
    ys = np.concatenate([c[:, 1] for c in contours])
    scale = 30.0 / (ys.max() - ys.min())
    mesh = shapes.letter(char, height=30.0, depth=8.0)
    assert mesh.volume == pytest.approx(net * scale**2 * 8.0, rel=1e-6)


def test_letter_scales_uniformly_with_height():
    small, big = (
        shapes.letter("R", height=30.0, depth=8.0),
        shapes.letter("R", height=60.0, depth=8.0),
    )
    np.testing.assert_allclose(big.extents[:2], 2 * small.extents[:2], rtol=1e-9)
    assert big.volume == pytest.approx(4 * small.volume, rel=1e-9)


def test_letter_I_is_a_box():
    # a sans-serif bold "I" is a plain rectangle: 8 vertices, volume = x * y * depth
    mesh = shapes.letter("I", height=30.0, depth=8.0)
    assert len(mesh.vertices) == 8
    assert mesh.volume == pytest.approx(np.prod(mesh.extents), rel=1e-9)


def test_letter_rejects_bad_input():
    with pytest.raises(ValueError):
        shapes.letter("AB")
    with pytest.raises(ValueError):
        shapes.letter(" ")
    with pytest.raises(ValueError):
        shapes.letter("A", font="No Such Font Family 12345")


# --------------------------------------------------------------------------------------------
# scenes/meshes: generated STL files and copied meshes
# --------------------------------------------------------------------------------------------

# known sizes (mm) from the scene-mesh brief, independent of the generator
EXPECTED_EXTENTS = {
    "cube.stl": (20, 20, 20),
    "sphere.stl": (24, 24, 24),
    "small_sphere.stl": (18, 18, 18),
    "prism.stl": (12, 12, 30),
}
SIMPLE = ["cube.stl", "sphere.stl", "small_sphere.stl", "l_rod.stl", "bowtie.stl", "arch.stl",
          "prism.stl"]  # fmt: skip
LETTER_FILES = [f"letter_{c}.stl" for c in "SIGRAPH"]
COIN_FILES = [f"coin_{c}.stl" for c in ("2eur", "1eur", "50c", "20c", "10c", "5c", "2c", "1c")]
# toy bricks and cells (sieve_mi.testing.catalogue; tests/testing/test_catalogue.py)
CATALOGUE_FILES = ["brick_1x2.stl", "brick_2x2.stl", "brick_2x4.stl", "cell_aaa.stl", "cell_aa.stl"]
# scenes/m3-vs-m4.toml, scenes/nuts-shaken.toml
HARDWARE_FILES = ["nut_m3.stl", "nut_m4.stl", "nut_m5.stl", "washer_m3.stl"]


@pytest.fixture(scope="module")
def generated():
    return load_generator().build()


def test_generator_covers_expected_files(generated):
    assert set(generated) == set(SIMPLE) | set(LETTER_FILES) | set(COIN_FILES) | set(
        CATALOGUE_FILES
    ) | set(HARDWARE_FILES)


@pytest.mark.parametrize(
    "name", SIMPLE + LETTER_FILES + COIN_FILES + CATALOGUE_FILES + HARDWARE_FILES
)
def test_stl_file_loads_and_matches_generator(name, generated):
    path = os.path.join(MESH_DIR, name)
    with open(path, "rb") as f:
        header = f.read(84)
    n_faces = int(np.frombuffer(header[80:84], dtype="<u4")[0])
    assert os.path.getsize(path) == 84 + 50 * n_faces  # binary STL layout
    loaded = trimesh.load(path, force="mesh")
    fresh = generated[name]
    assert n_faces == len(fresh.faces) == len(loaded.faces)
    assert loaded.is_watertight and loaded.body_count == 1
    # same vertex set (STL stores float32) and same volume
    tol = 1e-5 * float(fresh.extents.max())
    assert len(loaded.vertices) == len(fresh.vertices)
    assert cKDTree(fresh.vertices).query(loaded.vertices)[0].max() < tol
    assert cKDTree(loaded.vertices).query(fresh.vertices)[0].max() < tol
    assert loaded.volume == pytest.approx(fresh.volume, rel=1e-5)


@pytest.mark.parametrize("name", SIMPLE)
def test_simple_stl_files_are_small(name):
    assert trimesh.load(os.path.join(MESH_DIR, name), force="mesh").faces.shape[0] <= 2000


@pytest.mark.parametrize("name", sorted(EXPECTED_EXTENTS))
def test_stl_known_sizes(name):
    mesh = trimesh.load(os.path.join(MESH_DIR, name), force="mesh")
    np.testing.assert_allclose(mesh.extents, EXPECTED_EXTENTS[name], rtol=1e-6)


@pytest.mark.parametrize("name", LETTER_FILES)
def test_letter_stl_height_and_depth(name):
    mesh = trimesh.load(os.path.join(MESH_DIR, name), force="mesh")
    np.testing.assert_allclose(
        mesh.extents[1:], [30.0, 12.0], rtol=1e-6
    )  # tools/make_scene_meshes.py: height 30, depth 12


def test_stl_files_are_byte_identical_to_a_fresh_run():
    assert load_generator().main(["--check"]) == 0


@pytest.mark.parametrize("name", ["spot.obj", "cow.obj", "suzanne.obj", "alligator.obj"])
def test_copied_meshes_present_unchanged_and_documented(name):
    path = os.path.join(MESH_DIR, name)
    mesh = trimesh.load(path, force="mesh", process=False)
    assert len(mesh.faces) > 0
    with open(os.path.join(MESH_DIR, "SOURCES.md"), encoding="utf-8") as f:
        assert name in f.read()
    shared = os.path.join(SHARED_MESHES, name)
    if os.path.exists(shared):
        with open(path, "rb") as a, open(shared, "rb") as b:
            assert a.read() == b.read()


def test_coin_is_a_regular_prism_with_the_official_sizes():
    # a 2 euro coin: 25.75 mm across, 2.20 mm thick; a 96-gon prism inscribed in that cylinder
    coin = shapes.coin(25.75, 2.20)
    n, r, t = 96, 25.75 / 2, 2.20
    np.testing.assert_allclose(coin.extents, [25.75, 25.75, 2.20], atol=1e-9)
    assert coin.volume == pytest.approx(0.5 * n * r * r * np.sin(2 * np.pi / n) * t, rel=1e-9)
    assert coin.is_watertight
    with pytest.raises(ValueError):
        shapes.coin(0.0, 1.0)


def test_hex_nut_and_washer_have_the_catalogue_sizes():
    # ISO 4032 M4: 7 mm across flats (corners 7 / cos 30° = 8.083 mm), 3.2 mm thick, a 4 mm bore
    # (a 48-gon on the circle); ISO 7089 M3 washer: 7 mm outer, 3.2 mm inner, 0.5 mm thick
    nut = catalogue.hex_nut(7.0, 3.2, 4.0)
    np.testing.assert_allclose(nut.extents, [7.0, 7.0 / np.cos(np.pi / 6), 3.2], atol=1e-9)
    bore = 0.5 * 48 * 2.0**2 * np.sin(2 * np.pi / 48)
    assert nut.volume == pytest.approx((np.sqrt(3) / 2 * 7.0**2 - bore) * 3.2, rel=1e-9)
    assert nut.is_watertight and nut.body_count == 1
    washer = catalogue.washer(7.0, 3.2, 0.5)
    ring = 0.5 * 96 * (3.5**2 - 1.6**2) * np.sin(2 * np.pi / 96)
    np.testing.assert_allclose(washer.extents, [7.0, 7.0, 0.5], atol=1e-9)
    assert washer.volume == pytest.approx(ring * 0.5, rel=1e-9) and washer.is_watertight
    with pytest.raises(ValueError):
        catalogue.hex_nut(5.5, 2.4, 6.0)  # a bore wider than the flats
    with pytest.raises(ValueError):
        catalogue.washer(3.0, 3.2, 0.5)
