"""Small helpers that several test files import (fixtures live in conftest.py)."""

from __future__ import annotations

import numpy as np
import trimesh

from sieve_mi.geometry.meshes import Shape, shape_from_trimesh

#: Solver and verdict settings small enough for end-to-end tests (seconds per solve).
TINY = """
[solver]
resolution = 64
particles = 3
iterations = 1
starts = 4
steps = 20
[verdict]
starts = 8
steps = 40
resolution = 96
"""


def sphere(radius: float, subdivisions: int = 3) -> Shape:
    """An icosphere of ``radius`` as a Shape named "sphere"."""
    return shape_from_trimesh(trimesh.creation.icosphere(subdivisions, radius), name="sphere")


def rng(seed: int = 0) -> np.random.Generator:
    """NumPy's default generator with ``seed``."""
    return np.random.default_rng(seed)
