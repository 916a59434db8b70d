"""Every proof reads its clock inside a level: no batched test starts past the budget.

No timed test: each search gets a fake clock that ticks once per reading, so "past the budget"
is a count of readings, the same on every machine.
"""

from __future__ import annotations

import numpy as np
import pytest

from sieve_mi.certify import cells, search, symmetry
from sieve_mi.certify.search import CellSearch, Settings
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import hole_outline
from sieve_mi.geometry.rotations import align
from sieve_mi.testing import shapes


class Ticks:
    """A clock that moves on by one second each time it is read."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


@pytest.fixture(scope="module")
def tilted_unit_hole():
    unit = shape_from_trimesh(shapes.cube(1.0), name="unit")
    q = align(np.array([2.0, 2.0, -1.0]), np.array([0.0, 0.0, 1.0]))
    return hole_outline([unit], q[None], np.zeros((1, 2)), 0.0, closed=[True])


def test_cell_search_stops_inside_a_level(tilted_unit_hole, monkeypatch):
    # a 1.062 cube against the tilted unit cube's hole needs many levels (test_certify's
    # undecided case); with chunks of 8 cells a level of 64 has 8 chunks, each of which may
    # start only while the clock (one tick per reading) is within the budget of 40 ticks
    monkeypatch.setattr(search, "LEVEL_CHUNK", 8)
    shape = shape_from_trimesh(shapes.cube(1.062), name="b")
    group = symmetry.detect(shape)
    roots = cells.roots(*symmetry.domain(group))
    s = CellSearch(shape, tilted_unit_hole, Settings(budget_s=40.0), group)
    s.clock, started, seen = Ticks(), [], []
    pretest = s._pretest

    def watched(fr, theta, points, batched=False):
        started.append(s.clock.now)
        seen.append(len(theta))
        return pretest(fr, theta, points, batched)

    s._pretest = watched
    out = s.run(roots, started=0.0)
    assert out.open_cells > 0 and out.passage is None  # stopped by the budget
    assert max(seen) <= 8 and len(started) > 1  # the levels ran in chunks
    assert max(started) <= 40.0  # none began past the budget
    assert out.examined < 40  # each cell reads the clock once: examining stopped at it
