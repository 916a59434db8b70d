"""Rigid motions as pose sequences, and their conservative continuous re-check.

Between two consecutive poses the motion moves the centre along the straight segment and turns
along the shortest arc (slerp), both at constant speed. No point of the shape then moves farther
than ``L = |Δt| + r θ`` over the segment (r: the shape's radius about its centre, θ: the turn's
angle), and at fraction s it is within ``s L`` of its start and ``(1 - s) L`` of its end. So if the
shape is at distance ``d0`` from the plate at one end and ``d1`` at the other with
``d0 + d1 > L``, no intermediate pose meets the plate. :func:`verify` subdivides a path until every
segment passes this test (a passage, proved up to coal's distance tolerance) or a pose meets the
plate (no passage along this path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sieve_mi.geometry.rotations import angle_between, normalize

__all__ = ["Verified", "interpolate", "segment_reach", "slerp", "verify"]

#: Slack on every distance test, scene units (coal's GJK distances are accurate to ~1e-6).
DISTANCE_SLACK = 1e-5


def slerp(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    """The rotation a fraction ``s`` of the way along the shortest arc from ``q0`` to ``q1``."""
    q0, q1 = normalize(np.asarray(q0, float)), normalize(np.asarray(q1, float))
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 1 - 1e-12:
        return normalize(q0 + s * (q1 - q0))
    w = np.arccos(min(1.0, dot))
    return normalize((np.sin((1 - s) * w) * q0 + np.sin(s * w) * q1) / np.sin(w))


def interpolate(pose0, pose1, s: float):
    """The pose a fraction ``s`` of the way from ``pose0`` to ``pose1`` (each ``(quat, trans)``)."""
    (q0, t0), (q1, t1) = pose0, pose1
    return slerp(q0, q1, s), (1 - s) * np.asarray(t0, float) + s * np.asarray(t1, float)


def segment_reach(pose0, pose1, radius: float) -> float:
    """The farthest any point of the shape moves between two poses, bounded: ``|Δt| + r θ``."""
    (q0, t0), (q1, t1) = pose0, pose1
    step = float(np.linalg.norm(np.asarray(t1, float) - np.asarray(t0, float)))
    return step + radius * angle_between(q0, q1)


@dataclass
class Verified:
    """The outcome of :func:`verify`.

    Attributes
    ----------
    ok : bool
        True when every segment passed the distance test: the motion never meets the plate.
    poses : list of (quat, trans)
        The path after subdivision (where ``ok``), else up to the first pose that meets the plate.
    min_clearance : float
        Smallest distance from the shape to the plate over ``poses``, scene units.
    checked : int
        Distance queries made.
    """

    ok: bool
    poses: list
    min_clearance: float
    checked: int


def verify(world, poses: list, *, most: int = 200_000) -> Verified:
    """Re-check a path continuously with the distance test (module docstring).

    Parameters
    ----------
    world : sieve_mi.motion.collide.PlateWorld
    poses : list of (quat, trans)
        At least two poses.
    most : int
        Largest number of poses after subdivision before giving up (then ``ok`` is False).

    Returns
    -------
    Verified
    """
    radius = world.radius
    out, dists = [poses[0]], [world.distance(*poses[0])]
    checked = 1
    if dists[0] <= DISTANCE_SLACK:
        return Verified(False, out, dists[0], checked)
    todo = [(p, None) for p in reversed(poses[1:])]
    while todo:
        nxt, d = todo.pop()
        if d is None:
            d = world.distance(*nxt)
            checked += 1
        if d <= DISTANCE_SLACK:
            return Verified(False, out + [nxt], min(min(dists), d), checked)
        if dists[-1] + d > segment_reach(out[-1], nxt, radius) + 2 * DISTANCE_SLACK:
            out.append(nxt)
            dists.append(d)
        elif len(out) + len(todo) > most:
            return Verified(False, out, min(dists), checked)
        else:
            todo += [(nxt, d), (interpolate(out[-1], nxt, 0.5), None)]
    return Verified(True, out, float(min(dists)), checked)
