"""Player A: choose the passing shape's rotation so that B's best attempt fails (paper Sec. 6.2).

Player A maximises the game value (min over B of β, eq. 7) over its shape's rotation: canonical
views first, then a particle swarm whose particles are evaluated together in one attack of
player B (or an nlopt global method), then a local polish of the view direction. Its holes are
its dilated, filled silhouettes, built on a thread pool of its own.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from sieve_mi.game import maximin, reuse
from sieve_mi.game.player_b import PlayerB
from sieve_mi.game.scoring import with_core
from sieve_mi.geometry.hole import Hole, build_hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import (
    angle_between,
    from_rotvec,
    normalize,
    quat_multiply,
    random_uniform,
    to_rotvec,
)
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.optim import SwarmSettings, nlopt_maximise, particle_swarm
from sieve_mi.scene import Fabrication, Solver

__all__ = ["PlayerA"]


_POOL = None


def _pool():
    """A shared thread pool for per-pose raster work (distance transforms, hole filling)."""
    global _POOL
    if _POOL is None:
        from concurrent.futures import ThreadPoolExecutor

        _POOL = ThreadPoolExecutor(
            max_workers=max(1, min(8, os.cpu_count() or 1)), thread_name_prefix="sieve-mi-raster"
        )
    return _POOL


class PlayerA:
    """Chooses A's rotation so that B's best attempt fails by as much as possible (eq. 7).

    Parameters
    ----------
    shape : Shape
        The shape that must pass.
    frame : Frame
        Raster frame of the hole (covers A's dilated silhouette at every rotation).
    tolerance : float
        Dilation of A's silhouette, scene units.
    fill_holes : bool
        Whether holes in A's silhouette are filled.
    """

    def __init__(self, shape: Shape, frame: Frame, tolerance: float, fill_holes: bool = True):
        self.shape = shape
        self.frame = frame
        self.tolerance = tolerance
        self.fill_holes = fill_holes
        self.renderer = with_core(SilhouetteRenderer(shape))
        #: How player B's attacks on this player's holes settle (:meth:`PlayerB.attack`): per
        #: hole, since a hole's value is 0 once any B fits it; only for filled holes, where the
        #: clearance loss is 0 exactly when B fits (an island of plate inside H would let a
        #: silhouette's edges all lie in H while the silhouette covers the island).
        self.settle = "hole" if fill_holes else None
        #: Called with the candidate-steps done (candidates x Adam steps) as player B's attacks
        #: on this player's holes descend (progress bars); None: nothing reports.
        self.on_step: Callable[[int], None] | None = None
        #: The last search's classes of congruent holes (:mod:`sieve_mi.game.reuse`), or None.
        self.classes = None
        #: The last search's :class:`~sieve_mi.game.reuse.Incumbent` (with reuse), or None.
        self.incumbent = None
        #: The classes (:class:`~sieve_mi.game.reuse.Member`) of the holes of the last
        #: :meth:`values` with ``classes``.
        self.placed = None

    @classmethod
    def from_settings(
        cls, shape: Shape, frame: Frame, fabrication: Fabrication, solver: Solver | None = None
    ) -> PlayerA:
        """Player A with the ``[fabrication]`` table's ``tolerance`` and ``fill_holes``, and the
        ``[solver]`` table's ``settle`` where given."""
        player = cls(shape, frame, fabrication.tolerance, fabrication.fill_holes)
        if solver is not None and not solver.settle:
            player.settle = None
        return player

    def silhouettes(self, quats: np.ndarray, trans: np.ndarray | None = None) -> np.ndarray:
        """A's silhouettes on the frame for K poses, (K, N, N) bool (translations default to zero)."""
        quats = np.atleast_2d(normalize(quats))
        trans = np.zeros((len(quats), 2)) if trans is None else np.atleast_2d(trans)
        zero = np.zeros(len(quats), int)
        return self.renderer.masks(quats, trans, self.frame, zero, zero, self.frame.resolution)

    def holes(
        self, quats: np.ndarray, trans: np.ndarray | None = None, base: np.ndarray | None = None
    ) -> list[Hole]:
        """The hole H for each pose: silhouette, dilated by the tolerance, holes filled.

        Parameters
        ----------
        quats : (K, 4) ndarray
        trans : (K, 2) ndarray, optional
            Translations in scene units (default zero).
        base : (N, N) bool ndarray, optional
            Part of the hole made by other shapes (already dilated); each hole is its union with
            this shape's dilated silhouette, then filled.
        """
        extra = [] if base is None else [base]
        masks = self.silhouettes(quats, trans)

        def one(m):
            return build_hole([m], self.frame, self.tolerance, self.fill_holes, extra=extra)

        if len(masks) < 2:
            return [one(m) for m in masks]
        # SciPy's distance transforms release the GIL: build the particles' holes in parallel.
        return list(_pool().map(one, masks))

    def search(
        self,
        player_b: PlayerB,
        solver: Solver,
        *,
        rng: np.random.Generator,
        seed: int | None = None,
        progress: Callable[[int, float], None] | None = None,
        stage: Callable[[str], None] | None = None,
        extra: np.ndarray | None = None,
    ):
        """Global search over A's rotation: canonical views, then the swarm, then a local polish.

        Parameters
        ----------
        player_b : PlayerB
            The shapes to block, on this player's frame.
        solver : sieve_mi.scene.Solver
            The ``[solver]`` table: ``outer`` (PSO or an nlopt method) with ``particles``,
            ``iterations``, ``inertia``, ``c_personal`` and ``c_global``; B's ``starts``, ``steps``
            and ``learning_rate`` for every evaluation; ``canonical`` views evaluated first
            (:mod:`sieve_mi.geometry.canonical`; the best of them start half of the swarm's
            particles, nlopt starts from the best one); ``polish`` rounds of :meth:`polish` after
            the global method (0: none). Its ``resolution``, ``objective`` and ``freeze`` are
            the frame's and player B's.
        rng : numpy.random.Generator
        seed : int, optional
            Seed of nlopt's own generator and of the polish's common starts (default
            ``solver.seed``).
        progress : callable, optional
            Called as ``progress(iteration, best)`` by the global method.
        stage : callable, optional
            Called with "canonical", "swarm" and "polish" as each stage starts (progress bars).
        extra : (E, 4) ndarray, optional
            More rotations evaluated with the canonical views (A's rest poses,
            :mod:`sieve_mi.game.rest`), seeding the swarm like them; their values are returned
            in ``history.extra``.

        Returns
        -------
        quat : (4,) ndarray
            Best rotation found.
        value : float
            Its game value (min over B of beta).
        history : SwarmHistory
            Best value after each iteration (PSO) or evaluation (nlopt); ``history.polish`` holds
            the polish's record.
        """

        s = solver
        seed = s.seed if seed is None else seed
        evaluate = self._evaluator(player_b, s, rng, seed)

        def say(name: str) -> None:
            if stage is not None:
                stage(name)

        extra = np.zeros((0, 4)) if extra is None else np.atleast_2d(extra)
        if s.canonical > 0 or len(extra):
            say("canonical")
        seeds, evaluated, extra_values = self._canonical_seeds(
            evaluate, s.canonical, max(1, s.particles // 2), extra
        )
        say("swarm" if s.outer == "pso" else s.outer)
        q, f, history = self._global(evaluate, seeds, s, rng, seed, progress)
        history.evaluations += evaluated
        history.extra = [float(v) for v in extra_values]
        if s.polish > 0:
            say("polish")
            q, f, history.polish = self.polish(player_b, q, s, seed=seed, classes=self.classes)
        return q, f, history

    def _evaluator(self, player_b: PlayerB, s: Solver, rng, seed: int):
        """The search's ``evaluate(quats, floor=None)``: :meth:`values` with the search's classes
        of congruent holes (:mod:`sieve_mi.game.reuse`, made afresh here) and, with them, each
        class whose hole would become the search's best confirmed by a fresh attack
        (:class:`~sieve_mi.game.reuse.Incumbent`)."""
        self.classes = reuse.Classes() if reuse.REUSE else None

        def fresh(qs: np.ndarray, k: int) -> np.ndarray:  # a new best's confirming attack
            own = np.random.default_rng([int(seed), 0xC0F1, k])
            return self.values(player_b, qs, s.starts, s.steps, s.learning_rate, own,
                               halving=s.halving)  # fmt: skip

        self.incumbent = None if self.classes is None else reuse.Incumbent(fresh)

        def evaluate(qs: np.ndarray, floor=None) -> np.ndarray:
            got = self.values(player_b, qs, s.starts, s.steps, s.learning_rate, rng, floor,
                              classes=self.classes, halving=s.halving)  # fmt: skip
            return got if self.incumbent is None else self.incumbent(qs, got, self.placed)

        return evaluate

    def values(
        self,
        player_b: PlayerB,
        quats,
        starts,
        steps,
        learning_rate,
        rng,
        floor=None,
        classes=None,
        halving: float = 0.0,
    ) -> np.ndarray:
        """The game value (min over B of β, eq. 10) of the holes of rotations (K, 4), one attack.

        An empty raster hole (A seen edge-on, thinner than a pixel) blocks everything on the
        raster but not on the plate: it gets -1, below every real hole.

        ``floor`` (scalar or (K,)): only values above it matter to the caller; B are then
        attacked in rounds, the most dangerous first, and a candidate at or below its floor
        after a round is attacked no further (its value is then an upper bound at or below
        the floor; B far from fitting get fewer starts there, :data:`~sieve_mi.game.maximin.FAR`;
        :mod:`sieve_mi.game.maximin`). A :class:`~sieve_mi.game.maximin.Best`: only
        which candidates are its ``count`` best matters (and its ``exact`` ones' values). None:
        every B attacks every candidate.

        ``classes`` (:class:`~sieve_mi.game.reuse.Classes`, optional): the search's classes of
        congruent holes; a hole congruent to one attacked before is attacked from player B's
        best poses there (:mod:`sieve_mi.game.reuse`).

        ``halving`` (``[solver] halving``; 0: off): successive halving of each hole and B's
        starts (:func:`~sieve_mi.game.descent.halving_live`).
        """
        holes = self.holes(quats)
        step = None if self.on_step is None else _per_candidate(self.on_step, len(holes))
        prune = floor is not None and maximin.PRUNE and len(player_b.shapes) > 1
        if prune or classes is not None:
            pruned = maximin.Pruned(player_b, holes, starts, steps, learning_rate, rng,
                                    self.settle, step, classes, halving)  # fmt: skip
            self.placed = pruned.members
            if not prune:
                return pruned.advance().copy()
            if isinstance(floor, maximin.Best):
                return pruned.best(floor.count, floor.exact).copy()
            return pruned.advance(floor=floor).copy()
        attack = player_b.attack(holes, starts, steps, learning_rate, rng, progress=step,
                                 settle=self.settle, halving=halving)  # fmt: skip
        maximin.note(player_b, attack.beta)
        values = attack.value()
        return np.where([h.mask.any() for h in holes], values, -1.0)

    def _canonical_seeds(
        self, evaluate, count: int, keep: int, extra: np.ndarray
    ) -> tuple[np.ndarray, int, np.ndarray]:
        """The ``keep`` best of ``count`` canonical orientations and the ``extra`` ones (k, 4),
        evaluated in one batch, how many were evaluated, and the ``extra`` ones' values."""
        from sieve_mi.geometry.canonical import canonical_orientations

        views = canonical_orientations(self.shape, count) if count > 0 else np.zeros((0, 4))
        views = np.concatenate([views, extra]) if len(extra) else views
        if not len(views):
            return np.zeros((0, 4)), 0, np.zeros(0)
        tail = tuple(range(len(views) - len(extra), len(views)))  # their values are reported
        values = evaluate(views, maximin.Best(keep, tail))
        best = views[np.argsort(-values, kind="stable")[:keep]]
        return best, len(views), values[len(views) - len(extra) :]

    def _global(self, evaluate, seeds, solver: Solver, rng, seed: int, progress):
        """The swarm (or nlopt) of ``solver`` over A's rotation, started from ``seeds`` where given."""
        particles, iterations, method = solver.particles, solver.iterations, solver.outer
        if method == "pso":
            x0 = random_uniform(particles, rng)
            x0[: len(seeds)] = seeds[:particles]
            swarm = SwarmSettings(
                solver.inertia, solver.c_personal, solver.c_global, patience=solver.patience
            )
            return particle_swarm(evaluate, x0, iterations, rng, swarm, project=normalize,
                                  progress=progress, floors=True)  # fmt: skip
        lower, upper = -np.pi * np.ones(3), np.pi * np.ones(3)
        x0 = rng.uniform(-np.pi, np.pi, 3)
        if len(seeds):
            x0 = np.clip(to_rotvec(seeds[0]), lower, upper)
        x, f, history = nlopt_maximise(
            lambda v: float(evaluate(from_rotvec(v)[None])[0]),
            lower,
            upper,
            method,
            particles * (iterations + 1),
            x0,
            seed,
            progress,
        )
        return from_rotvec(x), f, history

    def polish(
        self,
        player_b: PlayerB,
        quat: np.ndarray,
        solver: Solver,
        *,
        seed: int | None = None,
        first: float = 1.0,
        last: float = 0.05,
        gain: float = 0.01,
        classes=None,
    ) -> tuple[np.ndarray, float, dict]:
        """Refine A's rotation locally: a batched compass search on the view direction.

        The starting rotation is evaluated once; then each round tilts the current one by ``step``
        about the x and y axes, both ways (turning about z only turns the hole), and evaluates the
        four holes in one attack whose B starts are the same every time (common random numbers, so differences come from
        the holes, not from luck). A tilt that is better by more than ``gain`` (relative, and at
        least 1e-3: less is a pixel's worth of raster noise) is taken; otherwise the step is
        halved, from ``first`` down to ``last`` degrees.

        Parameters
        ----------
        player_b : PlayerB
        quat : (4,) ndarray
            The rotation to start from.
        solver : sieve_mi.scene.Solver
            B's ``starts``, ``steps`` and ``learning_rate`` for every attack; at most ``polish``
            rounds.
        seed : int, optional
            Seed of the common starts (default ``solver.seed``).
        first, last : float
            The first and the smallest tilt, degrees.
        gain : float
            Relative improvement a tilt must bring to be taken.
        classes : Classes, optional
            Classes of congruent holes to reuse attacks from (:mod:`sieve_mi.game.reuse`; the
            search passes its own).

        Returns
        -------
        quat : (4,) ndarray
        value : float
            The value of ``quat`` with the common starts (comparable with ``record["before"]``).
        record : dict
            ``before`` and ``after`` values with the common starts, the rotation's ``moved``
            angle (degrees) and the ``rounds`` run.
        """
        tilts = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])

        seed, rounds = (solver.seed if seed is None else seed), solver.polish

        def values(qs, floor=None):
            common = np.random.default_rng([int(seed), 0x501])
            return self.values(player_b, qs, solver.starts, solver.steps, solver.learning_rate,
                               common, floor, classes=classes, halving=solver.halving)  # fmt: skip

        start = normalize(np.asarray(quat, dtype=np.float64))
        best, step, done = start, np.radians(first), 0
        current = float(values(best[None])[0])
        before = current
        while done < rounds and step >= np.radians(last) * (1 - 1e-9):
            tried = normalize(quat_multiply(from_rotvec(tilts * step), best))
            floor = current + max(1e-3, gain * abs(current))  # a tilt must beat this
            v = values(tried, floor)
            done += 1
            k = int(np.argmax(v))
            if v[k] > floor:
                best, current = tried[k], float(v[k])
            else:
                step /= 2
        moved = float(np.degrees(angle_between(best, start)))
        record = {"before": before, "after": current, "moved": moved, "rounds": done}
        return best, current, record


def _per_candidate(on_step: Callable[[int], None], candidates: int) -> Callable[[int], None]:
    """An attack's ``progress`` (steps done so far) as ``on_step`` increments of candidate-steps:
    each new step of the descent counts once per candidate hole."""
    last = [0]

    def report(n: int) -> None:
        on_step(candidates * (n - last[0]))
        last[0] = n

    return report
