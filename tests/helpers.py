"""Small helpers that several test files import (fixtures live in conftest.py)."""

from __future__ import annotations

import hashlib
import os

import numpy as np

from sieve_mi.geometry.meshes import Shape, shape_from_trimesh
from sieve_mi.testing import shapes

#: The checkout's root (scenes/, docs/ and tools/ are found from it).
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sphere(radius: float, subdivisions: int = 3) -> Shape:
    """:func:`sieve_mi.testing.shapes.sphere` (the one home of test solids) as a Shape named "sphere"."""
    return shape_from_trimesh(shapes.sphere(radius, subdivisions), name="sphere")


def rng(seed: int = 0) -> np.random.Generator:
    """NumPy's default generator with ``seed``."""
    return np.random.default_rng(seed)


def tree(folder) -> dict:
    """Every file under ``folder`` (relative path) with the SHA-256 of its bytes."""
    out = {}
    for root, _, names in os.walk(folder):
        for name in names:
            path = os.path.join(root, name)
            with open(path, "rb") as fh:
                out[os.path.relpath(path, folder)] = hashlib.sha256(fh.read()).hexdigest()
    return out


def exr_bitmap(path) -> object:
    """``mitsuba.Bitmap(path)`` of an OpenEXR file, read on at least two Dr.Jit threads
    (:func:`sieve_mi.backend.bitmap_threads`, as sieve-mi reads and writes them).

    Under ``pytest -n N`` each worker runs Dr.Jit on its share of the cores (tests/conftest.py):
    one thread on 2 cores, where Mitsuba 3.9's OpenEXR reader waits forever. Tests read EXR
    files with this, never with a bare ``mi.Bitmap``.
    """
    import mitsuba as mi

    from sieve_mi.backend import bitmap_threads

    with bitmap_threads():
        return mi.Bitmap(str(path))


def cli_run(capsys, *args) -> object:
    """``sieve-mi ARGS`` in this process (:func:`sieve_mi.cli.main`), for tests of what a command
    writes and returns rather than of the process (a subprocess costs about 1.5 CPU s of imports).

    Returns
    -------
    subprocess.CompletedProcess
        ``returncode`` (argparse's exit is its code), and the captured ``stdout`` and ``stderr``
        (str) of this call alone.
    """
    import subprocess

    from sieve_mi.cli import main

    capsys.readouterr()
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess([str(a) for a in args], code, out, err)
