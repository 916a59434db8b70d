"""The plate as geometry: diameters, the safe thickness and the exact convex decomposition."""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import shapely

from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.plate import (
    convex_pieces,
    diameter,
    plate_region,
    prism_vertices,
    safe_thickness,
)
from sieve_mi.testing import shapes


def test_diameters_of_known_solids():
    # a cube's diameter is its space diagonal, a ball's twice its radius (vertices on the sphere)
    assert diameter(shapes.cube(20.0).vertices) == pytest.approx(20 * math.sqrt(3))
    ball = shapes.sphere(radius=12.0, subdivisions=3)
    assert diameter(ball.vertices) == pytest.approx(24.0, abs=1e-6)
    # L-rod: the far ends of the two arms, (20, 0, 0) and (0, 20, 2) apart by sqrt(20² + 20² + 2²)
    rod = shape_from_trimesh(shapes.l_rod(20.0, 2.0), name="rod")
    assert diameter(rod.hull) == pytest.approx(math.sqrt(804))


def test_diameter_chunks_agree_with_one_block():
    p = np.random.default_rng(0).normal(size=(500, 3))
    assert diameter(p, chunk=7) == diameter(p, chunk=4096)


def test_safe_thickness_is_the_largest_diameter_rounded_up():
    cube, ball = shapes.cube(20.0).vertices, shapes.sphere(12.0).vertices
    assert safe_thickness([ball, cube]) == pytest.approx(34.7)  # 34.641 rounded up
    assert safe_thickness([ball]) == pytest.approx(24.0)  # exactly 24 stays 24


@pytest.mark.parametrize(
    "hole",
    [
        manifold3d.CrossSection.square([22, 22], center=True),
        manifold3d.CrossSection.circle(4.5, 64),
        manifold3d.CrossSection.square([19.5, 3], center=True),
        # two holes and a non-convex one (an L-shaped slot)
        manifold3d.CrossSection.square([4, 4]).translate([8, 0])
        + manifold3d.CrossSection.square([10, 2])
        + manifold3d.CrossSection.square([2, 10]),
    ],
)
def test_convex_pieces_partition_the_plate_exactly(hole):
    region = plate_region(hole, 5.0)
    pieces = [shapely.Polygon(p) for p in convex_pieces(region)]
    total = sum(p.area for p in pieces)
    assert total == pytest.approx(region.area(), rel=1e-12)
    # the union is the region (same area, and the union's area equals the sum: no overlaps)
    union = shapely.union_all(pieces)
    assert union.area == pytest.approx(total, rel=1e-9)
    for p in pieces:
        assert p.is_valid and p.exterior.is_ccw
        assert p.convex_hull.area == pytest.approx(p.area, rel=1e-9)  # convex
    # merging keeps the count small: at most the triangulation's, which is vertices + 2·holes - 2
    vertices = sum(len(c) for c in region.to_polygons())
    assert len(pieces) <= vertices + 2 * (len(region.to_polygons()) - 1)


def test_merging_leaves_the_fewest_convex_pieces_on_known_shapes():
    # A convex region is one piece however it was triangulated (a square's 2 triangles, a
    # 64-gon's 62), and a square frame (a square hole in a square plate: 8 triangles) needs at
    # least 4 convex pieces: a convex piece misses the hole, so it lies in a half-plane that misses
    # it, and a point just outside the middle of one of the hole's sides lies only in half-planes
    # bounded by (nearly) that side's line, one side per piece; 4 trapezoids do it. Gluing two pieces along their shared edge used to put the second
    # piece's vertices in the wrong order, so almost nothing merged (2 pieces for a square).
    assert len(convex_pieces(manifold3d.CrossSection.square([10, 10]))) == 1
    assert len(convex_pieces(manifold3d.CrossSection.circle(5.0, 64))) == 1
    pieces = convex_pieces(plate_region(manifold3d.CrossSection.square([22, 22], center=True), 5))
    assert len(pieces) == 4


def test_prism_vertices():
    tri = np.array([[0.0, 0], [1, 0], [0, 1]])
    v = prism_vertices(tri, -2.0, 0.0)
    assert v.shape == (6, 3) and set(v[:, 2]) == {-2.0, 0.0}
