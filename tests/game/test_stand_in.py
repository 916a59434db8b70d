"""Simplified stand-ins for the search (``[solver] stand_in``, sieve_mi.geometry.stand_in).

Known answers: an icosphere of radius 10 has every vertex on the sphere of radius 10; a stand-in
keeps a subset of them, so its vertices still lie on that sphere, and each of its triangles lies
within the tolerance of the original surface, hence (the original lying inside the ball of radius
10 and outside the ball of radius 10 cos(half the largest edge angle) > 9.9) within the shell
9.9 - tolerance <= |x| <= 10. A 24 mm ball cannot pass the hole of a 20 mm ball with a 1 mm
tolerance (radius at most 11.003 < 12 - 0.5 even for the stand-in).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import sieve_mi as sm
from sieve_mi.errors import SieveError
from sieve_mi.game import solver as solver_module
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.stand_in import stand_in, stand_ins
from sieve_mi.scene import load_scene
from sieve_mi.testing.settings import tiny_solver


def _sphere(radius: float = 10.0, subdivisions: int = 3):
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def test_a_stand_in_keeps_vertices_and_stays_within_its_tolerance():
    full = shape_from_trimesh(_sphere(), name="ball")
    coarse = stand_in(full, 0.5)
    assert coarse.face_count < full.face_count / 2  # far fewer triangles
    assert coarse.name == full.name and np.array_equal(coarse.centre, full.centre)
    rows = {tuple(p) for p in full.vertices}
    assert all(tuple(p) in rows for p in coarse.vertices)  # the original's own vertices, float64
    assert np.allclose(np.linalg.norm(coarse.vertices, axis=1), 10.0)
    centroids = coarse.vertices[coarse.faces].mean(axis=1)
    assert np.linalg.norm(centroids, axis=1).min() >= 9.9 - 0.5  # inside the tolerance's shell
    assert coarse.radius == pytest.approx(10.0)
    hull = trimesh.convex.convex_hull(coarse.vertices)  # the hull's vertices are recomputed
    assert len(coarse.hull) == len(hull.vertices)
    assert stand_in(full, 0.0) is full and stand_ins([full], 0.0) == [full]
    assert stand_ins([full], 0.5, faces=1280) == [full]  # not more faces than the bound


def test_an_open_mesh_stays_whole():
    mesh = _sphere()
    mesh.update_faces(np.arange(len(mesh.faces)) != 0)  # one triangle missing: not closed
    open_shape = shape_from_trimesh(mesh, name="open")
    assert stand_in(open_shape, 0.5) is open_shape


def test_auto_plays_big_b_within_half_a_pixel_and_the_verdict_the_full_mesh(
    monkeypatch,
):
    # A: a ball of radius 10, tolerance 1, so its frame covers radius 11 at 64 pixels with 3
    # pixels of margin a side: a pixel is 2 * 11 / (64 - 6) = 0.379 mm, "auto" half of it, for
    # B of more than 5,000 faces only (the 5,120-face ball; the 1,280-face one stays whole).
    big, small = _sphere(12.0, 4), _sphere(12.5)
    scene = sm.Scene.from_meshes(
        [_sphere()], [{"mesh": big, "name": "big"}, {"mesh": small, "name": "small"}], name="s"
    )
    scene.solver = tiny_solver(screen=False, stand_in="auto")
    scene.verdict.starts, scene.verdict.steps, scene.verdict.certify = 4, 10, False
    assert scene.fabrication.tolerance == 1.0
    tol = 0.5 * 2 * 11.0 / (64 - 6)
    seen = []
    search = solver_module.search

    def spy(scene, passes, blocks, *args):
        seen.extend(blocks)
        return search(scene, passes, blocks, *args)

    monkeypatch.setattr(solver_module, "search", spy)
    result = sm.solve(scene, progress=False)
    coarse, whole = seen
    assert coarse.face_count < 5120 and whole.face_count == 1280  # only the big B simplified
    assert np.allclose(np.linalg.norm(coarse.vertices, axis=1), 12.0)  # B's own vertices
    # The full mesh lies outside radius 12 cos(largest edge angle / 2); every stand-in
    # triangle within the tolerance of it.
    angle = big.edges_unique_length.max() / 12.0
    centroids = coarse.vertices[coarse.faces].mean(axis=1)
    assert np.linalg.norm(centroids, axis=1).min() >= 12.0 * np.cos(angle / 2) - tol - 1e-9
    assert [b.face_count for b in result.block_shapes] == [5120, 1280]  # the verdict: full
    assert result.winner == "A" and all(b.blocked for b in result.blocks)


def test_a_negative_stand_in_is_one_line(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(
        '[[pass]]\nmesh = "a.stl"\n[[block]]\nmesh = "b.stl"\n[solver]\nstand_in = -1.0\n'
    )
    with pytest.raises(SieveError) as err:
        load_scene(str(path))
    assert "stand_in" in str(err.value) and "\n" not in str(err.value)
