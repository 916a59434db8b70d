"""Read a hole outline from the SVG that :func:`sieve_mi.outputs.fabrication.write_svg` writes.

The file holds one ``<path>`` whose ``d`` attribute is a list of closed polygons
``M x y L x y ... Z`` (absolute coordinates, 1 user unit = 1 scene unit, y pointing down, so y is
flipped back), filled even-odd.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET

import manifold3d
import numpy as np

from sieve_mi.errors import SieveError

__all__ = ["MAX_COORDINATE", "parse_path", "read_svg_hole"]

#: Largest coordinate of a hole outline (scene units; the polygon library works on a 1e-8 grid in
#: 64-bit integers and refuses coordinates from about 4e10 on).
MAX_COORDINATE = 1e9

_TOKEN = re.compile(r"[MLZmlz]|[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def parse_path(d: str, where: str) -> list[np.ndarray]:
    """Polygons of an SVG path made of absolute M, L and Z commands, y flipped; list of (m, 2)."""
    contours, current, numbers = [], [], []
    for tok in _TOKEN.findall(d):
        if tok in "MLZmlz":
            if tok in "mlz" and tok != "z":
                raise SieveError(f"{where}: relative path commands are not supported")
            if len(numbers) % 2:
                raise SieveError(f"{where}: odd number of coordinates in the path")
            current += [(numbers[i], -numbers[i + 1]) for i in range(0, len(numbers), 2)]
            numbers = []
            if tok in "Mm" and current or tok in "Zz":
                if len(current) >= 3:
                    contours.append(np.asarray(current, dtype=np.float64))
                current = []
        else:
            numbers.append(float(tok))
    current += [(numbers[i], -numbers[i + 1]) for i in range(0, len(numbers) - 1, 2)]
    if len(current) >= 3:
        contours.append(np.asarray(current, dtype=np.float64))
    return contours


def read_svg_hole(path: str) -> manifold3d.CrossSection:
    """The hole outline of an SVG file as a CrossSection (scene units).

    Raises
    ------
    SieveError
        If the file is missing, not SVG, has no path, or the path encloses no area.
    """
    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole SVG not found")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SieveError(f"{path}: not a readable SVG file ({exc})") from None
    ds = [el.get("d", "") for el in root.iter() if el.tag.split("}")[-1] == "path"]
    contours = [c for d in ds for c in parse_path(d, path)]
    if not contours or not all(np.all(np.isfinite(c)) for c in contours):
        raise SieveError(f"{path}: no polygon with finite coordinates in any <path d=...>")
    if any(np.abs(c).max() > MAX_COORDINATE for c in contours):
        raise SieveError(f"{path}: a coordinate exceeds {MAX_COORDINATE:g} scene units")
    try:
        hole = manifold3d.CrossSection(contours, manifold3d.FillRule.EvenOdd)
    except RuntimeError as exc:  # Clipper2's own range check
        raise SieveError(f"{path}: the path cannot be read as a polygon ({exc})") from None
    if hole.is_empty() or hole.area() <= 0:
        raise SieveError(f"{path}: the path encloses no area")
    return hole
