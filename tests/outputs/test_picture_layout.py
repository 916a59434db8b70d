"""The pictures' layout: no text on a shape, no two texts overlapping, axes and a scale bar.

overlay.png and convergence.png are built by the functions the writer saves
(:func:`~sieve_mi.outputs.plots.overlay_figure`, :func:`~sieve_mi.outputs.plots.convergence_figure`)
and checked with :func:`sieve_mi.testing.pictures.layout_problems` (text boxes against the shapes'
drawn paths, in display pixels). figure.png's title is checked in test_figure.py, cascade.png in
tests/cascade/test_cascade_figure.py.
"""

from __future__ import annotations

import os
from types import SimpleNamespace

import manifold3d
import numpy as np
import pytest
from helpers import REPO

from sieve_mi.outputs.plots import (
    MERGED_VALUE,
    convergence_figure,
    draw_contours,
    new_figure,
    nice_length,
    overlay_figure,
    panel_grid,
    plan_view,
    save,
    wrap,
)
from sieve_mi.testing.pictures import layout_problems, plan_view_problems
from sieve_mi.testing.settings import TINY_LAYOUT, TINY_SOLVER, TINY_VERDICT, settings_toml
from sieve_mi.testing.shapes import cross_section, glyph_contours

LONG = "a_shape_with_a_very_long_name_that_has_no_spaces_in_it"


def _glyph(char: str, height: float = 30.0, angle: float = 0.0) -> manifold3d.CrossSection:
    """A bold glyph's outline, ``height`` tall, centred, turned by ``angle`` degrees."""
    contours = glyph_contours(char)
    pts = np.concatenate(contours)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = height / (hi[1] - lo[1])
    return cross_section([(c - 0.5 * (lo + hi)) * scale for c in contours]).rotate(angle)


def _fake_result(passes: str, blocks: list[tuple[str, str, bool]], name: str):
    """What overlay_figure reads of a Result: A's glyphs (one merged hole grown by 1 mm) and
    B's glyphs (name, character, blocked); the third B on is blocked straight down but passes."""
    a = [_glyph(c, angle=15.0 * i) for i, c in enumerate(passes)]
    hole = manifold3d.CrossSection.batch_boolean(a, manifold3d.OpType.Add).offset(
        1.0, manifold3d.JoinType.Round
    )
    b = [_glyph(c, 32.0, 30.0 + 20 * j) for j, (_, c, _) in enumerate(blocks)]
    n = len(blocks)
    blocked = np.array([[bl or j >= 2 for j, (_, _, bl) in enumerate(blocks)]])
    return SimpleNamespace(
        overlay_sections=lambda: (hole, a, b),
        hole=SimpleNamespace(frame=SimpleNamespace(half_extent=18.0)),
        block_shapes=[SimpleNamespace(name=nm) for nm, _, _ in blocks],
        blocks=[SimpleNamespace(blocked=bl, thin_plate=None) for _, _, bl in blocks],
        attack=SimpleNamespace(
            beta=np.linspace(0.0, 0.2, n)[None],
            protrusion=np.linspace(0.0, 4.0, n)[None],
            blocked=lambda: blocked,
        ),
        scene=SimpleNamespace(name=name, units="mm"),
        winner="B",
        sheet=None,
    )


def _panels(fig) -> list:
    return [ax for ax in fig.axes if ax.get_visible()]


def test_the_checker_finds_text_on_shapes_overlapping_and_cut_off():
    """layout_problems reports each kind of fault once, and leaves a clean figure alone."""
    fig = new_figure(4.0, 3.0, 100)
    ax = fig.subplots()
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    ax.fill([2, 6, 6, 2], [2, 2, 6, 6], color="grey")
    ax.plot([0, 10], [9, 9], linestyle="--")
    ax.set_title("a clean title")
    assert layout_problems(fig) == []
    ax.text(4, 4, "on the square", ha="center")
    ax.text(5, 9, "on the dashed line", ha="center", va="center")
    ax.text(6.5, 4, "one text", fontsize=7)
    ax.text(7.5, 4, "another text", fontsize=7)
    fig.text(0.98, 0.5, "beyond the right edge")
    problems = layout_problems(fig)
    assert sum("'on the square' lies on" in p for p in problems) == 1
    assert sum("'on the dashed line' lies on Line2D" in p for p in problems) == 1
    assert sum("'one text' and 'another text' overlap" in p for p in problems) == 1
    assert sum("cut off" in p for p in problems) == 1
    assert len(problems) == 4, problems
    missing = plan_view_problems(fig, "mm")
    assert any("not labelled in mm" in p for p in missing)
    assert any("no scale bar" in p for p in missing)


def test_a_text_inside_a_hole_of_a_shape_is_clear():
    """A shape's path is the drawn outline and area: a text in a ring's opening touches nothing,
    a text on the ring itself does."""
    fig = new_figure(4.0, 4.0, 100)
    ax = fig.subplots()
    plan_view(ax, 10.0, "mm")
    ring = manifold3d.CrossSection.circle(9.0, 64) - manifold3d.CrossSection.circle(6.0, 64)
    draw_contours(ax, ring.to_polygons(), facecolor="grey")
    ax.text(0, 0, "in", ha="center", va="center", fontsize=7)
    assert layout_problems(fig) == []
    ax.text(0, 7.5, "on the ring", ha="center", va="center", fontsize=7)
    assert len(layout_problems(fig)) == 1


def test_plot_helpers():
    assert [nice_length(s) for s in (0.7, 1.0, 3.1, 19.9, 20.0, 480.0)] == [
        0.5, 1.0, 2.0, 10.0, 20.0, 200.0,
    ]  # fmt: skip
    text = wrap(f"{LONG}: PASSES\nbeta=0.1", 2.0, 9)
    assert all(len(line) <= int(2.0 * 72 / (0.62 * 9)) for line in text.splitlines())
    assert "".join(text.split()) == "".join(f"{LONG}: PASSES\nbeta=0.1".split())
    fig = new_figure(6.0, 4.0, 80)
    rows = panel_grid(fig, [2, 3])
    fig.canvas.draw()
    top = [ax.get_position().x0 + ax.get_position().width / 2 for ax in rows[0]]
    bottom = [ax.get_position().x0 + ax.get_position().width / 2 for ax in rows[1]]
    # The shorter row is centred, half a panel in: each of its panels between two of the other's.
    assert bottom[0] < top[0] < bottom[1] < top[1] < bottom[2]


@pytest.mark.parametrize(
    "passes, blocks",
    [
        ("SIG", [("R", "R", True), ("A", "A", True), ("P", "P", False), ("H", "H", True)]),
        (
            "SI",
            [
                (LONG, "R", False),
                ("A", "A", True),
                ("letter P", "P", True),
                ("H", "H", False),
                ("B", "B", False),
            ],
        ),  # fmt: skip
        ("O", [(LONG + "_and_more_of_it", "A", True)]),
    ],
)
def test_overlay_layout(passes, blocks, tmp_path):
    """Several A, several B, long names, a short last row: nothing on a shape, nothing overlaps."""
    result = _fake_result(passes, blocks, name=f"letters, {LONG}")
    fig = overlay_figure(result)
    assert layout_problems(fig) == []
    panels = _panels(fig)
    assert len(panels) == len(blocks)  # one per B, no empty panel
    for ax, (name, _, _) in zip(panels, blocks):
        assert "".join(name.split()) in "".join(ax.get_title().split())  # wrapped, never cut
    assert plan_view_problems(fig, "mm") == []
    save(fig, str(tmp_path / "overlay.png"))
    assert (tmp_path / "overlay.png").stat().st_size > 0


@pytest.mark.parametrize(
    "history, final",
    [
        ([0.01, 0.02, 0.05, 0.05, 0.07], 0.072),
        ([0.30, 0.05, 0.06, 0.06], 0.30),  # the dashed line crosses the curve's start
        ([0.04] * 6, 0.04),  # flat
        ([0.04] * 6, 0.2),  # flat, and a last stage above it
        ([], None),  # a fixed rotation: no search
    ],
)
def test_convergence_layout(history, final):
    fig = convergence_figure(history, final)
    assert layout_problems(fig) == []
    caption = fig.get_supxlabel()
    if history and final != history[-1]:
        assert "search_value" in caption
    assert ("flat" in caption) == (len(set(history)) == 1)


MESHES = os.path.join(REPO, "scenes", "meshes")


@pytest.fixture(scope="module")
def letters(tmp_path_factory):
    """A tiny solve of two letters that pass (one hole) and three that must not, one long name;
    no proofs (``certify = false``: the pictures do not show them; 4 CPU s of a 13 s solve)."""
    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene

    text = f'name = "letters, {LONG}"\n'
    for key, letter in (("pass", "S"), ("pass", "I"), ("block", "R"), ("block", "A")):
        text += f'[[{key}]]\nmesh = "{MESHES}/letter_{letter}.stl"\n'
    text += f'[[block]]\nmesh = "{MESHES}/letter_H.stl"\nname = "{LONG}"\n'
    text += settings_toml(
        fabrication={"tolerance": 0.5}, layout={"mode": "merged", **TINY_LAYOUT},
        solver=TINY_SOLVER, verdict={**TINY_VERDICT, "certify": False},
    )  # fmt: skip
    path = tmp_path_factory.mktemp("letters") / "letters.toml"
    path.write_text(text)
    return solve(load_scene(str(path)), progress=False)


@pytest.mark.slow
def test_solved_letters_overlay_and_convergence(letters):
    """The pictures of a real solve (several A, several B, a long name), as the writer saves them."""
    fig = overlay_figure(letters)
    assert layout_problems(fig) == []
    assert len(_panels(fig)) == 3
    assert plan_view_problems(fig, "mm") == []
    # merged letters: the curve runs through each A's search, then the placement's eq. 14 energy
    fig = convergence_figure(letters.history.best, letters.search_value, MERGED_VALUE)
    assert layout_problems(fig) == []


@pytest.mark.parametrize("final", [0.04, 0.2, 0.01, None])
def test_a_single_value_says_why_it_is_alone(final, tmp_path):
    # a swarm without iterations gives one value: the plot says why, on no drawn shape
    from PIL import Image

    from sieve_mi.outputs.plots import SINGLE_VALUE, SINGLE_VALUE_GID

    fig = convergence_figure([0.04], final)
    assert layout_problems(fig) == []
    notes = [t for t in fig.axes[0].texts if t.get_gid() == SINGLE_VALUE_GID]
    assert [t.get_text() for t in notes] == [SINGLE_VALUE]
    assert "one candidate, no search iterations" in SINGLE_VALUE
    assert "0.04" in fig.get_supxlabel() and "flat" not in fig.get_supxlabel()
    save(fig, str(tmp_path / "c.png"))  # the text is in the pixels: dark ink above the dot
    img = np.asarray(Image.open(tmp_path / "c.png").convert("L"))
    assert (img < 100).sum() > (_ink_without_note([0.04], final) + 300)


def _ink_without_note(history, final) -> int:
    """Dark pixels of the same plot with the annotation removed."""
    import io

    from PIL import Image

    fig = convergence_figure(history, final)
    for t in [t for t in fig.axes[0].texts if t.get_gid()]:
        t.remove()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return int((np.asarray(Image.open(buf).convert("L")) < 100).sum())


def test_the_page_hatches_b_and_says_why_one_value_is_alone():
    import re

    from sieve_mi.outputs.svg import convergence_svg, outline_svg

    hole = cross_section([np.array([[-5.0, -5], [5, -5], [5, 5], [-5, 5]])])
    disk = manifold3d.CrossSection.circle(6.0, 64)
    svg = outline_svg([hole], [], [disk, disk.translate([1.0, 0.0])], [True, False], 8.0)
    b = re.findall(r'<path data-id="b\d"[^>]*>', svg)
    assert len(b) == 2 and not any("fill-opacity" in p for p in b)
    assert 'fill="url(#hatch-blocked)"' in b[0] and 'fill="url(#hatch-escaped)"' in b[1]
    assert '<pattern id="hatch-blocked"' in svg and '<pattern id="hatch-escaped"' in svg
    assert "no search iterations" in convergence_svg([0.25]) and "0.25" in convergence_svg([0.25])
    assert "<svg" in convergence_svg([0.3, 0.25])
