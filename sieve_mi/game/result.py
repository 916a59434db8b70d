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

__all__ = ["BlockAttempt", "Result"]


@dataclass
class BlockAttempt:
    """One shape of B in the verdict: its best attempt against the exact hole.

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
    """

    name: str
    blocked: bool
    beta: float
    protrusion: float
    rotation: np.ndarray
    translation: np.ndarray


@dataclass
class Result:
    """What a solve produced.

    Attributes
    ----------
    scene : Scene
    winner : {"A", "B"}
        "A" iff every shape to block is blocked after the verdict.
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
        Per searched A, the local polish of its rotation (see :class:`Search`).
    started : float or None
        ``time.perf_counter()`` when the solve started.
    certified : list of Certification or None
        With ``[verdict] certify``: per B, the proof attempt against the exact hole (None where
        the verdict let it through); empty otherwise.
    """

    scene: Scene
    winner: str
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
    #: Peak resident memory per stage (:class:`sieve_mi.backend.MemoryWatch`), or None.
    memory: object = None
    #: :meth:`overlay_sections`' polygons, made on first use (a 500k-face B's projection takes
    #: minutes; the images and the page both draw it).
    _sections: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def blocks(self) -> list[BlockAttempt]:
        """Per shape of B, its best attempt in the verdict (exact β and protrusion)."""
        blocked = self.attack.blocked()[0]
        out = []
        for j, shape in enumerate(self.block_shapes):
            c = self.certified[j] if j < len(self.certified) else None
            thin = self.sheet.per_block[j] if self.sheet is not None else None
            passage = (c is not None and c.status == "passage") or (
                thin is not None and thin.status == "passage"
            )
            out.append(
                BlockAttempt(
                    name=shape.name,
                    blocked=bool(blocked[j]) and not passage,
                    beta=float(self.attack.beta[0, j]),
                    protrusion=float(self.attack.protrusion[0, j]),
                    rotation=self.attack.quats[0, j].copy(),
                    translation=self.attack.trans[0, j].copy(),
                )
            )
        return out

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
