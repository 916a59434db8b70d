"""cascade.png: the sieves over the trays, no text on a shape, no empty cell, axes and scale bars.

The plans are built by hand (no game is played): each sieve's record holds only the hole's
outline that the picture reads, and the icons are the shapes' outlines in mm.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from sieve_mi.cascade.outputs import cascade_figure, write_figure
from sieve_mi.cascade.plan import Plan, Sieve
from sieve_mi.testing.pictures import layout_problems, plan_view_problems

LONG = "a_shape_with_a_rather_long_name_and_no_spaces"


def _circle(r: float, n: int = 48) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[r * np.cos(t), r * np.sin(t)]


def _square(half: float) -> np.ndarray:
    return half * np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]])


def _plan(trays: list[list[str]], holes: list[np.ndarray]) -> Plan:
    """Sieve k holds trays[k] (its hole holes[k]) and passes what the trays below it hold."""
    sieves = [
        Sieve(
            holds=list(held),
            passes=[n for below in trays[k + 1 :] for n in below],
            key=f"hold-{k}",
            record={"summary": {"outline": [hole.tolist()]}},
        )
        for k, (held, hole) in enumerate(zip(trays, holes))
    ]
    return Plan(sieves=sieves, bottom=list(trays[-1]))


ICONS = {
    "cube28": [_square(14.0)],
    LONG: [_circle(10.0)],
    "cube14": [_square(7.0)],
    "ball10": [_circle(5.0)],
    "ring": [_circle(4.0), _circle(2.0)[::-1]],
    "coin": [_circle(3.0)],
}

CASES = {
    "four trays": _plan(
        [["cube28"], [LONG], ["cube14"], ["ball10"]], [_circle(10.5), _square(7.5), _circle(5.5)]
    ),
    "an inseparable pair": _plan([["cube28"], ["cube14", LONG]], [_circle(10.5)]),
    "a shared bottom tray": _plan(
        [["cube28"], [LONG], ["cube14"], ["ball10"], ["ring", "coin"]],
        [_circle(10.5), _square(7.5), _circle(5.5), _circle(4.5)],
    ),
    "no sieve": Plan(sieves=[], bottom=["ring", "coin"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_cascade_layout(case):
    plan = CASES[case]
    fig = cascade_figure(plan, "mm", ICONS)
    assert layout_problems(fig) == []  # no text on a shape or on another text, none cut off
    assert plan_view_problems(fig, "mm") == []  # axes in mm and a scale bar on every panel
    n_sieves, n_trays = len(plan.sieves), len(plan.trays)
    assert len(fig.axes) == n_sieves + n_trays  # a panel each, and nothing else
    sieves, trays = fig.axes[:n_sieves], fig.axes[n_sieves:]
    for ax, sieve in zip(sieves, plan.sieves):
        title = "".join(ax.get_title().split())
        assert all(name in title for name in [*sieve.holds, *sieve.passes])
        assert len(ax.patches) == 2  # the plate and the hole
    for ax, names in zip(trays, plan.trays):
        assert all(name in "".join(ax.get_title().split()) for name in names)
        assert len(ax.patches) == len(names)  # one patch a shape, its holes cut out
    # No empty column: the sieves' row is centred over the trays' row, each sieve between the
    # tray it fills and the next one.
    centre = [ax.get_position().x0 + ax.get_position().width / 2 for ax in fig.axes]
    for k in range(n_sieves):
        assert centre[n_sieves + k] < centre[k] < centre[n_sieves + k + 1]


def test_panels_are_to_one_scale():
    fig = cascade_figure(CASES["four trays"], "mm", ICONS)
    fig.canvas.draw()
    scales = {round(ax.bbox.width / np.ptp(ax.get_xlim()), 6) for ax in fig.axes}
    limits = {ax.get_xlim() for ax in fig.axes}
    assert len(limits) == 1 and len(scales) == 1


def test_write_figure_saves_the_figure(tmp_path):
    path = tmp_path / "cascade.png"
    plan = CASES["an inseparable pair"]
    write_figure(str(path), plan, "mm", ICONS)
    fig = cascade_figure(plan, "mm", ICONS)
    with Image.open(path) as im:
        assert np.allclose(im.size, fig.get_size_inches() * fig.dpi, atol=1)
