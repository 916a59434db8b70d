"""The inscribed ball that the ball proofs, the size screen and the margins rest on."""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.certify.bounds import _parity_inside, inscribed_ball
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.solid import triangle_distance, winding_numbers


def _winding_number(p, tri) -> float:
    return float(winding_numbers(np.asarray(p)[None], tri)[0])


def _solid(*meshes: trimesh.Trimesh) -> trimesh.Trimesh:
    """The union of closed meshes (manifold3d), as one closed trimesh."""
    parts = [
        manifold3d.Manifold(
            manifold3d.Mesh(m.vertices.astype(np.float32), m.faces.astype(np.uint32))
        )
        for m in meshes
    ]
    union = parts[0]
    for p in parts[1:]:
        union = union + p
    out = union.to_mesh()
    return trimesh.Trimesh(out.vert_properties[:, :3], out.tri_verts)


def test_the_dumbbells_ball_is_found_between_lattice_points():
    # Two balls of radius 10 (icospheres: inscribed radius 9.98) 60 mm apart on a 2 mm rod: the
    # bounding box is 80 x 20 x 20, its centre lies in the rod (radius 2), and the nearest
    # lattice point to a ball's centre is off it. The largest inscribed ball is a bell's own,
    # radius >= 9.98 (its icosphere's inscribed radius), and none is larger than 10.
    bells = [trimesh.creation.icosphere(4, 10.0).apply_translation([x, 0, 0]) for x in (-30, 30)]
    rod = trimesh.creation.cylinder(2.0, 60.0, sections=32)
    rod.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    shape = shape_from_trimesh(_solid(*bells, rod), name="dumbbell")
    centre, rho = inscribed_ball(shape)
    assert 9.97 <= rho <= 10.0
    assert abs(abs(centre[0]) - 30.0) < 0.1 and np.hypot(centre[1], centre[2]) < 0.1
    # rigorous: the exact distance at the centre, which is enclosed
    tri = shape.vertices[shape.faces]
    assert triangle_distance(centre, tri).min() >= rho
    assert abs(round(_winding_number(centre, tri))) == 1


def test_a_box_holds_half_its_thinnest_side_and_an_open_mesh_none():
    box = shape_from_trimesh(trimesh.creation.box((20.0, 30.0, 8.0)), name="box")
    assert inscribed_ball(box)[1] == pytest.approx(4.0, rel=1e-6)
    open_box = trimesh.creation.box((20.0, 30.0, 8.0))
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)
    assert inscribed_ball(shape_from_trimesh(open_box, name="open")) is None


def test_the_parity_filter_keeps_every_enclosed_lattice_point_of_a_torus():
    # A torus (major radius 10, minor 4) turned off the axes, on the 12^3 lattice of its bounding
    # box: a point is enclosed iff its distance to the core circle is below 4 (the hole at the
    # centre is outside). The filter that spares the winding numbers of outside candidates must
    # keep every enclosed point (the lattice of a box, whose lines touch the diagonals of its
    # faces, keeps those lines whole) and drop the points well outside.
    torus = trimesh.creation.torus(10.0, 4.0, major_sections=48, minor_sections=24)
    torus.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 0.5]))
    tri = torus.vertices[torus.faces]
    lo, hi = torus.vertices.min(0), torus.vertices.max(0)
    axes = [lo[i] + (hi[i] - lo[i]) * (np.arange(12) + 0.5) / 12 for i in range(3)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    kept = _parity_inside(axes, tri)
    local = points @ trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 0.5])[:3, :3]
    core = np.hypot(np.hypot(local[:, 0], local[:, 1]) - 10.0, local[:, 2])
    assert np.all(kept[core < 3.8]) and not np.any(kept[core > 4.2])
    assert abs(round(_winding_number(np.zeros(3), tri))) == 0  # the hole: outside
    box = trimesh.creation.box((20.0, 30.0, 8.0))
    grid = [np.linspace(-10, 10, 13)[:-1] + 20 / 24, np.linspace(-15, 15, 13)[:-1] + 1.25,
            np.linspace(-4, 4, 13)[:-1] + 1 / 3]  # fmt: skip
    assert _parity_inside(grid, box.vertices[box.faces]).all()  # every lattice point is inside
