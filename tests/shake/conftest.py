"""Fixtures of the shake tests: a plate with a 22 mm round hole, and a part builder."""

from __future__ import annotations

import pytest
from shake_helpers import round_hole

from sieve_mi.shake.geometry import part_from_mesh, plate_from_outline


@pytest.fixture
def ball_plate():
    """A 2 mm plate with a 22 mm round hole and 14 mm of material around it."""
    return plate_from_outline(round_hole(22.0), 14.0, 2.0)


@pytest.fixture
def part_of():
    def make(mesh, name="part", role=None):
        return part_from_mesh(mesh, name, role, 0.05)

    return make
