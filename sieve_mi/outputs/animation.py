"""``passage.gif``: a short Mitsuba-rendered animation of every A sliding down through the plate and
every B coming to rest on it (the motion of :mod:`sieve_mi.outputs.passage`).

All frames are rendered by one ``mi.render`` call: the scene holds one copy of the plate and the
shapes per frame (Mitsuba instances of shared shape groups, so the geometry is stored once), the
copies far apart along x, and a ``batch`` sensor puts one perspective camera on each copy side by
side on one film. :func:`write_gif` renders in colour: it switches Mitsuba to an RGB variant for
the call (:func:`sieve_mi.outputs.stage.rgb_variant`, as :func:`sieve_mi.outputs.figure.render_figure`
does) and restores the previous one (green: every A; red: a blocked B; orange: a B that gets
through; grey: the plate). Where no RGB variant can be used (e.g. a packed GPU site without them)
it renders in the monochrome variant in effect: grey frames (light: passes, dark: blocked,
mid-grey: the plate). The sampler is seeded the same way every run and each sample lands in one pixel (box filter), so
the same inputs give the same GIF (``tests/game/test_repro.py`` compares two processes' files).
"""

from __future__ import annotations

import math
import os

import numpy as np

from sieve_mi.errors import raise_if_signalled
from sieve_mi.outputs import stage
from sieve_mi.outputs.passage import Passage

__all__ = [
    "gif_frames",
    "AZIMUTH",
    "BLOCKED_ALBEDO",
    "COLOURS",
    "ELEVATION",
    "ESCAPED_ALBEDO",
    "FOV",
    "FRAMES_PER_SLOT",
    "FRAME_MS",
    "HEIGHT",
    "PASS_ALBEDO",
    "PLATE_ALBEDO",
    "SAMPLER",
    "SKY",
    "SPP",
    "SUN",
    "SUN_AZIMUTH_OFFSET",
    "SUN_ELEVATION",
    "WIDTH",
    "camera",
    "frame_count",
    "phases",
    "render_frames",
    "to_gray8",
    "write_gif",
]

#: Frames per slot of the motion (all of A, then each B: :mod:`sieve_mi.outputs.passage`), picture size
#: (pixels) and samples per pixel of ``passage.gif``.
FRAMES_PER_SLOT = 10
WIDTH = 300
HEIGHT = 390
SPP = 8
#: Frame duration, milliseconds (the last frame is held three times as long).
FRAME_MS = 120
#: Camera direction: azimuth from +x towards +y and elevation above the plate, degrees; field of view.
AZIMUTH = -60.0
ELEVATION = 22.0
FOV = 35.0
#: Diffuse reflectances in RGB variants (linear RGB: the palette's, :data:`~sieve_mi.outputs.stage.COLOURS`) ...
COLOURS = stage.COLOURS
#: ... and in monochrome ones.
PLATE_ALBEDO = 0.35
PASS_ALBEDO = 0.6
BLOCKED_ALBEDO = 0.12
ESCAPED_ALBEDO = 0.6
#: Sky radiance and the sun's irradiance.
SKY = 0.55
#: Mitsuba sampler of the frames (stratified: far less grain than independent samples; with it
#: 8 spp, since 2026-12-04, shows what 16 did at half the rendering: docs/performance.md).
SAMPLER = "multijitter"
SUN = 2.2
#: The sun: azimuth offset to the camera's left and elevation, degrees.
SUN_AZIMUTH_OFFSET = 35.0
SUN_ELEVATION = 55.0


def frame_count(passage: Passage) -> int:
    """Number of frames of the passage's GIF: :data:`FRAMES_PER_SLOT` per slot."""
    return FRAMES_PER_SLOT * (1 + sum(p.role == "block" for p in passage.pieces))


def phases(frames: int) -> np.ndarray:
    """The animation phases of the frames: ``frames`` values from 0 to 1."""
    return np.linspace(0.0, 1.0, frames)


def render_frames(
    passage: Passage,
    *,
    phases: np.ndarray | None = None,
    box: np.ndarray | None = None,
    width: int = WIDTH,
    height: int = HEIGHT,
    spp: int = SPP,
) -> np.ndarray:
    """Render the passage's frames in one batch, in the Mitsuba variant in effect.

    Parameters
    ----------
    passage : Passage
    phases : (K,) array_like, optional
        The frames' phases in [0, 1] (default: :func:`phases` of :func:`frame_count` frames).
    box : (2, 3) ndarray, optional
        The box the camera frames (default: ``passage.bounds()``), scene units.
    width, height : int
        Frame size, pixels.
    spp : int
        Samples per pixel.

    Returns
    -------
    (K, height, width) or (K, height, width, 3) ndarray of float32
        Linear radiance per frame (row 0 at the top): grey in a monochrome variant, RGB in an
        RGB one.
    """
    film = _film(passage, phases, box, width, height, spp)
    return _frames(film, width)


def _film(passage: Passage, phases, box, width: int, height: int, spp: int) -> np.ndarray:
    """:func:`render_frames`' rendering, its frames side by side: (height, K * width) or
    (height, K * width, 3) float32 (the batch sensor's film, as Mitsuba develops it)."""
    import mitsuba as mi

    s = globals()["phases"](frame_count(passage)) if phases is None else np.asarray(phases, float)
    box = passage.bounds() if box is None else np.asarray(box, dtype=np.float64)
    size = float(np.max(box[1] - box[0]))
    spacing = 10.0 * size
    colour = "rgb" in mi.variant()
    scene = _scene(mi, passage, s, spacing, colour)
    sensor = _batch_sensor(mi, box, len(s), spacing, width, height, spp, size)
    image = np.asarray(mi.render(scene, sensor=sensor, spp=spp), dtype=np.float32)
    raise_if_signalled()  # Mitsuba may render on through an interrupt
    image = image.reshape(height, len(s) * width, -1)
    return image[..., :3] if colour else image.mean(axis=2)


def _frames(film: np.ndarray, width: int) -> np.ndarray:
    """The film's frames, one after the other: (K, height, width[, 3]), a copy."""
    count = film.shape[1] // width
    return np.stack([film[:, k * width : (k + 1) * width] for k in range(count)])


def _group(mi, vertices: np.ndarray, faces: np.ndarray, albedo):
    """A shape group (a dict for ``mi.load_dict``) holding one mesh with a two-sided diffuse
    material (:func:`sieve_mi.outputs.stage.mesh`); ``albedo`` is a float (monochrome) or an RGB
    triple."""
    return {"type": "shapegroup", "mesh": stage.mesh(mi, "m", vertices, faces, albedo)}


def _albedo(piece, colour: bool):
    """A piece's reflectance: its palette colour (:func:`sieve_mi.outputs.stage.colour_name`),
    or its grey in a monochrome variant."""
    kind = stage.colour_name(piece.role, piece.passes)
    if colour:
        return COLOURS[kind]
    return {"pass": PASS_ALBEDO, "escaped": ESCAPED_ALBEDO, "blocked": BLOCKED_ALBEDO}[kind]


def _light(value: float, colour: bool):
    """A grey light for :func:`sieve_mi.outputs.stage.spectrum`: white RGB in RGB variants (a
    flat spectrum would be tinted pink in sRGB), else the number."""
    return (value,) * 3 if colour else value


def _scene(mi, passage: Passage, phases: np.ndarray, spacing: float, colour: bool = False):
    """One copy of the plate and the shapes per phase, the k-th moved by k * spacing along x."""
    T = mi.ScalarTransform4f
    plate = COLOURS["plate"] if colour else PLATE_ALBEDO
    groups = [_group(mi, passage.plate_vertices, passage.plate_faces, plate)]
    groups += [_group(mi, p.vertices, p.faces, _albedo(p, colour)) for p in passage.pieces]
    scene = stage.scene(
        {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1},
        _light(SKY, colour),
        _light(SUN, colour),
        stage.sun_direction(AZIMUTH - SUN_AZIMUTH_OFFSET, SUN_ELEVATION),
    )
    for g, group in enumerate(groups):
        scene[f"group_{g}"] = group
    for k, s in enumerate(phases):
        x = k * spacing
        scene[f"plate_{k}"] = {
            "type": "instance",
            "shapegroup": {"type": "ref", "id": "group_0"},
            "to_world": T().translate([x, 0.0, 0.0]),
        }
        for i, p in enumerate(passage.pieces):
            if not p.visible(s):
                continue
            scene[f"piece_{k}_{i}"] = {
                "type": "instance",
                "shapegroup": {"type": "ref", "id": f"group_{i + 1}"},
                "to_world": T().translate([x, 0.0, 0.0]) @ T(p.matrix(s).tolist()),
            }
    return mi.load_dict(scene)


def camera(box: np.ndarray, aspect: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera origin and target that frame the box ``(2, 3)`` from the fixed direction.

    The camera looks at the box's centre from :data:`AZIMUTH`, :data:`ELEVATION` and stands as
    close as the field of view (:data:`FOV` horizontally, ``FOV / aspect`` vertically, 8 % margin)
    lets every corner of the box stay in the picture. Returns (3,) arrays, scene units.
    """
    centre = 0.5 * (box[0] + box[1])
    back, right, up = stage.view_axes(AZIMUTH, ELEVATION)
    rel = stage.box_corners(box) - centre
    tx = 0.92 * math.tan(math.radians(FOV) / 2)
    ty = tx / aspect
    need = np.maximum(np.abs(rel @ right) / tx, np.abs(rel @ up) / ty) + rel @ back
    dist = max(float(need.max()), 1e-6)
    return centre + dist * back, centre


def _batch_sensor(mi, box, frames, spacing, width, height, spp, size):
    """A batch sensor: one perspective camera per frame copy, side by side on one film."""
    origin, target = camera(box, width / height)
    sensor = {
        "type": "batch",
        "sampler": {"type": SAMPLER, "sample_count": spp},
        "film": stage.film(mi, frames * width, height, rfilter="box"),
    }
    for k in range(frames):
        shift = np.array([k * spacing, 0.0, 0.0])
        cam = stage.perspective(mi, (origin + shift, target + shift, [0, 0, 1]), FOV, size, far=1e2)
        cam["film"] = stage.film(mi, width, height)
        sensor[f"cam_{k}"] = cam
    return mi.load_dict(sensor)


def to_gray8(frames: np.ndarray) -> np.ndarray:
    """Linear radiance to 8-bit sRGB, one exposure for all frames (the sky maps to ~white); grey
    or RGB as the input."""
    return stage.srgb8(frames, white=1.1 * SKY)


def gif_frames(passage: Passage, phases: np.ndarray) -> tuple[list, str]:
    """GIF-ready frames of ``passage`` at ``phases``: rendered in an RGB variant where one exists
    (the caller's variant is restored after), each colour frame with its own adaptive palette.

    Returns
    -------
    frames : list of PIL.Image.Image
        Palette ("P") images in colour, else greyscale ("L").
    variant : str
        The variant that rendered them.
    """
    import mitsuba as mi
    from PIL import Image

    with stage.rgb_variant(mi) as variant:  # sRGB on the film, then cut (the same bytes: a
        # quarter of the memory that cutting the float frames first copies)
        images = _frames(to_gray8(_film(passage, phases, None, WIDTH, HEIGHT, SPP)), WIDTH)
    mode = "RGB" if images.ndim == 4 else "L"
    pics = [Image.fromarray(im, mode=mode) for im in images]
    if mode == "RGB":  # one adaptive palette per frame (PIL's default GIF palette tints greys)
        from concurrent.futures import ThreadPoolExecutor

        def palette(p):
            return p.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)

        # PIL quantizes without the GIL: the frames on every core (the same frames; 0.19 ->
        # 0.10 s for the default scene's 20 on 2 cores, 2026-12-07)
        with ThreadPoolExecutor(max(1, min(len(pics), os.cpu_count() or 1))) as pool:
            pics = list(pool.map(palette, pics))
    return pics, variant


def write_gif(path: str, passage: Passage) -> dict:
    """Render ``passage.gif`` (:func:`render_frames`) and return what report.json records of it.

    Returns
    -------
    dict
        ``frames``, ``width``, ``height``, ``spp``, ``frame_ms`` and ``phases``.
    """
    s = phases(frame_count(passage))
    pics, variant = gif_frames(passage, s)
    mode = "RGB" if pics[0].mode == "P" else "L"
    durations = [FRAME_MS] * (len(pics) - 1) + [3 * FRAME_MS]
    pics[0].save(path, save_all=True, append_images=pics[1:], duration=durations, loop=0)
    return {
        "frames": len(pics),
        "width": WIDTH,
        "height": HEIGHT,
        "spp": SPP,
        "frame_ms": FRAME_MS,
        "colour": mode == "RGB",
        "variant": variant,
        "phases": [float(x) for x in s],
    }
