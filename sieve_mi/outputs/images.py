"""The images of a solve: the hole as PNG and EXR, and every mask on the hole's lattice.

One idea: rasters on the hole's pixel lattice (row 0 at the top, +y up), written with the pixel
size they were drawn at. ``hole.png`` and ``hole.exr`` hold the exact hole at pixel centres;
``masks.exr`` holds every mask as one multi-layer EXR (:func:`mask_layers`): the exact hole, the
conservative raster player B attacked, B's distance field, each A's silhouette at its pass pose
and each B's best attempt, the A and B layers rendered by Mitsuba (:func:`rendered_masks`);
``masks/`` holds single-layer copies. Every EXR carries the frame in its header
(:func:`exr_metadata`), every PNG its pixel size (``pHYs``).
"""

from __future__ import annotations

import os

import numpy as np

from sieve_mi.backend import bitmap_threads
from sieve_mi.game.result import Result
from sieve_mi.geometry.pixels import png_metadata

__all__ = [
    "exr_metadata",
    "mask_layers",
    "paste_window",
    "rendered_masks",
    "safe_name",
    "window_origin",
    "write_exr",
    "write_images",
    "write_layers",
    "write_png",
]


def safe_name(name: str) -> str:
    """A file-name-safe version of a shape name."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def write_exr(path: str, image: np.ndarray, metadata: dict | None = None) -> None:
    """Write a single-channel float32 OpenEXR image with Mitsuba's Bitmap, plus header metadata.

    Parameters
    ----------
    path : str
    image : (H, W) ndarray
        Row 0 at the top.
    metadata : dict of str to float or str, optional
        Header attributes (:func:`exr_metadata`).
    """
    import mitsuba as mi

    bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    header = bitmap.metadata()
    for key, value in (metadata or {}).items():
        header[key] = value
    with bitmap_threads():
        bitmap.write(path)


def exr_metadata(result: Result, origin: tuple[float, float] | None = None) -> dict:
    """The header every written EXR carries: pixel size, units, top-left corner, sieve-mi version.

    Parameters
    ----------
    result : Result
    origin : (float, float), optional
        Scene (x, y) of the image's top-left corner; default the hole frame's.
    """
    from sieve_mi._version import VERSION

    frame = result.hole.frame
    x0, y0 = origin if origin is not None else (-frame.half_extent, frame.half_extent)
    return {
        "pixel_size": float(frame.pixel_size),
        "units": result.scene.units,
        "frame_origin": f"{float(x0)!r} {float(y0)!r}",
        "frame_note": "frame_origin is the top-left corner (x y); row 0 at the top, +y up",
        "software": f"sieve-mi {VERSION}",
    }


def write_layers(path: str, layers: dict, metadata: dict) -> None:
    """Write a multi-layer OpenEXR: one named float32 channel per (N, N) array, plus metadata.

    Parameters
    ----------
    path : str
    layers : dict of str to (N, N) ndarray
        Channel name to image (row 0 at the top); all of one size.
    metadata : dict of str to float or str
        Header attributes (e.g. the pixel size), shown by viewers such as tev.
    """
    import mitsuba as mi

    names = list(layers)
    stack = np.stack([np.asarray(layers[n], dtype=np.float32) for n in names], axis=-1)
    bitmap = mi.Bitmap(
        np.ascontiguousarray(stack),
        pixel_format=mi.Bitmap.PixelFormat.MultiChannel,
        channel_names=names,
    )
    header = bitmap.metadata()
    for key, value in metadata.items():
        header[key] = value
    with bitmap_threads():
        bitmap.write(path)


def paste_window(window, frame) -> np.ndarray:
    """A B attempt's mask window (:class:`~sieve_mi.game.scoring.MaskWindow`) on the frame's lattice.

    The window is a piece of the same pixel lattice, possibly reaching beyond the frame; what lies
    beyond is cut off. Returns an (N, N) bool array.
    """
    mask, n = window.mask, frame.resolution
    row0, col0 = window_origin(window, frame)
    out = np.zeros((n, n), dtype=bool)
    r0, c0 = max(row0, 0), max(col0, 0)
    r1, c1 = min(row0 + mask.shape[0], n), min(col0 + mask.shape[1], n)
    if r1 > r0 and c1 > c0:
        out[r0:r1, c0:c1] = mask[r0 - row0 : r1 - row0, c0 - col0 : c1 - col0]
    return out


def window_origin(window, frame) -> tuple[int, int]:
    """Lattice (row, column) of a :class:`~sieve_mi.game.scoring.MaskWindow`'s top-left pixel."""
    x0, _, _, y1 = window.extent
    h = frame.pixel_size
    return int(round((frame.half_extent - y1) / h)), int(round((x0 + frame.half_extent) / h))


def rendered_masks(result: Result) -> tuple[list, list]:
    """The silhouettes that get written, rendered by Mitsuba (``mi.render`` under the lattice's
    orthographic sensors, :meth:`~sieve_mi.geometry.silhouettes.SilhouetteRenderer.render`).

    Returns
    -------
    a : list of (N, N) bool ndarrays
        Each A at its pass pose, on the hole's frame (equal to ``result.a_masks``).
    b : list of MaskWindow
        Each B in its best attempt, on the window of ``result.block_masks`` (equal to it).
    """
    from sieve_mi.game.scoring import MaskWindow
    from sieve_mi.geometry.silhouettes import SilhouetteRenderer

    frame = result.hole.frame
    a = [
        SilhouetteRenderer(shape).render(q, t, frame)
        for shape, q, t in zip(result.pass_shapes, result.pass_quats, result.pass_trans)
    ]
    b = []
    for j, (shape, window) in enumerate(zip(result.block_shapes, result.block_masks)):
        row0, col0 = window_origin(window, frame)
        q, t = result.attack.quats[0, j], result.attack.trans[0, j]
        mask = SilhouetteRenderer(shape).render(q, t, frame, row0, col0, window.mask.shape[0])
        b.append(MaskWindow(window.extent, mask))
    return a, b


def mask_layers(result: Result, rendered: tuple | None = None) -> dict:
    """The layers of ``masks.exr``: the exact hole at pixel centres, the conservative raster the
    attack used, player B's distance field (scene units), every A's silhouette and every B's best
    attempt, all on the hole's lattice.

    Channel names follow OpenEXR's ``layer.channel`` rule (the layer is the text before the last
    dot), one luminance channel ``Y`` per layer: ``hole.Y``, ``cover.Y``, ``distance.Y``,
    ``a<i>_<name>.Y``, ``b<j>_<name>.Y``. ``rendered`` is :func:`rendered_masks`'s answer
    (computed when not given).
    """
    from sieve_mi.geometry.outline import rasterize

    hole = result.hole
    a_masks, b_windows = rendered_masks(result) if rendered is None else rendered
    layers = {
        "hole.Y": rasterize(result.outline, hole.frame),
        "cover.Y": hole.mask,
        "distance.Y": hole.outside,
    }
    for i, (m, shape) in enumerate(zip(a_masks, result.pass_shapes)):
        layers[f"a{i}_{safe_name(shape.name)}.Y"] = m
    for j, (shape, window) in enumerate(zip(result.block_shapes, b_windows)):
        layers[f"b{j}_{safe_name(shape.name)}.Y"] = paste_window(window, hole.frame)
    return layers


def write_png(
    path: str, mask: np.ndarray, pixel_size: float | None = None, units: str = "mm"
) -> None:
    """Write a binary mask as an 8-bit grey PNG (white = inside).

    With ``pixel_size`` (in ``units``) the PNG records it: ``pHYs`` in pixels per metre and the
    exact value as text (:func:`sieve_mi.geometry.pixels.png_metadata`).
    """
    from PIL import Image

    extra = {} if pixel_size is None else png_metadata(pixel_size, units)
    Image.fromarray((np.asarray(mask) > 0).astype(np.uint8) * 255).save(path, "PNG", **extra)


def write_images(result: Result, tmp: str) -> None:
    """``hole.png``, ``hole.exr``, ``masks.exr`` and ``masks/*.exr`` into folder ``tmp``."""
    os.makedirs(os.path.join(tmp, "masks"))
    frame, meta = result.hole.frame, exr_metadata(result)
    rendered = a_masks, b_windows = rendered_masks(result)
    layers = mask_layers(result, rendered)
    exact = layers["hole.Y"]  # pixel centres inside the printed polygon
    write_png(os.path.join(tmp, "hole.png"), exact, frame.pixel_size, result.scene.units)
    write_exr(os.path.join(tmp, "hole.exr"), exact.astype(np.float32), meta)
    a_union = np.logical_or.reduce(a_masks)
    write_exr(os.path.join(tmp, "masks", "a_silhouette.exr"), a_union.astype(np.float32), meta)
    if len(a_masks) > 1:
        for i, (m, shape) in enumerate(zip(a_masks, result.pass_shapes)):
            write_exr(
                os.path.join(tmp, "masks", f"pass_{i}_{safe_name(shape.name)}.exr"),
                m.astype(np.float32),
                meta,
            )
    for j, (shape, window) in enumerate(zip(result.block_shapes, b_windows)):
        x0, _, _, y1 = window.extent
        write_exr(
            os.path.join(tmp, "masks", f"block_{j}_{safe_name(shape.name)}.exr"),
            window.mask.astype(np.float32),
            exr_metadata(result, (x0, y1)),
        )
    write_layers(os.path.join(tmp, "masks.exr"), layers, meta)
