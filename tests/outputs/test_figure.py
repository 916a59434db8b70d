"""figure.png: the Mitsuba rendering of the sieve with A over the hole and the B attempts beside it."""

from __future__ import annotations

import math
import os

import manifold3d
import numpy as np
import pytest
import trimesh
from PIL import Image

import sieve_mi.outputs.figure as figure
from sieve_mi import backend
from sieve_mi.outputs.figure import FigureSettings, render_figure, title_figure
from sieve_mi.testing.pictures import layout_problems

W, H, SPP = 160, 120, 4
SMALL = FigureSettings(W, H, SPP)


def _plate(size: float = 80.0, thickness: float = 12.0, hole: float = 20.0) -> trimesh.Trimesh:
    """A plate (z from -thickness to 0) with a square hole around the origin, made by manifold3d."""
    box = manifold3d.Manifold.cube([size, size, thickness], center=True).translate(
        [0, 0, -thickness / 2]
    )
    cut = manifold3d.Manifold.cube([hole, hole, 3 * thickness], center=True).translate(
        [0, 0, -thickness / 2]
    )
    m = (box - cut).to_mesh()
    return trimesh.Trimesh(
        np.asarray(m.vert_properties)[:, :3], np.asarray(m.tri_verts), process=False
    )


@pytest.fixture(scope="module")
def scene():
    plate = _plate()
    cube = trimesh.creation.box((18.0, 18.0, 18.0))
    cube.apply_translation([0, 0, 10 + 9])
    ball = trimesh.creation.icosphere(3, 13.0)
    ball.apply_translation([40 + 8 + 13, 0, 13])
    return plate, [cube], [ball]


@pytest.fixture(scope="module")
def colour(mi):
    """Skip colour checks where no RGB variant of Mitsuba loads (the figure then falls back to grey)."""
    before = mi.variant()
    chosen = backend.select_rgb_variant(mi, before)
    if mi.variant() != before:
        mi.set_variant(before)
    if not chosen.endswith("rgb"):
        pytest.skip("no RGB variant of Mitsuba on this machine: the figure is rendered in grey")


def _read(path) -> np.ndarray:
    with Image.open(path) as im:
        assert im.size == (W, H)
        return np.asarray(im.convert("RGB")).astype(int)


def _green(img: np.ndarray) -> np.ndarray:
    """Pixels whose green channel exceeds red and blue by 40 (of 255)."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (g > r + 40) & (g > b + 40)


def _red(img: np.ndarray) -> np.ndarray:
    """Red pixels: red well above green and blue, green and blue alike (not orange)."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > g + 60) & (r > b + 60) & (np.abs(g - b) < 30)


def _orange(img: np.ndarray) -> np.ndarray:
    """Orange pixels: red above green, green well above blue."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > g + 30) & (g > b + 50)


def test_colours_size_and_variant(tmp_path, scene, mi, colour):
    plate, passes, blocks = scene
    before = mi.variant()
    path = tmp_path / "figure.png"
    render_figure(str(path), plate, passes, blocks, [True], picture=SMALL)
    assert mi.variant() == before
    assert path.is_file() and path.stat().st_size > 0
    assert os.listdir(tmp_path) == ["figure.png"], (
        "the temporary file must be renamed, not left behind"
    )
    img = _read(path)
    green, red = _green(img), _red(img)
    assert green.sum() > 0.01 * W * H, "the A cube must show as green pixels"
    assert red.sum() > 0.01 * W * H, "the blocked sphere must show as red pixels"
    assert _orange(img).sum() < 0.1 * red.sum()
    # A (over the hole, at the origin) lies left of B (beside the plate in +x) in this view.
    cols = np.arange(W)[None, :].repeat(H, 0)
    assert cols[green].mean() < cols[red].mean()
    # Plate and ground: most of the picture is neither green nor red.
    assert (green | red).mean() < 0.5


def test_escaped_block_is_orange_and_title_keeps_size(tmp_path, scene, mi, colour):
    plate, passes, blocks = scene
    path = tmp_path / "figure.png"
    render_figure(str(path), plate, passes, blocks, [False], picture=SMALL, title="a title")
    img = _read(path)
    orange = _orange(img)
    assert orange.sum() > 0.01 * W * H
    assert _red(img).sum() < 0.1 * orange.sum(), "a B that passes must not be drawn red"
    # The title band at the top is dark text on the light ground.
    assert img[: int(figure.TITLE_BAND * H)].min() < 100


def _grey(img: np.ndarray) -> np.ndarray:
    """The plate's pixels: grey or a little blue (the ground is beige: red above blue)."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (np.abs(r - g) < 10) & (np.abs(g - b) < 10) & (b >= r - 3)


def test_title_lies_in_its_band_on_no_shape(tmp_path, scene, mi, colour, monkeypatch):
    """figure.png's title (a long one) sits in the band at the top, whole, where no shape was
    rendered, and changes no pixel outside its own box."""
    plate, passes, blocks = scene
    w, h = 2 * W, 2 * H
    title = "a scene with a rather long name, longer than the picture is wide: winner A"
    args = (plate, passes, blocks, [True])
    monkeypatch.setattr(figure, "_with_title", lambda rgb, title, text=None: rgb)
    render_figure(str(tmp_path / "raw.png"), *args, picture=FigureSettings(w, h, SPP), title=title)
    monkeypatch.undo()
    render_figure(
        str(tmp_path / "titled.png"), *args, picture=FigureSettings(w, h, SPP), title=title
    )
    with Image.open(tmp_path / "raw.png") as raw, Image.open(tmp_path / "titled.png") as titled:
        raw, titled = (np.asarray(im.convert("RGB")).astype(int) for im in (raw, titled))
    fig = title_figure(w, h, title)
    assert layout_problems(fig) == []  # whole, inside the picture
    box = fig.texts[0].get_window_extent(fig.canvas.get_renderer())  # pixels, y up
    assert box.y0 >= h * (1 - figure.TITLE_BAND) - 1 and box.y1 <= h and box.width <= w
    top, bottom = int(h - box.y1) - 2, int(np.ceil(h - box.y0)) + 2  # rows, y down, 2 px more
    left, right = int(box.x0) - 2, int(np.ceil(box.x1)) + 2
    changed = np.argwhere(np.any(raw != titled, axis=2))
    assert len(changed) > 0
    assert changed[:, 0].min() >= top and changed[:, 0].max() < bottom
    assert changed[:, 1].min() >= left and changed[:, 1].max() < right
    shapes = _green(raw) | _red(raw) | _orange(raw) | _grey(raw)
    assert shapes[: int(h * (1 - figure.TITLE_BAND)) + 1].sum() > 0.2 * w * h
    assert shapes[max(0, top) : bottom, max(0, left) : right].sum() == 0, (
        "the title lies on a shape"
    )


def test_flat_open_meshes_render(tmp_path, mi, colour):
    """Zero-thickness open meshes (a flat plate with a hole, a flat A and a flat B) render in colour."""
    ring = trimesh.creation.annulus(8.0, 30.0, height=1.0, sections=48)
    top = ring.vertices[:, 2] > 0
    plate = trimesh.Trimesh(
        ring.vertices, ring.faces[np.all(top[ring.faces], axis=1)], process=False
    )
    plate.apply_translation(
        [0, 0, -plate.bounds[1, 2]]
    )  # open, one-sided: only the top face, z = 0
    sheet = trimesh.Trimesh(
        [[-6, -6, 5], [6, -6, 5], [6, 6, 5], [-6, 6, 5]], [[0, 1, 2], [0, 2, 3]], process=False
    )
    tilted = sheet.copy()
    tilted.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 3, [1, 0, 0]))
    tilted.apply_translation([45, 0, 10])
    path = tmp_path / "flat.png"
    render_figure(str(path), plate, [sheet], [tilted], [True], picture=SMALL)
    img = _read(path)
    assert _green(img).sum() > 0 and _red(img).sum() > 0


def test_degenerate_input_still_writes(tmp_path, mi):
    """An empty mesh list and a mesh with zero-area faces do not stop the figure."""
    plate = _plate(40.0, 5.0, 10.0)
    degenerate = trimesh.Trimesh([[0, 0, 3], [1, 1, 3], [2, 2, 3]], [[0, 1, 2]], process=False)
    path = tmp_path / "d.png"
    render_figure(str(path), plate, [degenerate], [], [], picture=SMALL)
    assert _read(path).std() > 1


def test_mono_fallback_and_restore_on_error(tmp_path, scene, mi, monkeypatch):
    plate, passes, blocks = scene
    before = mi.variant()
    monkeypatch.setattr(backend, "RGB_VARIANTS", ())
    path = tmp_path / "grey.png"
    render_figure(str(path), plate, passes, blocks, [True], picture=SMALL)
    img = _read(path)
    assert np.all(img[..., 0] == img[..., 1]) and np.all(img[..., 1] == img[..., 2]), (
        "mono renders grey"
    )
    assert mi.variant() == before
    monkeypatch.undo()

    def boom(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(figure, "_scene", boom)
    with pytest.raises(RuntimeError, match="boom"):
        render_figure(str(tmp_path / "x.png"), plate, passes, blocks, [True], picture=SMALL)
    assert mi.variant() == before
    assert not (tmp_path / "x.png").exists()
    with pytest.raises(ValueError):
        render_figure(str(tmp_path / "x.png"), plate, passes, blocks, [], picture=SMALL)


def test_silhouettes_work_after_a_render(tmp_path, scene, cube20, mi):
    """The rest of the program (mono variant) keeps working after the switch to RGB and back."""
    from sieve_mi.geometry.raster import Frame
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    f = Frame(64, 20.0)
    early = SilhouetteRenderer(cube20)
    m0 = early.frame_mask([1, 0, 0, 0], [5.0, -3.0], f)
    plate, passes, blocks = scene
    render_figure(str(tmp_path / "f.png"), plate, passes, blocks, [True], picture=SMALL)
    m1 = early.frame_mask([1, 0, 0, 0], [5.0, -3.0], f)
    m2 = SilhouetteRenderer(cube20).frame_mask([1, 0, 0, 0], [5.0, -3.0], f)
    assert m0.sum() > 0 and np.array_equal(m0, m1) and np.array_equal(m0, m2)


@pytest.mark.parametrize("title", [False, True])
def test_camera_frames_every_box(title):
    boxes = [
        np.array([[-40.0, -40, -12], [40, 40, 0]]),
        np.array([[-9.0, -9, 10], [9, 9, 28]]),
        np.array([[48.0, -13, 0], [74, 13, 26]]),
    ]
    aspect = 4 / 3
    origin, target, up = figure._camera(boxes, aspect, title)
    fwd = (target - origin) / np.linalg.norm(target - origin)
    right = np.cross(fwd, up)
    corners = np.array(
        [[b[i, 0], b[j, 1], b[k, 2]] for b in boxes for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    )
    d = corners - origin
    depth = d @ fwd
    x, y = (d @ right) / depth, (d @ up) / depth
    tx = math.tan(math.radians(figure.FOV) / 2)
    ty = tx / aspect
    m = 1 - figure.MARGIN
    top = ty * m - (2 * ty * figure.TITLE_BAND if title else 0.0)
    assert np.all(depth > 0)
    eps = 1e-9
    assert (
        np.all(np.abs(x) <= tx * m + eps) and np.all(y >= -ty * m - eps) and np.all(y <= top + eps)
    )
    # As close as possible: the picture's width or height is filled up to the margin.
    assert math.isclose(x.max() - x.min(), 2 * tx * m, rel_tol=1e-6) or math.isclose(
        y.max() - y.min(), top + ty * m, rel_tol=1e-6
    )
