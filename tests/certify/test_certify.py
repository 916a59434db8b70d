"""Certified blocks (issue 11): proofs, passages and the independent replay, on known answers.

Known answers used here:

* the hole of a face-on 20 mm cube grown by 1 mm is a 22 mm rounded square: its largest inscribed
  disk has radius 11, so the 24 mm sphere (inscribed ball radius ~11.9) and the 23 mm cube (11.5)
  cannot pass, while a 15 mm cube passes face-on;
* Nieuwland: the unit cube seen along (2, 2, -1) holds a square of side 3 sqrt(2) / 4 = 1.0607 and
  no cube larger than that passes a unit cube, so a 1.04 cube passes and a 1.08 cube cannot.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import io
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from sieve_mi.certify import cells, certify, read_svg_hole, replay, symmetry
from sieve_mi.certify.bounds import OffsetCache, boundary_distance, contour_segments, width_test
from sieve_mi.certify.search import Settings
from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import hole_outline
from sieve_mi.geometry.rotations import align, to_matrix
from sieve_mi.testing import shapes


def _shape(mesh, name="b"):
    return shape_from_trimesh(mesh, name=name)


@pytest.fixture(scope="module")
def cube_hole():
    cube = _shape(shapes.cube(20.0), "cube")
    return hole_outline([cube], np.array([[1.0, 0, 0, 0]]), np.zeros((1, 2)), 1.0, closed=[True])


@pytest.fixture(scope="module")
def nieuwland_hole():
    unit = _shape(shapes.cube(1.0), "unit")
    q = align(np.array([2.0, 2.0, -1.0]), np.array([0.0, 0.0, 1.0]))
    return hole_outline([unit], q[None], np.zeros((1, 2)), 0.0, closed=[True])


@pytest.fixture(scope="module")
def proof_108(nieuwland_hole):
    return certify(_shape(shapes.cube(1.08)), [nieuwland_hole], budget_s=60)


# ------------------------------------------------------------------------------------------------
# Geometry of the cells and the bounds
# ------------------------------------------------------------------------------------------------


def test_root_face_covering_angle_is_60_degrees():
    # The centre (1,0,0,0) and the corner (1,1,1,1)/2 are 60 degrees apart on S^3.
    theta = cells.covering_angles(cells.roots([0, 1, 2, 3], 1.0))
    assert np.allclose(theta, math.pi / 3, atol=1e-9)


def test_covering_angle_bounds_every_rotation_of_the_cell():
    rng = np.random.default_rng(0)
    c = cells.Cells(np.array([2]), np.array([[0.1, -0.3, 0.2]]), np.array([[0.35, -0.05, 0.45]]))
    q0 = cells.centres(c)[0]
    v = c.lo + rng.random((2000, 3)) * (c.hi - c.lo)
    q = cells.face_quaternions(np.full(2000, 2), v)
    angles = np.arccos(np.clip(q @ q0, -1, 1))
    theta = cells.covering_angles(c)[0]
    assert angles.max() <= theta
    assert angles.max() > 0.9 * theta  # attained near a corner


def test_split_covers_the_parent_exactly():
    parent = cells.roots([1], 1.0)
    kids = cells.split(parent)
    assert len(kids) == 8
    assert np.isclose(cells.volumes(kids).sum(), cells.volumes(parent)[0])
    assert np.allclose(kids.lo.min(0), -1) and np.allclose(kids.hi.max(0), 1)


def test_symmetry_groups():
    assert symmetry.detect(_shape(shapes.cube(10.0))) == "octahedral"
    assert symmetry.detect(_shape(shapes.box(20.0, 10.0, 5.0))) == "klein"
    bent = shapes.box(20.0, 10.0, 5.0)
    v = bent.vertices.copy()
    v[np.argmax(v.sum(1))] *= 1.2
    assert symmetry.detect(_shape(trimesh.Trimesh(v, bent.faces))) == "none"


def test_offsets_contain_the_exact_dilation(cube_hole):
    # Every point of the offset's boundary is at least r from H: the polygon contains H + disk(r).
    cache = OffsetCache(cube_hole, eta=1e-6, r_min=1e-6)
    segs = contour_segments([np.asarray(c) for c in cube_hole.to_polygons()])
    for r in (0.01, 0.7, 3.0):
        contour = np.asarray(cache.get(r).to_polygons()[0])
        nxt = np.roll(contour, -1, axis=0)
        t = np.linspace(0, 1, 50)[:, None, None]
        samples = (contour[None] + t * (nxt - contour)[None]).reshape(-1, 2)
        assert boundary_distance(samples, segs).min() >= r


def test_width_test_excludes_points_wider_than_the_hole():
    # Two points 30 mm apart along x, displacement bound 1 mm each, against a 22 mm wide square.
    square = np.array([[-11.0, -11], [11, -11], [11, 11], [-11, 11]])
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    support = np.stack([(square @ dirs.T).max(0), (square @ dirs.T).min(0)])
    proj = np.array([[[-15.0, 0.0], [15.0, 0.0]], [[-9.0, 0.0], [9.0, 0.0]]])
    excluded, direction = width_test(proj, np.ones((2, 2)), support, dirs, 1e-9)
    assert excluded.tolist() == [True, False]  # 30 - 2 > 22, but 18 - 2 < 22
    assert direction.tolist() == [0, -1]


# ------------------------------------------------------------------------------------------------
# Known answers
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "mesh", [shapes.sphere(12.0), shapes.cube(23.0)], ids=["sphere-24", "cube-23"]
)
def test_balls_too_big_for_the_cube_hole_are_proved_at_the_root(cube_hole, mesh):
    result = certify(_shape(mesh), [cube_hole], budget_s=10)
    assert result.status == "proved" and result.method == "ball"
    assert 11.0 < result.certificate["root"]["radius"] < 12.0
    assert replay(result.certificate)["proved"]


def test_smaller_cube_finds_a_passage_that_really_fits(cube_hole):
    from sieve_mi.geometry.outline import placed_vertices, projection

    shape = _shape(shapes.cube(15.0))
    result = certify(shape, [cube_hole], budget_s=10)
    assert result.status == "passage"
    p = result.passage
    sil = projection(placed_vertices(shape, p["quaternion"], p["translation"]), shape.faces)
    assert sil.area() >= 15.0**2 - 1e-6  # at least a face's area
    assert (sil - cube_hole).area() < 1e-9
    rep = replay(result.certificate)
    assert rep["valid"] and not rep["proved"]


def test_nieuwland_cube_108_proved_blocked(proof_108):
    assert proof_108.status == "proved" and proof_108.method == "cells"
    assert proof_108.symmetry == "octahedral"
    assert proof_108.cells_open == 0
    assert proof_108.excluded_fraction == pytest.approx(1.0)
    rep = replay(proof_108.certificate)
    assert rep["proved"] and rep["leaves"] == proof_108.cells_excluded


def test_nieuwland_cube_104_passes(nieuwland_hole):
    result = certify(_shape(shapes.cube(1.04)), [nieuwland_hole], budget_s=60)
    assert result.status == "passage"
    assert 0 < result.excluded_fraction < 1


def test_budget_exhausted_is_undecided(nieuwland_hole):
    result = certify(_shape(shapes.cube(1.062)), [nieuwland_hole], budget_s=0.05)
    assert result.status == "undecided" and result.cells_open > 0
    assert 0 <= result.excluded_fraction < 1
    rep = replay(result.certificate)
    assert rep["valid"] and not rep["proved"] and rep["open"] == result.cells_open


# ------------------------------------------------------------------------------------------------
# The replay rejects corrupted certificates
# ------------------------------------------------------------------------------------------------


def _first_split(node):
    if "c" in node:
        return node
    raise AssertionError("no split node")


def test_replay_rejects_a_moved_point(proof_108):
    cert = copy.deepcopy(proof_108.certificate)
    cert["shape"]["points"][0][0] += 0.01
    rep = replay(cert)
    assert not rep["valid"] and any("neither vertices nor on edges" in e for e in rep["errors"])


def test_replay_rejects_a_removed_leaf(proof_108):
    cert = copy.deepcopy(proof_108.certificate)
    _first_split(cert["tree"][0])["c"].pop()
    assert not replay(cert)["valid"]


@pytest.mark.parametrize("factor", [1.1, 1.5])
def test_replay_rejects_a_wider_hole(proof_108, factor):
    # Scaled 1.5x every leaf fails (the replay ran > 300 s): it stops after MAX_ERRORS problems.
    cert = copy.deepcopy(proof_108.certificate)
    cert["hole"] = [(np.asarray(c) * factor).tolist() for c in cert["hole"]]
    rep = replay(cert)
    assert not rep["valid"] and any("evidence does not hold" in e for e in rep["errors"])
    assert len(rep["errors"]) <= 10 and rep["seconds"] < 60


def test_replay_rejects_a_ball_proof_against_a_wider_hole(cube_hole):
    cert = copy.deepcopy(certify(_shape(shapes.sphere(12.0)), [cube_hole], budget_s=5).certificate)
    cert["hole"] = [(np.asarray(c) * 1.2).tolist() for c in cert["hole"]]
    assert not replay(cert)["valid"]


def test_replay_rejects_a_false_symmetry_claim(proof_108):
    cert = copy.deepcopy(proof_108.certificate)
    v = np.asarray(cert["shape"]["vertices"])
    v[0] *= 1.01  # no longer a cube (and the stored hash no longer matches)
    cert["shape"]["vertices"] = v.tolist()
    rep = replay(cert)
    assert not rep["valid"] and any("symmetric" in e for e in rep["errors"])


# ------------------------------------------------------------------------------------------------
# Input: SVG holes and the command line
# ------------------------------------------------------------------------------------------------


def test_svg_hole_round_trip(tmp_path, cube_hole):
    from sieve_mi.outputs.fabrication import write_svg

    path = str(tmp_path / "hole.svg")
    write_svg(path, cube_hole)
    back = read_svg_hole(path)
    assert back.area() == pytest.approx(cube_hole.area(), rel=1e-5)
    assert back.bounds() == pytest.approx(cube_hole.bounds(), abs=1e-4)


def test_bad_svg_is_one_clear_error(tmp_path):
    bad = tmp_path / "bad.svg"
    bad.write_text("<svg><path d='M 0 0 L 1 0'/></svg>")
    with pytest.raises(SieveError, match="no polygon|no area"):
        read_svg_hole(str(bad))


def _cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", "certify", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


def _main(*args) -> subprocess.CompletedProcess:
    """``sieve-mi certify ARGS`` in this process (:func:`sieve_mi.cli.main`): its exit code and
    what it printed, as :func:`_cli` gives them (about a CPU second less than a process; the
    certify and replay runs of :func:`test_cli_certifies_writes_and_replays` and the exit codes'
    test are real processes)."""
    from sieve_mi.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["certify", *args])
    return subprocess.CompletedProcess(list(args), code, out.getvalue(), err.getvalue())


def test_cli_certifies_writes_and_replays(tmp_path, cube_hole):
    from sieve_mi.outputs.fabrication import write_svg

    mesh, svg, cert = tmp_path / "s.stl", str(tmp_path / "h.svg"), str(tmp_path / "c.json")
    shapes.sphere(12.0).export(str(mesh))
    write_svg(svg, cube_hole)
    run = _cli(str(mesh), "--hole", svg, "--json", "--certificate", cert)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["status"] == "proved"
    again = _cli("--replay", cert, "--json")
    assert again.returncode == 0 and json.loads(again.stdout)["proved"]


def _digests(folder) -> dict:
    return {
        f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in folder.iterdir() if f.is_file()
    }


@pytest.mark.parametrize(
    "target, message",
    [
        ("s.stl", "is an input of this run"),  # the mesh itself (it was replaced by JSON)
        ("h.svg", "is an input of this run"),
        ("notes.txt", "is not a sieve-mi certificate"),
        ("other.json", "is not a sieve-mi certificate"),
        ("sub", "is a folder"),
    ],
)
def test_cli_certificate_never_overwrites_a_file_it_did_not_write(
    tmp_path, cube_hole, target, message
):
    from sieve_mi.outputs.fabrication import write_svg

    shapes.sphere(12.0).export(str(tmp_path / "s.stl"))
    write_svg(str(tmp_path / "h.svg"), cube_hole)
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    (tmp_path / "sub").mkdir()
    before = _digests(tmp_path)
    run = _main(str(tmp_path / "s.stl"), "--hole", str(tmp_path / "h.svg"), "--certificate",
                str(tmp_path / target))  # fmt: skip
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], run.stderr
    assert _digests(tmp_path) == before  # every file byte-identical, nothing added
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "h.svg",
        "notes.txt",
        "other.json",
        "s.stl",
        "sub",
    ]
    assert not any((tmp_path / "sub").iterdir())


def test_cli_certificate_replaces_its_own_earlier_certificate(tmp_path, cube_hole):
    from sieve_mi.outputs.fabrication import write_svg

    mesh, svg, cert = tmp_path / "s.stl", str(tmp_path / "h.svg"), str(tmp_path / "c.json")
    shapes.sphere(12.0).export(str(mesh))
    write_svg(svg, cube_hole)
    for _ in range(2):  # the second run replaces the first run's certificate
        run = _main(str(mesh), "--hole", svg, "--certificate", cert)
        assert run.returncode == 0, run.stderr
    assert json.loads(open(cert).read())["format"] == "sieve-mi-certificate/1"


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.stl", "--hole", "h.svg"], "not found"),
        (["--replay", "missing.json"], "certificate not found"),
        (["SHAPE"], "needs SHAPE and --sieve"),
        (["SHAPE", "--hole", "HOLE", "--budget", "-1"], "--budget"),
    ],
)
def test_cli_bad_input_one_line_exit_2(tmp_path, args, message):
    mesh = tmp_path / "s.stl"
    shapes.cube(5.0).export(str(mesh))
    args = [str(mesh) if a == "SHAPE" else a for a in args]
    args = [os.path.join(tmp_path, "h.svg") if a == "HOLE" else a for a in args]
    run = _main(*args)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sieve-mi: error:") and message in lines[0]


@pytest.mark.slow
def test_solve_certifies_its_blocks_and_a_passage_overrules_the_verdict(write_scene, tmp_path):
    # A: a 20 mm cube held face-on, tolerance 1 mm: the printed hole is a 22 mm square with
    # rounded corners. B: the 24 mm ball (no 24 mm disk fits in a 22 mm square: proved) and a
    # 21 x 21 x 22 mm box, which passes face-on and turned by less than about 2.6 degrees in the
    # plane (21 (|cos a| + |sin a|) <= 22). A verdict of one start and no Adam steps misses that
    # passage; certify must find it through the exact hole and hand the win to B.
    from sieve_mi.api import solve
    from sieve_mi.outputs.console import summary_table
    from sieve_mi.outputs.report import report_dict
    from sieve_mi.scene import load_scene

    body = """name = "t"
[[pass]]
mesh = "meshes/a.stl"
rotation = [1, 0, 0, 0]
[[block]]
mesh = "meshes/ball.stl"
[[block]]
mesh = "meshes/b.stl"
[fabrication]
tolerance = 1.0
[solver]
resolution = 64
[verdict]
starts = 1
steps = 0
resolution = 128
certify = true
certify_budget = 60
"""
    meshes = {
        "a.stl": trimesh.creation.box((20.0, 20.0, 20.0)),
        # 21 x 21 x 22 mm: face-on it passes the 22 mm rounded square, but it fits inside no
        # 20 mm cube grown by 1 mm (its corners are sqrt(0.5² + 0.5² + 1²) = 1.22 mm out), so the
        # feasibility test leaves it to the game (a 21 mm cube is unblockable from 0.87 mm)
        "b.stl": trimesh.creation.box((21.0, 21.0, 22.0)),
        "ball.stl": trimesh.creation.icosphere(4, 12.0),
    }
    r = solve(load_scene(write_scene(body, meshes)), progress=False)
    assert r.feasibility.impossible == []
    assert r.attack.blocked()[0].all()  # the weak verdict saw no passage
    ball, cube = r.certified
    assert ball.status == "proved" and ball.method == "ball"
    assert cube.status == "passage"
    q = np.asarray(cube.passage["quaternion"])
    # the passage holds the cube nearly face-on: one of its axes within a few degrees of z
    axis_z = np.abs(to_matrix(q)[2]).max()
    assert axis_z > np.cos(np.radians(5.0))
    assert r.winner == "B" and any("certify" in w for w in r.warnings)
    rep = report_dict(r)
    assert [b["certified"] for b in rep["block"]] == ["proved", "passage"]
    assert [b["blocked"] for b in rep["block"]] == [True, False]
    assert "passage" in summary_table(rep) and "proved" in summary_table(rep)
    # the ball (inscribed radius just under 12) against the 22 mm square: the largest disk in
    # the square grown by m has radius 11 + m, so the true margin is just under 1 mm; five
    # bisection steps from the protrusion found come within found / 32 of it
    saved = r.save(str(tmp_path / "out"), figure=False, animation=False)
    m = saved["block"][0]["margin"]
    assert 1.0 - m["found_at_most"] / 32 - 0.02 < m["proved_at_least"] <= 1.0 + 1e-9
    for key in ("certificate", "margin_certificate"):
        path = tmp_path / "out" / saved["block"][0]["certification"][key]
        assert replay(str(path))["valid"]


def test_cli_exit_codes_say_proved_passage_undecided_invalid(tmp_path):
    # docs/cli.md: 0 proved (or a valid certificate), 3 a passage (or an invalid certificate),
    # 4 the budget ran out with cells open. The hole is a 22 mm square.
    import manifold3d

    from sieve_mi.outputs.fabrication import write_svg

    svg = str(tmp_path / "h.svg")
    write_svg(svg, manifold3d.CrossSection.square([22.0, 22.0], center=True))
    shapes.sphere(12.0).export(str(tmp_path / "ball.stl"))  # no disk of its size fits
    shapes.cube(10.0).export(str(tmp_path / "small.stl"))  # face-on it passes
    trimesh.creation.box((31.5, 31.5, 4.0)).export(str(tmp_path / "slab.stl"))  # hard to decide
    cert = str(tmp_path / "ball.json")
    runs = {  # the proved ball in a process of its own, the others in this one
        name: (_cli if name == "ball" else _main)(
            str(tmp_path / f"{name}.stl"),
            "--hole",
            svg,
            "--budget",
            "0.05",
            "--json",
            *(["--certificate", cert] if name == "ball" else []),
        )  # fmt: skip
        for name in ("ball", "small", "slab")
    }
    statuses = {name: json.loads(r.stdout)["status"] for name, r in runs.items()}
    assert statuses == {"ball": "proved", "small": "passage", "slab": "undecided"}
    assert {name: r.returncode for name, r in runs.items()} == {"ball": 0, "small": 3, "slab": 4}
    assert _main("--replay", cert).returncode == 0
    forged = json.load(open(cert))
    forged["root"]["radius"] *= 3  # a ball that does not fit inside the sphere
    with open(tmp_path / "forged.json", "w") as fh:
        json.dump(forged, fh)
    bad = _cli("--replay", str(tmp_path / "forged.json"))
    assert bad.returncode == 3 and "certificate INVALID" in bad.stdout


def test_replay_far_outside_test_agrees_with_exact_distances(nieuwland_hole):
    """The replay's k-d tree shortcut (:meth:`Hole.beyond`) decides exactly like the exact
    point-to-segment distances, also for points within a sample spacing of their bound."""
    from sieve_mi.certify.replay_geometry import Hole

    hole = Hole([np.asarray(c, float) for c in nieuwland_hole.to_polygons()])
    rng = np.random.default_rng(3)
    lo, hi = hole.vertices.min(0) - 0.5, hole.vertices.max(0) + 0.5
    p = rng.uniform(lo, hi, size=(4000, 2))
    exact = hole.outside_by(p)
    # bounds at, just below and just above each point's exact distance, and random ones
    for bound in (exact, exact * (1 - 1e-7), exact * (1 + 1e-7) + 1e-12, rng.uniform(0, 0.3, 4000)):
        assert np.array_equal(hole.beyond(p, bound), exact > bound)


@pytest.fixture(scope="module")
def two_squares():
    """Two 4 mm squares 6 mm apart (x in [-7, -3] and [3, 7])."""
    import manifold3d

    sq = manifold3d.CrossSection.square((4.0, 4.0), center=True)
    return sq.translate((-5.0, 0.0)) + sq.translate((5.0, 0.0))


@pytest.fixture(scope="module")
def plate_proof(two_squares):
    plate = shape_from_trimesh(shapes.box(12.0, 12.0, 0.5), name="plate")
    return certify(plate, [two_squares], budget_s=60)


def test_edge_points_prove_what_vertices_cannot(two_squares, plate_proof):
    """A 12 x 12 x 0.5 mm plate cannot pass two disjoint 4 mm squares: its shadow is connected,
    so it must fit one square, yet it always holds a 12 mm segment (the plate's in-plane direction
    across the view), longer than the square's 5.66 mm diagonal. Seen edge-on along x, its eight
    corners sit at x = +-6, inside both squares, while its edges cross the 6 mm gap: vertices
    alone can never exclude the rotations near that pose; points on the edges do."""
    assert plate_proof.status == "proved" and plate_proof.method == "cells"
    assert plate_proof.symmetry == "klein"  # the box's half turns map its edges onto edges
    on_edge = plate_proof.certificate["shape"]["on_edge"]
    assert any(r is not None for r in on_edge)
    assert replay(plate_proof.certificate)["valid"]
    plate = shape_from_trimesh(shapes.box(12.0, 12.0, 0.5), name="plate")
    vertices_only = certify(plate, [two_squares], budget_s=5, settings=Settings(edge_spacing=0))
    assert vertices_only.status == "undecided"


def test_replay_rejects_an_edge_point_off_the_edges(plate_proof):
    cert = copy.deepcopy(plate_proof.certificate)
    k = next(i for i, r in enumerate(cert["shape"]["on_edge"]) if r is not None)
    faces = np.asarray(cert["shape"]["faces"])
    used = {frozenset(e) for f in faces for e in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2]))}
    n = len(cert["shape"]["vertices"])
    i, j = next((i, j) for i in range(n) for j in range(i + 1, n) if frozenset((i, j)) not in used)
    cert["shape"]["on_edge"][k] = [i, j, 0.5]  # a diagonal through the box: not an edge
    rep = replay(cert)
    assert not rep["valid"] and any("neither vertices nor on edges" in e for e in rep["errors"])


# ------------------------------------------------------------------------------------------------
# The first-order displacement bound (issue 28, item 1) and the batched quadtree (item 2)
# ------------------------------------------------------------------------------------------------


def _random_cells(rng, n, depths=(2, 9)):
    """Random cells of the quaternion cube's faces at random depths (half-width 2^(1 - depth))."""
    face = rng.integers(0, 4, n)
    h = 2.0 ** (1 - rng.integers(*depths, n))
    vc = -1.0 + h[:, None] * (2 * np.floor(rng.random((n, 3)) / h[:, None]) + 1)
    return cells.Cells(face, vc - h[:, None], vc + h[:, None])


def test_first_order_derivatives_match_finite_differences():
    rng = np.random.default_rng(5)
    c = _random_cells(rng, 20)
    fr = cells.frames(c)
    assert np.allclose(fr.rot, to_matrix(cells.centres(c)), atol=1e-14)
    vc, h = 0.5 * (c.lo + c.hi), 0.5 * (c.hi - c.lo)
    for j in range(3):
        step = np.zeros(3)
        step[j] = 1e-6
        ahead = to_matrix(cells.face_quaternions(c.face, vc + step))
        behind = to_matrix(cells.face_quaternions(c.face, vc - step))
        numeric = (ahead - behind) / 2e-6 * h[:, j, None, None]
        assert np.allclose(fr.steps[:, j], numeric, atol=1e-8)


def test_first_order_bound_contains_sampled_projections():
    """For random points and random rotations of random cells (corners included), the projection
    lies within the bound of the centre's; the bound is also nearly attained for small cells (it
    is exact to first order), and never worse than isotropic by more than its second-order term."""
    rng = np.random.default_rng(7)
    points = rng.normal(size=(40, 3)) * np.array([15.0, 10.0, 6.0])
    c = _random_cells(rng, 48)
    proj, bound = cells.first_order(cells.frames(c), points)
    for i in range(len(c)):
        v = c.lo[i] + rng.random((400, 3)) * (c.hi[i] - c.lo[i])
        v = np.vstack([v, cells.corners(c.take([i]))[0]])
        rot = to_matrix(cells.face_quaternions(np.full(len(v), c.face[i]), v))
        moved = np.einsum("mij,kj->mki", rot[:, :2], points)
        reach = np.linalg.norm(moved - proj[i][None], axis=-1).max(axis=0)
        assert (reach <= bound[i]).all()
        if c.hi[i, 0] - c.lo[i, 0] <= 2.0**-5:
            assert (reach / bound[i]).max() > 0.9


def test_first_order_radius_against_the_isotropic_one_known_answers():
    """Face 0 (w = 1), the cell [-h, h]^3 about the identity: dR/dv_j = 2 [e_j]x, so a point p
    moves by 2 e_j x p per unit v_j to first order. For p = a x^ only the turn about z shows
    (along y): first-order radius 2 a h, plus the second-order term (D_c / D_min = 1,
    |h|^2 = 3 h^2, |p| + |P p| = 2a): 2 a h + 6 a h^2. The isotropic radius is
    2 sin(theta) a with tan(theta) = sqrt(3) h (the corner), about 2 sqrt(3) a h: sqrt(3) times
    larger. For p = a z^ (along the view) the turns about x and y move it along y and x:
    2 sqrt(2) a h (plus 3 a h^2: its projection is 0), sqrt(3 / 2) times smaller than
    isotropic."""
    a, h = 10.0, 2.0**-6
    c = cells.roots([0], h)
    fr = cells.frames(c)
    assert np.allclose(fr.scale, 1.0) and np.allclose(fr.quad, 3 * h * h)
    _, bound = cells.first_order(fr, np.array([[a, 0, 0], [0, 0, a]]))
    assert bound[0, 0] == pytest.approx(2 * a * h + 6 * a * h * h, rel=1e-8)
    assert bound[0, 1] == pytest.approx(2 * math.sqrt(2) * a * h + 3 * a * h * h, rel=1e-8)
    iso = cells.displacement(cells.covering_angles(c), np.array([a, a]))[0]
    assert iso[0] == pytest.approx(2 * math.sqrt(3) * a * h / math.sqrt(1 + 3 * h * h), rel=1e-9)
    assert bound[0, 0] / iso[0] < 1 / math.sqrt(3) * (1 + 4 * h)
    assert bound[0, 1] / iso[1] < math.sqrt(2 / 3) * (1 + 4 * h)


def test_replay_first_order_bound_is_its_own_and_agrees():
    from sieve_mi.certify.replay_geometry import first_order_bounds

    rng = np.random.default_rng(11)
    points = rng.normal(size=(30, 3)) * 12.0
    c = _random_cells(rng, 30)
    proj, bound = cells.first_order(cells.frames(c), points)
    for i in range(len(c)):
        p2, b2 = first_order_bounds(int(c.face[i]), c.lo[i], c.hi[i], points)
        assert np.allclose(p2, proj[i], rtol=1e-12, atol=1e-12)
        assert np.allclose(b2, bound[i], rtol=1e-12, atol=1e-12)


def test_first_order_bound_proves_with_fewer_cells(nieuwland_hole, proof_108):
    """The 1.08 cube against Nieuwland's hole, isotropic against first-order bounds: both proved
    and replayed; the tighter bound needs fewer cells."""
    iso = certify(
        _shape(shapes.cube(1.08)),
        [nieuwland_hole],
        budget_s=60,
        settings=Settings(bound="isotropic"),
    )
    assert iso.status == "proved" and replay(iso.certificate)["proved"]
    assert proof_108.certificate["settings"]["bound"] == "first-order"
    assert proof_108.cells_examined < 0.9 * iso.cells_examined


def test_old_isotropic_certificates_still_replay(nieuwland_hole):
    # A certificate written before the first-order bound has no "bound": the replay reads it as
    # isotropic.
    old = certify(
        _shape(shapes.cube(1.08)),
        [nieuwland_hole],
        budget_s=60,
        settings=Settings(bound="isotropic"),
    ).certificate
    del old["settings"]["bound"]
    assert replay(old)["proved"]


def test_replay_uses_the_bound_the_certificate_names(proof_108):
    """A first-order proof relabelled isotropic fails (its leaves need the tighter radii); an
    unknown bound is an error."""
    cert = copy.deepcopy(proof_108.certificate)
    cert["settings"]["bound"] = "isotropic"
    assert not replay(cert)["valid"]
    cert["settings"]["bound"] = "zeroth-order"
    rep = replay(cert)
    assert not rep["valid"] and any("unknown displacement bound" in e for e in rep["errors"])


def test_even_odd_region_matches_the_crossing_count(two_squares):
    """H as shapely's prepared contours, even-odd, against the NumPy crossing count on 20k random
    points: two squares, and a 10 mm square with a 4 mm square hole holding a 2 mm island (three
    nested contours: inside, outside, inside again)."""
    import manifold3d

    from sieve_mi.certify.bounds import inside
    from sieve_mi.certify.search import EvenOdd

    sq = manifold3d.CrossSection.square
    nested = (sq((10.0, 10.0), center=True) - sq((4.0, 4.0), center=True)) + sq(
        (2.0, 2.0), center=True
    )
    rng = np.random.default_rng(5)
    p = rng.uniform(-12, 12, size=(20000, 2))
    for hole in (two_squares, nested):
        contours = [np.asarray(c, float) for c in hole.to_polygons()]
        got = EvenOdd(contours).contains_points(p)
        assert (got == inside(p, contour_segments(contours))).all()
    region = EvenOdd([np.asarray(c, float) for c in nested.to_polygons()])
    # the ring between 2 and 4 mm is outside, the island and the band from 4 to 10 mm inside
    probe = np.array([[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [6.0, 0.0]])
    assert region.contains_points(probe).tolist() == [True, False, True, False]


def test_lower_distance_is_a_lower_bound(two_squares):
    from sieve_mi.certify.bounds import LowerDistance, inside
    from sieve_mi.certify.search import EvenOdd

    contours = [np.asarray(c, float) for c in two_squares.to_polygons()]
    segs = contour_segments(contours)
    lower = LowerDistance(segs, EvenOdd(contours))
    rng = np.random.default_rng(2)
    p = rng.uniform(-12, 12, size=(20000, 2))
    exact = np.where(inside(p, segs), 0.0, boundary_distance(p, segs))
    got = lower(p)
    assert (got <= exact).all()
    # close where the grid reaches (5 % of H's size around its box): the node is at most
    # pitch / sqrt(2) away, counted twice (d(g) <= d(x) + |x - g|), plus half a sample spacing
    # (a quarter pitch): within 1.67 pitches
    near = ((p >= lower.lo) & (p <= lower.lo + lower.pitch * lower.top)).all(axis=1)
    assert near.sum() > 2000
    assert (got[near] >= exact[near] - 1.67 * lower.pitch).all()


def test_translation_quadtree_excludes_what_the_width_test_cannot(two_squares):
    """Two 4 mm squares, x in [-7, -3] and [3, 7]; points at x = -4, 0, 4 (a cell's projections).
    With radius 0.2 the middle point needs |t_x| >= 2.8, and then one end point is 1.8 mm from
    both squares: no translation works, though 8.4 mm fits the 14 mm hull. With radius 2,
    t_x = 1.5 fits all three (1.5, 0 and 0.5 mm from H)."""
    from sieve_mi.certify.bounds import LowerDistance, translation_quadtree
    from sieve_mi.certify.search import EvenOdd

    contours = [np.asarray(c, float) for c in two_squares.to_polygons()]
    segs = contour_segments(contours)
    lower = LowerDistance(segs, EvenOdd(contours))
    proj = np.array([[[-4.0, 0.0], [0.0, 0.0], [4.0, 0.0]]] * 2)
    radii = np.array([[0.2] * 3, [2.0] * 3])
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    support = np.stack([(segs[:, 0] @ dirs.T).max(0), (segs[:, 0] @ dirs.T).min(0)])
    assert not width_test(proj, radii, support, dirs, 1e-9)[0].any()
    assert translation_quadtree(lower, proj, radii, steps=8).tolist() == [True, False]
