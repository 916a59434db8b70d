"""Reading a given hole image (a sieve drawn as pixels): its hole pixels and its holes on a frame.

A binary image is a sieve for ``sieve-mi check --hole``: white (or opaque, for images with
alpha) pixels are the hole, square pixels of a given size in scene units, +y up. Greyscale of any
depth counts pixels above half its range as hole (:func:`image_mask`). The mask is cropped to
its hole pixels and padded to a square frame (:func:`frame_for_image`); each 8-connected piece
is one hole (:func:`read_image_holes`), the pixels being the truth (no exact outline).
"""

from __future__ import annotations

import math
import os

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.hole import Hole, split_pieces
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.sieve import SieveHoles

__all__ = ["frame_for_image", "image_mask", "mask_from_image", "read_image_holes"]


def mask_from_image(path: str) -> np.ndarray:
    """A binary hole mask from an image: white (or opaque, for images with alpha) pixels are the hole."""
    from PIL import Image, UnidentifiedImageError

    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole image not found")
    try:
        if path.lower().endswith(".exr"):
            import mitsuba as mi

            from sieve_mi.backend import bitmap_threads

            with bitmap_threads():
                img = np.asarray(mi.Bitmap(path), dtype=np.float64)
            img = img[..., 0] if img.ndim == 3 else img
            mask = img > 0.5
        else:
            with Image.open(path) as im:
                mask = image_mask(im)
    except (UnidentifiedImageError, OSError, RuntimeError) as exc:
        raise SieveError(
            f"{path}: could not be read as an image ({exc.__class__.__name__})"
        ) from None
    if not mask.any():
        raise SieveError(f"{path}: no hole pixels (the hole must be white on black)")
    if mask.all():
        raise SieveError(
            f"{path}: every pixel is hole; the hole must be white on a black background"
        )
    return mask


def image_mask(im) -> np.ndarray:
    """The hole pixels of a PIL image, at the image's own bit depth.

    Greyscale of any depth (8 or 16 bits, integer or float): pixels above half the range
    (255, 65535 or 1.0) are hole. With transparency that is used: the opaque pixels are the hole,
    or, where the opaque pixels hold both dark and light ones, the opaque light pixels.
    """
    if im.mode in ("RGBA", "LA", "PA") or "transparency" in im.info:
        rgba = np.asarray(im.convert("RGBA"))
        opaque = rgba[..., 3] > 127
        if (rgba[..., 3] < 255).any():
            light = np.asarray(im.convert("L")) > 127
            both = (light & opaque).any() and (~light & opaque).any()
            return opaque & light if both else opaque
    if im.mode.startswith("I;16") or im.mode in ("I", "F"):
        grey = np.asarray(im, dtype=np.float64)
        top = 1.0 if im.mode == "F" else (255.0 if grey.max() <= 255 else 65535.0)
        return grey > top / 2
    return np.asarray(im.convert("L")) > 127


def frame_for_image(mask: np.ndarray, pixel_size: float) -> tuple[Frame, np.ndarray]:
    """Pad an image mask to a square frame with pixel size ``pixel_size``, hole centred.

    Returns
    -------
    frame : Frame
    mask : (N, N) bool ndarray
    """
    rows, cols = np.nonzero(mask)
    crop = mask[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
    n = max(crop.shape) + 8
    out = np.zeros((n, n), dtype=bool)
    r0, c0 = (n - crop.shape[0]) // 2, (n - crop.shape[1]) // 2
    out[r0 : r0 + crop.shape[0], c0 : c0 + crop.shape[1]] = crop
    return Frame(n, 0.5 * n * pixel_size), out


def read_image_holes(path: str, pixel_size: float | None) -> SieveHoles:
    """The holes (8-connected white pieces) of a hole image with ``pixel_size``, on its frame.

    Returns
    -------
    SieveHoles
        Centred at the frame's origin, with the padded mask and no exact outlines.

    Raises
    ------
    SieveError
        No usable pixel size, or an image that cannot be read or holds no hole
        (:func:`mask_from_image`).
    """
    if pixel_size is None or not (pixel_size > 0 and math.isfinite(pixel_size)):
        raise SieveError(
            f"--pixel-size {pixel_size}: give the hole image's pixel size, a positive number in scene units"
        )
    frame, mask = frame_for_image(mask_from_image(path), pixel_size)
    holes = [Hole.from_mask(m, frame) for m in split_pieces(mask)]
    info = [{"area": h.area} for h in holes]
    return SieveHoles(path, holes, frame, np.zeros(2), info, mask=mask)
