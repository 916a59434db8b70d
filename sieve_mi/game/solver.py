"""The whole game for one scene: player A's search, then the verdict (:mod:`sieve_mi.game.verdict`).

:func:`search` chooses every A's rotation (each alone against all of B, Secs. 5.1-5.2) and, for
several A in one hole, their placements (:func:`sieve_mi.game.layout.merge`, Sec. 5.3); the verdict
re-runs player B for longer against the chosen hole and declares the winner.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.certify.blocks import on_sheet
from sieve_mi.errors import SieveError
from sieve_mi.game.attack import AttackMemory
from sieve_mi.game.feasible import feasibility, with_certificates
from sieve_mi.game.frames import hole_frame, union_frame
from sieve_mi.game.holes import hole_tolerances
from sieve_mi.game.layout import alternative_rotations, merge
from sieve_mi.game.overhang import block_overhangs
from sieve_mi.game.placement import PlacementContext
from sieve_mi.game.player_a import PlayerA
from sieve_mi.game.player_b import PlayerB
from sieve_mi.game.rest import likely_rests, prefer, rest_records
from sieve_mi.game.result import Result, block_margins, is_blocked
from sieve_mi.game.retry import Attempt, applies, with_retries
from sieve_mi.game.scoring import mask_window
from sieve_mi.game.screen import prove_proved, proved_by_size, with_proved
from sieve_mi.game.sheet import plate_sheet
from sieve_mi.game.tolerance import at_tolerance
from sieve_mi.game.verdict import CONVERGED, judge
from sieve_mi.game.window import at_window, widest_window, window_record
from sieve_mi.geometry.meshes import Shape, load_shape, shape_from_trimesh
from sieve_mi.geometry.outline import dilated
from sieve_mi.geometry.rotations import normalize
from sieve_mi.geometry.silhouettes import SilhouetteRenderer
from sieve_mi.geometry.stand_in import AUTO_FACES, stand_ins, tolerance
from sieve_mi.optim import SwarmHistory
from sieve_mi.progress import Progress
from sieve_mi.scene import Scene
from sieve_mi.telemetry import Run

__all__ = ["SearchOutcome", "load_shapes", "search", "solve"]


@dataclass
class SearchOutcome:
    """Player A's choice, as :func:`search` made it.

    Attributes
    ----------
    quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z).
    trans : (m, 2) ndarray
        Each A's translation, scene units (zeros unless merged).
    value : float
        The game value of the last stage (NaN when every A was fixed).
    history : SwarmHistory
    stages : list of (str, int)
    alone : list of float or None
        Each A's own search value (None where fixed).
    memory : AttackMemory or None
        Player B's best poses remembered by the many-A placement (None otherwise).
    polish : list of dict
        Per searched A, the local polish's record (shape, before, after, moved degrees, rounds).
    alternatives : dict of int to list of (4,) ndarray
        Per searched A, other good rotations from its own search.
    merged_blocks : bool
        For a merged hole: every placement blocked all of B (else ``[layout] restarts`` apply).
    feasibility : Feasibility or None
        The feasibility test before the search (:mod:`sieve_mi.game.feasible`): its impossible B
        were left out of the search and the verdict's attack.
    rest_choice : dict of int to dict
        Per searched A, with ``[solver] rest_poses``: the record of
        :func:`sieve_mi.game.rest.prefer` (search's rotation or a rest pose, and why).
    retries : list of dict
        With ``[solver] retries``, per attempt: :func:`sieve_mi.game.retry.with_retries`' records
        (empty when the first search's hole won).
    """

    quats: np.ndarray
    trans: np.ndarray
    value: float
    history: SwarmHistory
    stages: list
    alone: list
    memory: AttackMemory | None = None
    polish: list = field(default_factory=list)
    alternatives: dict = field(default_factory=dict)
    merged_blocks: bool = True
    feasibility: object = None
    rest_choice: dict = field(default_factory=dict)
    retries: list = field(default_factory=list)


def load_shapes(scene: Scene) -> tuple[list[Shape], list[Shape]]:
    """Read every mesh of the scene (raises SieveError on the first bad one)."""

    def load(e, key: str):
        try:
            if e.data is not None:  # a scene built in code (Scene.from_meshes)
                return shape_from_trimesh(e.data, name=e.name, scale=e.scale)
            return load_shape(scene.resolve(e.mesh), scale=e.scale, name=e.name)
        except SieveError as exc:  # name the scene file and its key too
            raise SieveError(f"{scene.path}: {key}.mesh: {exc}") from None

    passes = [load(e, f"pass[{i}]") for i, e in enumerate(scene.passes)]
    blocks = [load(e, f"block[{j}]") for j, e in enumerate(scene.blocks)]
    return passes, blocks


def _search_one(a: Shape, blocks: list[Shape], scene: Scene, rng, seed, bar: Progress, label: str):
    """Player A's rotation for one shape alone against all of B (Secs. 5.1, 5.2): (rotation,
    game value, SwarmHistory, the record of :func:`sieve_mi.game.rest.prefer` with ``[solver]
    rest_poses``, else None)."""
    s, fab = scene.solver, scene.fabrication
    frame = hole_frame(a, fab.tolerance, s.resolution)
    player_a = PlayerA.from_settings(a, frame, fab, s)
    player_b = PlayerB.from_settings(blocks, frame, s)
    player_a.on_step = bar.update  # each candidate's Adam steps: the bar moves within a stage
    rests, rest_quats = likely_rests(a) if s.rest_poses else (None, np.zeros((0, 4)))

    def report(it, best):
        step = "swarm" if s.outer == "pso" else s.outer
        bar.update(0, best=f"{best:.4f}", stage=f"{label}: {step}")

    q, f, h = player_a.search(
        player_b,
        s,
        rng=rng,
        seed=seed,
        progress=report,
        stage=lambda name: bar.update(0, stage=f"{label}: {name}"),
        extra=rest_quats,
    )
    if rests is None:
        return q, f, h, None
    bar.update(0, stage=f"{label}: rest poses")
    player_a.on_step = None  # the rest poses' check is not in the bar's plan

    def verify(quat):  # an attack as strong as the verdict's, on the rest pose's hole
        got = player_a.values(player_b, quat[None], scene.verdict.starts, scene.verdict.steps,
                              s.learning_rate, np.random.default_rng([seed, 0x8E57]))  # fmt: skip
        return float(got[0])

    q, f, choice = prefer(rests, (q, f), rest_quats, np.asarray(h.extra), verify)
    return q, f, h, choice


def search(
    scene: Scene, passes: list[Shape], blocks: list[Shape], rng, seed: int, progress: bool
) -> SearchOutcome:
    """Player A's placements: rotations (and translations for several shapes) of every A.

    Parameters
    ----------
    scene : Scene
    passes, blocks : list of Shape
        A and B.
    rng : numpy.random.Generator
    seed : int
        Seed for nlopt's own generator.
    progress : bool
        Show a progress bar on stderr: over player B's Adam steps on every candidate hole
        (canonical views and swarm particles, each x ``[solver] steps``), with the time left.

    Returns
    -------
    SearchOutcome
    """
    s, lay = scene.solver, scene.layout
    m = len(passes)
    fixed = [e.rotation for e in scene.passes]
    merged = m > 1 and lay.mode == "merged"
    per_stage = (s.canonical + s.particles * (s.iterations + 1)) * s.steps  # candidate-steps
    stages_planned = sum(q is None for q in fixed) + (m - 1 if merged else 0)
    planned = per_stage * stages_planned
    if s.rest_poses:  # each searched A's likely rest poses join its canonical views
        planned += s.steps * sum(
            len(likely_rests(p)[1]) for p, q in zip(passes, fixed) if q is None
        )
    bar = Progress(progress, planned, "search", unit="step", grow_by=per_stage)
    out = _rotate_each(scene, passes, blocks, rng, seed, bar)
    if merged:
        _merge_with_restarts(scene, passes, blocks, out, rng, seed, bar)
    bar.close()
    return out


def _search_pixel(scene: Scene, passes: list[Shape]) -> float:
    """The smallest pixel (scene units) of the rasters the search plays on: each A's own frame
    and, for a merged hole, the frame of their union (what ``[solver] stand_in = "auto"`` is
    measured in)."""
    fab, res = scene.fabrication, scene.solver.resolution
    pixels = [hole_frame(p, fab.tolerance, res).pixel_size for p in passes]
    if len(passes) > 1 and scene.layout.mode == "merged":
        pixels.append(union_frame([p.radius for p in passes], fab.tolerance, res).pixel_size)
    return min(pixels)


def _merge_with_restarts(
    scene: Scene, passes, blocks, out: SearchOutcome, rng, seed: int, bar
) -> None:
    """Merge every A into one hole (``out`` holds their rotations and receives the result).

    While the merge still lets some B through, every A's rotation is searched again from another
    seed (``[layout] restarts``) and merged again; the better merge is kept (blocking first, then
    the game value).
    """
    searchable = any(e.rotation is None for e in scene.passes)
    rotations = out
    for restart in range(scene.layout.restarts + 1):
        if restart:  # an independent search of every A's rotation from another seed
            rotations = _rotate_each(scene, passes, blocks, np.random.default_rng([seed, restart]),
                                     seed + restart, bar, f" (restart {restart})")  # fmt: skip
            out.history.extend(rotations.history)
            out.stages += rotations.stages
            out.polish += rotations.polish
        got = _merge(scene, passes, blocks, rotations.quats, rotations.alternatives, rng, bar)
        out.history.extend(got.history)
        out.stages += got.stages
        if restart == 0 or (got.blocks, got.value) > (out.merged_blocks, out.value):
            out.quats, out.trans, out.value, out.memory = (
                got.quats,
                got.trans,
                got.value,
                got.memory,
            )
            out.alone, out.merged_blocks = rotations.alone, got.blocks
            out.rest_choice = rotations.rest_choice
        if got.blocks or not searchable:
            return


def _rotate_each(
    scene: Scene, passes, blocks, rng, seed: int, bar: Progress, tag: str = ""
) -> SearchOutcome:
    """Every A's rotation searched alone against all of B (fixed ones taken from the scene)."""
    lay, m, own = scene.layout, len(passes), hole_tolerances(scene)  # each A's own tolerance
    out = SearchOutcome(
        np.zeros((m, 4)), np.zeros((m, 2)), float("nan"), SwarmHistory(), [], [None] * m
    )
    for i, entry in enumerate(scene.passes):
        if entry.rotation is not None:
            out.quats[i] = normalize(np.asarray(entry.rotation))
            continue
        out.quats[i], out.value, h, choice = _search_one(
            passes[i], blocks, at_tolerance(scene, own[i]), rng, seed, bar, passes[i].name
        )
        if choice is not None:
            out.rest_choice[i] = choice
        out.alone[i] = float(out.value)
        out.alternatives[i] = alternative_rotations(h.finalists, out.quats[i], lay.alternatives)
        out.history.extend(h)
        out.stages.append((f"rotate {passes[i].name}{tag}", len(h.best)))
        if h.polish is not None:
            out.polish.append({"shape": passes[i].name, **h.polish})
    return out


def _merge(scene: Scene, passes, blocks, quats, alternatives, rng, bar: Progress):
    """Several A in one hole: the placements of :func:`sieve_mi.game.layout.merge` on the union frame."""
    s, fab = scene.solver, scene.fabrication
    frame = union_frame([p.radius for p in passes], fab.tolerance, s.resolution)
    players = [PlayerA.from_settings(p, frame, fab, s) for p in passes]
    player_b = PlayerB.from_settings(blocks, frame, s)
    recheck = (scene.verdict.starts, scene.verdict.steps)
    context = PlacementContext(player_b, s, scene.layout, rng, recheck, converged=CONVERGED)
    return merge(
        players,
        quats,
        alternatives,
        context,
        progress=lambda label, best: bar.update(
            s.particles * s.steps, best=f"{best:.3f}", stage=label
        ),
    )


def solve(
    scene: Scene,
    *,
    variant: str | None = None,
    seed: int | None = None,
    progress: bool = True,
    run: Run | None = None,
    early=None,
) -> Result:
    """Play the sieve game for a scene; parameters as :func:`sieve_mi.api.solve`, which checks
    them and returns this game's :class:`~sieve_mi.game.result.Result` as a
    :class:`sieve_mi.api.Result` (one that can save its outputs).

    ``run`` is the record that gets the solve's stages and memory (default a new one, counted
    from here): the command line passes one counted from the process's start. ``early``, if
    given, is called with the game's Result before the margins stage (everything but
    ``margins``, ``overhangs`` and ``rest``): the command line starts the pictures there.
    """
    from sieve_mi.backend import use_variant

    run = (Run() if run is None else run).start(memory=True)
    with run.stage("init"):
        variant = use_variant(variant).variant()
    with run.stage("load"):
        passes, blocks = load_shapes(scene)
    seed = scene.solver.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    with run.stage("screen"):
        sure, feasible = _screen(scene, passes, blocks)
    _announce(feasible, progress)
    skip = set(sure) | set(feasible.impossible)  # decided before the game: not searched
    open_blocks = [b for j, b in enumerate(blocks) if j not in skip]
    searched = []  # the B the search plays, made once (the verdict: the full meshes)

    def attempt(rng, seed: int, run: Run) -> Attempt:  # a search, its window and its verdict
        with run.stage("search"):
            searched[:] = searched or _searched(scene, passes, open_blocks)
            found = search(scene, passes, searched, rng, seed, progress) if open_blocks else (
                _unsearched(scene))  # fmt: skip
            found.feasibility = feasible
        play, window, rng = _window(scene, passes, open_blocks, found, (seed, rng), progress, run)
        return Attempt(found, play, window, *_verdict(play, passes, blocks, sure, found, rng,
                                                     progress, run), seed)  # fmt: skip

    kept, retries = attempt(rng, seed, run), []
    if applies(scene, open_blocks):
        with run.stage("retry", mark=False):  # its searches' and verdicts' times count here
            kept, retries = with_retries(
                kept, lambda k: attempt(np.random.default_rng([seed, k]), seed + k, Run()),
                scene.solver.retries, [b.name for b in blocks], feasible.impossible, progress,
            )  # fmt: skip
        if retries:  # the memory line names the stage only where a retry ran
            run.mark("retry")
        kept.found.retries = retries
    found, play, window, v = kept.found, kept.play, kept.window, kept.judgement
    certified = _certified(play, passes, blocks, kept.sure, found, v, kept.certified, progress, run)
    with run.stage("thin", mark=False):  # its memory stage ends after the margins'
        sheet = _sheet(play, passes, blocks, v, certified, seed, progress)
    certified = on_sheet(certified, sheet.thickness)  # a cell proof needs a plate >= B's diameter
    game = (scene, passes, blocks, found, v, variant, run, seed, certified, sheet, window, feasible)
    if early is not None:
        early(_outcome(game))
    with run.stage("margins", mark=False):  # exact overhangs and their proved bounds
        grown = scene.fabrication.block_margin
        margins = block_margins(blocks, v.outline, v.attack, certified, grown)
        overhangs = _overhangs(blocks, v, margins, certified, progress, skip=set(sure))
    run.mark("thin")
    run.stop()
    return _outcome(game, margins=margins, overhangs=overhangs, rest=_rest(scene, passes, found))


def _outcome(game: tuple, **more) -> Result:
    """The game's :class:`Result` from the solve's parts ``game`` = (scene, passes, blocks,
    found, judgement, variant, run, seed, certified, sheet, window, feasible); ``more``:
    ``margins``, ``overhangs`` and ``rest`` (left empty in the one :func:`solve` gives
    ``early``)."""
    scene, passes, blocks, found, v, variant, run, seed, certified, sheet, window, feasible = game
    return Result(
        scene=scene,
        pass_shapes=passes,
        block_shapes=blocks,
        pass_quats=found.quats,
        pass_trans=v.trans,
        hole=v.hole,
        a_masks=v.a_masks,
        attack=v.attack,
        block_masks=v.block_masks,
        history=found.history,
        search_value=found.value,
        variant=variant,
        stages=found.stages,
        warnings=v.warnings,
        timings=run.timings,
        alone=found.alone,
        seed=seed,
        certified=certified,
        sheet=sheet,
        outline=v.outline,
        polish=found.polish,
        started=run.started,
        memory=run.memory,
        window=window,
        feasibility=feasible,
        mirrored=v.mirrored,
        retries=found.retries,
        **more,
    )


def _screen(scene: Scene, passes: list, blocks: list) -> tuple:
    """The B proved blocked by size (:func:`~sieve_mi.game.screen.proved_by_size`) and the
    feasibility test (:func:`~sieve_mi.game.feasible.feasibility`), both at the widest hole's
    tolerance (``[[pass]] tolerance``: a B that the widest hole cannot hold is held by all)."""
    wide = at_tolerance(scene, hole_tolerances(scene).max())
    return proved_by_size(wide, passes, blocks), feasibility(wide, passes, blocks)


def _searched(scene: Scene, passes: list, open_blocks: list) -> list:
    """The B the search plays: ``open_blocks``, closed ones simplified as ``[solver] stand_in``
    says (:mod:`sieve_mi.geometry.stand_in`; "auto": within half the search's finest pixel, only
    B of more than ``AUTO_FACES`` faces)."""
    stand = tolerance(scene.solver.stand_in, _search_pixel(scene, passes))
    big = AUTO_FACES if scene.solver.stand_in == "auto" else 0
    return stand_ins(open_blocks, stand, big)


def _rest(scene: Scene, passes: list, found: SearchOutcome) -> list:
    """report.json's ``rest`` per A (:func:`sieve_mi.game.rest.rest_records`) with ``[solver]
    rest_poses``; empty without (a round part's resting poses take seconds)."""
    if not scene.solver.rest_poses:
        return []
    return rest_records(passes, found.quats, found.rest_choice)


def _window(scene: Scene, passes, open_blocks, found, seeds: tuple, progress: bool, run: Run):
    """The scene the verdict plays (its ``[fabrication] window`` a number), report.json's window
    record (:mod:`sieve_mi.game.window`) and the verdict's random numbers; ``seeds`` is (seed,
    the solve's generator); ``run`` gets the stage "window" for "auto"."""
    seed, rng = seeds
    if scene.fabrication.window != "auto":
        return scene, window_record(scene, passes, "given"), rng
    degrees, tries = 0.0, []
    if open_blocks:
        with run.stage("window"):
            degrees, tries, rng = widest_window(scene, passes, open_blocks, found, seed, progress)
    play = at_window(scene, degrees)
    return play, window_record(play, passes, "auto", tries), rng


def _announce(feasible, progress: bool) -> None:
    """Print the feasibility test's findings on stderr before the search (with ``progress``)."""
    if progress:
        for line in feasible.lines():
            print(f"feasibility: {line}", file=sys.stderr, flush=True)


def _verdict(scene: Scene, passes, blocks, sure: dict, found: SearchOutcome, rng, progress,
             run: Run):  # fmt: skip
    """The verdict on the B not proved before the game, completed with those that were:
    (judgement, per B the proof made before the game or None, the B whose proof held); ``run``
    gets the stage "verdict"."""
    certified = [None] * len(blocks)
    unblockable = found.feasibility.impossible if found.feasibility is not None else []
    with run.stage("verdict"):
        while True:
            rows = [j for j in range(len(blocks)) if j not in sure and j not in unblockable]
            bar = Progress(progress and bool(rows), scene.verdict.steps, "verdict")
            v = judge(scene, passes, [blocks[j] for j in rows], found.quats, found.trans, rng,
                      progress=lambda n, bar=bar: bar.update(1), memory=found.memory)  # fmt: skip
            bar.close()
            failed = _with_screened(scene, blocks, rows, sure, v, certified) if sure else []
            if not failed:
                break
            sure = {j: r for j, r in sure.items() if j not in failed}  # play them after all
        if unblockable:  # their certificates' poses, where they pass
            with_certificates(scene, passes, blocks, rows, found.feasibility, found.quats, v)
    return v, certified, sure


def _certified(scene: Scene, passes, blocks, sure: dict, found, v, certified: list, progress,
               run: Run) -> list:  # fmt: skip
    """With ``[verdict] certify``, the verdict's blocked B certified (stage "certify"; those in
    ``sure`` keep their proofs from before the game): per B its certification, or [] if none."""
    if scene.verdict.certify:
        with run.stage("certify"):
            proofs = _certify(scene, passes, blocks, found.quats, v, progress, sure)
            for j, c in enumerate(proofs):
                certified[j] = certified[j] if j in sure else c
    return certified if any(c is not None for c in certified) else []


def _sheet(scene: Scene, passes, blocks, v, certified, seed, progress):
    """The plate's thickness and the thin-plate motion searches (:mod:`sieve_mi.game.sheet`) of
    the B still blocked after certify; a verified passage unblocks its B (:func:`is_blocked`)."""
    proofs = certified or [None] * len(blocks)
    blocked = np.array([is_blocked(b, c) for b, c in zip(v.attack.blocked()[0], proofs)])
    sheet = plate_sheet(scene, blocks, v.outline, v.attack, blocked, certified=certified,
                        seed=seed, progress=progress)  # fmt: skip
    for j in sheet.passages():
        v.warnings.append(
            f"{blocks[j].name} passes a {sheet.thickness:g} {scene.units} plate by tilting and "
            "turning on the way (thin-plate motion search, verified; motion in report.json): B wins"
        )
    return sheet


def _overhangs(blocks, v, margins: list, certified: list, progress: bool, skip=()) -> list:
    """Each blocked B's least overhang found and its proved bound
    (:func:`sieve_mi.game.overhang.block_overhangs`; none searched for the B in ``skip``, proved
    before the game by size), with a progress bar over the B searched."""
    todo = [j for j, m in enumerate(margins) if m is not None and j not in skip]
    bar = Progress(progress and bool(todo), len(todo), "overhang", unit="B", every=math.inf)

    def step(j: int) -> None:
        if j in todo:
            bar.update(1, stage=f"{blocks[j].name} measured")

    got = block_overhangs(blocks, v.outline, v.attack, margins, certified, step, skip)
    bar.close()
    for shape, o in zip(blocks, got):
        if o is not None and o.at_best_pose <= 0.0:  # not expected: the verdict missed a fit
            v.warnings.append(
                f"{shape.name} fits the exact hole in a pose the overhang search found (pose in "
                "report.json's overhang): the verdict's block is in doubt; certify it"
            )
    return got


def _certify_bar(scene: Scene, n: int, progress: bool) -> Progress:
    """certify's progress over its ``n`` B (:class:`~sieve_mi.progress.Progress`), opened with
    the most it can take: each proof's budget, as many at once as there are cores."""
    bar = Progress(progress and n > 0, n, "certify", unit="B", done_line=False, every=math.inf)
    if n:
        each = scene.verdict.certify_budget + scene.verdict.section_budget
        rounds = -(-n // max(1, min(n, os.cpu_count() or 1)))
        bar.write(f"certify: {n} B, up to {each:g} s each ([verdict] certify_budget + "
                  f"section_budget): at most about {rounds * each:g} s")  # fmt: skip
    return bar


def _unsearched(scene: Scene) -> SearchOutcome:
    """A's rotations when every B was proved before the game: the scene's fixed ones, else the
    identity (any rotation makes a hole that blocks them all)."""
    m = len(scene.passes)
    quats = np.array([normalize(np.asarray(e.rotation)) if e.rotation is not None else
                      [1.0, 0.0, 0.0, 0.0] for e in scene.passes])  # fmt: skip
    return SearchOutcome(quats, np.zeros((m, 2)), float("nan"), SwarmHistory(), [], [None] * m)


def _with_screened(scene: Scene, blocks, rows, sure: dict, v, certified: list):
    """Complete the verdict ``v`` with the B proved before the game (:mod:`sieve_mi.game.screen`):
    each is certified on the exact hole (into ``certified``) and gets one exact attempt's row.

    Returns the screened B whose proof failed on the exact hole (then ``v`` is left as it was
    and the caller plays them); normally none.
    """
    fab = scene.fabrication
    proofs = prove_proved(scene, blocks, sure, v.outline)
    failed = [j for j, c in proofs.items() if c.status != "proved"]
    if failed:  # not expected (the bound says the ball test holds): they play the verdict
        v.warnings.append("screened but not proved on the exact hole, played: "
                          + ", ".join(blocks[j].name for j in failed))  # fmt: skip
        return failed
    for j, c in proofs.items():
        certified[j] = c
    grown = dilated(v.outline, fab.block_margin) if fab.block_margin > 0 else None
    v.attack = with_proved(v.attack, rows, blocks, v.outline, grown, v.trans[0])
    masks = dict(zip(rows, v.block_masks))
    v.block_masks = [
        masks[j] if j in masks else
        mask_window(SilhouetteRenderer(b), v.hole, v.attack.quats[0, j], v.attack.trans[0, j])
        for j, b in enumerate(blocks)
    ]  # fmt: skip
    names = ", ".join(blocks[j].name for j in sorted(sure))
    v.warnings.append(
        f"proved blocked before the game by size (a ball inside larger than any hole A can make; "
        f"not attacked, β is one exact attempt's): {names}"
    )
    return []


def _certify(scene, passes, blocks, quats, v, progress: bool, proved=()) -> list:
    """Certify the verdict's blocked B (:func:`sieve_mi.certify.blocks.certify_blocks`), except
    those in ``proved`` (already certified before the game; None there).

    A passage found through the exact hole overrules the verdict: it is added to ``v.warnings``.
    """
    from sieve_mi.certify.blocks import certify_blocks, printed_hole
    from sieve_mi.geometry.pattern import from_settings

    todo = v.attack.blocked()[0] & ~np.isin(np.arange(len(blocks)), list(proved))
    bar = _certify_bar(scene, int(todo.sum()), progress)

    def say(line: str) -> None:
        bar.update(1)
        left = bar.left()
        bar.write(line + (f"; {left}" if left else ""))

    found = v.attack.protrusion[0]
    hole = printed_hole(scene, passes, quats, v.trans, v.outline)
    sheet = from_settings(v.outline, scene.fabrication, scene.units)  # None: one hole
    certified = certify_blocks(scene, hole, blocks, todo, say, found=found, pattern=sheet)
    bar.close()
    for shape, c in zip(blocks, certified):
        if c is not None and c.status == "passage":
            v.warnings.append(
                f"{shape.name} passes the exact hole in a pose the verdict's attack missed "
                "(found by certify; pose in report.json): B wins"
            )
    return certified
