"""Reading a given hole image (a sieve drawn as pixels): its hole pixels and its holes on a frame.

A binary image is a sieve for ``sieve-mi check --hole``: white (or opaque, for images with
alpha) pixels are the hole, square pixels of a given size in scene units, +y up. Greyscale of any
depth counts pixels above half its range as hole (:func:`image_mask`). The mask is cropped to
its hole pixels and padded to a square frame (:func:`frame_for_image`); each 8-connected piece
is one hole (:func:`read_image_holes`), the pixels being the truth (no exact outline).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import struct
import warnings

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.hole import Hole, split_pieces
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.sieve import SieveHoles

__all__ = [
    "IMAGE_PIXELS_MAX",
    "exr_size",
    "frame_for_image",
    "image_mask",
    "image_size",
    "mask_from_image",
    "open_image",
    "read_image_holes",
]


#: Most pixels a hole image may have: Pillow's own bound against decompression bombs
#: (``PIL.Image.MAX_IMAGE_PIXELS``, about 9459 x 9459; a 48 KB PNG can hold 20000 x 20000).
#: Beyond it Pillow warns (two lines on stderr) and, at twice as many, refuses with a traceback;
#: sieve-mi refuses it in one line. The search's raster is at most 4096 pixels across.
IMAGE_PIXELS_MAX = 89_478_485


def _unreadable(path: str, exc: BaseException) -> SieveError:
    return SieveError(f"{path}: could not be read as an image ({exc.__class__.__name__})")


@contextlib.contextmanager
def open_image(path: str):
    """A hole image opened with Pillow (header read, pixels not yet decoded), its size checked.

    Yields
    ------
    PIL.Image.Image

    Raises
    ------
    SieveError
        A missing or unreadable file; an image of more than :data:`IMAGE_PIXELS_MAX` pixels,
        naming its pixel count (Pillow's warning or error about a decompression bomb caught:
        nothing else is printed).
    """
    from PIL import Image, UnidentifiedImageError

    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole image not found")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            im = Image.open(path)
    except (Image.DecompressionBombWarning, Image.DecompressionBombError) as exc:
        raise _too_many_pixels(path, str(exc)) from None
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise _unreadable(path, exc) from None
    with im:
        if im.width * im.height > IMAGE_PIXELS_MAX:  # Pillow's bound may have been raised
            raise _too_many_pixels(path, f"({im.width * im.height} pixels)", im.size)
        yield im


def _too_many_pixels(path: str, words: str, size: tuple | None = None) -> SieveError:
    """The one line for an image of too many pixels (their count read from Pillow's words)."""
    count = re.search(r"\((\d+) pixels\)", words)
    pixels = f"{int(count.group(1)):,} pixels" if count else "too many pixels"
    dims = f" ({size[0]} x {size[1]})" if size else ""
    return SieveError(
        f"{path}: the image has {pixels}{dims}; hole images may have at most "
        f"{IMAGE_PIXELS_MAX:,} (Pillow's bound against decompression bombs): crop it to the "
        "holes or scale it down (and its pixel size up)"
    )


def exr_size(path: str) -> tuple[int, int] | None:
    """An OpenEXR file's width and height from its header's ``dataWindow`` (nothing decoded);
    None where the header cannot be read (Mitsuba's reader then says what is wrong)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    at = 8  # magic number and version
    while at < len(head) and head[at] != 0:  # attributes: name, type, size, value; "" ends them
        name_end = head.find(b"\0", at)
        type_end = head.find(b"\0", name_end + 1)
        if name_end < 0 or type_end < 0 or type_end + 5 > len(head):
            return None
        (size,) = struct.unpack_from("<i", head, type_end + 1)
        value = type_end + 5
        if head[at:name_end] == b"dataWindow" and size == 16 and value + 16 <= len(head):
            x0, y0, x1, y1 = struct.unpack_from("<4i", head, value)
            return x1 - x0 + 1, y1 - y0 + 1
        at = value + max(size, 0)
    return None


def image_size(path: str) -> tuple[int, int]:
    """A hole image's width and height in pixels, read from its header (:func:`open_image`,
    :func:`exr_size`): one line for a missing, unreadable or oversized image, before anything
    is decoded (an EXR whose header is not read here: ``(0, 0)``, left to Mitsuba's reader)."""
    if not path.lower().endswith(".exr"):
        with open_image(path) as im:
            return im.size
    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole image not found")
    try:
        size = exr_size(path)
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if size is not None and size[0] * size[1] > IMAGE_PIXELS_MAX:
        raise _too_many_pixels(path, f"({size[0] * size[1]} pixels)", size)
    return size or (0, 0)


def mask_from_image(path: str) -> np.ndarray:
    """A binary hole mask from an image: white (or opaque, for images with alpha) pixels are the hole."""
    from PIL import UnidentifiedImageError

    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole image not found")
    try:
        if path.lower().endswith(".exr"):
            import mitsuba as mi

            image_size(path)  # its header's size, before Mitsuba decodes it all

            from sieve_mi.backend import bitmap_threads

            with bitmap_threads():
                img = np.asarray(mi.Bitmap(path), dtype=np.float64)
            img = img[..., 0] if img.ndim == 3 else img
            mask = img > 0.5
        else:
            with open_image(path) as im:
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
