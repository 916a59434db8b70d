"""Search for a rigid motion through a thin plate: seeded straight descents, then OMPL's RRT-Connect on SE(3).

The hole is a narrow passage of SE(3), so uniform sampling rarely lands in it. The search
therefore (1) tries straight descents in seed orientations (player B's best attempts, flat views),
(2) plans directly from above to below, and (3) samples *crossing poses* — poses whose centre lies
in the plate's slab inside the hole's prism and that meet no material — and plans from above to
each and from each to below. Every planned path is re-checked continuously
(:func:`sieve_mi.motion.path.verify`) before it counts. OMPL is imported here only, inside the
worker that plans.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.geometry.rotations import random_uniform, to_matrix
from sieve_mi.motion.path import Verified, verify

__all__ = ["PassageSearch", "Window", "search_passage"]


@dataclass
class Window:
    """Where the shape's centre may go: a box around the hole's prism, scene units.

    Attributes
    ----------
    lo, hi : (3,) float
        Corners of the box.
    above, below : float
        The centre's height in the start pose (the whole shape above the plate) and in the goal
        pose (the whole shape below it).
    centre : (2,) float
        The hole's bounding-box centre.
    pieces : (k, 2) float
        The bounding-box centres of the hole's pieces (where crossing poses are centred).
    """

    lo: np.ndarray
    hi: np.ndarray
    above: float
    below: float
    centre: np.ndarray
    pieces: np.ndarray

    @classmethod
    def around(cls, world, outline) -> Window:
        """The box for ``world`` (a PlateWorld) and the hole ``outline`` (a CrossSection)."""
        r, t = world.radius, world.thickness
        gap = max(0.05 * r, 1e-3)
        x0, y0, x1, y1 = outline.bounds()
        lo = np.array([x0 - r, y0 - r, -t - r - 2 * gap])
        hi = np.array([x1 + r, y1 + r, r + 2 * gap])
        pieces = np.array([[(b[0] + b[2]) / 2, (b[1] + b[3]) / 2]
                           for b in (p.bounds() for p in outline.decompose())])  # fmt: skip
        centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
        return cls(lo, hi, r + gap, -t - r - gap, centre, pieces)


@dataclass
class PassageSearch:
    """What :func:`search_passage` did and found.

    Attributes
    ----------
    passage : Verified or None
        The verified motion, if one was found.
    poses : list of (quat, trans)
        The motion as planned (``passage`` subdivides it for the re-check).
    seconds : float
    checks : int
        Collision and distance queries made.
    plans : int
        Planner runs.
    crossings : int
        Valid crossing poses sampled.
    method : str
        What found the passage ("straight descent", "RRTConnect", "RRTConnect via a crossing pose").
    """

    passage: Verified | None = None
    poses: list = field(default_factory=list)
    seconds: float = 0.0
    checks: int = 0
    plans: int = 0
    crossings: int = 0
    method: str = ""


def _straight(world, window: Window, quat, xy) -> list:
    return [
        (quat, np.array([xy[0], xy[1], window.above])),
        (quat, np.array([xy[0], xy[1], window.below])),
    ]


def _slab_points(v: np.ndarray, edges: np.ndarray, z0: float, z1: float) -> np.ndarray:
    """Points of a placed mesh inside the slab z0 <= z <= z1: its vertices there and its edges'
    crossings of both planes ((k, 3) float)."""
    inside = v[(v[:, 2] >= z0) & (v[:, 2] <= z1)]
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    out = [inside]
    for z in (z0, z1):
        cross = (a[:, 2] - z) * (b[:, 2] - z) < 0
        t = (z - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
        out.append(a[cross] + t[:, None] * (b[cross] - a[cross]))
    return np.concatenate(out)


def _crossings(world, window: Window, seeds, rng, count: int, tries: int) -> list:
    """Up to ``count`` poses that meet no material with the plate cutting through the shape,
    clearest first: random rotations, a random height, and the shape's part inside the slab
    centred on one of the hole's pieces."""
    quats = np.concatenate([np.asarray(seeds).reshape(-1, 4), random_uniform(tries, rng)])
    t, shape = world.thickness, world.shape
    edges = world.edges
    found = []
    for q in quats:
        v = shape.vertices @ to_matrix(q).T
        h = rng.uniform(v[:, 2].min(), v[:, 2].max())
        v = v + np.array([0.0, 0.0, -t / 2 - h])
        section = _slab_points(v, edges, -t, 0.0)
        if not len(section):
            continue
        mid = 0.5 * (section[:, :2].min(0) + section[:, :2].max(0))
        hole = window.pieces[rng.integers(len(window.pieces))]
        trans = np.array([*(hole - mid), -t / 2 - h])
        inside = np.all(trans >= window.lo) and np.all(trans <= window.hi)
        if inside and not world.collides(q, trans):
            found.append((world.distance(q, trans), (q, trans)))
    found.sort(key=lambda f: -f[0])
    return [p for _, p in found[:count]]


class _Planner:
    """One OMPL SE(3) problem setup for a world and window (rotation weighted by the radius)."""

    def __init__(self, world, window: Window, seed: int):
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        ou.setLogLevel(ou.LOG_NONE)
        ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
        self.ob, self.og, self.world = ob, og, world
        space = ob.SE3StateSpace()
        bounds = ob.RealVectorBounds(3)
        for i in range(3):
            bounds.setLow(i, float(window.lo[i]))
            bounds.setHigh(i, float(window.hi[i]))
        space.setBounds(bounds)
        # OMPL's SO(3) distance is half the turn's angle: weight 2r makes a state distance bound
        # how far any point moves (|Δt| + r θ)
        space.setSubspaceWeight(1, 2.0 * world.radius)
        self.space = space
        self.step = 0.5 * min(world.thickness, world.radius)

    def _state(self, pose):
        q, t = pose
        s = self.space.allocState()
        s.setXYZ(float(t[0]), float(t[1]), float(t[2]))
        r = s.rotation()
        r.w, r.x, r.y, r.z = (float(v) for v in q)
        return s

    def _valid(self, s) -> bool:
        r = s.rotation()
        return not self.world.collides((r.w, r.x, r.y, r.z), (s.getX(), s.getY(), s.getZ()))

    @staticmethod
    def _pose(s):
        r = s.rotation()
        return np.array([r.w, r.x, r.y, r.z]), np.array([s.getX(), s.getY(), s.getZ()])

    def plan(self, start, goals: list, seconds: float) -> list | None:
        """RRT-Connect from ``start`` to any of ``goals`` (poses) within ``seconds``; the
        simplified path (ending at the goal it reached) or None."""
        ob, og = self.ob, self.og
        ss = og.SimpleSetup(self.space)
        ss.setStateValidityChecker(self._valid)
        si = ss.getSpaceInformation()
        si.setStateValidityCheckingResolution(self.step / self.space.getMaximumExtent())
        ss.setStartState(self._state(start))
        goal = ob.GoalStates(si)
        for g in goals:
            goal.addState(self._state(g))
        ss.setGoal(goal)
        ss.setPlanner(og.RRTConnect(si))
        solved = ss.solve(float(seconds))
        if not solved or not ss.haveExactSolutionPath():
            return None
        ss.simplifySolution(min(1.0, 0.2 * seconds))
        path = ss.getSolutionPath()
        return [self._pose(path.getState(i)) for i in range(path.getStateCount())]


def _down(world, out: PassageSearch, window: Window, ends, quat, xy) -> bool:
    """Try the straight descent in rotation ``quat`` over ``xy``: from the start, over the hole
    wholly above the plate, straight down through it, and on to the goal wholly below."""
    path = [ends[0], *_straight(world, window, quat, xy), ends[1]]
    return _try(world, out, path, "straight descent")


def _try(world, out: PassageSearch, poses, method: str) -> bool:
    """Re-check a candidate motion; keep it in ``out`` when it holds."""
    if poses is None:
        return False
    v = verify(world, poses)
    if v.ok:
        out.passage, out.poses, out.method = v, poses, method
    return v.ok


def _via_crossings(
    planner: _Planner, out: PassageSearch, ends, side: int, crossings, left, slice_s
):
    """Plan from ``ends[side]`` to the nearest reachable crossing pose, then on to the other end;
    drop a crossing that leads nowhere and try the others. True when a verified passage was found
    (kept in ``out`` from ``ends[0]`` to ``ends[1]``). ``left()`` is the budget's seconds left,
    ``slice_s`` the most one plan may take."""
    world, start, goal, reverse = planner.world, ends[side], ends[1 - side], side == 1
    pending = list(crossings)
    while pending and left() > 0.05:
        first = planner.plan(start, pending, min(slice_s, left()))
        out.plans += 1
        if first is None:
            return False
        end = first[-1][1]
        k = int(np.argmin([np.linalg.norm(w[1] - end) for w in pending]))
        w = pending.pop(k)
        second = planner.plan(w, [goal], min(slice_s, left()))
        out.plans += 1
        if second is None:
            continue
        path = first[:-1] + [w] + second[1:]
        if _try(world, out, path[::-1] if reverse else path, "RRTConnect via a crossing pose"):
            return True
    return False


def search_passage(world, outline, seeds, budget_s: float, seed: int = 0) -> PassageSearch:
    """Look for a motion taking the shape from wholly above the plate to wholly below it.

    Parameters
    ----------
    world : sieve_mi.motion.collide.PlateWorld
    outline : manifold3d.CrossSection
        The hole H (one or several pieces), scene units.
    seeds : list of (quat, xy)
        Orientations (w, x, y, z) and hole-plane positions to try first (player B's attempts).
    budget_s : float
        Time budget, seconds.
    seed : int
        Seeds the crossing-pose sampler and OMPL's random number generator.

    Returns
    -------
    PassageSearch
    """
    t0 = time.perf_counter()
    out = PassageSearch()
    window = Window.around(world, outline)
    seeds = list(seeds) or [(np.array([1.0, 0, 0, 0]), window.centre)]
    q0 = np.asarray(seeds[0][0], dtype=np.float64)
    ends = _straight(world, window, q0, window.centre)
    straight = seeds + [(q, xy) for q, _ in seeds for xy in window.pieces]
    done = any(_down(world, out, window, ends, q, xy) for q, xy in straight)
    rng = np.random.default_rng(seed)
    planner = None if done else _Planner(world, window, seed)
    left = lambda: budget_s - (time.perf_counter() - t0)  # noqa: E731
    slice_s = min(max(0.5, budget_s / 10), 3.0)
    rounds = 0
    while not done and left() > 0.05:
        out.plans += 1
        direct = planner.plan(ends[0], [ends[1]], min(slice_s, left()))
        if _try(world, out, direct, "RRTConnect"):
            break
        crossings = _crossings(world, window, [q for q, _ in seeds], rng, 8, 400)
        out.crossings += len(crossings)
        if any(_down(world, out, window, ends, q, t[:2]) for q, t in crossings):
            break
        side = rounds % 2  # reach the crossings from above, then from below, in turn
        done = _via_crossings(planner, out, ends, side, crossings, left, slice_s)
        rounds += 1
    out.seconds = time.perf_counter() - t0
    out.checks = world.checks
    return out
