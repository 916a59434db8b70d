"""The plate's thickness and the verdict on it: safe by a proof, or a thin-plate motion search per B.

The default thickness is the thinnest *proved* plate (:func:`proved_thickness`): for each blocked
B, none where a ball proves it (any plate), the thinnest plate its slab-section proof covers
(bisected by certify, :func:`sieve_mi.certify.thinnest_proved`), else its diameter (the
thick-plate argument); the largest of these, and at least ``[fabrication] min_thickness``. For a thinner plate (``[fabrication]
thickness``), each blocked B not proved there gets a motion search (:mod:`sieve_mi.motion`); a
verified passage overrules "blocked". ``thickness = "thinnest"`` bisects between the proved
thickness and zero for the thinnest plate on which no B was found to pass (a heuristic answer:
only the proved thickness is proved).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from sieve_mi.geometry.meshes import Shape, bodies
from sieve_mi.geometry.plate import safe_thickness
from sieve_mi.motion import each_thin_plate
from sieve_mi.motion.thin import SAFE_ARGUMENT
from sieve_mi.progress import Progress
from sieve_mi.scene import Scene

__all__ = [
    "Sheet",
    "not_covered",
    "passage_bracket",
    "plate_sheet",
    "proof_thickness",
    "proved_thickness",
]

#: Bisection steps of ``thickness = "thinnest"`` (the bracket shrinks 2^-steps of the safe value).
THINNEST_STEPS = 6

#: Most motion searches per B for the passage side of its proof bracket (:func:`passage_bracket`).
BRACKET_TRIES = 3


@dataclass
class Sheet:
    """The plate's thickness and each B's thin-plate answer.

    Attributes
    ----------
    thickness : float
        The thickness the plate files are written at, scene units.
    safe : float
        The thinnest plate on which the game's verdict is proved (:func:`proved_thickness`).
    mode : {"safe", "given", "thinnest"}
        Where ``thickness`` came from.
    per_block : list of ThinPlate or None
        Per B at ``thickness``: None where the verdict already lets it through.
    bisection : list of dict
        ``"thinnest"``: each thickness tried and whether some B passed.
    bracket : list of dict
        Per blocked B whose slab-section proofs stopped above the printable minimum: ``name``,
        ``proved`` (its thinnest proved plate), ``unproved`` (the thickest tried without a
        proof), ``passage`` (the thickest plate tried where a verified motion passes, or None)
        and ``no_passage_found`` (the plates tried where the motion search found none, a
        heuristic answer) (:func:`passage_bracket`).
    """

    thickness: float
    safe: float
    mode: str
    per_block: list = field(default_factory=list)
    bisection: list = field(default_factory=list)
    bracket: list = field(default_factory=list)

    @property
    def proved(self) -> bool:
        """Whether every block on this plate is proved (a ball, a section or its diameter)."""
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
        if self.bracket:
            out["bracket"] = self.bracket
        return out


def _say(progress: bool, line: str) -> None:
    if progress:
        print(line, file=sys.stderr, flush=True)


def proof_thickness(shape: Shape, proof) -> float:
    """The thinnest plate on which one blocked B is proved, scene units: 0 for a ball proof (any
    plate), the thickness of its slab-section proof, else its diameter (rounded up to 0.1).

    Parameters
    ----------
    shape : Shape
    proof : Certification or None
        Its certification (None: not certified).
    """
    if proof is not None and proof.method == "ball" and proof.status == "proved":
        return 0.0
    if proof is not None and proof.proved_section is not None:
        return float(proof.proved_section["thickness"])
    return safe_thickness([shape.hull])


def proved_thickness(blocks: list, blocked, certified: list) -> float:
    """The thinnest plate on which every blocked B is proved: the largest of
    :func:`proof_thickness` over them (0 when none is blocked or all by balls), scene units."""
    proofs = certified or [None] * len(blocks)
    need = [proof_thickness(b, c) for b, c, on in zip(blocks, proofs, blocked) if on]
    return max([0.0] + need)


class _Searches(NamedTuple):
    """What every thin-plate search of one plate shares: the scene, the B, which of them are
    searched (``todo``), the hole, the verdict's attack (its poses seed the searches), the seed,
    per B its proved section or None (:func:`_sections`), and whether to show progress."""

    scene: Scene
    blocks: list
    todo: list
    outline: object
    attack: object
    seed: int
    sections: list
    progress: bool = False

    def at(self, thickness: float, search: bool = True) -> list:
        """ThinPlate per B in ``todo`` (None elsewhere) at ``thickness``, searched in parallel;
        with ``progress`` and a ``search`` (a plate thinner than the proved one: on that one every
        B is safe at once), a line per B as its answer comes, with the time left."""
        out: list = [None] * len(self.blocks)
        sections = [self.sections[j] for j in self.todo]
        for j, t in self._run(self.todo, thickness, sections, search).items():
            out[j] = t
        return out

    def at_each(self, tries: dict) -> dict:
        """ThinPlate per B index of ``tries`` at its own thickness (no section proof first)."""
        js = sorted(tries)
        return self._run(js, [tries[j] for j in js], [None] * len(js), True)

    def _run(self, js: list, thickness, sections: list, show: bool) -> dict:
        """The searches of the B ``js`` (:func:`sieve_mi.motion.each_thin_plate`): index ->
        ThinPlate, with a progress line per B as its answer comes (``progress`` and ``show``)."""
        seeds = [[(self.attack.quats[0, j], self.attack.trans[0, j])] for j in js]
        bar = Progress(self.progress and show and bool(js), len(js), "thin plate", unit="B",
                       done_line=False, every=math.inf)  # fmt: skip
        found = each_thin_plate([self.blocks[j] for j in js], self.outline, thickness,
                                budget_s=self.scene.verdict.thin_budget, seeds=seeds,
                                seed=self.seed, sections=sections)  # fmt: skip
        out = {}
        for k, t in found:
            out[js[k]] = t
            bar.update(1)
            left = bar.left()
            bar.write(f"thin plate {t.thickness:g}: {t.name}: {_answer(t)}"
                      + (f"; {left}" if left else ""))  # fmt: skip
        bar.close()
        return out


def _answer(t) -> str:
    """A thin-plate answer in a progress line: ``safe (ball)``, ``passage (4.1 s)``,
    ``no passage found (10.0 s)``."""
    if t.status == "safe":
        return f"safe ({t.to_dict().get('by', 'diameter')})"
    return f"{t.status} ({t.seconds:.1f} s)"


def _thinnest(searches: _Searches, safe: float, progress: bool, low: float = 0.0):
    """Bisect (low, safe] for the thinnest plate where no B of ``todo`` was found to pass
    (``low``: ``[fabrication] min_thickness``, the thinnest printable sheet)."""
    lo, hi, best, steps = min(low, safe), safe, None, []
    for _ in range(THINNEST_STEPS):
        mid = round(0.5 * (lo + hi), 3)
        if not lo < mid < hi:
            break
        _say(progress, f"thinnest plate: trying {mid:g} (passage found at {lo:g}, none at {hi:g})")
        per = searches.at(mid)
        passed = [searches.blocks[j].name for j in searches.todo if per[j].status == "passage"]
        steps.append({"thickness": mid, "passage": passed})
        if passed:
            lo = mid
        else:
            hi, best = mid, per
    return hi, best, steps


def plate_sheet(
    scene: Scene,
    blocks: list[Shape],
    outline,
    attack,
    blocked: np.ndarray,
    *,
    certified: list | None = None,
    seed: int = 0,
    progress: bool = False,
) -> Sheet:
    """The plate's thickness and, below the safe value, each blocked B's motion search.

    Parameters
    ----------
    scene : Scene
        ``[fabrication] thickness`` and ``min_thickness``, ``[verdict] thin_budget`` are used.
    blocks : list of Shape
        The proved thickness is :func:`proved_thickness` of the blocked B.
    outline : manifold3d.CrossSection
        The exact hole H.
    attack : Attack
        The verdict's attack; each B's best attempt seeds its search.
    blocked : (n,) bool
        Which B the verdict (and certification) blocked; only those are searched.
    certified : list of Certification or None, optional
        Per B, its certification (ball and section proofs make the proved plate thinner).
    seed : int
    progress : bool
        Print a line per search round on stderr, and one per B as its answer comes (with the
        time left).

    Returns
    -------
    Sheet
    """
    given, low = scene.fabrication.thickness, scene.fabrication.min_thickness
    safe = proved_thickness(blocks, blocked, certified or [])
    todo = [j for j in range(len(blocks)) if blocked[j]]
    searches = _Searches(scene, blocks, todo, outline, attack, seed,
                         _sections(certified, len(blocks)), progress)  # fmt: skip
    if given == "thinnest" and todo:
        thickness, per, steps = _thinnest(searches, max(low, safe), progress, low)
        per = not_covered(
            scene, blocks, per or searches.at(max(low, safe), search=False), certified
        )
        return Sheet(thickness, safe, "thinnest", per, steps)
    thickness = max(low, safe) if given in (None, "thinnest") else float(given)
    if thickness < safe and todo:
        _say(progress, f"thin plate {thickness:g}: motion search for {len(todo)} B, "
                       f"up to {scene.verdict.thin_budget:g} s each")  # fmt: skip
    per = not_covered(scene, blocks, searches.at(thickness, search=thickness < safe), certified)
    if given is not None:
        return Sheet(thickness, safe, "given", per)
    return Sheet(
        thickness, safe, "safe", per, bracket=passage_bracket(searches, certified, low, progress)
    )


def not_covered(scene: Scene, blocks: list, per: list, certified: list | None) -> list:
    """``per`` with "safe by its diameter" made "not covered" for each B of several bodies on a
    perforated sheet (``[fabrication] pattern``) whose straight proof (against the copies within
    its reach, :func:`sieve_mi.certify.blocks.sheet_holes`), or a proved slab section (against
    the copies within its diameter, which also excludes straight passage), is missing: the
    diameter argument rests on the straight verdict, and that is against one hole, which such a
    B's bodies need not share (docs/fabrication.md, "A perforated sheet")."""
    if scene.fabrication.pattern == "single":
        return per
    proofs = certified or [None] * len(blocks)
    out = list(per)
    for j, t in enumerate(per):
        c = proofs[j]
        proved = c is not None and (c.straight == "proved" or c.proved_section is not None)
        if t is None or t.status != "safe" or t.argument != SAFE_ARGUMENT or proved:
            continue
        if bodies(blocks[j]) > 1:
            out[j] = replace(t, status="not covered", note=(
                f"{blocks[j].name} has {bodies(blocks[j])} separate bodies and no proof against "
                "the sheet's holes within its reach: its verdict is against one hole"))  # fmt: skip
    return out


def _gaps(searches: _Searches, certified: list | None, low: float) -> dict:
    """Per blocked B (index) whose section proofs stopped above ``low``: its bracket entry."""
    out = {}
    for j in searches.todo:
        c = (certified or [None] * len(searches.blocks))[j]
        bracket = None if c is None or c.section is None else c.section.get("bracket")
        if bracket and bracket.get("unproved") is not None and bracket["unproved"] > low:
            proved = proof_thickness(searches.blocks[j], c)
            out[j] = {"name": searches.blocks[j].name, "proved": proved,
                      "unproved": bracket["unproved"], "passage": None,
                      "no_passage_found": []}  # fmt: skip
    return out


def passage_bracket(searches: _Searches, certified: list | None, low: float,
                    progress: bool = False) -> list:  # fmt: skip
    """The other side of each B's proof bracket: the thickest plate where a verified motion
    passes, searched below the thickest plate its section proofs left unproved.

    Per B, motion searches (``[verdict] thin_budget`` each, in parallel over B) at its
    ``unproved`` thickness, then at ``low``, then halfway between when ``low`` passes and the
    other did not: at most :data:`BRACKET_TRIES`. A passage is a verified motion (a fact); "no
    passage found" is a heuristic answer.

    Returns
    -------
    list of dict
        :attr:`Sheet.bracket`.
    """
    gaps = _gaps(searches, certified, low)
    if gaps:
        _say(progress, f"proof bracket: motion searches below the proved plate for {len(gaps)} B, "
                       f"up to {BRACKET_TRIES} x {searches.scene.verdict.thin_budget:g} s")  # fmt: skip
    plan = {j: [g["unproved"], low] for j, g in gaps.items()}
    for _ in range(BRACKET_TRIES):
        active = [j for j in plan if plan[j]]
        if not active:
            break
        tries = {j: round(plan[j].pop(0), 4) for j in active}
        found = searches.at_each(tries)
        for j, t in tries.items():
            g = gaps[j]
            if found[j].status == "passage":
                g["passage"], plan[j] = t, _between(t, g, plan[j])
            else:
                g["no_passage_found"].append(t)
                plan[j] = [] if g["passage"] is None and t == low else plan[j]
    return [gaps[j] for j in sorted(gaps)]


def _between(t: float, gap: dict, left: list) -> list:
    """After a passage at ``t``: halfway up to the thinnest plate without one, if any is left."""
    above = [x for x in gap["no_passage_found"] if x > t]
    return [0.5 * (t + min(above))] if above and not left else []


def _sections(certified: list | None, n: int) -> list:
    """Per B, its proved section (the certification's ``section`` entry) or None."""
    out = [None] * n
    for j, c in enumerate(certified or []):
        out[j] = None if c is None else c.proved_section
    return out
