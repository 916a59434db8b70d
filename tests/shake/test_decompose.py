"""Convex decomposition against a bound: the Hausdorff distance of known splits of an L-shaped
prism, the refinement of a piece that bulges out, and the cache keyed by the bound."""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.shake import decompose
from sieve_mi.shake.decompose import bulge, hausdorff
from sieve_mi.shake.geometry import part_from_mesh

pytest.importorskip("coacd")


def _ell() -> trimesh.Trimesh:
    """The L prism [0, 20] x [0, 10] union [0, 10] x [0, 20], 10 mm deep (z from 0 to 10)."""
    solid = manifold3d.Manifold.cube([20.0, 10.0, 10.0]) + manifold3d.Manifold.cube(
        [10.0, 20.0, 10.0]
    )
    m = solid.to_mesh()
    return trimesh.Trimesh(np.asarray(m.vert_properties)[:, :3], np.asarray(m.tri_verts))


def _box(x0, y0, x1, y1) -> np.ndarray:
    return np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (0.0, 10.0)])


def test_hausdorff_of_known_splits_of_an_l():
    """Two boxes that tile the L (meeting 0.001 mm apart, as CoACD's pieces do) are the L: their
    seam lies inside it, 10 mm deep, and is not error (the sign along the nearest sample's
    normal counted it). The L's hull adds the triangle (10, 10), (20, 10), (10, 20); its
    hypotenuse's midpoint is 5 mm from both arms, the farthest any hull point is: 5 mm."""
    ell = _ell()
    exact = [_box(0, 0, 20, 10), _box(0, 10.001, 10, 20)]
    h, res = hausdorff(ell, exact, np.zeros(3))
    assert h < res / 2
    h, res = hausdorff(ell, [np.asarray(ell.vertices)], np.zeros(3))
    assert abs(h - 5.0) < res
    assert abs(bulge(ell, np.asarray(ell.vertices)) - 5.0) < 0.5
    assert bulge(ell, exact[1]) < np.sqrt(ell.area / 20_000)  # the reference samples' spacing


def test_refine_splits_a_bulging_piece_within_the_bound(coacd_cache):
    """The L's hull as one piece bulges 5 mm out; refined to 1 mm, the pieces cut from the L
    inside it are within the bound of the L (sampled, give or take the sample spacing)."""
    ell = _ell()
    pieces = decompose.refine(
        ell.vertices, ell.faces, [np.asarray(ell.vertices)], 1.0, threshold=0.05, seed=0
    )
    assert len(pieces) >= 2
    h, res = hausdorff(ell, pieces, np.zeros(3))
    assert h <= 1.0 + res


def test_part_reports_its_bound_and_the_cache_keys_it(coacd_cache, monkeypatch):
    """The L within a 1 mm bound: reported with the bound, no warning; the same L and bound
    again come from the cache (CoACD not called); another bound is another key."""
    part = part_from_mesh(_ell(), "L", "A", 0.05, bound=1.0)
    geo = part.to_dict()
    assert geo["hausdorff_bound"] == 1.0 and geo["within_bound"] is True and not part.warnings
    import coacd

    monkeypatch.setattr(coacd, "run_coacd", lambda *a, **k: pytest.fail("not from the cache"))
    again = part_from_mesh(_ell(), "L", "A", 0.05, bound=1.0)
    assert all(np.array_equal(a, b) for a, b in zip(again.hulls, part.hulls, strict=True))
    with pytest.raises(pytest.fail.Exception):
        part_from_mesh(_ell(), "L", "A", 0.05, bound=0.5)


def test_a_part_left_over_its_bound_is_said_plainly(coacd_cache, monkeypatch):
    """A split that stays coarse (CoACD made to return the L's hull, refinement made to keep it):
    5 mm from the L (the hull's known distance), over a 1 mm bound, so ``within_bound`` is False
    and a warning names the part and both numbers."""
    import coacd

    ell = _ell()
    hull = ell.convex_hull
    monkeypatch.setattr(coacd, "run_coacd", lambda *a, **k: [(hull.vertices, hull.faces)])
    monkeypatch.setattr(decompose, "refine", lambda v, f, pieces, bound, **k: pieces)
    part = part_from_mesh(ell, "L", "A", 0.05, bound=1.0)
    assert abs(part.hausdorff - 5.0) < part.hausdorff_resolution
    assert part.to_dict()["within_bound"] is False
    (warning,) = part.warnings
    assert warning.startswith("L: its 1 convex pieces are 5") and "over the bound of 1" in warning
