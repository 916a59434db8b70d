"""sieve-mi's matplotlib pictures: a solve's overlay.png and convergence.png, and their layout.

One idea: the 2D pictures drawn with matplotlib and the layout they share (:func:`overlay_figure`,
:func:`convergence_figure`; cascade.png, drawn by :mod:`sieve_mi.cascade.outputs`, keeps it too).
Every picture keeps three rules (``tests/outputs/test_picture_layout.py`` and
``tests/cascade/test_cascade_figure.py`` check them with :mod:`sieve_mi.testing.pictures`):

* text has its own area — titles above the panels, captions below them, a scale bar's label in
  the strip under the shapes — and never lies on a drawn shape; no two texts overlap, and none
  is cut off at the picture's edge (long titles are wrapped to their panel's width);
* every 2D view has axes in scene units and a scale bar (:func:`plan_view`);
* the figure is built by a function that returns it (a :class:`matplotlib.figure.Figure` with an
  Agg canvas, no pyplot state), and written by :func:`save`, so a test draws exactly what is saved.
"""

from __future__ import annotations

import math
import os
import textwrap
from typing import TYPE_CHECKING

import numpy as np

from sieve_mi.outputs.palette import block_colour, hex_colour

if TYPE_CHECKING:
    from sieve_mi.game.result import Result

__all__ = [
    "B_HATCH",
    "CHAR_WIDTH",
    "GAME_VALUE",
    "LINE_HEIGHT",
    "MERGED_VALUE",
    "OVERLAY_COLUMNS",
    "OVERHANG_ALPHA",
    "OVERLAY_PANEL",
    "SCALE_BAR_GID",
    "SCALE_STRIP",
    "SINGLE_VALUE",
    "SINGLE_VALUE_GID",
    "convergence_figure",
    "draw_contours",
    "grid_figure",
    "new_figure",
    "nice_length",
    "overlay_figure",
    "panel_grid",
    "plan_view",
    "save",
    "wrap",
    "write_plots",
]

#: Height of the strip under a 2D view that holds the scale bar, as a fraction of the view's width.
SCALE_STRIP = 0.16
#: A generous mean width of a character, in ems (DejaVu Sans averages about 0.55): :func:`wrap`
#: breaks lines so that they fit.
CHAR_WIDTH = 0.62
#: The height of a line of text, in ems (line spacing and padding included).
LINE_HEIGHT = 1.35
#: The ``gid`` of a scale bar's line and label (tests tell them from the shapes by it).
SCALE_BAR_GID = "scale-bar"


def new_figure(width: float, height: float, dpi: float):
    """A figure of ``width`` x ``height`` inches with constrained layout and an Agg canvas.

    Constrained layout keeps titles, axis labels, tick labels and a figure's super-title
    (``suptitle``, ``supxlabel``) apart from each other and inside the picture.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def draw_contours(ax, contours, **style) -> None:
    """Draw closed contours as one compound patch: a contour wound against the outer one is a hole.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    contours : list of (n, 2) array_like
        Closed polygons (the first point is not repeated), e.g. a CrossSection's
        ``to_polygons()``; nothing is drawn for none.
    **style
        Patch properties (``facecolor``, ``edgecolor``, ``linewidth``, ``fill``, ...).
    """
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path

    verts, codes = [], []
    for c in contours:
        c = np.asarray(c, dtype=np.float64)
        verts += [*c, c[0]]
        codes += [Path.MOVETO] + [Path.LINETO] * (len(c) - 1) + [Path.CLOSEPOLY]
    if verts:
        ax.add_patch(PathPatch(Path(np.array(verts), codes), **style))


def grid_figure(
    counts: list[int],
    panel: float,
    dpi: float,
    *,
    title_lines: list[int],
    title_size: float = 9.0,
    suptitle_lines: int = 1,
    suptitle_size: float = 10.0,
) -> tuple:
    """A figure for rows of 2D views (:func:`plan_view`), tall enough for their titles.

    Parameters
    ----------
    counts : list of int
        Panels per row (:func:`panel_grid`).
    panel : float
        Width of a panel with its tick labels, inches.
    dpi : float
    title_lines : list of int
        Per row, the most lines a panel title of that row takes (after :func:`wrap`).
    title_size, suptitle_size : float
        Font sizes of the panel titles and the figure's title, points.
    suptitle_lines : int
        Lines of the figure's title.

    Returns
    -------
    fig : matplotlib.figure.Figure
    rows : list of list of matplotlib.axes.Axes
        The panels, row by row (:func:`panel_grid`).
    """
    view = panel - 0.3  # the tick labels take the rest (never too little: an overfull layout fails)
    heights = [
        view * (1 + SCALE_STRIP) + 0.6 + lines * LINE_HEIGHT * title_size / 72
        for lines in title_lines
    ]
    height = sum(heights) + suptitle_lines * LINE_HEIGHT * suptitle_size / 72 + 0.2
    fig = new_figure(panel * max(counts) + 0.3, height, dpi)  # + the y label
    return fig, panel_grid(fig, counts)


def save(fig, path: str) -> None:
    """Write ``fig`` as a PNG at its own size and resolution."""
    fig.savefig(path, format="png")


def wrap(text: str, width: float, fontsize: float) -> str:
    """``text`` with its lines broken to fit ``width`` inches at ``fontsize`` points.

    Existing line breaks are kept; a word longer than a line (a long shape name) is broken too.
    """
    chars = max(8, int(width * 72 / (CHAR_WIDTH * fontsize)))
    return "\n".join(
        textwrap.fill(line, chars, break_on_hyphens=False) or line for line in text.split("\n")
    )


def nice_length(span: float) -> float:
    """The largest length of the form 1, 2 or 5 times a power of ten that is at most ``span``."""
    if not span > 0 or not math.isfinite(span):
        return 1.0
    power = 10.0 ** math.floor(math.log10(span))
    for step in (5.0, 2.0, 1.0):
        if step * power <= span * (1 + 1e-9):
            return float(f"{step * power:.6g}")
    return float(f"{power:.6g}")


def panel_grid(fig, counts: list[int]) -> list:
    """Rows of equal panels, ``counts[r]`` in row r; a shorter row is centred under the longest.

    The grid has two columns per panel of the longest row, so a row with one panel fewer is
    offset by half a panel: no grid cell is left empty.

    Returns
    -------
    list of list of matplotlib.axes.Axes
        The panels of each row, left to right.
    """
    width = max(counts)
    grid = fig.add_gridspec(len(counts), 2 * width)
    rows = []
    for r, m in enumerate(counts):
        start = width - m
        rows.append([fig.add_subplot(grid[r, start + 2 * c : start + 2 * c + 2]) for c in range(m)])
    return rows


def plan_view(
    ax,
    lim: float,
    units: str,
    *,
    plate: bool = False,
    ylabel: bool = True,
    fontsize: float = 7.0,
) -> None:
    """Make ``ax`` a 2D view of the square [-lim, lim]² with axes and a scale bar in ``units``.

    The view keeps equal scales on x and y; ticks and labels name scene units. Below the square a
    strip (:data:`SCALE_STRIP` of the view's width) holds the scale bar — a 1-2-5 length about a
    quarter of the view — and its label, so that neither lies on a shape drawn in the square.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    lim : float
        Half the view's width, scene units; everything drawn lies in [-lim, lim]².
    units : str
        Scene units, e.g. ``"mm"``.
    plate : bool
        Fill the square with the plate's colour (the palette's ``material``), under the shapes.
    ylabel : bool
        Label the y axis too (the leftmost panel of a row).
    fontsize : float
        Of the tick labels and the scale bar's label, points.
    """
    from matplotlib.patches import Rectangle
    from matplotlib.ticker import FixedLocator, MaxNLocator

    span = 2 * lim
    strip = SCALE_STRIP * span
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim - strip, lim)
    ax.set_aspect("equal")
    ticks = [
        t for t in MaxNLocator(5, steps=[1, 2, 5, 10]).tick_values(-lim, lim) if -lim <= t <= lim
    ]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.yaxis.set_major_locator(FixedLocator(ticks))
    ax.tick_params(labelsize=fontsize)
    if plate:
        ax.add_patch(Rectangle((-lim, -lim), span, span, facecolor=hex_colour("material"),
                               linewidth=0, zorder=0.5))  # fmt: skip
    ax.set_xlabel(f"x ({units})", fontsize=fontsize + 1)
    if ylabel:
        ax.set_ylabel(f"y ({units})", fontsize=fontsize + 1)
    length = nice_length(0.3 * span)
    x0, y = -lim + 0.06 * span, -lim - 0.5 * strip
    ax.plot([x0, x0 + length], [y, y], color="#202020", linewidth=2.5, solid_capstyle="butt",
            gid=SCALE_BAR_GID)  # fmt: skip
    ax.text(x0 + length + 0.03 * span, y, f"{length:g} {units}", ha="left", va="center",
            fontsize=fontsize, gid=SCALE_BAR_GID)  # fmt: skip


# ------------------------------------------------------------------------------------------------
# A solve's pictures: convergence.png and overlay.png
# ------------------------------------------------------------------------------------------------


#: overlay.png: the width of a panel (inches) and the most panels in a row.
OVERLAY_PANEL = 3.6
OVERLAY_COLUMNS = 4


#: convergence.png's y label: the game value (one A, or separate holes) ...
GAME_VALUE = "best game value (min beta)"
#: ... or, for several A merged into one hole, each A's search, then the placement's energy.
MERGED_VALUE = "best min beta, then eq. 14 energy"


#: convergence.png of a search with one value (no swarm iterations): the annotation that says why.
SINGLE_VALUE = "one candidate, no search iterations:\nnothing to converge"
#: The ``gid`` of that annotation (tests find it by it).
SINGLE_VALUE_GID = "single-value"


def convergence_figure(history: list[float], final: float | None = None, ylabel: str = GAME_VALUE):
    """convergence.png's figure: player A's best game value per search iteration.

    ``ylabel`` names the value: :data:`GAME_VALUE`, or :data:`MERGED_VALUE` for a merged hole of
    several A (its curve runs through each A's search, min beta, then the placement swarm,
    whose value is eq. 14's energy, not a beta).

    ``final`` (report.json's ``search_value``: the game value of the search's last stage, polish
    or placement) is drawn as a dashed line; what the dashed line is, and a note when the curve
    is flat, go into a caption under the plot, never onto the curve. A history of one value (the
    swarm ran no iterations) gets an annotation above its dot, :data:`SINGLE_VALUE`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(5.0, 3.4, 120)
    ax = fig.subplots()
    notes = []
    if len(history) == 1:  # a lone dot would say nothing: say why there is one value
        dashed = final is not None and np.isfinite(final) and final != history[0]
        ax.text(0.5, 0.5 if dashed else 0.8, SINGLE_VALUE, ha="center", va="center",
                transform=ax.transAxes, fontsize=9, gid=SINGLE_VALUE_GID)  # fmt: skip
        ax.set_xticks([0])
        notes.append(f"the one value: {history[0]:.5g} (the best of A's first candidates)")
    if history:
        ax.plot(range(len(history)), history, marker="o", color=hex_colour("curve"))
        if final is not None and np.isfinite(final) and final != history[-1]:
            ax.axhline(final, linestyle="--", color=hex_colour("curve"), alpha=0.6)
            notes.append(f"dashed: the value after the last stage (search_value), {final:.5g}")
        if len(history) > 1 and max(history) - min(history) <= 1e-12 * max(1.0, abs(history[0])):
            notes.append("flat: the canonical views already held the best rotation")
    else:
        ax.text(0.5, 0.5, "A's rotation was fixed: no search", ha="center", va="center",
                transform=ax.transAxes)  # fmt: skip
    ax.set_xlabel("search iteration")
    ax.set_ylabel(ylabel)
    ax.set_title("Convergence of player A's search")
    ax.grid(alpha=0.3)
    if notes:
        fig.supxlabel(wrap("\n".join(notes), 4.8, 8), fontsize=8)
    return fig


def _draw_section(ax, section, **style) -> None:
    """Draw a manifold3d CrossSection (all its contours as one compound path) on an axis."""
    draw_contours(ax, section.to_polygons(), **style)


def overlay_figure(result: Result):
    """overlay.png's figure: the exact hole H, A's projection (dashed) and B's best attempts
    (outlined and hatched over the visible hole, :func:`_draw_block`).

    One panel per B (at most :data:`OVERLAY_COLUMNS` in a row, a shorter last row centred), all
    to one scale, each with axes and a scale bar in scene units (:func:`plan_view`); each panel's
    title (the B, blocked or not, β and protrusion) is wrapped to the panel's width.

    Returns
    -------
    matplotlib.figure.Figure
    """
    hole, a_sections, b_sections = result.overlay_sections()
    lim = 1.04 * max(
        [result.hole.frame.half_extent]
        + [
            float(np.abs(s.bounds()).max())
            for s in [hole, *a_sections, *b_sections]
            if not s.is_empty()
        ]
    )
    titles = [_overlay_title(result, j) for j in range(len(b_sections))] or [""]
    titles = [wrap(t, OVERLAY_PANEL, 9) for t in titles]
    counts = _rows(len(titles), OVERLAY_COLUMNS)
    title = f"{result.scene.name}: winner {result.winner} (exact hole white, A dashed, B hatched)"
    title = wrap(title, OVERLAY_PANEL * max(counts) + 0.3, 10)  # the figure's width
    starts = np.cumsum([0, *counts])
    lines = [max(t.count("\n") + 1 for t in titles[a:b]) for a, b in zip(starts, starts[1:])]
    fig, rows = grid_figure(
        counts, OVERLAY_PANEL, 120, title_lines=lines, suptitle_lines=title.count("\n") + 1
    )
    panels = [(c, ax) for row in rows for c, ax in enumerate(row)]
    for j, (c, ax) in enumerate(panels):
        plan_view(ax, lim, result.scene.units, plate=True, ylabel=c == 0)
        _draw_section(
            ax, hole, facecolor=hex_colour("hole"), edgecolor=hex_colour("edge"), linewidth=0.6
        )
        for sec in a_sections:
            _draw_section(
                ax, sec, fill=False, edgecolor=hex_colour("pass"), linewidth=1.0, linestyle="--"
            )
        if j < len(b_sections):
            _draw_block(ax, b_sections[j], hole, bool(result.blocks[j].blocked))
        ax.set_title(titles[j], fontsize=9)
    fig.suptitle(title, fontsize=10)
    return fig


#: overlay.png: a B's hatching (matplotlib's pattern; lines at 45°) and the opacity of the light
#: fill of its part outside H (where it overhangs the plate).
B_HATCH = "///"
OVERHANG_ALPHA = 0.3


def _draw_block(ax, section, hole, blocked: bool) -> None:
    """One B's attempt over the hole: its outline and hatching in its colour (red blocked, orange
    gets through), never a fill over H, so the hole stays visible under it; its part outside H
    (what overhangs the plate) gets a light fill of the same colour."""
    colour = hex_colour(block_colour(blocked))
    outside = section - hole
    if not outside.is_empty():
        _draw_section(ax, outside, facecolor=colour, alpha=OVERHANG_ALPHA, linewidth=0)
    _draw_section(ax, section, fill=False, hatch=B_HATCH, edgecolor=colour, linewidth=1.4)


def _rows(n: int, columns: int) -> list[int]:
    """Panels per row for ``n`` panels, at most ``columns`` in a row, rows as even as can be."""
    rows = -(-n // columns)
    base, extra = divmod(n, rows)
    return [base + 1] * extra + [base] * (rows - extra)


def _overlay_title(result: Result, j: int) -> str:
    """A B's panel title: its name, blocked or not (and how a blocked-straight B passes), β and
    protrusion."""
    record = result.blocks[j]  # a thin-plate or certified passage passes
    status = "blocked" if record.blocked else "PASSES"
    if result.attack.blocked()[0][j] and not record.blocked:
        status += _motion_note(result, record)
    return (
        f"{result.block_shapes[j].name}: {status}\nbeta={result.attack.beta[0, j]:.4f}, "
        f"protrusion={result.attack.protrusion[0, j]:.3g} {result.scene.units}"
    )


def _motion_note(result: Result, record) -> str:
    """Why a B blocked straight down passes after all: a thin plate's motion or certify's pose."""
    thin = record.thin_plate
    if thin is not None and thin.status == "passage":
        return f" by tilting through the {thin.thickness:g} {result.scene.units} plate"
    return " (a pose certify found)"


def write_plots(result: Result, folder: str) -> None:
    """A solve's ``convergence.png`` and ``overlay.png`` into ``folder``."""
    history, final = result.history.best, result.search_value
    merged = len(result.pass_shapes) > 1 and result.scene.layout.mode == "merged"
    label = MERGED_VALUE if merged else GAME_VALUE
    save(convergence_figure(history, final, label), os.path.join(folder, "convergence.png"))
    save(overlay_figure(result), os.path.join(folder, "overlay.png"))
