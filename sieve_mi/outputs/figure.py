"""``figure.png``: a Mitsuba rendering of a sieve, like Fig. 1 of the paper.

The plate is seen from an oblique view with the A shapes hovering over the hole and the B attempts
standing beside the plate. Colours: plate light grey, A green, blocked B red, a B that gets through
orange; a ground plane a little below the plate catches the light falling through the hole.

The rest of sieve-mi works in a monochrome variant (``llvm_ad_mono`` / ``cuda_ad_mono``). For a
colour picture :func:`render_figure` switches Mitsuba to an RGB variant for the duration of the
call and restores the previous variant afterwards (also on error). Where no RGB variant can be
used it renders in the current monochrome variant (a grey picture) instead of failing.
"""

from __future__ import annotations

import math
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import trimesh

from sieve_mi import backend as _backend
from sieve_mi.outputs import stage

__all__ = [
    "AZIMUTH",
    "BLOCKED_RGB",
    "CREASE_ANGLE",
    "ELEVATION",
    "ESCAPED_RGB",
    "FOV",
    "FigureSettings",
    "GROUND_GAP",
    "GROUND_RGB",
    "INTEGRATOR",
    "MARGIN",
    "PASS_RGB",
    "PLATE_RGB",
    "PNG_LEVEL",
    "RFILTER",
    "SAMPLER",
    "SKY_RGB",
    "SUN_AZIMUTH_OFFSET",
    "SUN_ELEVATION",
    "SUN_RGB",
    "TITLE_BAND",
    "render_figure",
    "title_figure",
]

#: Camera direction: azimuth (degrees, from +x towards +y) and elevation above the plate (degrees)
#: of the camera as seen from the scene.
AZIMUTH = -60.0
ELEVATION = 45.0
#: Sunlight: azimuth offset to the camera's left and elevation, degrees (close to the camera's
#: direction, so the light falling through the hole lands where the camera looks through it).
SUN_AZIMUTH_OFFSET = 35.0
SUN_ELEVATION = 52.0
#: Gap between the plate's underside and the ground, in plate thicknesses (plus 2 % of the scene size):
#: light reaches the ground under the hole, so the hole is seen through.
GROUND_GAP = 0.15
#: Horizontal field of view, degrees.
FOV = 30.0
#: Free border around the shapes, as a fraction of the half-width / half-height of the picture.
MARGIN = 0.05
#: Fraction of the picture height kept free at the top for the title.
TITLE_BAND = 0.08
#: Corners whose normal deviates from the vertex's mean normal by more than this are shaded flat, degrees.
CREASE_ANGLE = 35.0

#: zlib level of figure.png: 1 writes 1200 x 900 pixels in 0.09 s instead of 0.48 s (level 6,
#: PIL's default) for a file 10 % larger (2026-12-03).
PNG_LEVEL = 1

#: Light transport and sampling. The film's reconstruction filter: ``box`` puts each sample in
#: its own pixel; Mitsuba's ``gaussian`` (its default) splats every sample over 4 x 4 pixels with
#: atomic adds, a third of the rendering's time, and its picture is no closer to a 64-spp one
#: (RMS 3.2 instead of 3.5 grey levels at 8 spp, the default scene, 2026-12-07:
#: docs/performance.md).
INTEGRATOR = {"type": "path", "max_depth": 4}
SAMPLER = "multijitter"
RFILTER = "box"

#: Lights (linear RGB): the sky's radiance and the sun's irradiance.
SKY_RGB = (0.36, 0.37, 0.39)
SUN_RGB = (1.7, 1.63, 1.52)

#: Diffuse reflectances (linear RGB): the palette's colours (:data:`sieve_mi.outputs.stage.COLOURS`).
PLATE_RGB = stage.COLOURS["plate"]
PASS_RGB = stage.COLOURS["pass"]
BLOCKED_RGB = stage.COLOURS["blocked"]
ESCAPED_RGB = stage.COLOURS["escaped"]
GROUND_RGB = (0.50, 0.45, 0.38)


@dataclass(frozen=True)
class FigureSettings:
    """The picture :func:`render_figure` makes: its size and its samples per pixel.

    Attributes
    ----------
    width, height : int
        Picture size, pixels.
    spp : int
        Samples per pixel.
    """

    width: int = 1200
    height: int = 900
    spp: int = 8


def render_figure(
    path: str,
    plate: trimesh.Trimesh,
    passes: list[trimesh.Trimesh],
    blocks: list[trimesh.Trimesh],
    blocked: list[bool],
    *,
    picture: FigureSettings | None = None,
    title: str | None = None,
) -> None:
    """Render the sieve, the shapes that pass and the attempts of the shapes to block into a PNG.

    Nothing is moved: every mesh is drawn where it is. The camera looks at the union of all bounding
    boxes from an oblique direction (azimuth :data:`AZIMUTH`, elevation :data:`ELEVATION`, +z up)
    and is placed as close as the field of view :data:`FOV` allows with a small margin.

    Parameters
    ----------
    path : str
        Output PNG file. It is written to a temporary file in the same folder and then renamed.
    plate : trimesh.Trimesh
        The sieve plate, world coordinates in scene units (mm): z in [-T, 0], hole around the
        origin. Drawn light grey.
    passes : list of trimesh.Trimesh
        The A shapes, placed above the hole (scene units). Drawn green.
    blocks : list of trimesh.Trimesh
        The B shapes, placed beside the plate (scene units).
    blocked : list of bool
        One per entry of ``blocks``: True draws the shape red (blocked), False orange (it passes).
    picture : FigureSettings, optional
        Picture size and samples per pixel (default: :class:`FigureSettings`' defaults, 1200 x
        900 pixels at 8 spp).
    title : str, optional
        A line of text drawn at the top of the picture (the picture keeps its size).

    Raises
    ------
    ValueError
        If ``blocked`` and ``blocks`` differ in length, or the size or ``spp`` is not positive.

    Notes
    -----
    Takes about 2 CPU s for 1200 x 900 pixels at 8 spp on a 2-core CPU (``llvm_ad_rgb``, the
    default scene, box filter :data:`RFILTER`; 3 CPU s with Mitsuba's gaussian filter:
    docs/performance.md). Open,
    non-manifold and flat meshes render (every material is two-sided). The Mitsuba variant in
    effect before the call is in effect after it; if none was set, the RGB variant stays selected
    (Mitsuba cannot unset a variant).
    """
    picture = FigureSettings() if picture is None else picture
    width, height, spp = picture.width, picture.height, picture.spp
    if len(blocked) != len(blocks):
        raise ValueError(
            f"blocked has {len(blocked)} entries but there are {len(blocks)} block meshes"
        )
    if width < 1 or height < 1 or spp < 1:
        raise ValueError(f"width, height and spp must be positive (got {width}, {height}, {spp})")
    _backend.configure_llvm()
    import mitsuba as mi

    with stage.rgb_variant(mi) as variant:
        scene, sensor = _scene(mi, plate, passes, blocks, blocked, picture, title is not None)
        rendered = mi.render(scene, sensor=sensor, spp=spp)  # traced: it runs when read
        with ThreadPoolExecutor(1) as pool:  # the title drawn while the kernel runs (no GIL)
            text = pool.submit(_title_text, width, height, title) if title else None
            image = np.asarray(rendered, dtype=np.float32)
    rgb = _to_srgb8(image, colour=variant.endswith("rgb"))
    _write_png(path, rgb, title, text.result() if text is not None else None)


def _triangles(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, int]:
    """The mesh's usable triangles: faces with valid indices and finite corners.

    Returns
    -------
    corners : (F, 3, 3) ndarray
        Corner positions, scene units.
    faces : (F, 3) ndarray of int
        Vertex indices of the corners.
    n_vertices : int
    """
    v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    f = f[np.all((f >= 0) & (f < len(v)), axis=1)] if len(v) else f[:0]
    if len(f):
        f = f[np.all(np.isfinite(v[f]).reshape(len(f), -1), axis=1)]
    return v[f], f, len(v)


def _mesh(mi, name: str, triangles: tuple[np.ndarray, np.ndarray, int], rgb, smooth: bool):
    """A Mitsuba mesh (world coordinates) with a two-sided diffuse BSDF (see :func:`_triangles`).

    Every triangle gets its own three corners (:func:`sieve_mi.outputs.stage.mesh`), so a
    corner's shading normal (:func:`_corner_normals`, with ``smooth``) may differ between faces.
    """
    corners, f, n_vertices = triangles
    normals = _corner_normals(corners, f, n_vertices) if smooth else None
    flat = np.arange(3 * len(f)).reshape(-1, 3)
    return stage.mesh(mi, name, corners.reshape(-1, 3), flat, rgb, normals)


def _corner_normals(corners: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Per-corner shading normals: the vertex's area-weighted mean normal, or the face normal at creases.

    Parameters
    ----------
    corners : (F, 3, 3) ndarray
        Corner positions of every triangle.
    faces : (F, 3) ndarray of int
        Vertex index of every corner.
    n_vertices : int

    Returns
    -------
    (F, 3, 3) ndarray
        Unit normals; a corner whose face normal is more than :data:`CREASE_ANGLE` from the mean (or
        whose mean vanishes, e.g. where the winding flips) gets its face normal (flat shading).
    """
    cross = np.cross(
        corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    )  # length = 2 * area
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    fn = np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)
    acc = np.zeros((n_vertices, 3))
    for k in range(3):
        np.add.at(acc, faces[:, k], cross)
    alen = np.linalg.norm(acc, axis=1, keepdims=True)
    vn = np.divide(acc, alen, out=np.zeros_like(acc), where=alen > 0)[faces]  # (F, 3, 3)
    cos = np.einsum("fkc,fc->fk", vn, fn)
    flat = cos < math.cos(math.radians(CREASE_ANGLE))
    out = np.where(flat[..., None], fn[:, None, :], vn)
    # Degenerate faces: any unit vector (they are never hit); keeps Mitsuba away from NaNs.
    bad = np.linalg.norm(out, axis=2) < 0.5
    out[bad] = (0.0, 0.0, 1.0)
    return out


def _camera(boxes: list[np.ndarray], aspect: float, title: bool):
    """Camera origin, target and up vector that fit the union of boxes into the picture.

    The viewing direction is fixed (:data:`AZIMUTH`, :data:`ELEVATION`); the camera is then moved
    sideways and forward as far as all box corners stay inside the frustum shrunk by
    :data:`MARGIN` (and below the title band). For each image axis the constraint
    ``a_lo * depth <= offset <= a_hi * depth`` is linear in the camera position, so the closest
    position has a closed form.

    Parameters
    ----------
    boxes : list of (2, 3) ndarrays
        Axis-aligned boxes (lower and upper corner), scene units.
    aspect : float
        Picture width / height.
    title : bool
        Keep the title band free.

    Returns
    -------
    origin, target, up : (3,) ndarrays
        Scene units.
    """
    back, right, up = stage.view_axes(AZIMUTH, ELEVATION)
    fwd = -back
    corners = stage.box_corners(boxes)
    pr, pu, pf = corners @ right, corners @ up, corners @ fwd
    tx = math.tan(math.radians(FOV) / 2)
    ty = tx / aspect
    windows = [
        (-tx * (1 - MARGIN), tx * (1 - MARGIN)),
        (-ty * (1 - MARGIN), ty * (1 - MARGIN) - (2 * ty * TITLE_BAND if title else 0.0)),
    ]
    # Largest forward coordinate cf such that some lateral c satisfies, for every corner,
    # a_lo * (pf - cf) <= p - c <= a_hi * (pf - cf).
    extent = float(np.max(np.ptp(corners, axis=0))) or 1.0
    cf = (
        float(np.min(pf)) - 0.5 * extent
    )  # never closer than half the scene's size (a point-like scene)
    for p, (a_lo, a_hi) in zip((pr, pu), windows):
        cf = min(cf, (np.min(p - a_lo * pf) - np.max(p - a_hi * pf)) / (a_hi - a_lo))
    lateral = []
    for p, (a_lo, a_hi) in zip((pr, pu), windows):
        c_min = np.max(p - a_hi * (pf - cf))
        c_max = np.min(p - a_lo * (pf - cf))
        lateral.append(0.5 * (c_min + c_max))
    origin = lateral[0] * right + lateral[1] * up + cf * fwd
    return origin, origin + fwd * max(1.0, float(np.max(pf) - cf)), up


def _scene(mi, plate, passes, blocks, blocked, picture: FigureSettings, title: bool):
    """The loaded Mitsuba scene (lights, ground, meshes) and the fitted perspective sensor.

    Arguments are those of :func:`render_figure`; ``title`` (bool) keeps the title band free.
    """
    width, height, spp = picture.width, picture.height, picture.spp
    items = (
        [(plate, PLATE_RGB, False)]
        + [(m, PASS_RGB, True) for m in passes]
        + [(m, BLOCKED_RGB if b else ESCAPED_RGB, True) for m, b in zip(blocks, blocked)]
    )
    tris = [_triangles(m) for m, _, _ in items]
    boxes = [
        np.array([c.reshape(-1, 3).min(0), c.reshape(-1, 3).max(0)]) if len(c) else None
        for c, _, _ in tris
    ]
    present = [b for b in boxes if b is not None]
    if not present:
        present = [np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 0.0]])]
    lo = np.min([b[0] for b in present], axis=0)
    hi = np.max([b[1] for b in present], axis=0)
    size = float(np.max(hi - lo)) or 1.0
    ground = _ground_height(boxes[0], [b for b in boxes[1:] if b is not None], float(lo[2]), size)
    origin, target, up = _camera(present, width / height, title)

    centre = 0.5 * (lo + hi)
    sun = stage.sun_direction(AZIMUTH - SUN_AZIMUTH_OFFSET, SUN_ELEVATION)
    scene = stage.scene(dict(INTEGRATOR), SKY_RGB, SUN_RGB, sun)
    scene["ground"] = {
        "type": "rectangle",
        "bsdf": stage.diffuse(GROUND_RGB),  # 40 scene sizes wide: fills the view
        "to_world": mi.ScalarTransform4f().translate([float(centre[0]), float(centre[1]), ground])
        @ mi.ScalarTransform4f().scale([20 * size, 20 * size, 1.0]),
    }
    for i, ((_, rgb, smooth), t) in enumerate(zip(items, tris)):
        if len(t[0]):
            scene[f"mesh_{i}"] = _mesh(mi, f"mesh_{i}", t, rgb, smooth)
    sensor = stage.perspective(mi, (origin, target, up), FOV, size, far=1e3)
    sensor["sampler"] = {"type": SAMPLER, "sample_count": spp}
    sensor["film"] = stage.film(mi, width, height, rfilter=RFILTER)
    return mi.load_dict(scene), mi.load_dict(sensor)


def _ground_height(
    plate_box: np.ndarray | None, boxes: list[np.ndarray], lowest: float, size: float
) -> float:
    """Height of the ground plane, scene units.

    A little below the plate (:data:`GROUND_GAP` plate thicknesses plus 2 % of the scene), so the
    light through the hole falls on it; shapes that reach down to the plate's underside or lower
    are taken to rest on the ground, which then lies at their lowest point.

    Parameters
    ----------
    plate_box : (2, 3) ndarray or None
        The plate's bounding box (None: no plate).
    boxes : list of (2, 3) ndarrays
        Bounding boxes of the other shapes.
    lowest : float
        Lowest z of everything, scene units.
    size : float
        The scene's largest extent, scene units.
    """
    if plate_box is None:
        return lowest - 0.02 * size
    plate_lo, plate_hi = plate_box[0, 2], plate_box[1, 2]
    others = min((b[0, 2] for b in boxes), default=math.inf)
    if others <= plate_lo + 1e-3 * size:
        return float(others - 1e-4 * size)
    return float(plate_lo - GROUND_GAP * (plate_hi - plate_lo) - 0.02 * size)


def _to_srgb8(image: np.ndarray, colour: bool) -> np.ndarray:
    """Linear radiance (H, W, C) to 8-bit sRGB (H, W, 3); a single channel becomes grey."""
    if image.ndim == 2:
        image = image[..., None]
    rgb = image[..., :3] if colour and image.shape[2] >= 3 else np.repeat(image[..., :1], 3, axis=2)
    return stage.srgb8(rgb)


def title_figure(width: int, height: int, title: str):
    """The title of a picture of ``width`` x ``height`` pixels, alone on a transparent figure.

    The title is centred in the top :data:`TITLE_BAND` of the picture, which :func:`_camera`
    keeps free of the shapes; its font is as large as half the band, or smaller, so that the
    line fits the picture's width with a margin (:data:`MARGIN`).

    Returns
    -------
    matplotlib.figure.Figure
        With an Agg canvas, 100 dpi, one text and a transparent background: drawn over the
        rendered picture by :func:`_with_title`.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    fig.patch.set_alpha(0.0)
    points = max(4.0, 0.5 * TITLE_BAND * height * 72 / dpi)
    text = fig.text(
        0.5, 1 - TITLE_BAND / 2, title, ha="center", va="center", fontsize=points, color="#202020"
    )
    wide = text.get_window_extent(fig.canvas.get_renderer()).width
    room = (1 - MARGIN) * width
    if wide > room:
        text.set_fontsize(max(1.0, points * room / wide))
    return fig


def _title_text(width: int, height: int, title: str) -> np.ndarray:
    """The title of a picture of ``width`` x ``height`` pixels drawn alone
    (:func:`title_figure`): (height, width, 4) uint8 RGBA, transparent where there is no text."""
    fig = title_figure(width, height, title)
    fig.canvas.draw()
    drawn = np.asarray(fig.canvas.buffer_rgba())
    text = np.zeros((height, width, 4), np.uint8)  # the figure may round by a pixel: keep the size
    text[: min(height, drawn.shape[0]), : min(width, drawn.shape[1])] = drawn[:height, :width]
    return text


def _with_title(rgb: np.ndarray, title: str, text: np.ndarray | None = None) -> np.ndarray:
    """The picture with ``title`` drawn over it (``text``: :func:`_title_text`'s drawing of it,
    made here where None); every pixel that the text does not cover keeps its value."""
    h, w = rgb.shape[:2]
    text = _title_text(w, h, title) if text is None else text
    rows = np.flatnonzero(text[..., 3].any(axis=1))  # only the text's rows change
    out = np.array(rgb, dtype=np.uint8, order="C")
    if len(rows):
        band = slice(rows[0], rows[-1] + 1)
        alpha = text[band, :, 3:].astype(np.float32) / 255
        mixed = rgb[band].astype(np.float32) * (1 - alpha)
        mixed += text[band, :, :3].astype(np.float32) * alpha
        out[band] = np.round(mixed).astype(np.uint8)
    return out


def _write_png(path: str, rgb: np.ndarray, title: str | None, text=None) -> None:
    """Write the picture (with the title drawn on top: ``text``, :func:`_title_text`'s, where
    given) to a temporary file beside ``path``, then rename it."""
    from PIL import Image

    if title:
        rgb = _with_title(rgb, title, text)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".figure-", suffix=".png", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            # zlib level 1: the same pixels, a tenth larger, five times faster to write
            Image.fromarray(rgb).save(fh, format="PNG", compress_level=PNG_LEVEL)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
