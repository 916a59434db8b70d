"""report.html and passage.gif: the page's inlined data, the passage's geometry, the GIF's frames,
and the page in a real browser (headless Chromium, where installed: ``make setup`` installs it)."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess

import manifold3d
import numpy as np
import pytest
import trimesh
from helpers import REPO

from sieve_mi.api import solve
from sieve_mi.geometry.outline import is_closed, placed_vertices, rasterize, silhouette
from sieve_mi.geometry.raster import Frame
from sieve_mi.outputs import animation, viewer
from sieve_mi.outputs.passage import Passage, build
from sieve_mi.outputs.svg import scale_bar
from sieve_mi.scene import load_scene
from sieve_mi.testing.settings import TINY

MESHES = os.path.abspath(os.path.join(REPO, "scenes", "meshes"))
# Several A shapes merged into one hole (A wins: the 24 mm sphere is blocked) ...
MERGED = (
    f'name = "merged"\n[[pass]]\nmesh = "{MESHES}/cube.stl"\n[[pass]]\nmesh = "{MESHES}/prism.stl"\n'
    f'[[block]]\nmesh = "{MESHES}/sphere.stl"\n[layout]\nmode = "merged"\nrounds = 1\n'
    "alternatives = 0\n"
)
# ... and a scene B wins: the 12 mm ball passes any hole the 20 mm cube needs.
B_WINS = (
    f'name = "b wins"\n[[pass]]\nmesh = "{MESHES}/cube.stl"\n[[block]]\nmesh = "{MESHES}/sphere.stl"\n'
    f'[[block]]\nmesh = "{MESHES}/small_sphere.stl"\n'
)


def _solved(tmp_path_factory, body):
    folder = tmp_path_factory.mktemp("scene")
    (folder / "scene.toml").write_text(body + TINY)
    result = solve(load_scene(str(folder / "scene.toml")), progress=False)
    out = folder / "out"
    report = result.save(str(out), figure=False)
    return result, report, out


@pytest.fixture(scope="module")
def merged(tmp_path_factory):
    return _solved(tmp_path_factory, MERGED)


@pytest.fixture(scope="module")
def b_wins(tmp_path_factory):
    return _solved(tmp_path_factory, B_WINS)


@pytest.fixture(params=["merged", "b_wins"])
def solved(request):
    return request.getfixturevalue(request.param)


def page_data(out) -> dict:
    text = (out / "report.html").read_text(encoding="utf-8")
    m = re.search(r'<script type="application/json" id="sieve-data">(.*?)</script>', text, re.S)
    return json.loads(m.group(1))


def svg_paths(out) -> dict:
    """data-id -> list of (K, 2) contours (y flipped back) of the page's 2D hole view."""
    text = (out / "report.html").read_text(encoding="utf-8")
    paths = {}
    for pid, d in re.findall(r'<path data-id="([^"]+)"[^>]* d="([^"]*)"', text):
        contours = []
        for part in re.findall(r"M ([^MZ]*) Z", d):
            xy = np.array([float(v) for v in part.replace("L", " ").split()]).reshape(-1, 2)
            contours.append(xy * [1.0, -1.0])
        paths[pid] = contours
    return paths


def _same_contours(got, want, tol):
    want = [np.asarray(c, dtype=np.float64) for c in want if len(c)]
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.shape == w.shape
        np.testing.assert_allclose(g, w, rtol=1e-5, atol=tol)


# ------------------------------------------------------------------------------------------------
# The page's inlined data
# ------------------------------------------------------------------------------------------------


def test_page_hole_and_outlines_are_the_exact_polygons(solved):
    result, report, out = solved
    paths = svg_paths(out)
    tol = 1e-5 * result.hole.frame.half_extent
    _same_contours(paths["hole"], result.outline.to_polygons(), tol)
    for i, (s, q, t) in enumerate(zip(result.pass_shapes, result.pass_quats, result.pass_trans)):
        _same_contours(paths[f"a{i}"], silhouette(s, q, t, is_closed(s)).to_polygons(), tol)
    for j, s in enumerate(result.block_shapes):
        sec = silhouette(s, result.attack.quats[0, j], result.attack.trans[0, j], is_closed(s))
        _same_contours(paths[f"b{j}"], sec.to_polygons(), tol)


def test_page_meshes_are_the_printed_plate_and_the_posed_shapes(solved):
    result, report, out = solved
    data = page_data(out)
    # The plate is sieve.stl, triangle for triangle.
    v = viewer.decode(data["plate"]["positions"], "<f4")
    f = viewer.decode(data["plate"]["faces"], "<u4")
    stl = trimesh.load(str(out / "sieve.stl"), process=False)
    key = lambda tris: np.sort(np.round(tris.reshape(len(tris), -1), 4), axis=0)  # noqa: E731
    np.testing.assert_allclose(key(v[f]), key(np.asarray(stl.triangles)), atol=1e-4)
    # Each shape is its mesh at report.json's pose (rotation about its centre, xy translation).
    poses = [("pass", p) for p in report["pass"]] + [("block", b) for b in report["block"]]
    shapes = result.pass_shapes + result.block_shapes
    assert [p["id"] for p in data["pieces"]] == [f"a{i}" for i in range(len(report["pass"]))] + [
        f"b{j}" for j in range(len(report["block"]))
    ]
    for piece, (role, row), shape in zip(data["pieces"], poses, shapes):
        assert piece["role"] == role and piece["name"] == row["name"]
        want = placed_vertices(shape, np.array(row["rotation"]), np.array(row["translation"]))
        got = viewer.decode(piece["positions"], "<f4")
        np.testing.assert_allclose(got, want, atol=1e-4 * shape.radius + 1e-5)
        assert np.array_equal(viewer.decode(piece["faces"], "<u4"), shape.faces)
        assert piece["passes"] == (role == "pass" or not row["blocked"])


@pytest.mark.parametrize(
    "evil",
    [
        'x</script><img src="http://example.invalid/a.png">{{DATA}}',
        "<!--<script>",  # an HTML comment opened in a script swallows the viewer's script
        "a<script>b</SCRIPT>&amp;",
    ],
)
def test_names_cannot_break_out_of_the_page(merged, evil):
    # Shape and scene names are text: escaped in the HTML, and no name changes the page's
    # structure: the same tags and comments as with plain names.
    result, report, out = merged
    rep = dict(report, name=evil, block=[dict(b, name=evil) for b in report["block"]])
    page = viewer.render_page(result, rep, build(result), [])
    plain = viewer.render_page(result, report, build(result), [])
    for marker in ("<script", "</script>", "<!--", "-->", "<img"):
        assert page.lower().count(marker.lower()) == plain.lower().count(marker.lower()), marker
    assert page.count("</script>") == 2  # the template's own data and script blocks
    assert '<img src="http://example.invalid' not in page  # never a live tag
    m = re.search(r'<script type="application/json" id="sieve-data">(.*?)</script>', page, re.S)
    assert json.loads(m.group(1))["name"] == evil
    assert f"<h1>{viewer.html.escape(evil)}</h1>" in page


def test_a_ball_rests_on_a_round_hole_at_the_known_height():
    # A 24 mm ball over a 22 mm round hole: the rim holds it where the sphere meets the circle,
    # its centre sqrt(12² - 11²) = 4.796 mm above the plate's top. A 20 mm ball falls through.
    from sieve_mi.outputs.passage import rest_offset

    hole = manifold3d.CrossSection.circle(11.0, 256)
    box = np.array([[-20.0, -20.0], [20.0, 20.0]])
    ball = trimesh.creation.icosphere(4, 12.0)
    rest = rest_offset(np.asarray(ball.vertices), np.asarray(ball.faces), hole, box)
    assert rest == pytest.approx(np.sqrt(12.0**2 - 11.0**2), abs=0.1)
    small = trimesh.creation.icosphere(4, 10.0)
    assert rest_offset(np.asarray(small.vertices), np.asarray(small.faces), hole, box) is None


def _volume(a: manifold3d.Manifold) -> float:
    return float(a.volume()) if hasattr(a, "volume") else float(a.get_volume())


def _solid(vertices, faces) -> manifold3d.Manifold:
    mesh = manifold3d.Mesh(
        vert_properties=np.asarray(vertices, dtype=np.float32),
        tri_verts=np.asarray(faces, dtype=np.uint32),
    )
    return manifold3d.Manifold(mesh)


def test_a_slides_through_and_a_blocked_b_rests_on_the_plate(merged):
    # Real solids: A never cuts into the plate on its way down; the blocked sphere at its resting
    # height touches the plate's top and would cut into it a little lower.
    result, report, out = merged
    passage = build(result)
    plate = _solid(passage.plate_vertices, passage.plate_faces)
    size = float(np.ptp(passage.plate_vertices, axis=0).max())
    for p in passage.pieces:
        solid = _solid(p.vertices, p.faces)

        def cut(dz, solid=solid):
            return _volume(solid.translate([0.0, 0.0, dz]) ^ plate)

        if p.passes:
            for s in np.linspace(0.0, 1.0, 9):
                assert cut(p.offset(p.slot[0] + s * (p.slot[1] - p.slot[0]))) < 1e-6 * size**3
        else:
            assert report["block"][p.index]["blocked"]
            assert 0.0 < p.stop < 1.0 and p.offset(p.slot[1] - 1e-9) == pytest.approx(p.end)
            assert cut(p.end + 0.01 * size) < 1e-6 * size**3
            assert cut(p.end - 0.03 * size) > 0.0


# ------------------------------------------------------------------------------------------------
# passage.gif
# ------------------------------------------------------------------------------------------------


def test_gif_has_its_frames_and_a_moves_down(merged):
    from PIL import Image

    result, report, out = merged
    passage = build(result)
    n = animation.frame_count(passage)
    assert n == animation.FRAMES_PER_SLOT * (1 + len(result.block_shapes))
    gif = Image.open(out / "passage.gif")
    assert gif.n_frames == report["animation"]["frames"] == n
    assert gif.size == (animation.WIDTH, animation.HEIGHT)
    # In the first slot only the As are shown: against the same camera's picture of the plate
    # alone, what differs in the GIF's first frames is A, and it moves down the picture.
    empty = Passage(passage.plate_vertices, passage.plate_faces, passage.thickness, passage.gap, [])
    plate_only = animation.to_gray8(
        animation.render_frames(empty, phases=[0.0], box=passage.bounds(), spp=64)
    )[0].astype(np.int16)
    rows = []
    for k in range(4):
        gif.seek(k)
        diff = np.abs(np.asarray(gif.convert("L"), dtype=np.int16) - plate_only) > 40
        assert diff.sum() > 100  # A is in the picture
        rows.append(int(np.nonzero(diff)[0].min()))  # the top of A
        if report["animation"]["colour"]:  # A is drawn green
            rgb = np.asarray(gif.convert("RGB"), dtype=np.float64)[diff]
            assert rgb[:, 1].mean() > 1.3 * rgb[:, 0].mean(), rgb.mean(axis=0)
    assert all(b > a + 5 for a, b in zip(rows, rows[1:])), rows
    import mitsuba as mi

    from sieve_mi.backend import select_rgb_variant

    before = mi.variant()  # colour wherever an RGB variant loads (one may be listed, not shipped)
    rgb = select_rgb_variant(mi, before).endswith("_rgb")
    mi.set_variant(before)
    assert report["animation"]["colour"] == rgb
    if report["animation"]["colour"]:  # rendered in RGB, and the variant switched back
        assert report["animation"]["variant"] != mi.variant()


# ------------------------------------------------------------------------------------------------
# In a real browser: headless Chromium
# ------------------------------------------------------------------------------------------------

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
SIZE = 640  # window side, pixels (square: the top view fits the plate's box to it)


def _browser() -> str:
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no headless Chromium on this machine (make setup installs Debian's chromium)")


def run_browser(
    url: str, tmp_path, *, screenshot: bool = False, size=(SIZE, SIZE), extra=()
) -> dict:
    """Load ``url`` headlessly; returns the DOM (or the screenshot), console lines and page requests.

    Page requests are the network log's requests whose initiator is the page (a file:// page's
    origin is "null"); Chromium's own background requests ("not an origin") are left out.
    """
    exe = _browser()
    net = tmp_path / "net.json"
    shot = tmp_path / "shot.png"
    args = [
        exe, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--hide-scrollbars", "--force-device-scale-factor=1", f"--window-size={size[0]},{size[1]}",
        f"--user-data-dir={tmp_path / 'profile'}", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--enable-logging=stderr", "--v=0",
        f"--log-net-log={net}", "--virtual-time-budget=4000",
        "--host-resolver-rules=MAP * ~NOTFOUND",  # no DNS: a request is logged, then fails at once
    ]  # fmt: skip
    args += list(extra) + ([f"--screenshot={shot}"] if screenshot else ["--dump-dom"])
    p = subprocess.run(args + [url], capture_output=True, text=True, timeout=120)
    console = [
        ln
        for ln in p.stderr.splitlines()
        if ":CONSOLE" in ln and "GL Driver Message" not in ln  # SwiftShader's performance notes
    ]
    return {
        "dom": p.stdout,
        "shot": shot if screenshot else None,
        "console": console,
        "requests": _page_requests(net),
    }


def _page_requests(path) -> list[str]:
    text = path.read_text() if path.exists() else '{"events": []}'
    text = text.rstrip()
    if not text.endswith("}"):  # a log cut short when the browser quit
        text = text.rstrip(",") + "]}"
    log = json.loads(text)
    names = {v: k for k, v in log.get("constants", {}).get("logEventTypes", {}).items()}
    urls = []
    for e in log["events"]:
        p = e.get("params", {})
        start = names.get(e["type"]) == "URL_REQUEST_START_JOB" and "url" in p  # not its end
        if start and p.get("initiator") != "not an origin":
            urls.append(p["url"])
    return [u for u in urls if not u.startswith(("file:", "data:", "blob:"))]


def test_the_browser_check_sees_errors_and_requests(tmp_path):
    # The checks below can fail: a page that logs an error and loads a remote image is caught.
    _browser()
    page = tmp_path / "bad.html"
    page.write_text(
        '<!DOCTYPE html><img src="http://example.invalid/x.png"><script>console.error("boom")</script>'
    )
    got = run_browser(page.as_uri(), tmp_path)
    assert any("boom" in ln for ln in got["console"])
    assert got["requests"] == ["http://example.invalid/x.png"]


def test_page_loads_offline_without_errors(solved, tmp_path):
    result, report, out = solved
    got = run_browser((out / "report.html").as_uri(), tmp_path)
    body = re.search(r"<body[^>]*>", got["dom"]).group(0)
    assert 'data-ready="1"' in body and "data-webgl" not in body and "data-errors" not in body
    assert re.search(r'<pre id="errors" hidden="?"?>\s*</pre>', got["dom"])
    assert got["console"] == [] and got["requests"] == []
    assert f'data-winner="{report["winner"]}"' in body
    # Desktop and phone widths: the page fits the window (no sideways scrolling).
    assert 'data-fits="1"' in body
    phone = run_browser((out / "report.html").as_uri(), tmp_path, size=(390, 844))
    assert re.search(r'<body[^>]*data-fits="1"', phone["dom"]) and phone["console"] == []


def test_page_without_webgl_still_shows_the_result(b_wins, tmp_path):
    # A browser without WebGL: a note instead of the 3D view, no error, the rest of the page.
    result, report, out = b_wins
    got = run_browser((out / "report.html").as_uri(), tmp_path, extra=["--disable-3d-apis"])
    body = re.search(r"<body[^>]*>", got["dom"]).group(0)
    assert 'data-webgl="none"' in body and 'data-ready="1"' in body and "data-errors" not in body
    assert re.search(r'<p id="nogl">', got["dom"])  # shown (no longer hidden)
    assert got["console"] == [] and 'data-id="hole"' in got["dom"]


def _deepest(section, box) -> np.ndarray:
    """The point of a CrossSection (within the box (2, 2)) farthest from its boundary, xy."""
    from scipy.ndimage import distance_transform_edt

    half = 0.5 * float(np.max(box[1] - box[0]))
    centre = 0.5 * (box[0] + box[1])
    frame = Frame(400, half)
    mask = rasterize(section.translate(list(-centre)), frame)
    dist = distance_transform_edt(mask)
    r, c = np.unravel_index(int(np.argmax(dist)), mask.shape)
    assert dist[r, c] > 3  # a clear spot, several screen pixels from any edge
    x, y = frame.centres()
    return np.array([x[c], y[r]]) + centre


def _pixel(image, point, box) -> tuple[int, int, int]:
    """The screenshot's colour at scene point (x, y) in the top view (plate box fitted, centred)."""
    centre = 0.5 * (box[0] + box[1])
    scale = SIZE / float(np.max(box[1] - box[0]))
    col = SIZE / 2 + (point[0] - centre[0]) * scale
    row = SIZE / 2 - (point[1] - centre[1]) * scale
    return tuple(int(v) for v in image.getpixel((int(col), int(row)))[:3])


def _kind(rgb) -> str:
    r, g, b = rgb
    if min(rgb) > 235:
        return "background"
    if max(rgb) - min(rgb) < 16:
        return "plate"
    if g > 1.5 * r and g > 1.5 * b:
        return "pass"
    if r > g > b and r > 1.5 * b:
        return "blocked" if g < 0.35 * r else "escaped"
    return f"other {rgb}"


def _shot(out, tmp_path, query: str):
    from PIL import Image

    url = (out / "report.html").as_uri() + "#view=top&full&" + query
    got = run_browser(url, tmp_path, screenshot=True)
    assert got["console"] == [] and got["requests"] == []
    image = Image.open(got["shot"]).convert("RGB")
    assert image.size == (SIZE, SIZE)
    return image


def test_screenshot_shows_the_hole_and_shapes_where_the_report_says(solved, tmp_path):
    result, report, out = solved
    data = page_data(out)
    box = np.array(data["plate_box"])
    plate_square = manifold3d.CrossSection.square(list(box[1] - box[0])).translate(list(box[0]))
    # The plate alone, from above: the hole's deepest point shows the background, the plate's
    # material the plate; the picture is not blank.
    image = _shot(out, tmp_path, "t=0&show=plate")
    assert len(np.unique(np.asarray(image).reshape(-1, 3), axis=0)) > 2
    assert _kind(_pixel(image, _deepest(result.outline, box), box)) == "background"
    assert _kind(_pixel(image, _deepest(plate_square - result.outline, box), box)) == "plate"
    # Every A at its start above the plate, at its pose's place.
    ids = ",".join(["plate"] + [f"a{i}" for i in range(len(result.pass_shapes))])
    image = _shot(out, tmp_path, f"t=0&show={ids}")
    for s, q, t in zip(result.pass_shapes, result.pass_quats, result.pass_trans):
        sec = silhouette(s, q, t, is_closed(s))
        assert _kind(_pixel(image, _deepest(sec, box), box)) == "pass"
    # Each B at the end of its turn: resting on the plate where it sticks out (blocked), or
    # below the plate, seen through the hole (it got through).
    for piece in data["pieces"]:
        if piece["role"] != "block":
            continue
        j = int(piece["id"][1:])
        shape = result.block_shapes[j]
        sec = silhouette(
            shape, result.attack.quats[0, j], result.attack.trans[0, j], is_closed(shape)
        )
        spot = sec - result.outline if not piece["passes"] else sec ^ result.outline
        image = _shot(out, tmp_path, f"t={piece['slot'][1] - 1e-4:.6f}&show=plate,{piece['id']}")
        want = "escaped" if piece["passes"] else "blocked"
        assert _kind(_pixel(image, _deepest(spot ^ plate_square, box), box)) == want


# ------------------------------------------------------------------------------------------------
# The command line: solve --no-animation, check --out, view
# ------------------------------------------------------------------------------------------------


def run_cli(*args, env=None):
    import sys

    return subprocess.run(
        [sys.executable, "-m", "sieve_mi", *args],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )


def test_no_animation_skips_only_the_gif(merged, tmp_path):
    from sieve_mi.cli import _parser

    assert _parser().parse_args(["solve", "s.toml", "--no-animation"]).no_animation
    result, report, out = merged
    rep = result.save(str(tmp_path / "o"), figure=False, animation=False)
    assert not (tmp_path / "o" / "passage.gif").exists() and "animation" not in rep
    assert (tmp_path / "o" / "report.html").is_file()
    marker = json.loads((tmp_path / "o" / ".sieve-mi").read_text())
    assert "report.html" in marker["files"] and "passage.gif" not in marker["files"]
    assert {"report.html", "passage.gif"} <= set(
        json.loads((out / ".sieve-mi").read_text())["files"]
    )


def test_check_out_writes_a_page_of_the_plate_hole(merged, tmp_path, capsys):
    from sieve_mi.cli import main
    from sieve_mi.geometry.sieve import plate_holes

    result, report, out = merged
    dest = tmp_path / "check"
    code = main([
        "check", os.path.join(MESHES, "sphere.stl"), "--sieve", str(out / "sieve.stl"),
        "--starts", "4", "--steps", "30", "--resolution", "64", "--no-fit", "--out", str(dest),
    ])  # fmt: skip
    rep = json.loads((dest / "report.json").read_text())
    assert code == (0 if rep["result"]["passes"] else 3), capsys.readouterr().err
    paths = svg_paths(dest)
    _same_contours(paths["hole"], plate_holes(str(out / "sieve.stl"))[0].to_polygons(), 1e-4)
    assert len(paths["b0"]) >= 1
    page = (dest / "report.html").read_text()
    assert ("is blocked" if not rep["result"]["passes"] else "passes") in page
    if any(shutil.which(b) for b in BROWSERS):
        got = run_browser((dest / "report.html").as_uri(), tmp_path)
        assert 'data-ready="1"' in got["dom"] and got["console"] == [] and got["requests"] == []


def test_view_opens_the_page_and_refuses_what_is_not_an_output(
    merged, tmp_path, capsys, monkeypatch
):
    import webbrowser

    from sieve_mi.cli import main

    result, report, out = merged
    log = tmp_path / "opened.txt"
    fake = tmp_path / "browser.sh"
    fake.write_text(f'#!/bin/sh\necho "$1" > {log}\n')
    fake.chmod(0o755)
    env = dict(os.environ, BROWSER=f"{fake} %s")
    p = run_cli("view", str(out), env=env)
    assert p.returncode == 0, p.stderr
    assert log.read_text().strip() == (out / "report.html").resolve().as_uri()
    foreign = tmp_path / "downloads"  # someone else's page: not opened
    foreign.mkdir()
    (foreign / "report.html").write_text("<script>alert(1)</script>")
    for folder, needle in (
        (tmp_path / "nope", "no such output folder"),
        (tmp_path, "no report.html"),
        (foreign, "was not written by sieve-mi"),
    ):
        # refused before any browser starts: in this process (any other exception fails it)
        monkeypatch.setattr(webbrowser, "open", lambda url: pytest.fail(f"opened {url}"))
        assert main(["view", str(folder)]) == 2
        err = capsys.readouterr().err
        assert needle in err and len(err.strip().splitlines()) == 1


def test_a_dense_mesh_is_simplified_for_the_3d_view_only():
    # A 327,680-triangle ball of radius 10 is shown with at most 20,000 triangles whose vertices
    # stay within the reported error of the sphere, still spanning it; a mesh under the cap is
    # shown as it is, and the page's toggle says when a mesh is simplified.
    ball = trimesh.creation.icosphere(7, 10.0)
    v, f, error = viewer.display_mesh(ball.vertices, ball.faces, max_faces=20_000)
    assert 5_000 < len(f) <= 20_000 and 0 < error < 1.0
    r = np.linalg.norm(v, axis=1)
    assert np.abs(r - 10.0).max() <= error
    np.testing.assert_allclose(v.min(0), -10.0, atol=error)
    np.testing.assert_allclose(v.max(0), 10.0, atol=error)
    assert f.max() < len(v) and len(np.unique(np.sort(f, axis=1), axis=0)) == len(f)
    small = trimesh.creation.box((1.0, 2.0, 3.0))
    v2, f2, e2 = viewer.display_mesh(small.vertices, small.faces, max_faces=20_000)
    assert e2 == 0 and np.array_equal(f2, small.faces) and np.array_equal(v2, small.vertices)
    data = viewer._mesh_data(ball.vertices, ball.faces)  # the page's cap: 100,000 triangles
    shown = viewer.decode(data["faces"], "<u4")
    assert data["simplified"]["faces"] == len(ball.faces) == 327_680
    assert data["simplified"]["shown"] == len(shown) <= viewer.DISPLAY_FACES
    label = viewer._simplified(data, "mm")
    assert label.startswith(" (3D: ") and "of 327,680 triangles, within" in label
    assert viewer._simplified(viewer._mesh_data(small.vertices, small.faces), "mm") == ""


def test_a_thin_plate_motion_is_followed_pose_by_pose():
    """A piece with keys (a found thin-plate motion) is placed by the motion's poses: the first
    pose at the start of its slot, the last at its end, slerp halfway between two keys, and the
    passage's box holds every key's placed vertices."""
    from sieve_mi.geometry.rotations import from_axis_angle, to_matrix
    from sieve_mi.outputs.passage import Piece

    cube = trimesh.creation.box([2.0, 2.0, 2.0])
    q0, q1 = np.array([1.0, 0, 0, 0]), from_axis_angle(np.array([1.0, 0, 0]), np.pi / 2)
    keys = np.array([[0.0, *q0, 0, 0, 5.0], [1.0, *q1, 0, 0, -5.0]])
    piece = Piece("b", "block", 0, np.asarray(cube.vertices), np.asarray(cube.faces), 5.0, -5.0,
                  1.0, True, np.zeros(2), slot=(0.5, 1.0), keys=keys)  # fmt: skip
    assert np.allclose(piece.matrix(0.5)[:3, 3], [0, 0, 5]) and np.allclose(
        piece.matrix(0.2), piece.matrix(0.5)
    )
    end = piece.matrix(1.0)
    assert np.allclose(end[:3, :3], to_matrix(q1)) and np.allclose(end[:3, 3], [0, 0, -5])
    half = piece.matrix(0.75)
    assert np.allclose(half[:3, :3], to_matrix(from_axis_angle(np.array([1.0, 0, 0]), np.pi / 4)))
    assert np.allclose(half[:3, 3], [0, 0, 0])
    plate = np.array([[-3.0, -3, -1], [3, 3, 0]])
    box = Passage(plate, np.array([[0, 1, 1]]), 1.0, 1.0, [piece]).bounds()
    assert box[1, 2] == pytest.approx(6.0) and box[0, 2] == pytest.approx(-6.0)


@pytest.mark.parametrize("lim", [0.8, 12.6, 26.5, 3000.0])
def test_the_hole_view_has_a_round_scale_bar(lim):
    """1, 2 or 5 × 10^k scene units, between a tenth and two fifths of the view's half-width
    (the next round length up would be more than 0.4 lim), drawn to scale and labelled."""
    svg = scale_bar(lim, "mm")
    length = float(re.search(r'data-length="([^"]+)"', svg).group(1))
    mantissa = length / 10 ** math.floor(math.log10(length))
    assert round(mantissa, 9) in (1.0, 2.0, 5.0)
    assert 0.1 * lim < length <= 0.4 * lim
    x1, x2 = (float(v) for v in re.search(r'x1="([^"]+)" y1="[^"]+" x2="([^"]+)"', svg).groups())
    assert x2 - x1 == pytest.approx(length) and f">{length:g} mm</text>" in svg
