"""A raster image's physical pixel size: PNG's ``pHYs`` chunk, written and read.

``hole.png`` carries its pixel size twice: as ``pHYs`` (whole pixels per metre, the PNG
standard's physical size, which image viewers, GIMP and laser-cutter software read) and, exactly,
as the text chunks ``sieve-mi:pixel_size`` and ``sieve-mi:units``. ``sieve-mi check --hole
hole.png`` then needs no ``--pixel-size``; any PNG with a metric ``pHYs`` works the same way.
"""

from __future__ import annotations

import math
import os

__all__ = ["METRES_PER_UNIT", "TEXT_PIXEL_SIZE", "TEXT_UNITS", "image_pixel_size", "png_metadata"]

#: Length of one scene unit in metres, for each accepted ``units`` label.
METRES_PER_UNIT = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254, "um": 1e-6}
#: PNG text keys holding the exact pixel size (``repr`` of the float) and its unit.
TEXT_PIXEL_SIZE = "sieve-mi:pixel_size"
TEXT_UNITS = "sieve-mi:units"


def png_metadata(pixel_size: float, units: str) -> dict:
    """Keyword arguments for Pillow's ``Image.save(..., format="PNG")`` that record the pixel size.

    Parameters
    ----------
    pixel_size : float
        Side of one pixel, in ``units``.
    units : str
        One of :data:`METRES_PER_UNIT` (other labels get the text chunks only).

    Returns
    -------
    dict
        ``pnginfo`` (the text chunks) and, for a known unit, ``dpi`` chosen so that Pillow writes
        ``pHYs`` with ``round(1 / pixel size in metres)`` pixels per metre on both axes.
    """
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text(TEXT_PIXEL_SIZE, repr(float(pixel_size)))
    info.add_text(TEXT_UNITS, units)
    out = {"pnginfo": info}
    metres = METRES_PER_UNIT.get(units)
    if metres is not None:
        per_metre = max(1, round(1.0 / (pixel_size * metres)))
        out["dpi"] = (per_metre * 0.0254, per_metre * 0.0254)  # Pillow: int(dpi / 0.0254 + 0.5)
    return out


def image_pixel_size(path: str, units: str) -> float | None:
    """The pixel size an image records, in ``units``; None where it records none.

    sieve-mi's exact text chunks come first; else a metric ``pHYs`` chunk (square pixels). A
    missing or unreadable file records none (the image reader then says what is wrong).
    """
    from PIL import Image, UnidentifiedImageError

    if not os.path.isfile(path):
        return None
    try:
        with Image.open(path) as im:
            info = dict(im.info)
    except (UnidentifiedImageError, OSError):
        return None
    exact = _exact(info, units)
    if exact is not None:
        return exact
    dpi, metres = info.get("dpi"), METRES_PER_UNIT.get(units)
    if not dpi or metres is None or not dpi[0] > 0 or abs(dpi[0] - dpi[1]) > 1e-9 * dpi[0]:
        return None
    return 0.0254 / float(dpi[0]) / metres


def _exact(info: dict, units: str) -> float | None:
    """The text chunks' pixel size converted to ``units``, or None."""
    try:
        size = float(info[TEXT_PIXEL_SIZE])
    except (KeyError, TypeError, ValueError):
        return None
    written = info.get(TEXT_UNITS)
    if not (size > 0 and math.isfinite(size)):
        return None
    if written == units:
        return size
    if written in METRES_PER_UNIT and units in METRES_PER_UNIT:
        return size * METRES_PER_UNIT[written] / METRES_PER_UNIT[units]
    return None
