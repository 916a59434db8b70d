"""report.json, the console table and the written images, on one small solved scene."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from helpers import REPO, exr_bitmap

from sieve_mi.api import solve
from sieve_mi.geometry.outline import rasterize
from sieve_mi.outputs.console import summary_table
from sieve_mi.outputs.images import paste_window
from sieve_mi.outputs.report import report_dict, write_outputs
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
def timed(tmp_path_factory):
    """A fresh solve of :data:`SCENE` (its start is recorded), saved with the plate, the figure
    and the GIF: (the result, the report ``save`` returned, the wall time of both, s, and the
    output folder). One solve for the timing test and the tests of ``solved`` (about 4 CPU s)."""
    import time

    path = tmp_path_factory.mktemp("scene") / "scene.toml"
    path.write_text(SCENE)
    out = tmp_path_factory.mktemp("timed") / "out"
    t0 = time.perf_counter()
    result = solve(load_scene(str(path)), progress=False)
    report = result.save(str(out), figure=True, animation=True)
    return result, report, time.perf_counter() - t0, out


@pytest.fixture(scope="module")
def solved(timed):
    return timed[0]


@pytest.fixture(scope="module")
def written(solved, tmp_path_factory):
    """The solved scene's outputs without the plate, written once for the tests that read them:
    (folder, the report dict write_outputs returned)."""
    out = tmp_path_factory.mktemp("written") / "out"
    return out, write_outputs(solved, str(out), fabricate=False)


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


def test_the_margin_is_the_records_computed_once_by_the_game(solved, monkeypatch):
    # the game computes each blocked B's margin once (Result.margins); the report only copies it
    import sieve_mi.certify.bounds as bounds

    sphere, small = solved.blocks
    assert sphere.blocked and not small.blocked and small.margin is None
    assert sphere.margin["found_at_most"] == pytest.approx(sphere.protrusion)
    assert sphere.margin["proved_at_least"] > 0  # certify proved it
    monkeypatch.setattr(bounds, "inscribed_ball", None)  # no proof is made again
    rows = report_dict(solved)["block"]
    assert rows[0]["margin"] == sphere.margin and "margin" not in rows[1]


def test_each_blocked_b_gets_its_overhang_in_words(solved):
    # the least overhang found (exact polygon) lies inside the margin's bracket, and the console
    # says it in a maker's words under the table
    rep = report_dict(solved)
    sphere, small = rep["block"]
    o, m = sphere["overhang"], sphere["margin"]
    assert m["proved_at_least"] <= o["at_best_pose"] <= m["found_at_most"] + 1e-12
    assert o["proved_at_least"] == m["proved_at_least"] and o["proof"] == "bisection"
    assert "overhang" not in small  # it passes
    assert sphere["certification"]["margin_steps"] > 0
    line = f"sphere: blocked (proved); {o['text']}"
    assert line in summary_table(rep).splitlines()
    assert o["text"].startswith(f"overhangs the hole by ≥ {o['proved_at_least']:.2f} mm in every")
    from sieve_mi.outputs.viewer import result_table

    assert f"<li>{line}</li>" in result_table(rep)  # the page lists it under its table


def test_the_passage_takes_the_saved_plate(solved):
    from sieve_mi.outputs.fabrication import plate, plate_thickness
    from sieve_mi.outputs.passage import build

    thickness, _ = plate_thickness(solved)
    mesh = plate(solved.outline, thickness, solved.scene.fabrication.border).mesh
    given, own = build(solved, mesh), build(solved)
    assert given.plate_vertices.tobytes() == own.plate_vertices.tobytes()
    assert given.plate_faces.tobytes() == own.plate_faces.tobytes()


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
    assert small[2] == "0.0000" and small[4] == "PASSES"
    # certify runs by default: the blocked sphere gets a proof, the passing one none
    assert "certified" in lines[0] and "proved" in rows[1] and small[-1] == "-"
    assert f"winner: {rep['winner']}" in text


def test_written_images_are_the_hole(solved, written):
    from PIL import Image

    out, rep = written
    on_disk = json.loads((out / "report.json").read_text())
    assert on_disk["winner"] == rep["winner"] and on_disk["block"] == rep["block"]
    # hole.png and hole.exr: the printed polygon's pixel centres (not the conservative cover)
    exact = rasterize(solved.outline, solved.hole.frame)
    png = np.array(Image.open(out / "hole.png")) > 127
    exr = np.array(exr_bitmap(out / "hole.exr")).reshape(png.shape) > 0.5
    assert np.array_equal(png, exact) and np.array_equal(exr, exact)
    assert exact.sum() < solved.hole.mask.sum() and (solved.hole.mask >= exact).all()
    assert (out / ".sieve-mi").is_file()
    assert {p.name for p in (out / "masks").iterdir()} >= {
        "a_silhouette.exr",
        "block_0_sphere.exr",
        "block_1_small_sphere.exr",
    }


def test_layered_exr_has_every_layer_on_one_lattice(solved, written):
    import manifold3d

    from sieve_mi.geometry.outline import Boundary, silhouette

    out = written[0]
    bitmap = exr_bitmap(out / "masks.exr")
    names = [f.name for f in bitmap.struct_()]
    data = np.array(bitmap)
    # OpenEXR's rule (tev's, OpenEXR's ChannelList::layers): the layer is the text before the
    # last dot; every layer has one channel Y, and no channel sits at the root
    assert sorted(_channels(out / "masks.exr")) == sorted(names)
    split = [n.rpartition(".") for n in names]
    assert {layer for layer, _, _ in split} == {
        "hole", "cover", "distance", "a0_cube", "b0_sphere", "b1_small_sphere",
    } and {c for _, _, c in split} == {"Y"}  # fmt: skip
    layer = {n.rpartition(".")[0]: data[..., k] for k, n in enumerate(names)}
    meta = bitmap.metadata()
    frame = solved.hole.frame
    assert meta["pixel_size"] == pytest.approx(frame.pixel_size)
    assert [float(v) for v in meta["frame_origin"].split()] == [
        -frame.half_extent,
        frame.half_extent,
    ]
    h = frame.pixel_size
    hole, cover = layer["hole"] > 0.5, layer["cover"] > 0.5
    # pixel centres inside the exact polygon: its area to within a ring of one pixel
    area = solved.outline.area()
    assert abs(hole.sum() * h * h - area) < 0.1 * area
    assert (cover >= hole).all() and np.array_equal(cover, solved.hole.mask)
    assert (layer["distance"][hole] == 0).all() and layer["distance"][~cover].min() > 0
    assert np.array_equal(layer["a0_cube"] > 0.5, solved.a_masks[0])
    # the written B layers and files are Mitsuba renders of the verdict's attempts: the same
    # pixels as the verdict's ray-traced windows
    for j, name in enumerate(["b0_sphere", "b1_small_sphere"]):
        window = solved.block_masks[j]
        assert np.array_equal(layer[name] > 0.5, paste_window(window, frame))
        single = np.array(exr_bitmap(out / "masks" / f"block_{j}_{name[3:]}.exr"))
        assert np.array_equal(single.reshape(window.mask.shape) > 0.5, window.mask)
    # each B's layer is its best attempt: its pixel centres lie on B's exact silhouette at the
    # reported pose (up to the ray caster's rounding), and that silhouette's area inside the frame
    # is covered to within a ring of one pixel
    x, y = frame.centres()
    for j, name in enumerate(["b0_sphere", "b1_small_sphere"]):
        shape = solved.block_shapes[j]
        sil = silhouette(shape, solved.attack.quats[0, j], solved.attack.trans[0, j])
        rows, cols = np.nonzero(layer[name] > 0.5)
        pts = np.column_stack([x[cols], y[rows]])
        assert len(pts) > 0 and Boundary(sil).signed(pts).max() <= 1e-6 * h
        box = manifold3d.CrossSection.square([2 * frame.half_extent] * 2, center=True)
        inside = (sil ^ box).area()
        assert abs(len(pts) * h * h - inside) <= 0.1 * inside


@pytest.mark.slow
def test_every_stage_is_timed_and_they_sum_to_the_wall_time(timed):
    # A fresh solve, saved with the plate, the figure and the GIF (``timed``): the stages in
    # report.json add up to its total within 5 %, and the console's line says so.
    _, report, wall, out = timed
    t = report["timings"]
    for key in ("load_s", "search_s", "verdict_s", "images_s", "fabrication_s", "figure_s",
                "passage_s", "animation_s", "page_s", "total_s"):  # fmt: skip
        assert key in t, key
    stages = sum(v for k, v in t.items() if k != "total_s")
    assert stages == pytest.approx(t["total_s"], rel=0.05)
    assert t["total_s"] <= wall + 0.01  # the total is measured inside this wall time
    assert t["total_s"] >= 0.9 * wall
    with open(out / "report.json") as fh:
        assert json.load(fh)["timings"] == t
    lines = summary_table(report).splitlines()
    line = next(x for x in lines if x.startswith("time: "))
    assert line.startswith(f"time: {t['total_s']:.1f} s = ") and "figure" in line and "gif" in line
    # the memory line follows it: the process's peak and each stage's, no stage above the peak
    mem = report["memory"]
    assert lines[lines.index(line) + 1].startswith(f"memory: peak {mem['peak_gb']:.2f} GB (")
    assert {"search", "verdict", "fabrication", "page"} <= set(mem["stages_gb"])
    assert max(mem["stages_gb"].values()) <= mem["peak_gb"]


def _exr_header(path) -> dict:
    """An OpenEXR file's header attributes, read from the bytes (name -> (type, raw value))."""
    import struct

    data = open(path, "rb").read()
    assert data[:4] == b"\x76\x2f\x31\x01"  # OpenEXR's magic number
    pos, attrs = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack("<i", data[type_end + 1 : type_end + 5])
        value = data[type_end + 5 : type_end + 5 + size]
        attrs[data[pos:name_end].decode()] = (data[name_end + 1 : type_end].decode(), value)
        pos = type_end + 5 + size
    return attrs


def _channels(path) -> list[str]:
    """The channel names of an OpenEXR file's ``chlist`` (each: name, NUL, 16 bytes)."""
    kind, raw = _exr_header(path)["channels"]
    assert kind == "chlist"
    names, pos = [], 0
    while raw[pos] != 0:
        end = raw.index(b"\0", pos)
        names.append(raw[pos:end].decode())
        pos = end + 1 + 16
    return names


def test_every_exr_carries_pixel_size_units_and_version(solved, written):
    import struct

    from sieve_mi import __version__

    out = written[0]
    frame = solved.hole.frame
    exrs = sorted(out.rglob("*.exr"))
    assert {p.name for p in exrs} >= {
        "hole.exr",
        "masks.exr",
        "a_silhouette.exr",
        "block_0_sphere.exr",
    }
    for path in exrs:
        head = _exr_header(path)
        assert head["pixel_size"][0] in ("float", "double"), path
        fmt = "<f" if head["pixel_size"][0] == "float" else "<d"
        assert struct.unpack(fmt, head["pixel_size"][1])[0] == pytest.approx(frame.pixel_size)
        assert (
            head["units"][1].endswith(b"mm")
            and f"sieve-mi {__version__}".encode() in head["software"][1]
        )
        assert b" " in head["frame_origin"][1]
    x0, _, _, y1 = solved.block_masks[0].extent  # a window's own top-left corner
    origin = _exr_header(out / "masks" / "block_0_sphere.exr")["frame_origin"][1]
    assert [float(v) for v in origin[-60:].decode(errors="ignore").split()[-2:]] == pytest.approx(
        [x0, y1]
    )


def _png_chunks(path) -> dict:
    """A PNG's chunks by type (the first of each), read from the bytes."""
    import struct

    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (size,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8].decode()
        chunks.setdefault(kind, []).append(data[pos + 8 : pos + 8 + size])
        pos += 12 + size
    return chunks


def test_hole_png_records_its_pixel_size(solved, written):
    import struct

    from sieve_mi.geometry.pixels import image_pixel_size

    out = written[0]
    h = solved.hole.frame.pixel_size  # mm
    chunks = _png_chunks(out / "hole.png")
    (phys,) = chunks["pHYs"]
    x, y, unit = struct.unpack(">IIB", phys)
    assert unit == 1 and x == y == round(1000.0 / h)  # pixels per metre
    texts = dict(t.split(b"\0", 1) for t in chunks["tEXt"])
    assert float(texts[b"sieve-mi:pixel_size"]) == h and texts[b"sieve-mi:units"] == b"mm"
    assert image_pixel_size(str(out / "hole.png"), "mm") == h
    assert image_pixel_size(str(out / "hole.png"), "cm") == pytest.approx(h / 10)


def test_a_png_with_only_phys_gives_its_pixel_size(tmp_path):
    from PIL import Image

    from sieve_mi.geometry.pixels import image_pixel_size

    img = Image.fromarray(np.zeros((4, 4), np.uint8))
    img.save(tmp_path / "plain.png")
    img.save(tmp_path / "phys.png", dpi=(254.0, 254.0))  # 10,000 pixels per metre: 0.1 mm
    assert image_pixel_size(str(tmp_path / "plain.png"), "mm") is None
    assert image_pixel_size(str(tmp_path / "phys.png"), "mm") == pytest.approx(0.1)
    assert image_pixel_size(str(tmp_path / "phys.png"), "in") == pytest.approx(0.1 / 25.4)
    assert image_pixel_size(str(tmp_path / "missing.png"), "mm") is None


def test_overlay_draws_blocked_red_escaping_orange_and_a_green(solved, written):
    # Panel 0: the sphere, blocked; panel 1: the small sphere, which gets through. Each B is an
    # outline with hatching in its colour over the hole, which stays visible under it.
    from PIL import Image

    from sieve_mi.outputs.palette import PALETTE

    out = written[0]
    img = np.asarray(Image.open(out / "overlay.png").convert("RGB"), dtype=np.float64)
    halves = img[:, : img.shape[1] // 2], img[:, img.shape[1] // 2 :]

    def near(part, rgb, alpha=1.0):  # the colour at alpha over the white hole
        want = 255 * (alpha * np.asarray(rgb) + (1 - alpha))
        return (np.abs(part - want).max(axis=2) < 40).sum()

    assert near(halves[0], PALETTE["blocked"]) > 200 and near(halves[0], PALETTE["escaped"]) == 0
    assert near(halves[1], PALETTE["escaped"]) > 200 and near(halves[1], PALETTE["blocked"]) == 0
    for half in halves:  # A's dashed outline: green, not the old black
        r, g, b = half[..., 0], half[..., 1], half[..., 2]
        assert ((g > r + 60) & (g > b + 60)).sum() > 20


def test_the_overlay_hatches_b_over_a_visible_hole(solved):
    # Inside H and inside the blocked sphere's attempt: white hole between red hatch lines, not a
    # red fill; outside H, the sphere's overhang gets a light red fill over the plate.
    from sieve_mi.geometry.outline import Boundary
    from sieve_mi.outputs.palette import PALETTE
    from sieve_mi.outputs.plots import overlay_figure

    fig = overlay_figure(solved)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(np.float64)
    hole, _, b = solved.overlay_sections()
    ax = fig.axes[0]
    lo, hi = np.asarray(hole.bounds()).reshape(2, 2)
    xy = np.stack(np.meshgrid(*[np.linspace(lo[k], hi[k], 60) for k in (0, 1)]), -1).reshape(-1, 2)
    inner = hole.offset(-0.5, manifold3d_join()) ^ b[0].offset(-0.5, manifold3d_join())
    xy = xy[Boundary(inner).inside(xy)]
    assert len(xy) > 100
    px = ax.transData.transform(xy)
    rows = np.clip((img.shape[0] - px[:, 1]).astype(int), 0, img.shape[0] - 1)
    colours = img[rows, px[:, 0].astype(int)]
    white = (colours.min(axis=1) > 235).mean()
    red = (np.abs(colours - 255 * np.asarray(PALETTE["blocked"])).max(axis=1) < 60).mean()
    assert white > 0.4, white  # the hole shows through
    assert 0.05 < red < 0.6, red  # the hatching's lines cross it


def manifold3d_join():
    import manifold3d

    return manifold3d.JoinType.Miter


def test_every_mesh_and_outline_file_reopens_in_trimesh(solved, tmp_path):
    # Every 3MF, STL, OBJ and SVG a solve writes loads in trimesh from the project's own venv
    # (lxml for 3MF and SVG is a declared dependency) and holds what it should.
    import trimesh

    out = tmp_path / "out"
    write_outputs(solved, str(out), figure=False, animation=False)
    files = sorted(p for p in out.rglob("*") if p.suffix in (".3mf", ".stl", ".obj", ".svg"))
    names = {p.name for p in files}
    assert {
        "sieve.stl",
        "sieve.3mf",
        "hole.svg",
        "pass_0.stl",
        "block_0.stl",
        "block_1.stl",
    } <= names
    loaded = {p.name: trimesh.load(str(p)) for p in files}
    plate = loaded["sieve.stl"]
    assert plate.is_watertight and plate.volume > 0
    (three,) = loaded["sieve.3mf"].geometry.values()  # one object: the plate
    assert three.volume == pytest.approx(plate.volume, rel=1e-6)
    assert loaded["pass_0.stl"].volume == pytest.approx(8000.0, rel=1e-6)  # the 20 mm cube
    outline = loaded["hole.svg"]  # a Path2D: the exact hole, 1 unit = 1 mm
    assert outline.area == pytest.approx(solved.outline.area(), rel=1e-4)
    for name, mesh in loaded.items():
        if name.endswith((".stl", ".obj")):
            assert len(mesh.faces) > 0 and np.isfinite(mesh.vertices).all(), name
