"""One more A placed into a hole: eq. 14, screened candidates, a particle swarm, a long re-ranking.

Each placement (:func:`place`) maximises eq. 14 of paper Sec. 5.3,

    tau/2 * tanh(rho * (beta_H - eta)) - alpha * area(H),

where beta_H is player B's best beta against the new hole and area(H) is the hole's area as a
fraction of the frame; a placement that splits the hole into several pieces is penalised by tau,
so the final hole stays one simply connected region (:func:`eq14`). Over the candidates of
:func:`sieve_mi.game.candidates.candidate_pool`:

1. *Screening*: ``SCREEN x particles`` distinct candidates get one short attack of B each; the best
   ``particles`` start a particle swarm (accelerations ``c_personal``, ``c_global``).
2. *Re-ranking*: the swarm's :data:`FINALISTS` best placements are attacked as long as the verdict
   will attack, and the best survivor is kept.
3. *Rounds*: while every finalist still lets some B through, the round is repeated (at most
   ``[layout] rounds``); B's attacks remember the passing poses found so far.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from sieve_mi.game.attack import AttackMemory, Starts
from sieve_mi.game.candidates import candidate_pool
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.geometry.hole import pieces
from sieve_mi.geometry.rotations import normalize
from sieve_mi.optim import SwarmHistory, SwarmSettings, particle_swarm
from sieve_mi.scene import Layout, Solver

__all__ = ["FINALISTS", "SCREEN", "Placement", "PlacementContext", "eq14", "place"]

#: ``SCREEN * particles`` distinct candidates are screened with a short attack.
SCREEN = 5
#: The swarm's best placements re-ranked by the long attack.
FINALISTS = 5


class Placement(NamedTuple):
    """One shape's place in a merged hole, as :func:`place` found it."""

    #: (4,) rotation (w, x, y, z).
    quat: np.ndarray
    #: (2,) translation, scene units.
    trans: np.ndarray
    #: Best eq. 14 energy.
    value: float
    #: The weakest B's loss against this placement in the long re-ranking attack (> 0: every B
    #: was blocked there).
    beta: float
    history: SwarmHistory

    @property
    def blocks(self) -> bool:
        """Whether every B was blocked by the hole with this placement."""
        return self.beta > 0


def eq14(beta: np.ndarray, area_fraction: np.ndarray, pieces: np.ndarray, s: Layout) -> np.ndarray:
    """The energy of eq. 14, minus tau for every hole that falls apart into several pieces."""
    return (
        s.tau / 2 * np.tanh(s.rho * (beta - s.eta)) - s.alpha * area_fraction - s.tau * (pieces > 1)
    )


@dataclass
class PlacementContext:
    """What every placement of one merge shares: B, the settings, the random generator and B's
    memory.

    Attributes
    ----------
    player_b : PlayerB
        The shapes to block, on the union frame.
    solver : sieve_mi.scene.Solver
        Its ``particles``, ``iterations`` and ``patience`` are the placement swarm's; its
        ``starts``, ``steps`` and ``learning_rate`` player B's attack on every candidate hole.
    layout : sieve_mi.scene.Layout
        Eq. 14's tau, rho, eta, alpha, the swarm's accelerations and ``rounds``.
    rng : numpy.random.Generator
    recheck : (int, int), optional
        Starts and Adam steps of the attack that re-ranks the swarm's finalists (the solver passes
        the verdict's settings, so the placement kept is the one that survives the attack the
        winner is decided by); default three times ``solver.starts`` and ``solver.steps``.
    memory : AttackMemory, optional
        B's best poses so far, shared by the placements; every attack starts from them too.
        Default: an empty memory sized for ``solver.starts``
        (:meth:`~sieve_mi.game.attack.AttackMemory.for_starts`).
    converged : (int, float), optional
        The re-ranking attack's starts leave its descent once converged (``(window, rtol)`` of
        :data:`sieve_mi.game.descent.CONVERGED`); the solver passes the verdict's
        (:data:`sieve_mi.game.verdict.CONVERGED`), as for ``recheck``. None: every start runs
        every step.
    """

    player_b: PlayerB
    solver: Solver
    layout: Layout
    rng: np.random.Generator
    recheck: tuple[int, int] | None = None
    memory: AttackMemory | None = None
    converged: tuple | None = None

    def __post_init__(self):
        if self.recheck is None:
            self.recheck = (3 * self.solver.starts, 3 * self.solver.steps)
        if self.memory is None:
            self.memory = AttackMemory.for_starts(len(self.player_b.shapes), self.solver.starts)

    @property
    def swarm(self) -> SwarmSettings:
        """The placement swarm's settings: ``[layout]``'s accelerations, ``[solver] patience``
        (the default inertia)."""
        return SwarmSettings(
            c_personal=self.layout.c_personal,
            c_global=self.layout.c_global,
            patience=self.solver.patience,
        )


def place(
    player: PlayerA,
    base: np.ndarray,
    quat: np.ndarray,
    context: PlacementContext,
    *,
    progress: Callable[[int, float], None] | None = None,
    rounds: int | None = None,
    finalists: int = FINALISTS,
    screen: int = SCREEN,
):
    """Place one more A shape into a hole (one step of the sequential scheme).

    Parameters
    ----------
    player : PlayerA
        The shape to add, on the union frame.
    base : (N, N) bool ndarray
        The current hole (dilated, filled).
    quat : (4,) ndarray
        The shape's best rotation when it was solved alone.
    context : PlacementContext
        Player B, the ``[solver]`` and ``[layout]`` settings, the random generator, the
        re-ranking attack's size and B's memory (updated by every attack).
    progress : callable, optional
        Per-iteration callback of the swarm.
    rounds : int, optional
        Screening + swarm + re-ranking is repeated (at most this many times, default
        ``layout.rounds``) while every re-ranked placement still lets some B through; each
        round's attacks start from the passing poses the previous rounds found.
    finalists : int
        The swarm's best placements re-ranked by the ``context.recheck`` attack.
    screen : int
        ``screen * particles`` distinct candidate placements (half the most compact, half spread
        over the others, see :func:`~sieve_mi.game.candidates.candidate_pool`) are scored with
        one short attack each; the best ``particles`` of them start the swarm.

    Returns
    -------
    Placement
    """
    reach = player.frame.half_extent / 2.0  # centres stay within the largest radius of the origin
    game = _PlacementGame(player, base, reach, context)
    pool = candidate_pool(player, base, quat, reach, screen * context.solver.particles)
    rounds = context.layout.rounds if rounds is None else rounds
    return game.play(pool, finalists, rounds, progress)


@dataclass
class _PlacementGame:
    """Eq. 14 for placements of one A into a base hole, each scored by one batched attack of B."""

    player: PlayerA
    base: np.ndarray
    reach: float
    context: PlacementContext

    def energy(
        self, x: np.ndarray, starts: int, steps: int, converged=None, halving: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Eq. 14 energy and the weakest B's β of placements ``x`` (P, 6): (P,) and (P,);
        ``converged``, ``halving``: the attack's converged stop and successive halving
        (:meth:`PlayerB.attack`)."""
        c = self.context
        holes = self.player.holes(x[:, :4], x[:, 4:] * self.reach, base=self.base)
        attack = c.player_b.attack(
            holes, Starts(starts, memory=c.memory), steps, c.solver.learning_rate, c.rng,
            settle=self.player.settle, converged=converged, halving=halving,
        )  # fmt: skip
        area = np.array([hh.mask.mean() for hh in holes])
        n = np.array([pieces(hh.mask) for hh in holes])
        return eq14(attack.value(), area, n, c.layout), attack.value()

    def play(self, pool, finalists: int, rounds: int, progress) -> Placement:
        """Rounds of screening, swarm and re-ranking over the candidate ``pool`` (see :func:`place`).

        The swarm's attacks are ``[solver]``'s (starts, steps), the re-ranking's
        ``context.recheck``.
        """
        reach, c = self.reach, self.context
        particles, iterations = c.solver.particles, c.solver.iterations

        def evaluate(x):
            return self.energy(x, c.solver.starts, c.solver.steps, halving=c.solver.halving)[0]

        history = SwarmHistory()
        best, value, best_beta = pool[0], -np.inf, -np.inf
        for _ in range(rounds):
            x0 = _swarm_starts(pool, evaluate, particles, self.player.frame.pixel_size / reach)
            x, _, h = particle_swarm(
                evaluate, _project(x0), iterations, c.rng, c.swarm, project=_project,
                progress=progress,
            )  # fmt: skip
            history.extend(h)
            history.finalists = h.finalists
            # The swarm ranks placements with a short attack, which can miss a narrow passage.
            # Re-rank its best few placements with a long attack and keep the best of those.
            xs = np.stack([f for f, _ in h.finalists[:finalists]]) if h.finalists else x[None]
            values, betas = self.energy(xs, *c.recheck, c.converged)
            i = int(np.argmax(values))
            if values[i] > value:
                best, value, best_beta = xs[i], float(values[i]), float(betas[i])
            if best_beta > 0:
                break
            # Every finalist lets some B through. The memory now holds the passing poses, so
            # another round of screening and swarming sees through the placements that looked
            # safe before.
        return Placement(normalize(best[:4]), best[4:] * reach, value, best_beta, history)


def _project(x: np.ndarray) -> np.ndarray:
    """Placements (P, 6) with unit quaternions and translations inside the unit disc."""
    x = x.copy()
    x[:, :4] = normalize(x[:, :4])
    norm = np.linalg.norm(x[:, 4:], axis=1, keepdims=True)
    x[:, 4:] = x[:, 4:] / np.maximum(norm, 1.0)
    return x


def _swarm_starts(pool: np.ndarray, evaluate, particles: int, nudge: float) -> np.ndarray:
    """The swarm's first ``particles`` placements (P, 6): the pool's best by ``evaluate``.

    With no more candidates than particles, the pool is repeated, the copies moved by ``nudge``
    along x (in units of the reach: a pixel).
    """
    if len(pool) > particles:
        return pool[np.argsort(evaluate(pool), kind="stable")[::-1][:particles]]
    extra = particles - len(pool)
    shift = np.array([0, 0, 0, 0, nudge, 0])
    return np.concatenate([pool, pool[np.arange(extra) % len(pool)] + shift])
