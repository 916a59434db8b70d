"""shake.gif shows what was simulated: the plate moves with the engine's shaker motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image
from shake_helpers import ball, plate_mesh, quick, round_hole

from sieve_mi.shake.clip import FRAMES_PER_SHAPE, frame_steps, trajectory, write_clip
from sieve_mi.shake.geometry import plate_from_mesh


def test_frames_catch_successive_quarters_of_the_stroke():
    """At 50 Hz and 0.25 ms steps a period is 80 steps. Frames a whole number of periods apart
    would all catch the plate at one point of its stroke; frame k is moved (by at most half a
    period) to k quarter periods into the cycle, so the plate is seen at 0, 90, 180 and 270
    degrees in turn; the last frame is the stretch's last step."""
    steps = frame_steps(12_000, 0.25e-3, 50.0)  # a 3 s stretch
    even = np.linspace(0, 12_000, FRAMES_PER_SHAPE)
    assert len(steps) == FRAMES_PER_SHAPE and steps[0] == 0 and steps[-1] == 12_000
    assert np.all(np.diff(steps) > 0) and np.abs(steps - even).max() <= 40
    assert list(steps[:-1] % 80) == [0, 20, 40, 60] * 3 + [0, 20, 40]
    # A stretch shorter than 15 periods (the part fell through at once): evenly spaced.
    assert list(frame_steps(1000, 0.25e-3, 50.0)) == list(np.round(np.linspace(0, 1000, 16)))
    # A still plate: evenly spaced.
    assert list(frame_steps(3000, 0.25e-3, 0.0)) == list(np.round(np.linspace(0, 3000, 16)))


@pytest.fixture(scope="module")
def ball_trial():
    """Trial 0 of a 20 mm ball over a 22 mm hole in a 2 mm plate (it falls through, as 200 of
    200 did), at the default 1 mm, 50 Hz."""
    mesh = plate_mesh(round_hole(22.0), 14.0, 2.0)
    plate = plate_from_mesh(mesh)
    from sieve_mi.shake.geometry import part_from_mesh

    part = part_from_mesh(ball(20.0), "ball20", "A", 0.05)
    settings = quick()
    return mesh, plate, part, settings, trajectory(plate, part, settings, 1e-3, 0, passed=True)


def test_frames_carry_the_simulated_plate_pose(ball_trial):
    """Each frame's plate pose is the engine's (its lift joint, which follows z = A sin(2 pi f t)
    because the plate is 10^6 times heavier than the part: one Euler step moves it by A w dt,
    so it is within (w dt)^2 A / 2 = 0.003 mm of the formula at the frame's time); the frames
    show the whole 2 mm stroke; there is no twist by default; the part is drawn in the same
    world frame, and the clip ends once it is wholly below the plate's lowest position."""
    _, plate, part, settings, traj = ball_trial
    w = 2 * math.pi * settings.frequency
    expected = settings.amplitude * np.sin(w * traj.times)
    assert np.allclose(traj.plate[:, 0], expected, atol=0.005)
    assert traj.plate[:, 0].max() - traj.plate[:, 0].min() > 1.99 * settings.amplitude
    assert np.abs(traj.plate[:, 1]).max() < 1e-6  # only the contacts' reaction on the heavy plate
    bottom = -plate.thickness - settings.amplitude - part.radius
    assert traj.keys[0, 7] > 0 and traj.keys[-1, 7] < bottom  # released above, ends below
    assert np.all(traj.keys[:-1, 7] >= bottom)


def test_a_passing_trial_is_shown_up_to_its_pass(ball_trial, monkeypatch):
    """A trial that passed is shown over its last CLIP_S seconds, ending with the part wholly
    below the plate, however late it passed; one that did not, over its first CLIP_S seconds
    from the release. With CLIP_S cut to 0.2 s the ball (through at about 0.5 s) shows both."""
    import sieve_mi.shake.clip as clip

    _, plate, part, settings, whole = ball_trial
    monkeypatch.setattr(clip, "CLIP_S", 0.2)
    end = trajectory(plate, part, settings, 1e-3, 0, passed=True)
    start = trajectory(plate, part, settings, 1e-3, 0, passed=False)
    assert end.times[-1] == pytest.approx(whole.times[-1]) and end.times[0] > 0.2
    assert end.times[-1] - end.times[0] == pytest.approx(0.2, abs=1e-3)
    assert np.array_equal(end.keys[-1], whole.keys[-1])  # the same simulation, the same end
    assert start.times[0] == pytest.approx(2.5e-4) and start.times[-1] == pytest.approx(0.2)
    assert np.all(start.keys[:, 7] > 0)  # still above the plate's top face


def _bottom_edge_rows(gif: str, frames: list[int]) -> list[float]:
    """Median over the plate's columns of the lowest non-background row, per frame."""
    im, out = Image.open(gif), []
    for k in frames:
        im.seek(k)
        a = np.asarray(im.convert("RGB")).astype(int)
        fg = np.abs(a - a[0, 0]).sum(axis=2) > 30
        cols = [c for c in range(a.shape[1] // 5, 4 * a.shape[1] // 5) if fg[:, c].any()]
        out.append(float(np.median([np.nonzero(fg[:, c])[0].max() for c in cols])))
    return out


def _row(point: np.ndarray, box: np.ndarray, width: int, height: int) -> float:
    """The image row of a point (scene units) seen by the clip's camera (a pinhole camera with
    a horizontal field of view FOV, as outputs.animation builds it)."""
    from sieve_mi.outputs.animation import FOV, camera

    origin, target = camera(box, width / height)
    fwd = (target - origin) / np.linalg.norm(target - origin)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    f = (width / 2) / math.tan(math.radians(FOV) / 2)
    d = point - origin
    return height / 2 - f * (d @ up) / (d @ fwd)


@pytest.mark.slow  # 16 rendered frames: 8-16 s on 2 cores
def test_rendered_plate_moves_by_its_stroke(ball_trial, tmp_path):
    """In the GIF the plate's bottom edge is higher when the engine had the plate at the top of
    its stroke (+1 mm) than at the bottom (-1 mm), by the 2 mm stroke projected through the
    clip's camera: between the shift of the nearest and of the farthest bottom corner of the
    plate, give or take a pixel. (Drawn still, as before, it would not move at all.)"""
    mesh, plate, part, settings, traj = ball_trial
    gif = str(tmp_path / "shake.gif")
    info = write_clip(gif, mesh, plate, [(ball(20.0), part.com, "A", True, traj)])
    lift = np.array(info["plate_lift"])
    up, down = int(np.argmax(lift[:8])), int(np.argmin(lift[:8]))  # the ball still on top
    rows = _bottom_edge_rows(gif, [up, down])
    box = np.array(info["box"])
    width, height = Image.open(gif).size
    hx, hy = plate.half_size
    shifts = []
    for x, y in ((-hx, -hy), (hx, -hy), (-hx, hy), (hx, hy)):
        base = np.array([x, y, -plate.thickness])
        shifts.append(
            _row(base + [0, 0, lift[down]], box, width, height)
            - _row(base + [0, 0, lift[up]], box, width, height)
        )
    measured = rows[1] - rows[0]
    assert min(shifts) - 1.0 <= measured <= max(shifts) + 1.0, (measured, shifts)
    assert measured > 3.0  # several pixels: the motion shows
