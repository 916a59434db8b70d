"""Checks of a drawn matplotlib picture: no text on a shape, no two texts overlapping, none cut off.

:func:`layout_problems` draws a figure, records every text the renderer really draws (tick
labels outside the view are not drawn and not counted), and compares, in display pixels:

* each text's box with each shape: the patches, lines and collections of every axes (their
  actual paths, clipped to their axes; a line's box is grown by half its width and its markers);
  the scale bar (:data:`sieve_mi.outputs.plots.SCALE_BAR_GID`) counts as text, not as a shape,
  so it must keep clear of the shapes and of its own label too;
* each two texts' boxes;
* each text's box with the picture's edges.

Boxes are shrunk by ``tolerance`` pixels before the comparison: touching is allowed.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.outputs.plots import SCALE_BAR_GID

__all__ = ["drawn_texts", "label_boxes", "layout_problems", "plan_view_problems", "shape_paths"]


def drawn_texts(fig) -> list:
    """Draw ``fig`` and return the Text artists with non-blank text that the renderer drew."""
    renderer = fig.canvas.get_renderer()
    drawn = []
    original = renderer.draw_text

    def record(gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if mtext is not None and s.strip() and mtext not in drawn:
            drawn.append(mtext)
        return original(gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)

    renderer.draw_text = record
    try:
        fig.canvas.draw()  # the canvas's own renderer: the one patched here
    finally:
        del renderer.draw_text
    return drawn


def label_boxes(fig) -> list[tuple[str, object]]:
    """(name, display Bbox) of every drawn text and every scale bar line of ``fig``."""
    from matplotlib.lines import Line2D

    renderer = fig.canvas.get_renderer()
    boxes = [(repr(t.get_text()), t.get_window_extent(renderer)) for t in drawn_texts(fig)]
    for ax in fig.axes:
        for line in ax.lines:
            if isinstance(line, Line2D) and line.get_gid() == SCALE_BAR_GID:
                path = line.get_transform().transform_path(line.get_path())
                grow = 0.5 * line.get_linewidth() * fig.dpi / 72
                boxes.append(("scale bar", path.get_extents().expanded(1, 1).padded(grow)))
    return boxes


def shape_paths(fig) -> list[tuple[str, object, object, bool, float]]:
    """Every shape of ``fig`` as (name, display Path, clip Bbox or None, filled, grow pixels).

    Shapes are the patches, lines and collections of every axes except the scale bar; ``grow``
    is half the drawn line width (and half the marker size) in pixels.
    """
    out = []
    scale = fig.dpi / 72
    for ax in fig.axes:
        for artist in [*ax.patches, *ax.lines, *ax.collections]:
            if artist.get_gid() == SCALE_BAR_GID or not artist.get_visible():
                continue
            clip = artist.get_clip_box() if artist.get_clip_on() else None
            if hasattr(artist, "get_paths"):  # a collection
                paths = [artist.get_transform().transform_path(p) for p in artist.get_paths()]
                filled, width = True, float(np.max(artist.get_linewidth(), initial=0.0))
            else:
                paths = [artist.get_transform().transform_path(artist.get_path())]
                filled = bool(getattr(artist, "get_fill", lambda: False)())
                width = artist.get_linewidth()
                if hasattr(artist, "get_markersize") and artist.get_marker() not in (
                    None,
                    "None",
                    "",
                ):
                    width = max(width, artist.get_markersize())
            name = f"{type(artist).__name__} {artist.get_label()!r}"
            out += [(name, p, clip, filled, 0.5 * width * scale) for p in paths]
    return out


def layout_problems(fig, tolerance: float = 2.0) -> list[str]:
    """What is wrong with ``fig``'s layout, one line per problem (an empty list: nothing).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        With a canvas (Agg); it is drawn here.
    tolerance : float
        Pixels by which boxes may touch or overlap.
    """
    from matplotlib.transforms import Bbox

    labels = label_boxes(fig)
    shapes = shape_paths(fig)
    page = fig.bbox.padded(tolerance)
    problems = []
    for i, (name, box) in enumerate(labels):
        inner = box.padded(-tolerance)
        if not page.contains(box.x0, box.y0) or not page.contains(box.x1, box.y1):
            problems.append(f"text {name} is cut off at the picture's edge ({_fmt(box)})")
        for other, box2 in labels[i + 1 :]:
            if Bbox.intersection(inner, box2.padded(-tolerance)) is not None:
                problems.append(f"texts {name} and {other} overlap ({_fmt(box)}, {_fmt(box2)})")
        for shape, path, clip, filled, grow in shapes:
            area = inner.padded(grow)
            if clip is not None:
                area = Bbox.intersection(area, clip)
            if area is not None and _touches(path, area, filled):
                problems.append(f"text {name} lies on {shape} ({_fmt(box)})")
    return problems


def plan_view_problems(fig, units: str) -> list[str]:
    """What a 2D view of ``fig`` lacks, one line per problem (an empty list: nothing).

    Every axes must have an x label naming ``units``, at least three ticks on each axis, and one
    scale bar (:func:`sieve_mi.outputs.plots.plan_view`): a line, a label ``"<length> <units>"``
    whose length is the line's, both under the lowest y tick (below the view, not on it).
    """
    problems = []
    for k, ax in enumerate(fig.axes):
        name = f"panel {k} ({ax.get_title()!r})"
        if units not in ax.get_xlabel():
            problems.append(f"{name}: the x axis is not labelled in {units}")
        if ax.get_xticks().size < 3 or ax.get_yticks().size < 3:
            problems.append(f"{name}: fewer than three ticks on an axis")
        bars = [ln for ln in ax.lines if ln.get_gid() == SCALE_BAR_GID]
        labels = [t for t in ax.texts if t.get_gid() == SCALE_BAR_GID]
        if len(bars) != 1 or len(labels) != 1 or not labels[0].get_text().endswith(f" {units}"):
            problems.append(f"{name}: no scale bar in {units}")
            continue
        x, y = (np.asarray(v, dtype=float) for v in bars[0].get_data())
        if not np.isclose(abs(x[-1] - x[0]), float(labels[0].get_text().split()[0])):
            problems.append(f"{name}: the scale bar's label is not its length")
        if max(y.max(), labels[0].get_position()[1]) >= min(ax.get_yticks()):
            problems.append(f"{name}: the scale bar is not under the view")
    return problems


def _touches(path, box, filled: bool) -> bool:
    """Whether a display path's outline crosses ``box`` or, for a filled path, its area (even-odd
    rule over all its contours, so a hole is not area) holds ``box``'s centre."""
    if path.intersects_bbox(box, filled=False):
        return True
    if not filled:
        return False
    x, y = 0.5 * (box.x0 + box.x1), 0.5 * (box.y0 + box.y1)
    crossings = 0
    for poly in path.to_polygons(closed_only=True):
        a, b = poly, np.roll(poly, -1, axis=0)
        up = (a[:, 1] > y) != (b[:, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
        crossings += int(np.count_nonzero(up & (xs > x)))
    return crossings % 2 == 1


def _fmt(box) -> str:
    """A display box as ``x0,y0-x1,y1`` in whole pixels."""
    return f"{box.x0:.0f},{box.y0:.0f}-{box.x1:.0f},{box.y1:.0f}"
