"""Player B's attempts: :class:`Starts` (where an attack's starts begin), :class:`Attack` (best
poses and scores per hole and shape) and :class:`AttackMemory` (the best poses seen so far, reused
as warm starts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Attack", "AttackMemory", "Starts"]


@dataclass(frozen=True)
class Starts:
    """Where the starts of one attack of player B begin
    (:meth:`~sieve_mi.game.player_b.PlayerB.attack`).

    Each start is a uniform random rotation and a translation uniform in +-0.1 of the frame's
    half extent (paper Sec. 6.1), about the origin unless ``centres`` are given; ``memory``'s
    poses replace the first ones.

    Attributes
    ----------
    count : int
        Starts per hole and shape.
    centres : (H, 2) or (H, C, 2) ndarray, optional
        Where each hole's starts are centred, scene units; default the origin. With C centres
        per hole, start ``s`` is centred on centre ``s % C``.
    memory : AttackMemory, optional
        B's remembered best poses replace the first random starts of every hole (at most
        ``count - 1`` per shape, so at least one start stays random); the attack then updates
        the memory with its results.
    """

    count: int
    centres: np.ndarray | None = None
    memory: AttackMemory | None = None

    @classmethod
    def of(cls, starts: int | Starts) -> Starts:
        """``starts`` itself, or ``Starts(starts)`` for a count alone."""
        return starts if isinstance(starts, Starts) else cls(int(starts))


@dataclass
class Attack:
    """Player B's best attempts against a list of holes.

    Attributes
    ----------
    beta : (H, B) ndarray
        Lowest binary beta over the starts, per hole and shape.
    protrusion : (H, B) ndarray
        Protrusion (scene units) of that best pose.
    quats : (H, B, 4) ndarray
    trans : (H, B, 2) ndarray
        The best pose per hole and shape (translation in scene units).
    fits : (H, B) ndarray of int
        How many starts ended in a pose that fits (beta == 0).
    candidates : tuple of ((H, B, K, 4), (H, B, K, 2)) ndarrays, optional
        The K best poses per hole and shape by raster score (best first), for exact rescoring
        (:mod:`sieve_mi.game.exact`); set when the attack was asked to keep them.
    margin_beta, margin_protrusion : (H, B) ndarrays, optional
        Scores against the hole grown by the block margin (the ones that decide ``blocked``).
    """

    beta: np.ndarray
    protrusion: np.ndarray
    quats: np.ndarray
    trans: np.ndarray
    fits: np.ndarray
    candidates: tuple | None = None
    margin_beta: np.ndarray | None = None
    margin_protrusion: np.ndarray | None = None

    def blocked(self) -> np.ndarray:
        """(H, B) bool: the shape cannot pass (against the margin-grown hole when there is one)."""
        return (self.beta if self.margin_beta is None else self.margin_beta) > 0

    def value(self) -> np.ndarray:
        """The game value per hole: the weakest block, min over shapes of beta (eq. 10)."""
        return self.beta.min(axis=1)


class AttackMemory:
    """Player B's best poses seen so far, per shape, to reuse as warm starts.

    While player A compares many similar holes (the placement swarm of Sec. 5.3), a pose with
    which B passed one hole is a good first guess for the next. Random starts find a narrow
    passage only now and then; remembering it makes every later hole face it again, so a hole
    that lets B through is not ranked high just because its attack was unlucky.

    Parameters
    ----------
    shapes : int
        Number of B shapes.
    size : int
        Poses kept per shape (lowest beta first, then lowest protrusion).
    """

    def __init__(self, shapes: int, size: int = 3):
        self.size = int(size)
        self._poses: list[list[tuple[float, float, np.ndarray, np.ndarray]]] = [
            [] for _ in range(shapes)
        ]

    @classmethod
    def for_starts(cls, shapes: int, starts: int) -> AttackMemory:
        """A memory sized for attacks of ``starts`` random starts: a third of them, at least one."""
        return cls(shapes, size=max(1, starts // 3))

    def update(self, attack: Attack) -> None:
        """Add each hole's best pose per shape from ``attack``, keep the ``size`` best per shape."""
        for b, kept in enumerate(self._poses):
            for h in range(attack.beta.shape[0]):
                kept.append(
                    (
                        float(attack.beta[h, b]),
                        float(attack.protrusion[h, b]),
                        np.array(attack.quats[h, b]),
                        np.array(attack.trans[h, b]),
                    )
                )
            kept.sort(key=lambda e: (e[0], e[1]))
            del kept[self.size :]

    def shifted(self, offset: np.ndarray) -> AttackMemory:
        """A copy whose remembered translations are moved by ``offset`` (2,), scene units."""
        out = AttackMemory(len(self._poses), self.size)
        out._poses = [
            [(b, p, q.copy(), t + np.asarray(offset, dtype=np.float64)) for b, p, q, t in kept]
            for kept in self._poses
        ]
        return out

    def poses(self, shape: int) -> tuple[np.ndarray, np.ndarray]:
        """The remembered rotations (W, 4) and translations (W, 2, scene units) of one shape."""
        kept = self._poses[shape]
        return np.array([e[2] for e in kept]).reshape(-1, 4), np.array(
            [e[3] for e in kept]
        ).reshape(-1, 2)
