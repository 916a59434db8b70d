"""The whole game for one scene: search (player A against player B), then the verdict."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from sieve_mi.hole import Hole
from sieve_mi.layout import (
    LayoutSettings,
    alternative_rotations,
    compose,
    place,
    separate_layout,
    sort_by_area,
    union_frame,
)
from sieve_mi.meshes import Shape, load_shape
from sieve_mi.optim import SwarmHistory
from sieve_mi.players import Attack, AttackMemory, PlayerA, PlayerB
from sieve_mi.raster import Frame
from sieve_mi.rotations import normalize
from sieve_mi.scene import Scene
from sieve_mi.scoring import score_poses


@dataclass
class Result:
    """What a solve produced.

    Attributes
    ----------
    winner : {"A", "B"}
        "A" iff every shape to block is blocked after the verdict.
    pass_shapes, block_shapes : list of Shape
    pass_quats : (m, 4) ndarray
        Each A's rotation (w, x, y, z).
    pass_trans : (m, 2) ndarray
        Each A's translation in the hole's frame, scene units (the first is at the origin).
    hole : Hole
        The verdict's hole (at the verdict resolution).
    a_masks : list of (N, N) bool ndarrays
        Each A's undilated silhouette at its placement, on the hole's frame.
    attack : Attack
        Player B's best attempts in the verdict (one hole).
    history : SwarmHistory
        Best search value per iteration (all stages of a many-A search, one after another).
    stages : list of (str, int)
        Label and number of iterations of each search stage.
    search_value : float
        The game value of the chosen placement during the search (NaN when A was fixed).
    timings : dict
        Seconds per stage.
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
    history: SwarmHistory
    search_value: float
    variant: str
    stages: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    renderers: list = field(default_factory=list, repr=False)
    #: Per pass shape: its own search's value (the weakest B's loss against that shape's hole
    #: alone, short attack), or None where its rotation was fixed in the scene.
    alone: list = field(default_factory=list)
    #: The seed the run used (``[solver] seed`` or the ``seed`` argument that overrode it).
    seed: int | None = None

    @property
    def pass_quat(self) -> np.ndarray:
        """The first A's rotation."""
        return self.pass_quats[0]

    @property
    def a_mask(self) -> np.ndarray:
        """All A silhouettes together."""
        out = np.zeros_like(self.a_masks[0])
        for m in self.a_masks:
            out |= m
        return out


def load_shapes(scene: Scene) -> tuple[list[Shape], list[Shape]]:
    """Read every mesh of the scene (raises SieveError on the first bad one)."""
    passes = [load_shape(scene.resolve(e.mesh), scale=e.scale, name=e.name) for e in scene.passes]
    blocks = [load_shape(scene.resolve(e.mesh), scale=e.scale, name=e.name) for e in scene.blocks]
    return passes, blocks


def hole_frame(shape: Shape, tolerance: float, resolution: int) -> Frame:
    """The raster frame for one A's hole: covers A's dilated silhouette at every rotation."""
    return Frame.covering(shape.radius + tolerance, resolution)


def frame_for(
    passes: list[Shape], tolerance: float, resolution: int, trans: np.ndarray | None = None
) -> Frame:
    """The frame of the final hole.

    One shape: its own frame. Several shapes at known in-plane translations ``trans`` (scene
    units): the smallest centred frame that holds every shape's bounding disk at its place, so the
    verdict's pixels are as fine as the placed hole allows. Without ``trans``: the union frame,
    which holds any placement the search may choose.
    """
    if len(passes) == 1:
        return hole_frame(passes[0], tolerance, resolution)
    if trans is None:
        return union_frame([p.radius for p in passes], tolerance, resolution)
    reach = max(float(np.hypot(*t)) + p.radius for p, t in zip(passes, trans))
    return Frame.covering(reach + tolerance, resolution)


class _Bar:
    """A tqdm progress bar on stderr, or nothing when quiet."""

    def __init__(self, enabled: bool, total: int, desc: str, grow_by: int = 0):
        self.bar = None
        self.grow_by = grow_by
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="it", leave=True, dynamic_ncols=True)

    def update(self, n: int = 1, **postfix):
        if self.bar is not None:
            if self.bar.total is not None and self.grow_by and self.bar.n + n > self.bar.total:
                self.bar.total += self.grow_by  # an extra round of work nobody could foresee
            if postfix:
                self.bar.set_postfix(postfix, refresh=False)
            self.bar.update(n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _search_one(a: Shape, blocks: list[Shape], scene: Scene, rng, seed, bar: _Bar, label: str):
    """Player A's rotation for one shape alone against all of B (Secs. 5.1, 5.2)."""
    s, fab = scene.solver, scene.fabrication
    frame = hole_frame(a, fab.tolerance, s.resolution)
    player_a = PlayerA(a, frame, fab.tolerance, fab.fill_holes)
    player_b = PlayerB(blocks, frame, s.objective)

    def report(it, best):
        bar.update(s.particles if s.outer == "pso" else 1, best=f"{best:.4f}", stage=label)

    return player_a.search(
        player_b,
        method=s.outer,
        particles=s.particles,
        iterations=s.iterations,
        starts=s.starts,
        steps=s.steps,
        learning_rate=s.learning_rate,
        rng=rng,
        seed=seed,
        inertia=s.inertia,
        c_personal=s.c_personal,
        c_global=s.c_global,
        progress=report,
    )


def search(scene: Scene, passes: list[Shape], blocks: list[Shape], rng, seed: int, progress: bool):
    """Player A's placements: rotations (and translations for several shapes) of every A.

    Returns
    -------
    quats : (m, 4) ndarray
    trans : (m, 2) ndarray
    value : float
    history : SwarmHistory
    stages : list of (str, int)
    """
    s, fab, lay = scene.solver, scene.fabrication, scene.layout
    m = len(passes)
    quats = np.zeros((m, 4))
    trans = np.zeros((m, 2))
    fixed = [e.rotation for e in scene.passes]
    history, stages = SwarmHistory(), []
    free = [i for i in range(m) if fixed[i] is None]
    placements = m - 1 if (m > 1 and lay.mode == "merged") else 0
    per_stage = s.particles * (s.iterations + 1)
    bar = _Bar(progress, per_stage * (len(free) + placements), "search", grow_by=per_stage)
    alternatives: dict[int, list[np.ndarray]] = {}
    alone: list[float | None] = [None] * m
    value = float("nan")
    for i in range(m):
        if fixed[i] is not None:
            quats[i] = normalize(np.asarray(fixed[i]))
            continue
        quats[i], value, h = _search_one(passes[i], blocks, scene, rng, seed, bar, passes[i].name)
        alone[i] = float(value)
        alternatives[i] = alternative_rotations(h.finalists, quats[i], lay.alternatives)
        history.best += h.best
        history.evaluations += h.evaluations
        stages.append((f"rotate {passes[i].name}", len(h.best)))
    if m > 1 and lay.mode == "merged":
        frame = union_frame([p.radius for p in passes], fab.tolerance, s.resolution)
        players = [PlayerA(p, frame, fab.tolerance, fab.fill_holes) for p in passes]
        player_b = PlayerB(blocks, frame, s.objective)
        settings = LayoutSettings(
            lay.tau, lay.rho, lay.eta, lay.alpha, lay.c_personal, lay.c_global
        )
        order = sort_by_area(players, quats)
        placed = [order[0]]
        memory = AttackMemory(len(blocks), size=max(1, s.starts // 3))
        lost = False  # a placement already lets some B through: later ones cannot mend that
        for i in order[1:]:

            def report(it, best, _n=passes[i].name):
                bar.update(s.particles, best=f"{best:.3f}", stage=f"place {_n}")

            # The shape's own best rotation first (several rounds); if every placement still lets
            # some B through, its next-best distinct rotations from its own search, and for the
            # first pair the base shape's too (Sec. 5.3 is greedy: a hole that lets B through
            # cannot be mended by adding more shapes to it). One round each.
            tries = [(None, quats[i], lay.rounds)]
            if not lost:
                tries += [(None, q, 1) for q in alternatives.get(i, [])]
                if len(placed) == 1:
                    tries += [(q, quats[i], 1) for q in alternatives.get(placed[0], [])]
            current = compose(
                [players[j] for j in placed], quats[placed], trans[placed], fab.fill_holes
            ).mask
            kept, kept_base = None, quats[placed[0]]
            for attempt, (base_q, q, rounds) in enumerate(tries):
                base = current
                if base_q is not None:  # the first pair, with another rotation of the base shape
                    base = compose(
                        [players[placed[0]]], base_q[None], trans[placed], fab.fill_holes
                    ).mask
                got = place(
                    players[i],
                    player_b,
                    base,
                    q,
                    particles=s.particles,
                    iterations=s.iterations,
                    starts=s.starts,
                    steps=s.steps,
                    learning_rate=s.learning_rate,
                    settings=settings,
                    rng=rng,
                    progress=report,
                    memory=memory,
                    recheck=(scene.verdict.starts, scene.verdict.steps),
                    rounds=rounds,
                )
                history.best += got.history.best
                history.evaluations += got.history.evaluations
                label = f"place {passes[i].name}" + (f" (try {attempt + 1})" if attempt else "")
                stages.append((label, len(got.history.best)))
                if kept is None or (got.blocks, got.value) > (kept.blocks, kept.value):
                    kept, kept_base = got, (quats[placed[0]] if base_q is None else base_q).copy()
                if kept.blocks:
                    break
            quats[i], trans[i], value = kept.quat, kept.trans, kept.value
            quats[placed[0]] = kept_base
            lost = lost or not kept.blocks
            placed.append(i)
        # The first (largest) shape sits at the origin: shift everything so.
        trans -= trans[order[0]]
    bar.close()
    return quats, trans, value, history, stages, alone


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


def solve(
    scene: Scene, *, variant: str | None = None, seed: int | None = None, progress: bool = True
) -> Result:
    """Play the sieve game for a scene.

    Parameters
    ----------
    scene : Scene
    variant : str, optional
        Mitsuba variant ("llvm_ad_mono" or "cuda_ad_mono"); default ``$SIEVE_MI_VARIANT`` or "llvm_ad_mono".
    seed : int, optional
        Overrides ``[solver] seed``.
    progress : bool
        Show progress bars on stderr.
    """
    from sieve_mi.backend import use_variant

    t_init = time.perf_counter()
    variant = use_variant(variant).variant()
    t_load = time.perf_counter()
    passes, blocks = load_shapes(scene)
    s, v, fab = scene.solver, scene.verdict, scene.fabrication
    seed = s.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    timings = {"init_s": t_load - t_init, "load_s": time.perf_counter() - t_load}

    t0 = time.perf_counter()
    quats, trans, value, history, stages, alone = search(scene, passes, blocks, rng, seed, progress)
    timings["search_s"] = time.perf_counter() - t0

    # Verdict: a long re-run of player B against the chosen hole.
    t1 = time.perf_counter()
    separate = len(passes) > 1 and scene.layout.mode == "separate"
    if separate:
        trans, vframe = separate_layout(
            [p.radius for p in passes], fab.tolerance, fab.border, v.resolution
        )
    else:
        vframe = frame_for(passes, fab.tolerance, v.resolution, trans)
    vplayers = [PlayerA(p, vframe, fab.tolerance, fab.fill_holes) for p in passes]
    if len(passes) == 1:
        trans[0] = 0.0
    hole = compose(vplayers, quats, trans, fab.fill_holes)
    a_masks = [p.silhouettes(q[None], t[None])[0] for p, q, t in zip(vplayers, quats, trans)]
    if (
        len(passes) > 1
        and not separate
        and int(ndimage.label(hole.mask, structure=np.ones((3, 3)))[1]) > 1
    ):
        stages.append(("warning: the merged hole is not connected", 0))
    # Separate holes: B passes if it passes any one of them, so it is attacked on each.
    groups = [[i] for i in range(len(passes))] if separate else [list(range(len(passes)))]
    holes = [compose([vplayers[i] for i in g], quats[g], trans[g], fab.fill_holes) for g in groups]
    # With a blocking margin, B must fail against the hole grown by that margin (paper Fig. 14).
    if fab.block_margin > 0:
        grown = [
            PlayerA(p, vframe, fab.tolerance + fab.block_margin, fab.fill_holes) for p in passes
        ]
        targets = [
            compose([grown[i] for i in g], quats[g], trans[g], fab.fill_holes) for g in groups
        ]
    else:
        targets = holes
    vplayer_b = PlayerB(blocks, vframe, "clearance")
    bar = _Bar(progress, v.steps, "verdict")
    centres = np.array([trans[g].mean(axis=0) for g in groups]) if separate else None
    attack = vplayer_b.attack(
        targets,
        v.starts,
        v.steps,
        s.learning_rate,
        rng,
        progress=lambda n: bar.update(1),
        centres=centres,
    )
    bar.close()
    attack = weakest_hole(attack)
    if fab.block_margin > 0:
        attack.margin_beta = attack.beta.copy()
        attack.margin_protrusion = attack.protrusion.copy()
        for j, r in enumerate(vplayer_b.renderers):
            sc = score_poses(r, hole, attack.quats[0, j : j + 1], attack.trans[0, j : j + 1])
            attack.beta[0, j], attack.protrusion[0, j] = sc.beta[0], sc.protrusion[0]
    timings["verdict_s"] = time.perf_counter() - t1
    winner = "A" if bool(np.all(attack.blocked()[0])) else "B"
    return Result(
        scene=scene,
        winner=winner,
        pass_shapes=passes,
        block_shapes=blocks,
        pass_quats=quats,
        pass_trans=trans,
        hole=hole,
        a_masks=a_masks,
        attack=attack,
        history=history,
        search_value=value,
        variant=variant,
        stages=stages,
        timings=timings,
        renderers=vplayer_b.renderers,
        alone=alone,
        seed=seed,
    )
