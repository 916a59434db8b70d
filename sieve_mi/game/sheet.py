"""The plate's thickness and the verdict on it: safe by diameter, or a thin-plate motion search per B.

The game's verdict holds for a plate at least as thick as every B's diameter (the default
thickness). For a thinner plate (``[fabrication] thickness``), each blocked B whose diameter
exceeds it gets a motion search (:mod:`sieve_mi.motion`); a verified passage overrules "blocked".
``thickness = "thinnest"`` bisects between the safe thickness and zero for the thinnest plate on
which no B was found to pass (a heuristic answer: only the safe thickness is proved).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.plate import safe_thickness
from sieve_mi.motion import thin_plates
from sieve_mi.scene import Scene

__all__ = ["Sheet", "plate_sheet"]

#: Bisection steps of ``thickness = "thinnest"`` (the bracket shrinks 2^-steps of the safe value).
THINNEST_STEPS = 6


@dataclass
class Sheet:
    """The plate's thickness and each B's thin-plate answer.

    Attributes
    ----------
    thickness : float
        The thickness the plate files are written at, scene units.
    safe : float
        The thinnest plate on which the game's verdict is proved: the largest diameter of a B
        (rounded up to 0.1 scene units).
    mode : {"safe", "given", "thinnest"}
        Where ``thickness`` came from.
    per_block : list of ThinPlate or None
        Per B at ``thickness``: None where the verdict already lets it through.
    bisection : list of dict
        ``"thinnest"``: each thickness tried and whether some B passed.
    """

    thickness: float
    safe: float
    mode: str
    per_block: list = field(default_factory=list)
    bisection: list = field(default_factory=list)

    @property
    def proved(self) -> bool:
        """Whether every block on this plate is proved by the diameter argument."""
        return self.thickness >= self.safe

    def passages(self) -> list[int]:
        """The B that pass this plate by a verified motion."""
        return [j for j, t in enumerate(self.per_block) if t is not None and t.status == "passage"]

    def to_dict(self) -> dict:
        """report.json's ``fabrication.sheet``."""
        out = {"thickness": self.thickness, "safe_thickness": self.safe, "mode": self.mode}
        out["proved"] = self.proved
        if self.bisection:
            out["bisection"] = self.bisection
        return out


def _say(progress: bool, line: str) -> None:
    if progress:
        print(line, file=sys.stderr, flush=True)


def _search(scene: Scene, blocks, todo, outline, attack, thickness: float, seed: int):
    """ThinPlate per B in ``todo`` (None elsewhere), searched in parallel."""
    out: list = [None] * len(blocks)
    seeds = [[(attack.quats[0, j], attack.trans[0, j])] for j in todo]
    found = thin_plates([blocks[j] for j in todo], outline, thickness,
                        budget_s=scene.verdict.thin_budget, seeds=seeds, seed=seed)  # fmt: skip
    for j, t in zip(todo, found):
        out[j] = t
    return out


def _thinnest(scene, blocks, todo, outline, attack, safe: float, seed: int, progress: bool):
    """Bisect (0, safe] for the thinnest plate where no B of ``todo`` was found to pass."""
    lo, hi, best, steps = 0.0, safe, None, []
    for _ in range(THINNEST_STEPS):
        mid = round(0.5 * (lo + hi), 3)
        if not lo < mid < hi:
            break
        _say(progress, f"thinnest plate: trying {mid:g} (passage found at {lo:g}, none at {hi:g})")
        per = _search(scene, blocks, todo, outline, attack, mid, seed)
        passed = [blocks[j].name for j in todo if per[j].status == "passage"]
        steps.append({"thickness": mid, "passage": passed})
        if passed:
            lo = mid
        else:
            hi, best = mid, per
    return hi, best, steps


def plate_sheet(
    scene: Scene,
    passes: list[Shape],
    blocks: list[Shape],
    outline,
    attack,
    blocked: np.ndarray,
    *,
    seed: int = 0,
    progress: bool = False,
) -> Sheet:
    """The plate's thickness and, below the safe value, each blocked B's motion search.

    Parameters
    ----------
    scene : Scene
        ``[fabrication] thickness`` and ``[verdict] thin_budget`` are used.
    passes, blocks : list of Shape
        The safe thickness is the largest diameter of a B (of an A when there is no B).
    outline : manifold3d.CrossSection
        The exact hole H.
    attack : Attack
        The verdict's attack; each B's best attempt seeds its search.
    blocked : (n,) bool
        Which B the verdict (and certification) blocked; only those are searched.
    seed : int
    progress : bool
        Print a line per search round on stderr.

    Returns
    -------
    Sheet
    """
    given = scene.fabrication.thickness
    safe = safe_thickness([b.hull for b in (blocks or passes)])
    todo = [j for j in range(len(blocks)) if blocked[j]]
    if given == "thinnest" and todo:
        thickness, per, steps = _thinnest(
            scene, blocks, todo, outline, attack, safe, seed, progress
        )
        per = per or _search(scene, blocks, todo, outline, attack, safe, seed)
        return Sheet(thickness, safe, "thinnest", per, steps)
    thickness = safe if given in (None, "thinnest") else float(given)
    if thickness < safe and todo:
        _say(progress, f"thin plate {thickness:g}: motion search for {len(todo)} B, "
                       f"up to {scene.verdict.thin_budget:g} s each")  # fmt: skip
    per = _search(scene, blocks, todo, outline, attack, thickness, seed)
    return Sheet(thickness, safe, "safe" if given in (None, "thinnest") else "given", per)
