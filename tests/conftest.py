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


# `pytest -n N` runs N worker processes: each runs Dr.Jit's kernels on its share of the cores.
# With a thread per core in every worker, N pools spin against each other: two letters solves
# side by side on 2 cores took 18 s each, and 10 s each with one thread per worker. Only this
# process's pool: the sieve-mi processes a test starts keep their default (a $SIEVE_MI_THREADS
# here would change what they do, e.g. start Dr.Jit before a refused --out, which writes its
# kernel cache into $HOME). On one thread Mitsuba's OpenEXR reader waits forever: tests read
# EXR files with helpers.exr_bitmap.
_XDIST_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
_THREADS = max(1, (os.cpu_count() or 1) // _XDIST_WORKERS) if _XDIST_WORKERS > 1 else None


@pytest.fixture(autouse=True)
def coacd_cache(tmp_path_factory, monkeypatch):
    """Every test keeps CoACD's decompositions in a folder of its own (beside its ``tmp_path``,
    whose listing some tests check), not in the user's cache."""
    folder = tmp_path_factory.mktemp("cache")
    monkeypatch.setenv("SIEVE_MI_CACHE", str(folder))
    return folder / "coacd"


@pytest.fixture(scope="session", autouse=True)
def mi():
    """Mitsuba on the default variant for every test: CPU unless ``SIEVE_MI_VARIANT=cuda_ad_mono``.

    Tests that switch variants switch back to this one.
    """
    variant = use_variant(default_variant())
    if _THREADS is not None:
        import drjit as dr

        dr.set_thread_count(_THREADS)
    return variant


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
