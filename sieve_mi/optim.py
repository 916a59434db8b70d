"""Optimisers: Adam over batched poses (player B) and particle swarm / nlopt (player A)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "NLOPT_METHODS",
    "POSE_KEYS",
    "PSO_COEFFICIENT",
    "QUAT_KEYS",
    "SwarmHistory",
    "SwarmSettings",
    "live_poses",
    "nlopt_maximise",
    "particle_swarm",
    "pose_adam",
    "pose_columns",
    "renormalise_quaternions",
]

#: Names of a pose's parameters in :func:`pose_adam`: quaternion (w, x, y, z), then translation.
QUAT_KEYS = ("qw", "qx", "qy", "qz")
POSE_KEYS = QUAT_KEYS + ("tx", "ty")
#: The default inertia and both accelerations of :func:`particle_swarm` (omega, psi_1, psi_2;
#: the paper's Sec. 6 value for each, and the ``[solver]`` defaults).
PSO_COEFFICIENT = 0.25


def pose_adam(q0: np.ndarray, t0: np.ndarray, lr: float):
    """:class:`drjit.opt.Adam` over K independent poses, one Dr.Jit array per pose parameter.

    Adam's update is element-wise, so every pose is its own problem; the library keeps each
    step's learning-rate and bias-correction factor opaque, so the kernels compiled in the first
    step are reused by every later step. Moments are (beta_1, beta_2) = (0.9, 0.999) and
    epsilon 1e-8 (the paper's values, the library's defaults).

    Parameters
    ----------
    q0 : (K, 4) ndarray
        Starting quaternions (w, x, y, z).
    t0 : (K, 2) ndarray
        Starting translations (in the units the caller optimises in).
    lr : float
        Learning rate (parameter units per step).

    Returns
    -------
    drjit.opt.Adam
        With parameters :data:`POSE_KEYS`, each (K,) float32.
    """
    import drjit as dr
    import mitsuba as mi

    opt = dr.opt.Adam(lr=float(lr))
    for key, column in zip(POSE_KEYS, pose_columns(q0, t0)):
        opt[key] = mi.Float(column)
    return opt


def pose_columns(q0: np.ndarray, t0: np.ndarray) -> list:
    """Poses as :func:`pose_adam` holds them: one new (K,) float32 array per parameter,
    :data:`POSE_KEYS` order, each 64-byte aligned (one kernel source:
    :func:`sieve_mi.backend.aligned`).

    Parameters
    ----------
    q0 : (K, 4) ndarray
        Quaternions (w, x, y, z).
    t0 : (K, 2) ndarray
        Translations (in the units the caller optimises in).

    Returns
    -------
    list of 6 (K,) ndarray
    """
    from sieve_mi.backend import aligned

    x0 = np.concatenate([np.asarray(q0), np.asarray(t0)], axis=1).astype(np.float32)
    return [aligned(x0[:, i], np.float32) for i in range(len(POSE_KEYS))]


def renormalise_quaternions(opt, *also) -> None:
    """Project the quaternions of a :func:`pose_adam` optimiser back onto the unit sphere.

    The projection, the optimiser's pending step and ``also`` (any Dr.Jit arrays or PyTrees)
    are evaluated in one kernel launch. Adam's moments are kept.
    """
    import drjit as dr

    q = [opt[k] for k in QUAT_KEYS]
    norm = dr.rsqrt(sum(dr.square(dr.detach(x)) for x in q))
    unit = [dr.detach(x) * norm for x in q]
    dr.schedule(unit, also)
    dr.eval()
    for key, value in zip(QUAT_KEYS, unit):
        opt[key] = value


def live_poses(best_loss, group, groups: int, fit_loss: float):
    """Which poses still descend: those whose group has no pose with a loss <= ``fit_loss`` yet.

    Parameters
    ----------
    best_loss : mi.Float
        Each pose's best loss so far (K,).
    group : mi.UInt32
        Each pose's group (K,), in ``[0, groups)``.
    groups : int
        Number of groups.
    fit_loss : float
        The objective's loss of a pose that fits.

    Returns
    -------
    mi.Bool
        (K,): True where no pose of the group fits. An integer maximum per group, so the result
        does not depend on the order of the scatter.
    """
    import drjit as dr
    import mitsuba as mi

    fits = dr.zeros(mi.UInt32, groups)
    dr.scatter_reduce(dr.ReduceOp.Max, fits, mi.UInt32(1), group, best_loss <= fit_loss)
    return dr.gather(mi.UInt32, fits, group) == 0


@dataclass
class SwarmHistory:
    """Best value after each iteration of a global search (for convergence plots)."""

    best: list[float] = field(default_factory=list)
    evaluations: int = 0
    #: Final personal bests of a swarm (positions and values), best first; empty for nlopt.
    finalists: list = field(default_factory=list)
    #: The local polish's record (:meth:`sieve_mi.game.player_a.PlayerA.polish`), if one ran.
    polish: dict | None = None
    #: The iteration a swarm's patience stopped it at (None: it ran every iteration).
    stopped: int | None = None
    #: Game values of extra candidates evaluated with the canonical views (player A's rest
    #: poses, :mod:`sieve_mi.game.rest`), in the order given; empty when none were.
    extra: list = field(default_factory=list)

    def extend(self, other: SwarmHistory) -> None:
        """Append a later stage's values and evaluations (its finalists are not kept)."""
        self.best += other.best
        self.evaluations += other.evaluations


@dataclass(frozen=True)
class SwarmSettings:
    """How a particle swarm (:func:`particle_swarm`) moves and when it stops early.

    Attributes
    ----------
    inertia, c_personal, c_global : float
        omega, psi_1 and psi_2 of the velocity update (default :data:`PSO_COEFFICIENT` each, the
        paper's value).
    patience : int
        Stop early once the swarm's best has not improved for this many iterations in a row
        (0: run every iteration).
    gain, floor : float
        An improvement must exceed ``gain`` times the best (relative) and ``floor`` (absolute).
    """

    inertia: float = PSO_COEFFICIENT
    c_personal: float = PSO_COEFFICIENT
    c_global: float = PSO_COEFFICIENT
    patience: int = 0
    gain: float = 0.01
    floor: float = 1e-3


class _Stall:
    """Counts a search's iterations in a row whose best beat the last marked best by less than
    ``gain`` (relative) or ``floor`` (absolute)."""

    def __init__(self, best: float, gain: float, floor: float):
        self.mark, self.idle, self.gain, self.floor = best, 0, gain, floor

    def idle_after(self, best: float) -> int:
        """Take one iteration's best; return the idle iterations in a row so far."""
        if best > self.mark + max(self.floor, self.gain * abs(self.mark)):
            self.mark, self.idle = best, 0
        else:
            self.idle += 1
        return self.idle


def particle_swarm(
    evaluate: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    iterations: int,
    rng: np.random.Generator,
    settings: SwarmSettings | None = None,
    *,
    v0: np.ndarray | None = None,
    project: Callable[[np.ndarray], np.ndarray] | None = None,
    progress: Callable[[int, float], None] | None = None,
    floors: bool = False,
):
    """Maximise ``evaluate`` with particle swarm optimisation (Poli 2008), all particles per call.

    Parameters
    ----------
    evaluate : callable
        Maps positions (P, D) to values (P,), larger is better; called once per iteration with
        every particle, so it can batch their evaluations.
    x0 : (P, D) ndarray
        Initial positions.
    iterations : int
        Number of velocity updates after the initial evaluation.
    rng : numpy.random.Generator
    settings : SwarmSettings, optional
        Inertia, accelerations and early stop (default: :class:`SwarmSettings`' defaults, the
        paper's coefficients and no early stop).
    v0 : (P, D) ndarray, optional
        Initial velocities (zeros by default).
    project : callable, optional
        Maps positions back onto the feasible set after every move (e.g. normalise quaternions).
    progress : callable, optional
        Called as ``progress(iteration, best_value)``.
    floors : bool
        After the first evaluation, call ``evaluate(x, floor)`` with each particle's personal
        best (P,): a value at or below it changes nothing here, so ``evaluate`` may return any
        value not above the floor there (an upper bound; maximin pruning,
        :mod:`sieve_mi.game.maximin`).

    Returns
    -------
    best_x : (D,) ndarray
    best_value : float
    history : SwarmHistory
        ``history.stopped`` is the iteration the patience ended the swarm at (None: it ran all).
    """
    s = SwarmSettings() if settings is None else settings
    x = np.array(x0, dtype=np.float64)
    v = np.zeros_like(x) if v0 is None else np.array(v0, dtype=np.float64)
    f = np.asarray(evaluate(x), dtype=np.float64)
    history = SwarmHistory(evaluations=len(x))
    p_best, p_val = x.copy(), f.copy()
    g = int(np.argmax(p_val))
    history.best.append(float(p_val[g]))
    if progress:
        progress(0, float(p_val[g]))
    stall = _Stall(float(p_val[g]), s.gain, s.floor)
    for it in range(1, iterations + 1):
        r1, r2 = rng.random(x.shape), rng.random(x.shape)
        v = s.inertia * v + s.c_personal * r1 * (p_best - x) + s.c_global * r2 * (p_best[g] - x)
        x = x + v
        if project is not None:
            x = project(x)
        f = np.asarray(evaluate(x, p_val.copy()) if floors else evaluate(x), dtype=np.float64)
        history.evaluations += len(x)
        better = f > p_val
        p_best[better], p_val[better] = x[better], f[better]
        g = int(np.argmax(p_val))
        history.best.append(float(p_val[g]))
        if progress:
            progress(it, float(p_val[g]))
        if stall.idle_after(float(p_val[g])) >= s.patience > 0 and it < iterations:
            history.stopped = it
            break
    order = np.argsort(p_val)[::-1]
    history.finalists = [(p_best[i].copy(), float(p_val[i])) for i in order]
    return p_best[g].copy(), float(p_val[g]), history


NLOPT_METHODS = {
    "crs2": "GN_CRS2_LM",
    "esch": "GN_ESCH",
    "direct": "GN_DIRECT_L",
    "isres": "GN_ISRES",
    "mlsl": "GN_MLSL_LDS",
    "ags": "GN_AGS",
}


def nlopt_maximise(
    evaluate_one: Callable[[np.ndarray], float],
    lower: np.ndarray,
    upper: np.ndarray,
    method: str,
    max_evaluations: int,
    x0: np.ndarray,
    seed: int,
    progress: Callable[[int, float], None] | None = None,
):
    """Maximise a function of a box-bounded vector with one of nlopt's global methods.

    The budget is enforced here, not only by nlopt (some methods overshoot ``maxeval``): once it
    is spent, the objective asks nlopt to stop with ``opt.force_stop()`` and no longer calls
    ``evaluate_one``. An exception raised by ``evaluate_one`` stops nlopt the same way and is
    re-raised unchanged (raising through nlopt's C code would surface as ``SystemError``).

    Parameters
    ----------
    evaluate_one : callable
        Maps one position (D,) to a value.
    lower, upper : (D,) ndarrays
        Box bounds.
    method : str
        A key of :data:`NLOPT_METHODS`.
    max_evaluations : int
        Evaluation budget (at least 1).
    x0 : (D,) ndarray
        Starting point (used by methods that take one).
    seed : int
        nlopt's random seed.

    Returns
    -------
    best_x : (D,) ndarray
    best_value : float
    history : SwarmHistory

    Raises
    ------
    SieveError
        When nlopt fails before evaluating anything (e.g. a method that rejects the problem).
    """
    import nlopt

    nlopt.srand(int(seed))
    opt = nlopt.opt(getattr(nlopt, NLOPT_METHODS[method]), len(lower))
    history = SwarmHistory()
    best = {"x": np.array(x0, float), "f": -np.inf}
    failure: list[BaseException] = []

    def objective(x, grad):
        if failure or history.evaluations >= max_evaluations:
            opt.force_stop()  # methods that ignore it (crs2) stop at maxeval; nothing is evaluated
            return -np.inf
        try:
            f = float(evaluate_one(np.asarray(x)))
        except Exception as e:  # re-raised below, after nlopt has returned
            failure.append(e)
            opt.force_stop()
            return -np.inf
        history.evaluations += 1
        if f > best["f"]:
            best["x"], best["f"] = np.array(x, float), f
        history.best.append(best["f"])
        if progress:
            progress(history.evaluations, best["f"])
        return f

    opt.set_max_objective(objective)
    opt.set_lower_bounds(list(lower))
    opt.set_upper_bounds(list(upper))
    opt.set_maxeval(int(max_evaluations))
    if method == "mlsl":
        opt.set_local_optimizer(nlopt.opt(nlopt.LN_BOBYQA, len(lower)))
    _run_nlopt(opt, np.clip(x0, lower, upper), method, history)
    if failure:
        raise failure[0]
    return best["x"], best["f"], history


def _run_nlopt(opt, x0: np.ndarray, method: str, history: SwarmHistory) -> None:
    """``opt.optimize(x0)``, where a forced stop and a round-off limit are normal ends."""
    import nlopt

    from sieve_mi.errors import SieveError

    try:
        opt.optimize(list(x0))
    except (nlopt.ForcedStop, nlopt.RoundoffLimited):
        pass  # our budget or nlopt's precision: the best point seen so far stands
    except (RuntimeError, ValueError) as e:
        if history.evaluations == 0:
            raise SieveError(f"[solver] outer = {method!r}: nlopt failed to start: {e}") from None
        # nlopt's generic failure after some evaluations: they are still valid points.
