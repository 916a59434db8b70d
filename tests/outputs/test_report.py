"""report.json, the console table and the written images, on one small solved scene."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from helpers import REPO

from sieve_mi.api import solve
from sieve_mi.outputs.report import paste_window, report_dict, summary_table, write_outputs
from sieve_mi.scene import load_scene
from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT, settings_toml

MESHES = os.path.abspath(os.path.join(REPO, "scenes", "meshes"))
SCENE = f"""name = "report test"
[[pass]]
mesh = "{MESHES}/cube.stl"
[[block]]
mesh = "{MESHES}/sphere.stl"
[[block]]
mesh = "{MESHES}/small_sphere.stl"
""" + settings_toml(solver=TINY_SOLVER, verdict={**TINY_VERDICT, "steps": 60})


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.toml"
    path.write_text(SCENE)
    return solve(load_scene(str(path)), progress=False)


def test_report_numbers_are_the_results(solved):
    r = solved
    rep = report_dict(r)
    assert rep["winner"] == r.winner
    assert rep["winner"] == ("A" if all(b["blocked"] for b in rep["block"]) else "B")
    for j, b in enumerate(rep["block"]):
        assert b["beta"] == b["loss"] == pytest.approx(float(r.attack.beta[0, j]))
        assert b["protrusion"] == pytest.approx(float(r.attack.protrusion[0, j]))
        assert np.linalg.norm(b["rotation"]) == pytest.approx(1.0, abs=1e-6)
    h = r.hole.frame.pixel_size
    assert rep["pixel_size"] == h
    assert rep["hole"]["raster_area"] == pytest.approx(r.hole.mask.sum() * h * h)
    assert rep["hole"]["area"] == pytest.approx(r.outline.area())  # the printed polygon's
    assert all(b["verdict"] == "exact-polygon" for b in rep["block"])
    assert rep["provenance"]["seed"] == r.seed == 0
    json.loads(json.dumps(rep))  # plain JSON, no NumPy scalars


def test_small_sphere_passes_the_cube_hole(solved):
    # The 12 mm ball fits through any 20 mm cube's hole (every projection of the cube contains
    # the projection of its inscribed 20 mm ball): it must be reported as passing, with β = 0.
    rep = report_dict(solved)
    small = next(b for b in rep["block"] if b["name"] == "small_sphere")
    assert not small["blocked"] and small["beta"] == 0.0 and rep["winner"] == "B"


def test_summary_table_has_one_row_per_shape(solved):
    rep = report_dict(solved)
    text = summary_table(rep)
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["role", "shape", "beta"]
    rows = [ln.split() for ln in lines[2:] if ln.startswith(("pass", "block"))]
    assert [r[1] for r in rows] == ["cube", "sphere", "small_sphere"]
    small = rows[2]
    assert small[2] == "0.0000" and small[-1] == "PASSES"
    assert f"winner: {rep['winner']}" in text


def test_written_images_are_the_hole(solved, tmp_path):
    import mitsuba as mi
    from PIL import Image

    out = tmp_path / "out"
    rep = write_outputs(solved, str(out), fabricate=False)
    on_disk = json.loads((out / "report.json").read_text())
    assert on_disk["winner"] == rep["winner"] and on_disk["block"] == rep["block"]
    png = np.array(Image.open(out / "hole.png")) > 127
    exr = np.array(mi.Bitmap(str(out / "hole.exr"))).reshape(png.shape) > 0.5
    assert np.array_equal(png, solved.hole.mask) and np.array_equal(exr, solved.hole.mask)
    assert (out / ".sieve-mi").is_file()
    assert {p.name for p in (out / "masks").iterdir()} >= {
        "a_silhouette.exr",
        "block_0_sphere.exr",
        "block_1_small_sphere.exr",
    }


def test_layered_exr_has_every_layer_on_one_lattice(solved, tmp_path):
    import manifold3d
    import mitsuba as mi

    from sieve_mi.geometry.outline import Boundary, silhouette

    out = tmp_path / "out"
    write_outputs(solved, str(out), fabricate=False)
    bitmap = mi.Bitmap(str(out / "masks.exr"))
    names = [f.name for f in bitmap.struct_()]
    data = np.array(bitmap)
    layer = {n: data[..., k] for k, n in enumerate(names)}
    assert set(names) == {
        "hole", "hole.cover", "distance", "a.0.cube", "b.0.sphere", "b.1.small_sphere",
    }  # fmt: skip
    meta = bitmap.metadata()
    frame = solved.hole.frame
    assert meta["pixel_size"] == pytest.approx(frame.pixel_size)
    assert [float(v) for v in meta["frame_origin"].split()] == [
        -frame.half_extent,
        frame.half_extent,
    ]
    h = frame.pixel_size
    hole, cover = layer["hole"] > 0.5, layer["hole.cover"] > 0.5
    # pixel centres inside the exact polygon: its area to within a ring of one pixel
    area = solved.outline.area()
    assert abs(hole.sum() * h * h - area) < 0.1 * area
    assert (cover >= hole).all() and np.array_equal(cover, solved.hole.mask)
    assert (layer["distance"][hole] == 0).all() and layer["distance"][~cover].min() > 0
    assert np.array_equal(layer["a.0.cube"] > 0.5, solved.a_masks[0])
    # the written B layers and files are Mitsuba renders of the verdict's attempts: the same
    # pixels as the verdict's ray-traced windows
    for j, name in enumerate(["b.0.sphere", "b.1.small_sphere"]):
        window = solved.block_masks[j]
        assert np.array_equal(layer[name] > 0.5, paste_window(window, frame))
        single = np.array(mi.Bitmap(str(out / "masks" / f"block_{j}_{name[4:]}.exr")))
        assert np.array_equal(single.reshape(window.mask.shape) > 0.5, window.mask)
    # each B's layer is its best attempt: its pixel centres lie on B's exact silhouette at the
    # reported pose (up to the ray caster's rounding), and that silhouette's area inside the frame
    # is covered to within a ring of one pixel
    x, y = frame.centres()
    for j, name in enumerate(["b.0.sphere", "b.1.small_sphere"]):
        shape = solved.block_shapes[j]
        sil = silhouette(shape, solved.attack.quats[0, j], solved.attack.trans[0, j])
        rows, cols = np.nonzero(layer[name] > 0.5)
        pts = np.column_stack([x[cols], y[rows]])
        assert len(pts) > 0 and Boundary(sil).signed(pts).max() <= 1e-6 * h
        box = manifold3d.CrossSection.square([2 * frame.half_extent] * 2, center=True)
        inside = (sil ^ box).area()
        assert abs(len(pts) * h * h - inside) <= 0.1 * inside


@pytest.mark.slow
def test_every_stage_is_timed_and_they_sum_to_the_wall_time(tmp_path):
    # A fresh solve (its start is recorded), saved with the plate, the figure and the GIF: the
    # stages in report.json add up to its total within 5 %, and the console's line says so.
    import time

    scene_path = tmp_path / "scene.toml"
    scene_path.write_text(SCENE)
    t0 = time.perf_counter()
    result = solve(load_scene(str(scene_path)), progress=False)
    report = result.save(str(tmp_path / "out"), figure=True, animation=True)
    wall = time.perf_counter() - t0
    t = report["timings"]
    for key in ("load_s", "search_s", "verdict_s", "images_s", "fabrication_s", "figure_s",
                "passage_s", "animation_s", "page_s", "total_s"):  # fmt: skip
        assert key in t, key
    stages = sum(v for k, v in t.items() if k != "total_s")
    assert stages == pytest.approx(t["total_s"], rel=0.05)
    assert t["total_s"] <= wall + 0.01  # the total is measured inside this wall time
    assert t["total_s"] >= 0.9 * wall
    with open(tmp_path / "out" / "report.json") as fh:
        assert json.load(fh)["timings"] == t
    line = summary_table(report).splitlines()[-1]
    assert line.startswith(f"time: {t['total_s']:.1f} s = ") and "figure" in line and "gif" in line
