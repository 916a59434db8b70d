"""The verdict: a long re-run of player B against the hole player A chose, which names the winner.

Player B attacks the final hole (paper Sec. 6.1: 100 starts x 500 Adam steps by default); A wins
iff no shape of B fits in any of its attempts. With ``[fabrication] block_margin``, B must also fail
against the hole grown by that margin (paper Fig. 14). With ``[layout] mode = "separate"``, B is
attacked on every hole and passes the sieve if it passes any one of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sieve_mi.hole import Hole, build_hole, pieces
from sieve_mi.layout import frame_for, separate_layout
from sieve_mi.meshes import Shape
from sieve_mi.players import Attack, PlayerA, PlayerB
from sieve_mi.scene import Scene
from sieve_mi.scoring import mask_window, score_poses


@dataclass
class Judgement:
    """What the verdict decided.

    Attributes
    ----------
    winner : {"A", "B"}
    hole : Hole
        The final hole (all of A's holes together) at the verdict resolution.
    trans : (m, 2) ndarray
        Each A's translation, scene units (the separate layout's places, or the search's).
    a_masks : list of (N, N) bool ndarrays
        Each A's undilated silhouette at its place on ``hole``'s frame.
    attack : Attack
        One row: per B, its best attempt over the holes.
    block_masks : list of MaskWindow
        Each B's silhouette in that attempt.
    warnings : list of str
    """

    winner: str
    hole: Hole
    trans: np.ndarray
    a_masks: list
    attack: Attack
    block_masks: list
    warnings: list


def weakest_hole(attack: Attack) -> Attack:
    """Collapse an attack on several separate holes to one row: per shape, its best hole.

    A shape passes a sieve with several holes if it passes any of them, so per shape the hole with
    the lowest beta (then protrusion) is kept.
    """
    if attack.beta.shape[0] == 1:
        return attack
    order = np.lexsort((attack.protrusion, attack.beta), axis=0)[0]
    cols = np.arange(attack.beta.shape[1])
    return Attack(
        beta=attack.beta[order, cols][None],
        protrusion=attack.protrusion[order, cols][None],
        quats=attack.quats[order, cols][None],
        trans=attack.trans[order, cols][None],
        fits=attack.fits.sum(axis=0)[None],
    )


def _groups(count: int, separate: bool) -> list[list[int]]:
    """Which A shapes make each hole: one each (separate) or all in one."""
    return [[i] for i in range(count)] if separate else [list(range(count))]


def judge(
    scene: Scene,
    passes: list[Shape],
    blocks: list[Shape],
    quats: np.ndarray,
    trans: np.ndarray,
    rng: np.random.Generator,
    progress: Callable[[int], None] | None = None,
) -> Judgement:
    """Attack the hole made by A at its placements and declare the winner.

    Parameters
    ----------
    scene : Scene
        Its ``[verdict]``, ``[fabrication]`` and ``[layout]`` tables are used.
    passes, blocks : list of Shape
    quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z).
    trans : (m, 2) ndarray
        Each A's translation from the search, scene units (ignored for separate holes).
    rng : numpy.random.Generator
    progress : callable, optional
        Called with the number of Adam steps done.

    Returns
    -------
    Judgement
    """
    fab, v = scene.fabrication, scene.verdict
    separate = len(passes) > 1 and scene.layout.mode == "separate"
    if separate:
        radii = [p.radius for p in passes]
        trans, frame = separate_layout(radii, fab.tolerance, fab.border, v.resolution)
    else:
        trans = np.zeros((1, 2)) if len(passes) == 1 else np.asarray(trans, dtype=np.float64)
        frame = frame_for(passes, fab.tolerance, v.resolution, trans)
    players = [PlayerA(p, frame, fab.tolerance, fab.fill_holes) for p in passes]
    a_masks = [p.silhouettes(q[None], t[None])[0] for p, q, t in zip(players, quats, trans)]
    hole = build_hole(a_masks, frame, fab.tolerance, fab.fill_holes)
    warnings = []
    if len(passes) > 1 and not separate and pieces(hole.mask) > 1:
        warnings.append("the merged hole is not connected")
    groups = _groups(len(passes), separate)

    def holes_grown_by(margin: float) -> list[Hole]:
        if not separate and margin == 0:
            return [hole]
        return [
            build_hole([a_masks[i] for i in g], frame, fab.tolerance + margin, fab.fill_holes)
            for g in groups
        ]

    player_b = PlayerB(blocks, frame, "clearance")
    centres = np.array([trans[g].mean(axis=0) for g in groups]) if separate else None
    attack = player_b.attack(
        holes_grown_by(fab.block_margin),
        v.starts,
        v.steps,
        scene.solver.learning_rate,
        rng,
        progress=progress,
        centres=centres,
    )
    attack = weakest_hole(attack)
    if fab.block_margin > 0:
        _rescore_against(attack, player_b, hole)
    block_masks = [
        mask_window(r, hole, attack.quats[0, j], attack.trans[0, j])
        for j, r in enumerate(player_b.renderers)
    ]
    winner = "A" if bool(np.all(attack.blocked()[0])) else "B"
    return Judgement(winner, hole, trans, a_masks, attack, block_masks, warnings)


def _rescore_against(attack: Attack, player_b: PlayerB, hole: Hole) -> None:
    """Keep the margin scores aside and score each best pose against the hole itself."""
    attack.margin_beta = attack.beta.copy()
    attack.margin_protrusion = attack.protrusion.copy()
    for j, r in enumerate(player_b.renderers):
        sc = score_poses(r, hole, attack.quats[0, j : j + 1], attack.trans[0, j : j + 1])
        attack.beta[0, j], attack.protrusion[0, j] = sc.beta[0], sc.protrusion[0]
