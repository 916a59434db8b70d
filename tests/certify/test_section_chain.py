"""The slab-section proof's chain test on a sheet of holes (:mod:`sieve_mi.certify.chain`).

Known answers, on paper. A ring (an annulus: bore radius 2.5, outer radius 4, 4 mm tall; an
octagon, so its outer flats are 4 cos 22.5 deg = 3.70 from the axis) against discs of radius
3.3 on a 1 mm plate. Any plane through the ring's centre meets its outer faces at least 3.70
from the centre, and the centre slab is centrally symmetric, so its projection is at least 7.4
across: more than one disc's 6.6, so one disc is proved. Stood on edge, the ring's slab through
its axis is two bars 1.5 x 4 mm whose facing sides are at least 2 sqrt(2.31^2 - 0.5^2) = 4.5
apart (the bore's flats at 2.5 cos 22.5 deg = 2.31): each bar fits a disc, so two discs with a
1 mm web between them hold the section (no section test can exclude it), while across a 7 mm
web no point of one bar can be in another disc than a point of the other bar less than 7 away.
Across the 1 mm web topology keeps the ring out (:mod:`sieve_mi.certify.link`): the web would
pass through the bore, and the ring's core loop would link a loop of the plate around a disc.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.certify import replay, section_only
from sieve_mi.certify.chain import Chain, hull_gap
from sieve_mi.certify.replay_section import hull_separation
from sieve_mi.certify.search import Settings
from sieve_mi.geometry.meshes import shape_from_trimesh

R = 3.3


def _disc(x: float = 0.0) -> np.ndarray:
    a = 2 * np.pi * np.arange(64) / 64
    return np.column_stack([R * np.cos(a) + x, R * np.sin(a)])


def _holes(web: float) -> list:
    return [manifold3d.CrossSection([_disc()]), manifold3d.CrossSection([_disc(2 * R + web)])]


@pytest.fixture(scope="module")
def ring():
    mesh = trimesh.creation.annulus(r_min=2.5, r_max=4.0, height=4.0, sections=8)
    return shape_from_trimesh(mesh, name="ring")


def test_both_separation_bounds_are_the_gap_between_two_discs_and_never_more():
    for web in (0.5, 1.2, 7.0):
        contours = [_disc(), _disc(2 * R + web)]
        for gap in (hull_gap(contours), hull_separation(contours)):
            # a 64-gon's edge lies within R (1 - cos(pi / 64)) of its circle, and the lower
            # bound never exceeds the polygons' true distance (their facing vertices at web)
            assert web - 2e-3 < gap <= web + 1e-12
    crossing = [_disc(), _disc(R)]
    assert hull_gap(crossing) <= 0 and hull_separation(crossing) <= 0
    assert Chain(crossing, 1e-6).step == 0.0  # hulls that meet: no chain test


def test_a_chain_needs_short_steps_and_far_ends():
    chain = Chain([_disc(), _disc(2 * R + 2.0)], 1e-9)  # step < 2, ends > 6.6
    x = np.array([[0.0, 0.0], [1.9, 0.0], [3.8, 0.0], [5.7, 0.0], [7.0, 0.0], [3.0, 1.0]])
    r = np.zeros(len(x))
    path = chain.path(x, r, 0, 4)
    assert path is not None and path[0] == 0 and path[-1] == 4
    steps = np.linalg.norm(np.diff(x[path], axis=0), axis=1)
    assert steps.max() < 2.0
    assert chain.path(x, r + 0.1, 0, 4) is None  # 1.9 + 0.2 is no step below 2
    assert chain.path(x, r, 0, 3) is None  # 5.7 apart: one disc holds both


def _evidence_kinds(tree: list) -> set:
    """The kinds of evidence in a section certificate's tree (its six roots)."""
    kinds, todo = set(), list(tree)
    while todo:
        node = todo.pop()
        todo.extend(node.get("c", []))
        if "e" in node:
            kinds.add(node["e"]["kind"])
    return kinds


def test_the_ring_is_proved_across_a_wide_web_by_chains_and_the_replay_agrees(ring):
    c = section_only(ring, _holes(7.0), 1.0, 60.0)  # a cap: a loaded machine needs more than 20 s
    assert c.section["status"] == "proved"
    sec = c.certificate["section"]
    kinds = _evidence_kinds(sec["tree"])
    assert "chain" in kinds
    wide = [np.asarray(x).tolist() for x in (_holes(7.0)[0] + _holes(7.0)[1]).to_polygons()]
    assert replay({**c.certificate, "section": {**sec, "hole": wide}})["valid"]
    # the same chains across a 1 mm web: their steps are no longer shorter than the gap
    narrow = [np.asarray(x).tolist() for x in (_holes(1.0)[0] + _holes(1.0)[1]).to_polygons()]
    r = replay({**c.certificate, "section": {**sec, "hole": narrow}})
    assert not r["valid"] and any("evidence does not hold" in e for e in r["errors"])


def test_without_its_loop_the_ring_is_not_proved_where_two_discs_hold_its_section(ring):
    from sieve_mi.certify import link

    real = link.find_loops
    link.find_loops = lambda shape: []  # the section tests alone: each bar fits one disc
    try:
        c = section_only(ring, _holes(1.0), 1.0, 1.0)
    finally:
        link.find_loops = real
    assert c.proved_section is None
    assert math.isfinite(c.diameter)


def test_its_loop_proves_the_ring_across_a_narrow_web_and_the_replay_checks_the_loop(ring):
    """Stood on edge across the 1 mm web, the ring's bars fit the two discs, but its core loop
    would then link a loop of the plate around either disc: the link test excludes it."""
    from sieve_mi.certify.link import find_loops, inside_clearance

    loops = find_loops(ring)
    # the core loops lie between the bore's flats (2.31) and the outer flats (3.70), and within
    # the ring's height
    core = np.concatenate(loops)
    radii = np.linalg.norm(core[:, :2], axis=1)
    assert np.all(radii > 2.31) and np.all(radii < 3.70) and np.all(np.abs(core[:, 2]) < 2.0)
    assert all(inside_clearance(q, ring.vertices[ring.faces]) > 0 for q in loops)
    # a 3 mm plate: the bars' facing sides are 2 sqrt(2.31^2 - 1.5^2) = 3.5 apart, and each bar
    # (4 x 2.24 mm at most) fits one disc; fewer points than the default keep the test short
    settings = Settings(max_candidates=1000, edge_spacing=0.03)
    c = section_only(ring, _holes(1.0), 3.0, 30.0, settings)
    assert c.section["status"] == "proved"
    sec = c.certificate["section"]
    kinds = _evidence_kinds(sec["tree"])
    assert "link" in kinds and "loops" in sec
    assert replay(c.certificate)["valid"]
    # a loop shrunk into the bore (radius 2.2 < 2.31) is not inside the ring: rejected
    q = np.asarray(sec["loops"][0])
    bore = (q * (2.2 / np.linalg.norm(q[:, :2], axis=1).max())).tolist()
    r = replay({**c.certificate, "section": {**sec, "loops": [bore] + sec["loops"][1:]}})
    assert not r["valid"] and any("section.loops" in e for e in r["errors"])
    # a link between two loop vertices that are not both on the loop's stretches: rejected
    leaf = _first_link(sec["tree"])
    path = leaf["path"]
    k = next(i for i in range(len(path) - 1) if isinstance(path[i], list)
             and isinstance(path[i + 1], list) and path[i][0] == path[i + 1][0])  # fmt: skip
    q = sec["loops"][path[k][0]]
    far = [path[k][0], (path[k][1] + len(q) // 4) % len(q)]  # a quarter turn round the loop
    leaf["path"] = path[: k + 1] + [far] + path[k + 2 :]
    r = replay(c.certificate)
    assert not r["valid"] and any("evidence does not hold" in e for e in r["errors"])
    leaf["path"] = path
    # without its loops the link leaves do not hold
    r = replay({**c.certificate, "section": {k: v for k, v in sec.items() if k != "loops"}})
    assert not r["valid"]


def _first_link(tree: list) -> dict:
    """The evidence of the first leaf whose path takes a link step."""
    todo = list(tree)
    while todo:
        node = todo.pop()
        todo += node.get("c", [])
        ev = node.get("e")
        if ev and ev["kind"] == "link":
            path = ev["path"]
            if any(isinstance(a, list) and isinstance(b, list) and a[0] == b[0]
                   for a, b in zip(path, path[1:])):  # fmt: skip
                return ev
    raise AssertionError("no link step")
