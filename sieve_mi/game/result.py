"""What a solve produced: :class:`Result` (the game's outcome) and :class:`BlockAttempt` (one B's).

The game writes no files: :meth:`sieve_mi.api.Result.save` (the public ``sieve_mi.Result``) does,
through :mod:`sieve_mi.outputs`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sieve_mi.game.attack import Attack
from sieve_mi.game.scoring import MaskWindow
from sieve_mi.geometry.hole import Hole
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import is_closed, silhouette
from sieve_mi.optim import SwarmHistory
from sieve_mi.scene import Scene

__all__ = ["BlockAttempt", "Result", "block_margin", "block_margins", "is_blocked"]


def is_blocked(attack_blocked, certification=None, thin_plate=None) -> bool:
    """Whether a shape of B is blocked: the one rule every verdict, report and picture uses.

    A B is blocked when the verdict's attack on the exact printed hole left it sticking out
    (``attack_blocked``), certify found no pose that passes the exact hole, and the thin-plate
    motion search found no verified passage through the plate. Each later stage can only turn
    "blocked" into "passes", never the other way.

    Parameters
    ----------
    attack_blocked : bool
        The verdict's answer (:meth:`sieve_mi.game.attack.Attack.blocked`).
    certification : Certification, optional
        The proof attempt against the exact hole (its ``status``).
    thin_plate : ThinPlate, optional
        The motion search through a plate thinner than the B (its ``status``).

    Returns
    -------
    bool

    Examples
    --------
    >>> from types import SimpleNamespace as S
    >>> is_blocked(True), is_blocked(True, S(status="proved")), is_blocked(False)
    (True, True, False)
    >>> is_blocked(True, S(status="passage")), is_blocked(True, None, S(status="passage"))
    (False, False)
    """
    passage = any(
        x is not None and getattr(x, "status", None) == "passage"
        for x in (certification, thin_plate)
    )
    return bool(attack_blocked) and not passage


def block_margin(shape, hole, found: float, certified=None, grown: float = 0.0) -> dict:
    """How far a blocked B sticks out of H at best, bracketed (:attr:`BlockAttempt.margin`,
    report.json's ``margin``).

    ``found_at_most``: the protrusion of the best pose found (the true margin is at most this).
    ``proved_at_least``: from a certification that proved the block (``certified``, a
    :class:`~sieve_mi.certify.Certification` against H grown by ``grown``, the scene's
    ``block_margin``), ``grown`` plus its margin bisection's m
    (:func:`sieve_mi.certify.blocks.prove_margin`, whose steps try the ball test first); without
    one, from a ball certified inside B, the largest m for which no disk of its radius fits H
    grown by m (:func:`sieve_mi.certify.blocks.margin_by_ball`). None when nothing proves it.
    """
    from sieve_mi.certify.blocks import margin_by_ball
    from sieve_mi.certify.bounds import inscribed_ball

    if certified is not None and certified.status == "proved":
        proved = grown + (certified.margin or 0.0)
    else:
        ball = inscribed_ball(shape)
        proved = (margin_by_ball(ball[1], hole, found) if ball is not None else 0.0) or None
    return {"proved_at_least": proved, "found_at_most": float(found)}


def block_margins(shapes, hole, attack: Attack, certified: list, grown: float) -> list:
    """Per shape of B, its :func:`block_margin` where it is blocked straight through the exact
    hole ``hole`` (the verdict's attack and its certification, :func:`is_blocked`), else None.
    The solver computes them once (:attr:`Result.margins`)."""
    blocked = attack.blocked()[0]
    out = []
    for j, shape in enumerate(shapes):
        c = certified[j] if j < len(certified) else None
        found = float(attack.protrusion[0, j])
        out.append(
            block_margin(shape, hole, found, c, grown) if is_blocked(blocked[j], c) else None
        )
    return out


@dataclass
class BlockAttempt:
    """One shape of B in the verdict: its best attempt against the exact hole, its proof and
    its thin-plate answer, and whether it is blocked after all (:func:`is_blocked`).

    Attributes
    ----------
    name : str
    blocked : bool
    beta : float
        area(S \\ H) / area(S) of its best pose (0: it fits).
    protrusion : float
        Largest distance by which that pose sticks out of H, scene units.
    rotation : (4,) ndarray
        (w, x, y, z).
    translation : (2,) ndarray
        Scene units, in the hole's frame.
    certification : Certification or None
        certify's answer against the exact hole (``[verdict] certify``).
    thin_plate : ThinPlate or None
        The motion search through a plate thinner than the shape, where one ran.
    margin : dict or None
        Where it is blocked straight through the exact hole: how far it sticks out of H at best,
        bracketed (:func:`block_margin`); None otherwise.
    overhang : Overhang or None
        Where it has a ``margin``: the least overhang found over poses (exact polygon) and the
        proved lower bound, in a maker's words (:mod:`sieve_mi.game.overhang`); None otherwise.
    """

    name: str
    blocked: bool
    beta: float
    protrusion: float
    rotation: np.ndarray
    translation: np.ndarray
    certification: object = None
    thin_plate: object = None
    margin: dict | None = None
    overhang: object = None


@dataclass
class Result:
    """What a solve produced.

    Attributes
    ----------
    scene : Scene
    pass_shapes, block_shapes : list of Shape
    pass_quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z).
    pass_trans : (m, 2) ndarray
        Each A's translation in the hole's frame, scene units (the first is at the origin).
    hole : Hole
        The verdict's hole raster (at the verdict resolution), made from ``outline``.
    outline : manifold3d.CrossSection
        The exact hole H that is printed and that decided the verdict (scene units).
    a_masks : list of (N, N) bool ndarrays
        Each A's undilated silhouette at its placement, on the hole's frame.
    attack : Attack
        Player B's best attempts in the verdict (one row: per shape, its best hole).
    block_masks : list of MaskWindow
        Each B's silhouette in its best attempt, on a window of the hole's pixel lattice.
    history : SwarmHistory
        Best search value per iteration (all stages of a many-A search, one after another).
    search_value : float
        The game value of the chosen placement during the search (NaN when A was fixed).
    variant : str
        The Mitsuba variant that ran.
    stages : list of (str, int)
        Label and number of iterations of each search stage.
    warnings : list of str
        What the user should know about the result (e.g. a merged hole in several pieces).
    timings : dict
        Seconds per stage.
    alone : list of float or None
        Per pass shape: its own search's value (the weakest B's loss against that shape's hole
        alone, short attack), or None where its rotation was fixed in the scene.
    seed : int
        The seed the run used.
    polish : list of dict
        Per searched A, the local polish of its rotation (see :class:`SearchOutcome`).
    started : float or None
        ``time.perf_counter()`` when the solve started.
    certified : list of Certification or None
        With ``[verdict] certify``: per B, the proof attempt against the exact hole (None where
        the verdict let it through); empty otherwise.
    """

    scene: Scene
    pass_shapes: list[Shape]
    block_shapes: list[Shape]
    pass_quats: np.ndarray
    pass_trans: np.ndarray
    hole: Hole
    a_masks: list
    attack: Attack
    block_masks: list[MaskWindow]
    history: SwarmHistory
    search_value: float
    variant: str
    stages: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    alone: list = field(default_factory=list)
    #: The seed the run used (``[solver] seed`` or the ``seed`` argument that overrode it).
    seed: int | None = None
    certified: list = field(default_factory=list)
    #: The plate's thickness and each B's thin-plate answer (:class:`sieve_mi.game.sheet.Sheet`).
    sheet: object = None
    outline: object = None
    polish: list = field(default_factory=list)
    #: ``time.perf_counter()`` when the solve started (report.json's ``total_s`` counts from it).
    started: float | None = None
    #: Per B, its :func:`block_margin` or None (:func:`block_margins`, computed once by the
    #: solver); empty when none were computed.
    margins: list = field(default_factory=list)
    #: Per B, its :class:`sieve_mi.game.overhang.Overhang` or None
    #: (:func:`sieve_mi.game.overhang.block_overhangs`); empty when none were computed.
    overhangs: list = field(default_factory=list)
    #: Peak resident memory per stage (:class:`sieve_mi.backend.MemoryWatch`), or None.
    memory: object = None
    #: The turning window (report.json's ``fabrication.window``, :mod:`sieve_mi.game.window`),
    #: or None without one.
    window: dict | None = None
    #: The feasibility test before the search (:class:`sieve_mi.game.feasible.Feasibility`), or
    #: None where none ran.
    feasibility: object = None
    #: Per A, its pass pose's nearest resting pose (:func:`sieve_mi.game.rest.nearest_rest`, with
    #: ``preferred``), None for a flat part; empty without ``[solver] rest_poses``.
    rest: list = field(default_factory=list)
    #: Separate holes with ``[layout] mirrored``: each chiral A's mirrored hole (``of``, ``name``,
    #: ``translation``; :class:`sieve_mi.game.holes.SeparateHoles`).
    mirrored: list = field(default_factory=list)
    #: With ``[solver] retries``, per search of A (the first included): its seed, the B that
    #: passed its hole in the verdict, the least β and whether it was kept
    #: (:func:`sieve_mi.game.retry.with_retries`); empty when the first search won.
    retries: list = field(default_factory=list)
    #: :meth:`overlay_sections`' polygons, made on first use (a 500k-face B's projection takes
    #: minutes; the images and the page both draw it).
    _sections: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def blocks(self) -> list[BlockAttempt]:
        """Per shape of B, its record: the verdict's best attempt (exact β and protrusion), its
        certification and thin-plate answer, and whether it is blocked (:func:`is_blocked`)."""
        blocked = self.attack.blocked()[0]
        out = []
        for j, shape in enumerate(self.block_shapes):
            c = self.certified[j] if j < len(self.certified) else None
            thin = self.sheet.per_block[j] if self.sheet is not None else None
            out.append(
                BlockAttempt(
                    name=shape.name,
                    blocked=is_blocked(blocked[j], c, thin),
                    beta=float(self.attack.beta[0, j]),
                    protrusion=float(self.attack.protrusion[0, j]),
                    rotation=self.attack.quats[0, j].copy(),
                    translation=self.attack.trans[0, j].copy(),
                    certification=c,
                    thin_plate=thin,
                    margin=self.margins[j] if j < len(self.margins) else None,
                    overhang=self.overhangs[j] if j < len(self.overhangs) else None,
                )
            )
        return out

    @property
    def winner(self) -> str:
        """ "A" iff every shape of B is blocked after the verdict, certify and the thin-plate
        searches (:func:`is_blocked`), else "B"."""
        return "A" if all(b.blocked for b in self.blocks) else "B"

    def overlay_sections(self) -> tuple:
        """The exact polygons of a picture of the result, scene units.

        Returns
        -------
        hole : manifold3d.CrossSection
            H, as printed.
        a : list of manifold3d.CrossSection
            Each A's projection at its placement (undilated).
        b : list of manifold3d.CrossSection
            Each B's projection in its best attempt.
        """
        if self._sections is None:
            a = [
                silhouette(s, q, t, is_closed(s))
                for s, q, t in zip(self.pass_shapes, self.pass_quats, self.pass_trans)
            ]
            b = [
                silhouette(s, self.attack.quats[0, j], self.attack.trans[0, j], is_closed(s))
                for j, s in enumerate(self.block_shapes)
            ]
            self._sections = (a, b)
        return self.outline, *self._sections

    @property
    def a_mask(self) -> np.ndarray:
        """All A silhouettes together, (N, N) bool."""
        return np.logical_or.reduce(self.a_masks)
