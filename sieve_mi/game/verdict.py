"""The verdict: a long re-run of player B against the hole player A chose, which names the winner.

Player B attacks the final hole (paper Sec. 6.1: 100 starts x 500 Adam steps by default); A wins
iff no shape of B fits in any of its attempts. The attack runs on the raster; its best poses are
then polished and scored exactly against the polygon H that gets printed (:mod:`sieve_mi.game.exact`),
and only those exact scores decide. With ``[fabrication] block_margin``, B must also fail
against the hole grown by that margin (paper Fig. 14). With ``[layout] mode = "separate"``, B is
attacked on every hole and passes the sieve if it passes any one of them.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.game.attack import Attack, AttackMemory, Starts
from sieve_mi.game.exact import CANDIDATES, exact_rescore
from sieve_mi.game.frames import frame_for
from sieve_mi.game.holes import hole_tolerances, separate_holes
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.game.scoring import mask_window
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import dilated, is_closed, union
from sieve_mi.geometry.window import GROWTH, windowed_hole
from sieve_mi.scene import Scene

__all__ = ["CONVERGED", "Judgement", "REACH", "exact_holes", "judge", "start_centres"]


@dataclass
class Judgement:
    """What the verdict decided.

    Attributes
    ----------
    hole : Hole
        The raster of the final hole (all of A's holes together) at the verdict resolution, made
        from ``outline`` (:meth:`Hole.from_outline`).
    outline : manifold3d.CrossSection
        The exact hole H that gets printed; every score in ``attack`` is against it.
    trans : (m, 2) ndarray
        Each A's translation, scene units (the separate layout's places, or the search's).
    a_masks : list of (N, N) bool ndarrays
        Each A's undilated silhouette at its place on ``hole``'s frame.
    attack : Attack
        One row: per B, its best attempt over the holes, scored exactly against ``outline``.
    block_masks : list of MaskWindow
        Each B's silhouette in that attempt.
    warnings : list of str
    mirrored : list of dict
        Separate holes with ``[layout] mirrored``: one per chiral A's mirrored hole
        (:class:`~sieve_mi.game.holes.SeparateHoles`).
    """

    hole: Hole
    outline: object
    trans: np.ndarray
    a_masks: list
    attack: Attack
    block_masks: list
    warnings: list
    mirrored: list = field(default_factory=list)

    @property
    def winner(self) -> str:
        """ "A" iff the attack blocked every B (before certify and the thin-plate searches,
        which :attr:`sieve_mi.game.result.Result.winner` also counts)."""
        return "A" if bool(np.all(self.attack.blocked()[0])) else "B"


#: The exact polish is tried on poses that stick out by at most this many pixels.
REACH = 3.0
#: Player B's verdict starts leave its descent once converged
#: (:data:`sieve_mi.game.descent.CONVERGED`'s ``(window, rtol)``): every 20 steps, a start whose
#: best loss fell by less than 1e-4 of itself stops at its best pose; the exact polish and scores
#: then decide as before. None: every start runs every step.
CONVERGED = (20, 1e-4)


def _groups(count: int, separate: bool) -> list[list[int]]:
    """Which A shapes make each hole: one each (separate) or all in one."""
    return [[i] for i in range(count)] if separate else [list(range(count))]


def exact_holes(
    passes: list[Shape], quats: np.ndarray, trans: np.ndarray, groups: list[list[int]], fab
) -> list:
    """The exact outline of each hole (one per group of A), as manifold3d CrossSections.

    Raises
    ------
    SieveError
        When a hole has zero area (A seen edge-on with no tolerance): no hole, no verdict.
    """
    closed = [is_closed(p) for p in passes]
    outlines = []
    for g in groups:
        o, _ = windowed_hole(
            [passes[i] for i in g],
            quats[g],
            trans[g],
            fab.tolerance,
            math.radians(fab.window),
            fab.fill_holes,
            closed=[closed[i] for i in g],
        )
        if o.is_empty() or o.area() <= 0:
            names = ", ".join(passes[i].name for i in g)
            raise SieveError(
                f"the hole of {names} has zero area: the shape is seen edge-on and "
                "[fabrication] tolerance is 0; set a positive tolerance or another rotation"
            )
        outlines.append(o)
    return outlines


def start_centres(outlines: list, trans: np.ndarray, groups: list[list[int]]) -> np.ndarray:
    """Where each hole's verdict starts are centred: every piece of it and every A in it.

    Returns
    -------
    (H, C, 2) ndarray
        Scene units; holes with fewer than C places repeat theirs.
    """
    per_hole = []
    for o, g in zip(outlines, groups):
        places = [np.asarray(trans[i], dtype=np.float64) for i in g]
        for piece in o.decompose():
            lo, hi = np.asarray(piece.bounds()[:2]), np.asarray(piece.bounds()[2:])
            places.append((lo + hi) / 2)
        per_hole.append(np.array(places))
    c = max(len(p) for p in per_hole)
    return np.stack([np.resize(p, (c, 2)) for p in per_hole])


def _holes(passes, quats, trans, frame, groups, fab, outlines=None):
    """A's silhouettes, the exact holes (``outlines`` where given), their union H, its raster
    and the warnings about it."""
    players = [PlayerA.from_settings(p, frame, fab) for p in passes]
    a_masks = [p.silhouettes(q[None], t[None])[0] for p, q, t in zip(players, quats, trans)]
    if outlines is None:
        outlines = exact_holes(passes, np.asarray(quats), trans, groups, fab)
    outline = union(outlines)
    hole = Hole.from_outline(outline, frame)
    warnings = []
    if len(passes) > 1 and len(groups) == 1 and len(outline.decompose()) > 1:
        warnings.append("the merged hole is not connected")
    return a_masks, outlines, outline, hole, warnings


def _placed(scene: Scene, passes: list, quats, trans):
    """Where the holes lie: each A's place, the verdict's frame, the groups of A per hole, the
    exact holes (separate holes, :func:`~sieve_mi.game.holes.separate_holes`; None: made from
    the groups), where each hole's starts are centred, the mirrored holes and the
    ``[fabrication]`` table the holes are made with (one A's own tolerance)."""
    fab, res = scene.fabrication, scene.verdict.resolution
    if scene.layout.mode == "separate" and (len(passes) > 1 or scene.layout.mirrored):
        sep = separate_holes(scene, passes, quats, res)  # each A's own tolerance, its mirror
        return sep.trans, sep.frame, sep.groups, sep.outlines, sep.places, sep.mirrored, fab
    tolerance = float(hole_tolerances(scene).max())  # a single A's own, or the scene's
    if tolerance != fab.tolerance:
        fab = copy.copy(fab)
        fab.tolerance = tolerance
    reach = tolerance * (1 + GROWTH) if fab.window else tolerance  # a window's chord bound
    trans = np.zeros((1, 2)) if len(passes) == 1 else np.asarray(trans, dtype=np.float64)
    frame = frame_for(passes, reach, res, trans)
    return trans, frame, _groups(len(passes), False), None, trans, [], fab


def _no_attack(margin: bool) -> Attack:
    """An attack on no shape (one row, zero columns)."""
    out = Attack(np.ones((1, 0)), np.zeros((1, 0)), np.zeros((1, 0, 4)), np.zeros((1, 0, 2)),
                 np.zeros((1, 0), dtype=np.int64))  # fmt: skip
    if margin:
        out.margin_beta, out.margin_protrusion = np.ones((1, 0)), np.zeros((1, 0))
    return out


def judge(
    scene: Scene,
    passes: list[Shape],
    blocks: list[Shape],
    quats: np.ndarray,
    trans: np.ndarray,
    rng: np.random.Generator,
    progress: Callable[[int], None] | None = None,
    memory: AttackMemory | None = None,
) -> Judgement:
    """Attack the hole made by A at its placements and declare the winner.

    Player B's raster attack (Adam from ``[verdict] starts``, spread over every piece of the hole
    and every placed A) proposes :data:`~sieve_mi.game.exact.CANDIDATES` poses per shape and hole;
    each is polished and scored exactly against the polygon H (grown by the block margin), and
    only those exact scores decide.

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
    memory : AttackMemory, optional
        Player B's best poses from the search (merged holes); the first starts begin there.
        Ignored for separate holes, whose places the verdict chooses anew.

    Returns
    -------
    Judgement
    """
    v = scene.verdict
    trans, frame, groups, own, places, mirrored, fab = _placed(scene, passes, quats, trans)
    separate = own is not None
    a_masks, outlines, outline, hole, warnings = _holes(
        passes, quats, trans, frame, groups, fab, own
    )
    grown = [dilated(o, fab.block_margin) for o in outlines] if fab.block_margin > 0 else outlines
    if not blocks:  # every B was proved before the game (sieve_mi.game.screen)
        attack = _no_attack(fab.block_margin > 0)
        return Judgement(hole, outline, trans, a_masks, attack, [], warnings, mirrored)
    player_b = PlayerB.from_settings(blocks, frame, scene.solver, objective="clearance")
    # without a margin, one merged hole's raster is the one already built
    same = fab.block_margin == 0 and not separate
    attack = player_b.attack(
        [hole] if same else [Hole.from_outline(g, frame) for g in grown],
        Starts(
            v.starts,
            centres=start_centres(grown, places, groups),
            memory=None if separate else memory,
        ),
        v.steps,
        scene.solver.learning_rate,
        rng,
        progress=progress,
        keep=CANDIDATES,
        settle="start" if fab.fill_holes and scene.solver.settle else None,
        converged=CONVERGED,
    )
    margin = fab.block_margin > 0
    attack = exact_rescore(
        attack, blocks, union(grown), outline if margin else None, reach=REACH * frame.pixel_size
    )
    block_masks = [
        mask_window(r, hole, attack.quats[0, j], attack.trans[0, j])
        for j, r in enumerate(player_b.renderers)
    ]
    return Judgement(hole, outline, trans, a_masks, attack, block_masks, warnings, mirrored)
