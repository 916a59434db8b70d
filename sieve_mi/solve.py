"""The whole game for one scene: search (player A against player B), then the verdict."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.hole import Hole
from sieve_mi.meshes import Shape, load_shape
from sieve_mi.optim import SwarmHistory
from sieve_mi.players import Attack, PlayerA, PlayerB
from sieve_mi.raster import Frame
from sieve_mi.rotations import normalize
from sieve_mi.scoring import score_poses
from sieve_mi.scene import Scene


@dataclass
class Result:
    """What a solve produced.

    Attributes
    ----------
    winner : {"A", "B"}
        "A" iff every shape to block has beta > 0 after the verdict.
    pass_shapes, block_shapes : list of Shape
    pass_quat : (4,) ndarray
        A's rotation (w, x, y, z).
    hole : Hole
        The verdict's hole (at the verdict resolution).
    a_mask : (N, N) bool ndarray
        A's undilated silhouette on the hole's frame.
    attack : Attack
        Player B's best attempts in the verdict (one hole).
    history : SwarmHistory
        Best game value per search iteration.
    search_value : float
        The game value of the chosen rotation during the search.
    timings : dict
        Seconds per stage.
    """

    scene: Scene
    winner: str
    pass_shapes: list[Shape]
    block_shapes: list[Shape]
    pass_quat: np.ndarray
    hole: Hole
    a_mask: np.ndarray
    attack: Attack
    history: SwarmHistory
    search_value: float
    variant: str
    timings: dict = field(default_factory=dict)
    renderers: list = field(default_factory=list, repr=False)


def load_shapes(scene: Scene) -> tuple[list[Shape], list[Shape]]:
    """Read every mesh of the scene (raises SieveError on the first bad one)."""

    def read(entries, role):
        shapes = []
        for i, e in enumerate(entries):
            s = load_shape(scene.resolve(e.mesh), scale=e.scale, name=e.name)
            shapes.append(s)
        return shapes

    return read(scene.passes, "pass"), read(scene.blocks, "block")


def hole_frame(shape: Shape, tolerance: float, resolution: int) -> Frame:
    """The raster frame for A's hole: covers A's dilated silhouette at every rotation."""
    return Frame.covering(shape.radius + tolerance, resolution)


class _Bar:
    """A tqdm progress bar, or nothing when quiet."""

    def __init__(self, enabled: bool, total: int, desc: str):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="it", leave=True, dynamic_ncols=True)

    def update(self, n: int = 1, **postfix):
        if self.bar is not None:
            if postfix:
                self.bar.set_postfix(postfix, refresh=False)
            self.bar.update(n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def solve(scene: Scene, *, variant: str = "llvm_ad_mono", seed: int | None = None, progress: bool = True) -> Result:
    """Play the sieve game for a scene with one shape to pass and any number to block.

    Parameters
    ----------
    scene : Scene
    variant : str
        Mitsuba variant ("llvm_ad_mono" or "cuda_ad_mono").
    seed : int, optional
        Overrides ``[solver] seed``.
    progress : bool
        Show progress bars on stderr.
    """
    from sieve_mi.backend import use_variant

    use_variant(variant)
    t_load = time.perf_counter()
    passes, blocks = load_shapes(scene)
    if len(passes) != 1:
        raise SieveError(f"{scene.path}: pass: this version designs a hole for exactly one [[pass]] shape, got {len(passes)}")
    a = passes[0]
    s, v, fab = scene.solver, scene.verdict, scene.fabrication
    rng = np.random.default_rng(s.seed if seed is None else seed)
    timings = {"load_s": time.perf_counter() - t_load}

    # Search: player A's rotation against player B (skipped when the scene fixes A's rotation).
    t0 = time.perf_counter()
    fixed = scene.passes[0].rotation
    if fixed is not None:
        quat = normalize(np.asarray(fixed))
        history, value = SwarmHistory(), float("nan")
    else:
        frame = hole_frame(a, fab.tolerance, s.resolution)
        player_a = PlayerA(a, frame, fab.tolerance, fab.fill_holes)
        player_b = PlayerB(blocks, frame, s.objective)
        total = s.particles * (s.iterations + 1)
        bar = _Bar(progress, total, "search")

        def report(it, best):
            bar.update(s.particles if s.outer == "pso" else 1, best=f"{best:.4f}")

        quat, value, history = player_a.search(
            player_b, method=s.outer, particles=s.particles, iterations=s.iterations, starts=s.starts, steps=s.steps,
            learning_rate=s.learning_rate, rng=rng, seed=s.seed if seed is None else seed, inertia=s.inertia,
            c_personal=s.c_personal, c_global=s.c_global, progress=report)
        bar.close()
    timings["search_s"] = time.perf_counter() - t0

    # Verdict: a long re-run of player B against the chosen hole.
    t1 = time.perf_counter()
    vframe = hole_frame(a, fab.tolerance, v.resolution)
    vplayer_a = PlayerA(a, vframe, fab.tolerance, fab.fill_holes)
    hole = vplayer_a.holes(quat[None])[0]
    a_mask = vplayer_a.silhouette(quat)
    # With a blocking margin, B must fail against the hole grown by that margin (paper Fig. 14).
    if fab.block_margin > 0:
        target = PlayerA(a, vframe, fab.tolerance + fab.block_margin, fab.fill_holes).holes(quat[None])[0]
    else:
        target = hole
    vplayer_b = PlayerB(blocks, vframe, "clearance")
    bar = _Bar(progress, v.steps, "verdict")
    attack = vplayer_b.attack([target], v.starts, v.steps, s.learning_rate, rng, progress=lambda n: bar.update(1))
    bar.close()
    if target is not hole:
        attack.margin_beta = attack.beta.copy()
        attack.margin_protrusion = attack.protrusion.copy()
        for j, r in enumerate(vplayer_b.renderers):
            sc = score_poses(r, hole, attack.quats[0, j:j + 1], attack.trans[0, j:j + 1])
            attack.beta[0, j], attack.protrusion[0, j] = sc.beta[0], sc.protrusion[0]
    timings["verdict_s"] = time.perf_counter() - t1
    winner = "A" if bool(np.all(attack.blocked()[0])) else "B"
    return Result(scene=scene, winner=winner, pass_shapes=passes, block_shapes=blocks, pass_quat=quat, hole=hole, a_mask=a_mask,
                  attack=attack, history=history, search_value=value, variant=variant, timings=timings,
                  renderers=vplayer_b.renderers)
