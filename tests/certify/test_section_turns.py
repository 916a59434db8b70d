"""The slab-section proof's batched turn test (sieve_mi.certify.turns): known answers on paper.

Three points at the corners of an equilateral triangle of side s lie on a circle of radius
s / sqrt(3) (the smallest disk that holds them), and their two furthest points are s apart. Against
a round hole of radius 5 (diameter 10):

* side 10: the circumradius 5.774 exceeds 5 by 0.774, more than the bounds r = 0.05 grown by the
  turn of the deepest intervals, so no turn and offset fits; yet the diameter test (10 is not above
  10) and the width test (8.66 is below 10) cannot tell: only the turn test proves it;
* side 8: the circumradius 4.62 is below 5, so the points fit at every turn: never proved.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest

from sieve_mi.certify import bounds
from sieve_mi.certify.replay_geometry import Hole, no_translation
from sieve_mi.certify.search import EvenOdd
from sieve_mi.certify.turns import TurnTest

CIRCLE = manifold3d.CrossSection.circle(5.0, 256)


def _triangle(side: float) -> np.ndarray:
    a = np.radians([90.0, 210.0, 330.0])
    return side / math.sqrt(3.0) * np.column_stack([np.cos(a), np.sin(a)])


def _test():
    contours = [np.asarray(c, dtype=np.float64) for c in CIRCLE.to_polygons()]
    region = EvenOdd(contours)
    lower = bounds.LowerDistance(bounds.contour_segments(contours), region, 400)
    cache = bounds.OffsetCache(CIRCLE, 1e-6, r_min=1e-6)
    return TurnTest(cache, lower, region, depth=6), Hole(contours)


def _leaves(node, lo: float, hi: float):
    if "c" in node:
        mid = 0.5 * (lo + hi)
        yield from _leaves(node["c"][0], lo, mid)
        yield from _leaves(node["c"][1], mid, hi)
    else:
        assert node == {"e": True}
        yield lo, hi


def test_a_wide_triangle_is_excluded_at_every_turn_and_the_replay_agrees():
    test, hole = _test()
    x, r = _triangle(10.0), np.full(3, 0.05)
    tree, too_small = test.run([(x, r), (_triangle(8.0), r)], deadline=math.inf)
    assert too_small is None and test.stats["fits"] == 1  # side 8 fits at the first turn tried
    step, covered = 2.0 * math.pi / 8, 0.0
    for k, root in enumerate(tree["roots"]):
        for lo, hi in _leaves(root, k * step, (k + 1) * step):
            covered += hi - lo
            mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
            c, s = math.cos(mid), math.sin(mid)
            placed = x @ np.array([[c, s], [-s, c]])
            grow = 2.0 * math.sin(0.5 * half) * np.linalg.norm(x, axis=1) * (1 + 1e-9)
            assert no_translation(hole, placed, r + grow, 0.01)  # the replay's own quadtree
    assert covered == pytest.approx(
        2.0 * math.pi, abs=1e-12
    )  # every turn is covered by an excluded interval
