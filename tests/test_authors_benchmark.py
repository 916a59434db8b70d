"""The like-for-like scenes of ``benchmarks.authors`` match the authors' runs they stand in for."""

from __future__ import annotations

import os
import sys

import pytest
import trimesh

import sieve_mi as sm

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks import authors  # noqa: E402

SCENE_CASES = [name for name in authors.AUTHORS if name not in authors.STRESS]


@pytest.fixture(scope="module")
def meshes():
    authors.ensure_meshes()


def _faces(scene, entry) -> int:
    return len(trimesh.load(scene.resolve(entry.mesh), force="mesh").faces)


@pytest.mark.parametrize("name", SCENE_CASES)
def test_scene_has_their_shape_counts_face_counts_and_settings(meshes, name):
    scene = sm.load_scene(os.path.join(authors.SCENES, f"{name}.toml"))
    theirs = authors.AUTHORS[name]
    assert len(scene.passes) == len(theirs["faces_a"])
    assert len(scene.blocks) == len(theirs["faces_b"]) == len(theirs["losses"])
    pairs = list(zip(scene.passes, theirs["faces_a"])) + list(zip(scene.blocks, theirs["faces_b"]))
    for entry, faces in pairs:
        assert 1 / 1.6 <= _faces(scene, entry) / faces <= 1.6, (entry.mesh, faces)
    s, v = scene.solver, scene.verdict
    assert (s.particles, s.iterations, s.starts, s.steps, s.resolution) == (10, 10, 10, 100, 256)
    assert (s.inertia, s.c_personal, s.c_global, s.learning_rate) == (0.5, 0.25, 0.25, 0.05)
    assert (v.starts, v.steps, v.resolution) == (100, 500, 256)
    assert scene.fabrication.tolerance == 1.0
    assert (scene.layout.c_personal, scene.layout.c_global) == (0.05, 0.05)


def test_reduced_scene_keeps_the_shapes_and_lowers_the_settings(meshes, tmp_path):
    path = os.path.join(authors.SCENES, "mechanical-parts.toml")
    original = sm.load_scene(path)
    reduced = sm.load_scene(authors.reduced_scene(path, str(tmp_path)))
    assert [reduced.resolve(e.mesh) for e in reduced.passes] == [
        original.resolve(e.mesh) for e in original.passes
    ]
    assert [e.scale for e in reduced.blocks] == [e.scale for e in original.blocks]
    assert reduced.layout.mode == "merged"
    for table, keys in authors.REDUCED.items():
        for key, value in keys.items():
            assert getattr(getattr(reduced, table), key) == value
    assert reduced.solver.inertia == original.solver.inertia == 0.5


def test_uv_sphere_has_the_authors_vertex_and_face_counts():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_meshes", os.path.join(authors.SCENES, "make_meshes.py")
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sphere = module.uv_sphere()
    assert (len(sphere.vertices), len(sphere.faces)) == (50, 96)
    assert sphere.is_watertight and sphere.volume > 0
    assert abs(sphere.vertices).max() == pytest.approx(1.0)
