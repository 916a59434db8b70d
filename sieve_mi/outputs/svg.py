"""The pages' inline SVG pictures: the 2D hole view (with its scale bar) and the convergence plot.

One idea: vector pictures drawn as SVG text for :mod:`sieve_mi.outputs.viewer`'s pages, in scene
units with y flipped (SVG's y points down), in the colours of :mod:`sieve_mi.outputs.palette`.
Every element the page's toggles hide carries ``data-id`` (``hole``, ``a<i>``, ``b<j>``).
"""

from __future__ import annotations

import html
import math

import numpy as np

from sieve_mi.outputs.palette import block_colour, hex_colour

__all__ = ["convergence_svg", "hole_svg", "outline_svg", "scale_bar"]


def _path_d(section) -> str:
    """SVG path data of a CrossSection's contours, y flipped (SVG's y points down)."""
    d = []
    for c in section.to_polygons():
        pts = " L ".join(f"{x:.6g} {-y:.6g}" for x, y in np.asarray(c, dtype=np.float64))
        if pts:
            d.append(f"M {pts} Z")
    return " ".join(d)


def hole_svg(result, blocked: list[bool], a_titles: list[str] | None = None) -> str:
    """The 2D view: the exact hole (white, even-odd), every A's outline and every B's best attempt.

    Coordinates are scene units with y flipped; elements carry ``data-id`` (``hole``, ``a<i>``,
    ``b<j>``) so the page's toggles can hide them; ``a_titles`` (per A, e.g. its pass pose in
    words) become each A outline's ``<title>`` (a browser shows it on hover).
    """
    hole, a_sections, b_sections = result.overlay_sections()
    half = result.hole.frame.half_extent
    units = result.scene.units
    return outline_svg([hole], a_sections, b_sections, blocked, half, units, a_titles)


def outline_svg(
    holes: list,
    a_sections: list,
    b_sections: list,
    blocked: list[bool],
    half: float,
    units: str = "mm",
    a_titles: list[str] | None = None,
) -> str:
    """An inline SVG of hole outlines, dashed A outlines and outlined, hatched B attempts
    (CrossSections; the hole stays visible under them).

    Parameters
    ----------
    holes, a_sections, b_sections : list of manifold3d.CrossSection
        Scene units, xy; the first hole gets ``data-id="hole"``, the others ``hole<k>``.
    blocked : list of bool
        Per B: red (blocked) or orange (gets through), its outline and hatching.
    half : float
        Least half-width of the view, scene units (grown to hold every hole and B).
    units : str
        The scale bar's label.
    a_titles : list of str, optional
        Per A, the text of its outline's ``<title>`` (escaped here); none without it.
    """
    boxes = [np.asarray(s.bounds(), dtype=float) for s in [*holes, *b_sections] if not s.is_empty()]
    lim = max([half] + [float(np.abs(b).max()) for b in boxes]) * 1.05
    stroke = lim / 250
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" id="hole2d" viewBox="{-lim:.6g} {-lim:.6g} '
        f'{2 * lim:.6g} {2 * lim:.6g}" data-lim="{lim:.6g}">',
        f'<rect x="{-lim:.6g}" y="{-lim:.6g}" width="{2 * lim:.6g}" height="{2 * lim:.6g}" fill="{hex_colour("material")}"/>',
    ]
    for k, hole in enumerate(holes):
        parts.append(
            f'<path data-id="hole{k or ""}" fill="{hex_colour("hole")}" fill-rule="evenodd" '
            f'stroke="{hex_colour("edge")}" '
            f'stroke-width="{stroke:.3g}" d="{_path_d(hole)}"/>'
        )
    parts.append(_hatches(stroke))
    for j, sec in enumerate(b_sections):
        name = block_colour(blocked[j])
        parts.append(
            f'<path data-id="b{j}" fill="url(#hatch-{name})" fill-rule="nonzero" '
            f'stroke="{hex_colour(name)}" stroke-width="{2 * stroke:.3g}" d="{_path_d(sec)}"/>'
        )
    for i, sec in enumerate(a_sections):
        title = f"<title>{html.escape(a_titles[i])}</title>" if a_titles else ""
        parts.append(
            f'<path data-id="a{i}" fill="none" stroke="{hex_colour("pass")}" '
            f'stroke-width="{2 * stroke:.3g}" stroke-dasharray="{6 * stroke:.3g} {3 * stroke:.3g}" '
            f'd="{_path_d(sec)}"' + (f">{title}</path>" if title else "/>")
        )
    parts.append(scale_bar(lim, units))
    parts.append("</svg>")
    return "\n".join(parts)


def _hatches(stroke: float) -> str:
    """``<defs>`` of the B's hatchings, ``#hatch-blocked`` (red) and ``#hatch-escaped`` (orange):
    lines at 45°, six strokes apart, so the hole stays visible under a B (no fill over it)."""
    gap = 6 * stroke
    pats = "".join(
        f'<pattern id="hatch-{name}" patternUnits="userSpaceOnUse" width="{gap:.3g}" '
        f'height="{gap:.3g}" patternTransform="rotate(45)"><line x1="0" y1="0" x2="0" '
        f'y2="{gap:.3g}" stroke="{hex_colour(name)}" stroke-width="{stroke:.3g}"/></pattern>'
        for name in ("blocked", "escaped")
    )
    return f"<defs>{pats}</defs>"


def scale_bar(lim: float, units: str) -> str:
    """A scale bar in the bottom left of a view ``[-lim, lim]²`` (SVG units = scene units): a
    round length (1, 2 or 5 × 10^k) about a fifth of the view, labelled, with ``data-length``."""
    target = 0.4 * lim
    k = 10.0 ** math.floor(math.log10(target))
    length = max(m * k for m in (1, 2, 5) if m * k <= target)
    x0, y = -0.92 * lim, 0.9 * lim
    w, size = lim / 120, lim / 14
    return (
        f'<g id="scalebar" data-length="{length:g}"><line x1="{x0:.6g}" y1="{y:.6g}" '
        f'x2="{x0 + length:.6g}" y2="{y:.6g}" stroke="black" stroke-width="{w:.3g}"/>'
        f'<text x="{x0:.6g}" y="{y - size * 0.4:.6g}" font-size="{size:.3g}" '
        f'font-family="sans-serif">{length:g} {html.escape(units)}</text></g>'
    )


def convergence_svg(history: list[float]) -> str:
    """The best game value per search iteration as an inline SVG line plot (or a note: no
    search, or one value and no search iterations)."""
    if not history:
        return "<p>A's rotation was fixed: no search.</p>"
    if len(history) == 1:  # no curve to draw: say why (as convergence.png does)
        return (f"<p>One candidate, no search iterations: nothing to converge (the one value, "
                f"the best of A's first candidates: {history[0]:.5g}).</p>")  # fmt: skip
    w, h, left, pad = 480, 260, 64, 24
    y = np.asarray(history, dtype=np.float64)
    lo, hi = float(y.min()), float(y.max())
    span = hi - lo or max(abs(hi), 1.0)
    xs = left + (w - left - pad) * np.arange(len(y)) / max(len(y) - 1, 1)
    ys = h - 2 * pad - (h - 3 * pad) * (y - lo) / span
    pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(xs, ys))
    dots = "".join(
        f'<circle cx="{a:.1f}" cy="{b:.1f}" r="2.5" fill="{hex_colour("curve")}"/>'
        for a, b in zip(xs, ys)
    )
    levels = [(lo, h - 2 * pad)] + ([(hi, pad)] if hi > lo else [])
    ticks = "".join(
        f'<text x="{left - 6}" y="{yy + 4:.1f}" text-anchor="end" font-size="11">{v:.4g}</text>'
        for v, yy in levels
    )
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" class="plot" viewBox="0 0 {w} {h}" role="img" '
        f'aria-label="convergence of A\'s search">'
        f'<line x1="{left}" y1="{h - 2 * pad}" x2="{w - pad}" y2="{h - 2 * pad}" stroke="#444"/>'
        f'<line x1="{left}" y1="{h - 2 * pad}" x2="{left}" y2="{pad / 2}" stroke="#444"/>'
        f'<polyline fill="none" stroke="{hex_colour("curve")}" stroke-width="2" points="{pts}"/>{dots}{ticks}'
        f'<text x="{(w + left) / 2}" y="{h - 8}" text-anchor="middle" font-size="12">search '
        f"iteration (0..{len(y) - 1})</text>"
        f'<text x="12" y="{h / 2}" font-size="12" transform="rotate(-90 12 {h / 2})" '
        f'text-anchor="middle">best game value (min β)</text></svg>'
    )
