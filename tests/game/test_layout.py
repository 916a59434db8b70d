"""Placement of further A shapes into a hole (paper Sec. 5.3): the candidate ranking, known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from sieve_mi.game.candidates import _shifted, _stratified, candidate_placements
from sieve_mi.game.player_a import PlayerA
from sieve_mi.geometry.hole import pieces
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.raster import Frame


def _c_ring(frame: Frame, outer: float, inner: float, mouth: float) -> np.ndarray:
    """An annulus (radii in mm) with a gap of width ``mouth`` cut out of it on the +x side: a 'C'."""
    xc, yc = frame.centres()
    x, y = np.meshgrid(xc, yc)  # rows run along y, columns along x
    r = np.hypot(x, y)
    return (r <= outer) & (r >= inner) & ~((x > 0) & (np.abs(y) < mouth / 2))


def test_shifted_moves_without_wrapping():
    m = np.zeros((5, 5), dtype=bool)
    m[0, 0] = m[4, 4] = m[2, 3] = True
    assert np.argwhere(_shifted(m, 1, 1)).tolist() == [[1, 1], [3, 4]]  # (4, 4) leaves the grid
    assert np.argwhere(_shifted(m, -2, 0)).tolist() == [[0, 3], [2, 4]]  # (0, 0) leaves the grid
    assert _shifted(m, 0, 0).tolist() == m.tolist()


def test_stratified_takes_the_head_then_spreads():
    assert _stratified(5, 10).tolist() == [0, 1, 2, 3, 4]
    pick = _stratified(100, 10)
    assert pick[:5].tolist() == [0, 1, 2, 3, 4] and pick[-1] == 99 and len(set(pick.tolist())) == 10


def test_most_compact_placement_does_not_close_the_c():
    # Base: a 'C' (annulus 10..14 mm, mouth 6 mm wide). New shape: a 3 x 12 x 3 mm bar. Laid
    # across the mouth it closes the C, and filling the closed ring turns the hole into a disk of
    # radius 14 (616 mm^2): the bar's best overlap is *not* the best placement. Every placement
    # that leaves the mouth open has a filled area of at most ring + bar (~ 327 + 36 + dilation).
    frame = Frame.covering(30.0, 192)
    base = _c_ring(frame, 14.0, 10.0, 6.0)
    bar = shape_from_trimesh(trimesh.creation.box(extents=(12.0, 3.0, 3.0)), name="bar")
    player = PlayerA(bar, frame, tolerance=0.5)
    quats, trans, area = candidate_placements(player, base, np.array([1.0, 0, 0, 0]), reach=15.0)
    px = frame.pixel_size**2
    disk = np.pi * 14.0**2
    assert len(quats) > 10
    assert np.all(np.diff(area) >= 0)  # sorted, most compact first
    assert area[0] * px < 0.75 * disk  # the best leaves the mouth open
    assert area[-1] * px > 0.9 * disk  # ... while closing placements exist among the candidates
    # The first candidate really is what it claims: rebuild its hole from the returned pose.
    hole = player.holes(quats[:1], trans[:1], base=base)[0].mask
    assert pieces(hole) == 1
    assert abs(hole.sum() - area[0]) <= 0.03 * area[0]
    assert ndimage.binary_fill_holes(hole).sum() == hole.sum()


def test_alternative_rotations_are_distinct_and_good():
    from sieve_mi.game.layout import alternative_rotations
    from sieve_mi.geometry.rotations import from_axis_angle

    best = np.array([1.0, 0, 0, 0])
    about_z = lambda a: from_axis_angle(np.array([0.0, 0, 1]), a)  # noqa: E731
    finalists = [
        (best, 0.5),
        (-best, 0.45),  # the same rotation as best (q and -q)
        (about_z(0.1), 0.4),  # within 0.35 rad of best
        (about_z(1.0), 0.3),  # distinct: kept
        (about_z(1.2), 0.25),  # within 0.35 rad of the one just kept
        (about_z(2.0), 0.2),  # distinct: kept
        (about_z(3.0), 0.1),  # distinct, but the count is reached
    ]
    alt = alternative_rotations(finalists, best, 2)
    assert len(alt) == 2
    assert np.allclose(np.abs(alt[0]), np.abs(about_z(1.0))) and np.allclose(
        np.abs(alt[1]), np.abs(about_z(2.0))
    )
    # Rotations that did not block every B alone (value <= 0) are never offered.
    assert (
        alternative_rotations([(best, 0.5), (about_z(1.0), 0.0), (about_z(2.0), 0.3)], best, 3)
        == []
    )


def test_merge_hint_only_when_each_shape_alone_blocked():
    from sieve_mi.outputs.console import merge_hint, summary_table

    report = {
        "winner": "B",
        "units": "mm",
        "pixel_size": 0.2,
        "timings": {"search_s": 1.0, "verdict_s": 0.5},
        "settings": {"layout": {"mode": "merged"}},
        "pass": [{"name": "S", "alone_loss": 0.18}, {"name": "G", "alone_loss": 0.1}],
        "block": [
            {"name": "R", "loss": 0.0, "protrusion": 0.0, "blocked": False},
            {"name": "A", "loss": 0.01, "protrusion": 0.4, "blocked": True},
        ],
    }
    hint = merge_hint(report)
    assert "lets R through" in hint and 'mode = "separate"' in hint and "S 0.180" in hint
    assert hint in summary_table(report)
    # No hint when A wins, when one shape alone already let B through, or for a separate layout.
    assert merge_hint({**report, "winner": "A"}) is None
    assert (
        merge_hint(
            {
                **report,
                "pass": [{"name": "S", "alone_loss": 0.18}, {"name": "G", "alone_loss": 0.0}],
            }
        )
        is None
    )
    assert merge_hint({**report, "settings": {"layout": {"mode": "separate"}}}) is None
    assert merge_hint({**report, "pass": report["pass"][:1]}) is None


@pytest.mark.parametrize(
    "restarts, seeds, kept", [(0, [7], 0.0), (1, [7, 8], 1.0), (3, [7, 8], 1.0)]
)
def test_a_lost_merge_restarts_from_another_seed(write_scene, monkeypatch, restarts, seeds, kept):
    # The first merge loses (some B passes); with restarts, every A is searched again from
    # another seed and merged again, the blocking merge is kept and no further restart runs.
    import sieve_mi.game.solver as solve_mod
    from sieve_mi.game.layout import Merged
    from sieve_mi.optim import SwarmHistory
    from sieve_mi.scene import load_scene

    cube = trimesh.creation.box((10.0, 10.0, 10.0))
    body = (
        '[[pass]]\nmesh = "meshes/a.stl"\n[[pass]]\nmesh = "meshes/a.stl"\n'
        f'[[block]]\nmesh = "meshes/a.stl"\n[layout]\nrestarts = {restarts}\n'
    )
    scene = load_scene(write_scene(body, {"a.stl": cube}))
    rotated, merges = [], []

    def fake_rotate(scene, passes, blocks, rng, seed, bar, tag=""):
        rotated.append(seed)
        out = solve_mod.SearchOutcome(
            np.tile([1.0, 0, 0, 0], (2, 1)), np.zeros((2, 2)), 0.0, SwarmHistory(), [], [0.5] * 2
        )
        return out

    def fake_merge(scene, passes, blocks, quats, alternatives, rng, bar):
        k = len(merges)
        merges.append(k)
        return Merged(quats, np.zeros((2, 2)), float(k), SwarmHistory(), [(f"merge {k}", 1)],
                      None, blocks=k >= 1)  # fmt: skip

    monkeypatch.setattr(solve_mod, "_rotate_each", fake_rotate)
    monkeypatch.setattr(solve_mod, "_merge", fake_merge)
    out = solve_mod.search(scene, [None, None], [None], np.random.default_rng(0), 7, False)
    assert rotated == seeds
    assert out.value == kept and out.merged_blocks == (kept == 1.0)
    assert [label for label, _ in out.stages] == [f"merge {k}" for k in range(len(seeds))]
