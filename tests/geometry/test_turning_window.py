"""The turning window's hole (:mod:`sieve_mi.geometry.window`), against answers argued on paper.

A 20 mm cube seen face-on, grown by 1 mm, turned within ±δ about its centre: along a face normal
turned by φ the hole reaches 11 / cos φ (the flat side of the face turned furthest), so the disk
it holds about the centre has radius 11 / cos δ (while δ < atan(10 / 11) = 42.3°).
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from sieve_mi.geometry.meshes import shape_from_trimesh
from sieve_mi.geometry.outline import Boundary, hole_outline
from sieve_mi.geometry.rotations import from_axis_angle, quat_multiply
from sieve_mi.geometry.window import GROWTH, turn_samples, windowed_hole

CUBE = shape_from_trimesh(trimesh.creation.box([20.0, 20.0, 20.0]), name="cube")
FACE_ON = np.array([[1.0, 0.0, 0.0, 0.0]])


@pytest.mark.parametrize("degrees", [5.0, 15.0, 30.0])
def test_the_window_holds_the_disk_of_radius_11_over_cos_delta(degrees):
    hole, w = windowed_hole([CUBE], FACE_ON, np.zeros((1, 2)), 1.0, math.radians(degrees))
    inscribed = float(Boundary(hole).distance(np.zeros((1, 2)))[0])
    cos = math.cos(math.radians(degrees))
    # the hole is the exact window's grown by at most the chord bound g (and the round joins'
    # 0.3 % of the offset): its faces lie at most 11 + g + 0.003 (1 + g) out, turned by δ
    assert 11.0 / cos - 1e-6 <= inscribed <= (11.0 + w.grow + 0.003 * (1 + w.grow)) / cos
    assert w.degrees == pytest.approx(degrees) and 0 < w.grow <= GROWTH * 1.0 + 1e-12


def test_no_window_is_the_hole_itself():
    hole, w = windowed_hole([CUBE], FACE_ON, np.array([[3.0, -2.0]]), 1.0, 0.0)
    plain = hole_outline([CUBE], FACE_ON, np.array([[3.0, -2.0]]), 1.0)
    assert w.samples == 1 and w.grow == 0.0
    assert (hole - plain).area() == 0.0 and (plain - hole).area() == 0.0


def test_every_turn_in_the_window_fits_between_the_samples():
    """A turned by any ψ in [-δ, δ] (not a sample) and grown by the tolerance lies in the hole."""
    delta, place = math.radians(20.0), np.array([[4.0, 1.0]])
    tilted = quat_multiply(from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.3), FACE_ON[0])[None]
    hole, _ = windowed_hole([CUBE], tilted, place, 1.0, delta)
    for psi in np.linspace(-delta, delta, 17) + 0.37 * (2 * delta / 16):
        if abs(psi) > delta:
            continue
        turned = quat_multiply(from_axis_angle(np.array([0.0, 0.0, 1.0]), psi), tilted[0])[None]
        part = hole_outline([CUBE], turned, place, 1.0)
        outside = (part - hole).area()
        assert outside <= 1e-9 * part.area(), psi


def test_samples_keep_the_chord_bound():
    turns, grow = turn_samples(17.32, math.radians(30.0), 1.0)
    step = turns[1] - turns[0]
    assert turns[0] == pytest.approx(-math.radians(30)) and turns[-1] == pytest.approx(
        math.radians(30)
    )
    assert grow == pytest.approx(2 * math.sin(step / 4) * 17.32) and grow <= 0.05 + 1e-12
    assert turn_samples(17.32, 0.0, 1.0) == (pytest.approx(np.zeros(1)), 0.0)


def test_a_window_of_a_slot_is_a_bow_tie_of_slots():
    """A flat 20 × 2 mm plate seen edge-on (an open mesh's edge-on segments) turned ±10°."""
    plate = trimesh.Trimesh(
        vertices=[[-10, 0, -1], [10, 0, -1], [10, 0, 1], [-10, 0, 1]], faces=[[0, 1, 2], [0, 2, 3]]
    )
    shape = shape_from_trimesh(plate, name="card")
    down = from_axis_angle(np.array([1.0, 0.0, 0.0]), math.pi / 2)[None]  # the card edge-on
    hole, _ = windowed_hole([shape], down, np.zeros((1, 2)), 0.5, math.radians(10.0))
    tip = 10.0 * np.array([math.cos(math.radians(10)), math.sin(math.radians(10))])
    inside = Boundary(hole).inside(np.array([tip, -tip, [0.0, 0.0]]))
    assert inside.all()
    assert not Boundary(hole).inside(np.array([[0.0, 3.0]]))[0]  # still a narrow bow tie
    assert isinstance(hole, manifold3d.CrossSection)
