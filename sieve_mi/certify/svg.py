"""Read a hole outline from an SVG file exactly, or refuse it in one line.

The file :func:`sieve_mi.outputs.fabrication.write_svg` writes holds one ``<path>`` whose ``d``
attribute is a list of closed polygons ``M x y L x y ... Z``, filled even-odd. Other files are
read when every drawn element is one this reader takes exactly:

* ``<path>`` with the straight-line commands M, L, H, V, Z, absolute or relative (lower case),
  with repeated coordinates (after M they are line-tos, as SVG says);
* ``<polygon>`` and ``<polyline>`` (``points``; a polyline's fill closes it, as SVG fills it);
* ``<rect>`` (``x``, ``y``, ``width``, ``height``) without rounded corners.

Each element is filled with its own ``fill-rule`` (attribute or style, inherited; SVG's default
``nonzero``) and the hole is the union of the elements, as a renderer fills them. Fill, stroke and
display styles are not read: every such element counts as filled, and a stroke adds nothing.

**Units.** One user unit is one scene unit (the shape mesh's unit), y pointing down (flipped
back here). The root's ``width`` and ``height`` may name mm, cm, in, px or no unit (solve writes
its scene's unit there); with a ``viewBox`` they must equal its size, so the drawing is not
scaled. A physical ``width`` without a ``viewBox`` (user units are then CSS pixels), a ``viewBox``
that scales, or any other unit is refused.

**Refused**, each with one line naming it: curves (path commands A, C, S, Q, T), ``transform``
on an element or any ancestor, ``<circle>``, ``<ellipse>``, ``<line>``, ``<text>``, ``<use>``,
``<image>``, nested ``<svg>``, ``<style>`` sheets, clip paths, masks and markers. Elements in
``<defs>`` are not drawn and are skipped; elements of other namespaces (an editor's metadata)
are skipped.
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

SVG_NS = "http://www.w3.org/2000/svg"

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_PIECE = re.compile(rf"(?P<cmd>[A-Za-z])|(?P<num>{_NUMBER})|(?P<sep>[\s,]+)|(?P<bad>.)", re.S)

#: Path commands that are not straight lines, and what they draw.
CURVES = {
    "A": "an elliptical arc",
    "C": "a cubic Bézier curve",
    "S": "a smooth cubic Bézier curve",
    "Q": "a quadratic Bézier curve",
    "T": "a smooth quadratic Bézier curve",
}

#: Drawn SVG elements this reader does not take, and why.
REFUSED_ELEMENTS = {
    "circle": "a circle",
    "ellipse": "an ellipse",
    "line": "a line",
    "text": "text",
    "tspan": "text",
    "textPath": "text",
    "use": "a reference to other elements",
    "image": "an image",
    "foreignObject": "foreign content",
    "svg": "a nested drawing with its own viewport",
    "style": "a style sheet (it could move or restyle the drawing)",
    "switch": "a conditional group",
    "clipPath": "a clip path",
    "mask": "a mask",
    "marker": "a marker",
    "pattern": "a pattern",
    "symbol": "a symbol",
}

#: Attributes (and style properties) that change the geometry, refused on any element.
REFUSED_ATTRIBUTES = ("transform", "clip-path", "mask", "marker", "marker-start", "marker-mid",
                      "marker-end")  # fmt: skip

#: SVG elements that draw nothing themselves.
CONTAINERS = {"g", "a", "title", "desc", "metadata"}

#: Units the root's width and height may carry (one user unit is then one of them).
UNITS = ("", "px", "mm", "cm", "in")

_TO_ABSOLUTE = "to convert them to straight segments (e.g. Inkscape: Path > Object to Path, then "
_FLATTEN = _TO_ABSOLUTE + "Extensions > Modify Path > Flatten Beziers)"


def _tokens(d: str, where: str) -> list:
    """The commands (str) and numbers (float) of a path's ``d``, in order."""
    out = []
    for m in _PIECE.finditer(d):
        if m.group("cmd"):
            out.append(m.group("cmd"))
        elif m.group("num"):
            out.append(float(m.group("num")))
        elif m.group("bad"):
            raise SieveError(f"{where}: <path d=...>: unexpected {m.group('bad')!r} in the path")
    return out


def _segments(d: str, where: str) -> list[tuple[str, list[float]]]:
    """The path as (command, its numbers) pairs; curves and unknown letters refused."""
    segs: list[tuple[str, list[float]]] = []
    for tok in _tokens(d, where):
        if isinstance(tok, float):
            if not segs:
                raise SieveError(f"{where}: <path d=...> must start with M (a move-to)")
            segs[-1][1].append(tok)
            continue
        up = tok.upper()
        if up in CURVES:
            raise SieveError(
                f"{where}: <path> command {tok} ({CURVES[up]}) is not read: certify reads "
                f"straight segments only (M, L, H, V, Z); {_FLATTEN}"
            )
        if up not in "MLHVZ":
            raise SieveError(f"{where}: <path> command {tok!r} is not an SVG path command")
        if not segs and up != "M":
            raise SieveError(f"{where}: <path d=...> must start with M (a move-to), not {tok}")
        segs.append((tok, []))
    return segs


def _arity(cmd: str, nums: list[float], where: str) -> None:
    """Refuse a command with the wrong count of numbers."""
    up = cmd.upper()
    if up == "Z" and nums:
        raise SieveError(f"{where}: <path> command {cmd} takes no coordinates")
    if up in "ML" and (not nums or len(nums) % 2):
        raise SieveError(f"{where}: <path> command {cmd} needs x y pairs, got {len(nums)} numbers")
    if up in "HV" and not nums:
        raise SieveError(f"{where}: <path> command {cmd} needs at least one coordinate")


def parse_path(d: str, where: str) -> list[np.ndarray]:
    """The subpaths of an SVG path of straight segments as polygons, y flipped.

    Parameters
    ----------
    d : str
        The ``d`` attribute: commands M, L, H, V, Z (absolute) and m, l, h, v, z (relative).
    where : str
        The file's name, for messages.

    Returns
    -------
    list of (m, 2) float ndarray
        One polygon per subpath of at least three points (fewer enclose no area), scene units.

    Raises
    ------
    SieveError
        A curve, an unknown command, a wrong count of coordinates, or a stray character.
    """
    contours: list = []
    sub: list = []
    cur = start = (0.0, 0.0)
    for cmd, nums in _segments(d, where):
        _arity(cmd, nums, where)
        up, rel = cmd.upper(), cmd.islower()
        if up == "Z":
            contours.append(sub)
            sub, cur = [], start
            continue
        if up == "M":
            contours.append(sub)
            cur = (cur[0] + nums[0], cur[1] + nums[1]) if rel else (nums[0], nums[1])
            sub, start, nums, up = [cur], cur, nums[2:], "L"
        for point in _line_points(up, rel, nums, cur):
            sub = sub or [cur]  # a line after Z starts a subpath at the closed one's start
            cur = point
            sub.append(cur)
    contours.append(sub)
    return [np.array([(x, -y) for x, y in c], dtype=np.float64) for c in contours if len(c) >= 3]


def _line_points(up: str, rel: bool, nums: list[float], cur: tuple) -> list[tuple]:
    """The points an L, H or V command draws to, from the current point ``cur``."""
    out = []
    x, y = cur
    if up == "L":
        for i in range(0, len(nums), 2):
            x, y = (x + nums[i], y + nums[i + 1]) if rel else (nums[i], nums[i + 1])
            out.append((x, y))
    elif up == "H":
        for v in nums:
            x = x + v if rel else v
            out.append((x, y))
    else:
        for v in nums:
            y = y + v if rel else v
            out.append((x, y))
    return out


def _local(tag) -> tuple[str, bool]:
    """An element's local name and whether it is an SVG element (SVG namespace or none)."""
    if not isinstance(tag, str):  # a comment or processing instruction
        return "", False
    if tag.startswith("{"):
        ns, name = tag[1:].split("}", 1)
        return name, ns == SVG_NS
    return tag, True


def _style(el: ET.Element) -> dict:
    """The element's ``style`` attribute as {property: value}."""
    out = {}
    for item in (el.get("style") or "").split(";"):
        if ":" in item:
            key, value = item.split(":", 1)
            out[key.strip().lower()] = value.strip()
    return out


def _refuse_attributes(el: ET.Element, name: str, where: str) -> None:
    style = _style(el)
    for attr in REFUSED_ATTRIBUTES:
        if el.get(attr) is not None or attr in style:
            raise SieveError(
                f"{where}: <{name}> has a {attr} (not read: it would move or cut the outline); "
                f"apply it to the coordinates (e.g. Inkscape: Path > Object to Path) or remove it"
            )


def _fill_rule(el: ET.Element, inherited: str, where: str) -> str:
    rule = _style(el).get("fill-rule", el.get("fill-rule", inherited)).strip().lower()
    if rule == "inherit":
        return inherited
    if rule not in ("nonzero", "evenodd"):
        raise SieveError(f"{where}: fill-rule {rule!r} must be nonzero or evenodd")
    return rule


def _plain_number(text, what: str, where: str, default: float | None = None) -> float:
    """A length attribute in user units: a plain number (or px)."""
    if text is None and default is not None:
        return default
    m = re.fullmatch(rf"\s*({_NUMBER})\s*(px)?\s*", text or "")
    if m is None:
        raise SieveError(f"{where}: {what} {text!r} is not read: give a plain number of user units")
    return float(m.group(1))


def _points(text: str, what: str, where: str) -> np.ndarray:
    """A polygon's or polyline's ``points`` as (n, 2), y flipped."""
    nums = [float(x) for x in re.findall(_NUMBER, text or "")]
    if re.sub(rf"{_NUMBER}|[\s,]", "", text or ""):
        raise SieveError(f"{where}: <{what} points=...> holds something that is not a number")
    if len(nums) % 2:
        raise SieveError(f"{where}: <{what} points=...> has an odd number of coordinates")
    return np.array([(nums[i], -nums[i + 1]) for i in range(0, len(nums), 2)], dtype=np.float64)


def _rect(el: ET.Element, where: str) -> list[np.ndarray]:
    for corner in ("rx", "ry"):
        if _plain_number(el.get(corner), f"<rect {corner}>", where, 0.0) != 0:
            raise SieveError(
                f"{where}: <rect> with rounded corners ({corner}) is not read; "
                f"{_TO_ABSOLUTE}Extensions > Modify Path > Flatten Beziers)"
            )
    x = _plain_number(el.get("x"), "<rect x>", where, 0.0)
    y = _plain_number(el.get("y"), "<rect y>", where, 0.0)
    w = _plain_number(el.get("width"), "<rect width>", where)
    h = _plain_number(el.get("height"), "<rect height>", where)
    if w < 0 or h < 0:
        raise SieveError(f"{where}: <rect> has a negative width or height")
    if w == 0 or h == 0:
        return []  # SVG draws nothing
    return [np.array([(x, -y), (x + w, -y), (x + w, -y - h), (x, -y - h)], dtype=np.float64)]


def _contours(el: ET.Element, name: str, where: str) -> list[np.ndarray]:
    """The polygons one drawn element fills (scene units, y up)."""
    if name == "path":
        return parse_path(el.get("d", ""), where)
    if name == "rect":
        return _rect(el, where)
    pts = _points(el.get("points", ""), name, where)
    return [pts] if len(pts) >= 3 else []


def _walk(el: ET.Element, rule: str, where: str, out: list) -> None:
    """Collect (contours, fill rule) of every drawn element under ``el`` (its children)."""
    for child in el:
        name, svg = _local(child.tag)
        if not svg:
            continue  # an editor's metadata (another namespace), a comment
        _refuse_attributes(child, name, where)
        if name in REFUSED_ELEMENTS:
            raise SieveError(
                f"{where}: <{name}> ({REFUSED_ELEMENTS[name]}) is not read; certify reads "
                "<path> (straight segments), <polygon>, <polyline> and <rect> only"
            )
        child_rule = _fill_rule(child, rule, where)
        if name == "defs":
            _refuse_style_sheets(child, where)
        elif name in ("path", "polygon", "polyline", "rect"):
            out.append((_contours(child, name, where), child_rule))
        elif name in CONTAINERS:
            _walk(child, child_rule, where, out)
        else:
            raise SieveError(
                f"{where}: <{name}> is not read; certify reads <path> (straight segments), "
                "<polygon>, <polyline> and <rect> only"
            )


def _refuse_style_sheets(defs: ET.Element, where: str) -> None:
    """A ``<style>`` sheet in ``<defs>`` applies to the drawing: refused like one elsewhere."""
    for el in defs.iter():
        if _local(el.tag) == ("style", True):
            raise SieveError(f"{where}: <style> ({REFUSED_ELEMENTS['style']}) is not read")


def _length(text, what: str, where: str):
    """(number, unit) of a root ``width``/``height``, or None when absent."""
    if text is None:
        return None
    m = re.fullmatch(rf"\s*({_NUMBER})\s*([A-Za-z%]*)\s*", text)
    if m is None or m.group(2).lower() not in UNITS:
        raise SieveError(
            f"{where}: <svg {what}={text!r}> is not read: give a number in mm, cm, in, px or "
            "no unit (one user unit is read as one scene unit)"
        )
    return float(m.group(1)), m.group(2).lower()


def _check_units(root: ET.Element, where: str) -> None:
    """Refuse a root whose width, height and viewBox would scale user units."""
    size = {k: _length(root.get(k), k, where) for k in ("width", "height")}
    box = root.get("viewBox")
    if box is None:
        for k, v in size.items():
            if v is not None and v[1] not in ("", "px"):
                raise SieveError(
                    f'{where}: <svg {k}="{root.get(k)}"> without a viewBox makes user units '
                    f'CSS pixels; add viewBox="0 0 WIDTH HEIGHT" in the same numbers (one user '
                    "unit is read as one scene unit)"
                )
        return
    nums = [float(x) for x in re.findall(_NUMBER, box)]
    if len(nums) != 4 or not (nums[2] > 0 and nums[3] > 0):
        raise SieveError(
            f"{where}: <svg viewBox={box!r}> must be four numbers, width and height > 0"
        )
    for (k, v), n in zip(size.items(), nums[2:]):
        if v is not None and abs(v[0] - n) > 1e-9 * max(abs(n), 1e-300):
            raise SieveError(
                f'{where}: <svg {k}="{root.get(k)}"> for a viewBox {n:g} wide scales the '
                f"drawing by {v[0] / n:.6g}; certify reads one user unit as one scene unit: make "
                f"{k} equal the viewBox's ({n:g}) or remove it"
            )


def _parse(path: str) -> ET.Element:
    if not os.path.isfile(path):
        raise SieveError(f"{path}: hole SVG not found")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SieveError(f"{path}: not a readable SVG file ({exc})") from None
    except (OSError, UnicodeError, ValueError) as exc:
        raise SieveError(f"{path}: not a readable SVG file ({type(exc).__name__})") from None
    if _local(root.tag) != ("svg", True):
        raise SieveError(f"{path}: not an SVG file (its root element is not <svg>)")
    return root


def read_svg_hole(path: str) -> manifold3d.CrossSection:
    """The hole outline of an SVG file as a CrossSection (scene units), read exactly.

    Raises
    ------
    SieveError
        If the file is missing or not SVG, holds anything this reader does not take exactly (see
        the module docstring), has no polygon, or the polygons enclose no area.
    """
    root = _parse(path)
    _refuse_attributes(root, "svg", path)
    _check_units(root, path)
    drawn: list = []
    _walk(root, _fill_rule(root, "nonzero", path), path, drawn)
    contours = [c for cs, _ in drawn for c in cs]
    if not contours or not all(np.all(np.isfinite(c)) for c in contours):
        raise SieveError(
            f"{path}: no polygon with finite coordinates in any <path>, <polygon>, <polyline> "
            "or <rect>"
        )
    if any(np.abs(c).max() > MAX_COORDINATE for c in contours):
        raise SieveError(f"{path}: a coordinate exceeds {MAX_COORDINATE:g} scene units")
    rules = {"nonzero": manifold3d.FillRule.NonZero, "evenodd": manifold3d.FillRule.EvenOdd}
    hole = manifold3d.CrossSection()
    try:
        for cs, rule in drawn:
            if cs:
                hole = hole + manifold3d.CrossSection(cs, rules[rule])
    except RuntimeError as exc:  # Clipper2's own range check
        raise SieveError(f"{path}: the outline cannot be read as a polygon ({exc})") from None
    if hole.is_empty() or hole.area() <= 0:
        raise SieveError(f"{path}: the outline encloses no area")
    return hole
