"""Known-answer tests for the catalogue parts (sieve_mi.testing.catalogue): toy bricks and cells.

Sizes from the catalogue figures the module states (LEGO-compatible bricks: 8.0 mm pitch less
0.2 mm play, 9.6 mm body, studs 4.8 mm across and 1.7 mm high; IEC R03 and R6 cells), volumes
from prisms: body + studs, each stud a 32-gon prism inscribed in its circle.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import trimesh
from helpers import REPO

from sieve_mi.scene import load_scene
from sieve_mi.testing.catalogue import CELLS, brick, cell


def ngon_area(r: float, n: int) -> float:
    return 0.5 * n * r * r * math.sin(2 * math.pi / n)


@pytest.mark.parametrize(
    "nx, ny, size", [(2, 1, (15.8, 7.8)), (2, 2, (15.8, 15.8)), (4, 2, (31.8, 15.8))]
)
def test_brick_sizes_volume_and_studs(nx, ny, size):
    b = brick(nx, ny)
    np.testing.assert_allclose(b.extents, [*size, 9.6 + 1.7], atol=1e-9)
    assert b.is_watertight and b.is_volume and b.body_count == 1
    body = size[0] * size[1] * 9.6
    studs = nx * ny * ngon_area(2.4, 32) * 1.7
    assert b.volume == pytest.approx(body + studs, rel=1e-9)
    # the studs stand on the top face, on the 8 mm grid centred on the brick
    top = b.vertices[np.isclose(b.vertices[:, 2], b.bounds[1, 2])]
    assert np.ptp(top[:, 0]) == pytest.approx((nx - 1) * 8.0 + 4.8, abs=1e-9)
    assert np.ptp(top[:, 1]) == pytest.approx((ny - 1) * 8.0 + 4.8, abs=1e-9)
    with pytest.raises(ValueError):
        brick(0, 2)


@pytest.mark.parametrize("name", ["AAA", "AA"])
def test_cells_are_cylinders_of_the_catalogue_size(name):
    d, length = CELLS[name]
    c = cell(d, length)
    np.testing.assert_allclose(c.extents, [d, d, length], atol=1e-9)
    assert c.volume == pytest.approx(ngon_area(d / 2, 96) * length, rel=1e-9)
    assert c.is_watertight
    with pytest.raises(ValueError):
        cell(-1.0, length)


@pytest.mark.parametrize("scene", ["bricks.toml", "batteries.toml"])
def test_the_makers_scenes_load(scene):
    s = load_scene(os.path.join(REPO, "scenes", scene))
    names = [p.name for p in s.passes], [b.name for b in s.blocks]
    assert names == {"bricks.toml": (["1x2"], ["2x2", "2x4"]),
                     "batteries.toml": (["AAA"], ["AA"])}[scene]  # fmt: skip
    assert s.fabrication.tolerance == {"bricks.toml": 0.4, "batteries.toml": 0.5}[scene]
    for entry in [*s.passes, *s.blocks]:
        assert trimesh.load(s.resolve(entry.mesh), force="mesh").is_watertight
