"""Shared fixtures: the CPU variant, a 20 mm cube, and a scene writer (helpers: helpers.py)."""

from __future__ import annotations

import os
import signal

import pytest
import trimesh

import sieve_mi  # noqa: F401  (points Dr.Jit at a usable libLLVM before drjit is imported)
from sieve_mi.backend import default_variant, use_variant
from sieve_mi.geometry.meshes import shape_from_trimesh

# A shell starts background jobs with SIGINT ignored (POSIX, no job control), and children
# inherit that: the interruption tests need Ctrl-C to mean what it means in a terminal.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session", autouse=True)
def mi():
    """Mitsuba on the default variant for every test: CPU unless ``SIEVE_MI_VARIANT=cuda_ad_mono``.

    Tests that switch variants switch back to this one.
    """
    return use_variant(default_variant())


@pytest.fixture
def cube20():
    return shape_from_trimesh(trimesh.creation.box((20.0, 20.0, 20.0)), name="cube")


@pytest.fixture
def write_scene(tmp_path):
    """Write meshes and a scene TOML into tmp_path; returns the scene path."""

    def write(text: str, meshes: dict[str, trimesh.Trimesh] | None = None) -> str:
        os.makedirs(tmp_path / "meshes", exist_ok=True)
        for name, mesh in (meshes or {}).items():
            mesh.export(str(tmp_path / "meshes" / name))
        path = tmp_path / "scene.toml"
        path.write_text(text)
        return str(path)

    return write
