"""What a run needs to be reproduced: seed, variant, software versions, machine, input hashes.

A solve is deterministic (see docs/method.md, "Reproducibility"): the same scene files, seed,
variant, software versions and machine give the same ``report.json`` (timings aside), masks and
plate files, bit for bit. ``report.json``'s ``"provenance"`` section records all of these.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
from importlib import metadata

from sieve_mi._version import VERSION

__all__ = ["PACKAGES", "VERSION", "git_commit", "machine", "provenance", "sha256", "versions"]

#: Distributions whose versions are recorded (their numerics or geometry enter the result).
PACKAGES = ("sieve-mi", "mitsuba", "drjit", "manifold3d", "nlopt", "numpy", "scipy", "trimesh")


def sha256(path: str) -> str:
    """Hex SHA-256 of a file's bytes (64 characters)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def versions() -> dict[str, str | None]:
    """Installed version of each of :data:`PACKAGES` (None where one is not installed).

    sieve-mi run from a checkout on ``PYTHONPATH`` (not pip-installed, as on an offline GPU
    machine) reports its own ``sieve_mi._version.VERSION``.
    """
    from sieve_mi._version import VERSION

    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = VERSION if name == "sieve-mi" else None
    return out


def git_commit() -> str | None:
    """The commit of the sieve-mi checkout this code runs from, or None outside a git checkout."""
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        p = subprocess.run(
            ["git", "-C", here, "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return p.stdout.strip() if p.returncode == 0 and p.stdout.strip() else None


def machine() -> dict[str, str | int | None]:
    """The machine's architecture, CPU model, core count and Dr.Jit's thread count (float
    results may depend on them)."""
    model = None
    try:
        with open("/proc/cpuinfo") as f:
            model = next(
                (ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), None
            )
    except OSError:
        pass
    dr = sys.modules.get("drjit")  # imported by a solve; its pool's size (``--threads``)
    return {
        "system": platform.system(),
        "architecture": platform.machine(),
        "cpu": model or platform.processor() or None,
        "cores": os.cpu_count(),
        "threads": None if dr is None else int(dr.thread_count()),
    }


def provenance(scene_path: str | None, meshes: list[tuple[str, str]], variant: str, seed) -> dict:
    """The ``"provenance"`` section of ``report.json``.

    Parameters
    ----------
    scene_path : str or None
        The scene file (hashed when given).
    meshes : list of (str, str)
        (name as written in the scene, resolved path) of every mesh file, in scene order.
    variant : str
        The Mitsuba variant the run used.
    seed : int or None
        The seed the run used (after any ``--seed`` override).

    Returns
    -------
    dict
        ``seed``, ``variant``, ``versions`` (see :func:`versions`), ``git_commit``, ``machine``,
        ``scene_sha256`` and ``meshes`` (each ``{"mesh", "sha256"}``).
    """
    return {
        "seed": None if seed is None else int(seed),
        "variant": variant,
        "versions": versions(),
        "git_commit": git_commit(),
        "machine": machine(),
        "scene_sha256": sha256(scene_path) if scene_path and os.path.isfile(scene_path) else None,
        "meshes": [{"mesh": name, "sha256": sha256(path)} for name, path in meshes],
    }
