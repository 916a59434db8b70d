"""Player B's Adam step, recorded once with :func:`drjit.freeze` and replayed.

A step of player B's descent (:func:`sieve_mi.game.descent.adam_step`, the same step a traced
descent runs) is loss, gradient, "keep the best pose" and Adam's update: about fifteen kernel
launches, re-traced in Python every time. Frozen, the first call records the launches and later
calls replay them with new inputs, skipping the tracing. For that, a step may neither read values back nor make arrays whose size depends on data, so the
objective must offer ``loss_fixed(q, t, holes, pose_hole, capacity)`` (a fixed-size version of
``loss`` that also returns an overflow flag, see
:meth:`sieve_mi.objectives.clearance.ClearanceObjective.loss_fixed`) and ``capacity(q)``, and say so with
``freezable = True``; its Dr.Jit arrays must be listed in ``DRJIT_STRUCT`` (frozen functions see
only what they can traverse).

Every step of a descent is frozen, the first too: its inputs have the layout of the later
ones, since :class:`~sieve_mi.game.descent.Descent` keeps the best poses in arrays of their own
(not the optimiser's, which an input may not alias) and :func:`replay` makes Adam's state
opaque (until 2026-12-07 the first two steps were traced: 2 x 21 ms a descent on the CPU).
A recording is reused by every call with the same Python values (frame scale, buffer capacity,
pose count): every Adam step of an attack, and the attacks of later PSO iterations of the same
size. The results are the same as unfrozen (a test holds them together); when the buffer
overflows, :meth:`~sieve_mi.game.player_b.PlayerB.descend` runs the descent again unfrozen.
Freezing pays where the objective allows it and, on the CPU, up to :data:`CPU_FREEZE_PAIRS`
(:func:`pays`).

Python's cyclic garbage collector is held off while a frozen step runs (:func:`collector_held`).
A collection that lands inside a recording and frees a Mitsuba scene that has traced rays (a
renderer left in a reference cycle by an earlier solve or test) ends the process: the scene's
Embree release queues a host function, which a recording refuses with a C++ exception thrown
from a destructor, so ``std::terminate`` aborts the interpreter with nothing to catch (seen
twice in the suite, 2026-12-08, as a crashed worker). Held off, the collection runs after the
step instead.
"""

from __future__ import annotations

import contextlib
import gc
import threading

from sieve_mi.game.descent import adam_step, pose_loss
from sieve_mi.optim import QUAT_KEYS, live_poses

__all__ = ["CPU_FREEZE_PAIRS", "collector_held", "frozen_step", "pays", "replay"]

#: On the CPU (LLVM variants) descents with more (pose, segment) pairs than this trace their steps
#: even with ``freeze``: there a big step is bound by arithmetic and the frozen step's fixed-size
#: buffer passes cost more than tracing saves (benchmarks/notes/performance-history.md: a 70k-face bunny at 100 poses,
#: 15M pairs, steps 15 % slower frozen; spot/cow's verdict, 2.7M pairs, is 1.1x faster frozen).
CPU_FREEZE_PAIRS = 5_000_000


def _step(opt, best, best_loss, overflow, loss, holes, key, settle=None, alive=None):
    """One :func:`~sieve_mi.game.descent.adam_step` with the objective's fixed-size loss;
    ``holes`` = (stack, pose_hole) the hole stack and each pose's hole; ``key`` = (scale,
    capacity, poses, pairs) are Python values (recording key); ``settle`` = (group, groups,
    fit_loss), the poses' settling groups (mi.UInt32, K) and two Python values, or None;
    ``alive`` (mi.Bool, K, or None): the poses successive halving keeps descending."""
    scale, capacity = key[0], key[1]
    live = None if settle is None else live_poses(best_loss, *settle)
    if alive is not None:
        live = alive if live is None else live & alive

    def evaluate():
        return pose_loss(opt, loss, *holes, scale, live, capacity)

    best, best_loss, over = adam_step(opt, best, best_loss, evaluate)
    return best, best_loss, overflow | over


class _Collector:
    """Holds Python's cyclic garbage collector off while any thread is inside :meth:`held`,
    and gives it back as it was (enabled or not) when the last one leaves."""

    def __init__(self):
        self._lock = threading.Lock()
        self._inside = 0
        self._was_enabled = False

    @contextlib.contextmanager
    def held(self):
        with self._lock:
            if self._inside == 0:
                self._was_enabled = gc.isenabled()
                gc.disable()
            self._inside += 1
        try:
            yield
        finally:
            with self._lock:
                self._inside -= 1
                if self._inside == 0 and self._was_enabled:
                    gc.enable()


_COLLECTOR = _Collector()


def collector_held():
    """A context manager in which Python's cyclic garbage collector does not run (see the module
    docstring: a collection inside a :func:`drjit.freeze` recording may abort the process).
    Objects freed by their reference counts are freed as always; cycles wait for the block's end.

    Examples
    --------
    >>> import gc
    >>> with collector_held():
    ...     gc.isenabled()
    False
    """
    return _COLLECTOR.held()


def frozen_step():
    """A new frozen Adam step: ``step(opt, best, best_loss, overflow, loss, holes, key,
    settle, alive)`` returns the new ``(best, best_loss, overflow)`` and updates ``opt`` in place.

    Parameters of the returned callable
    -----------------------------------
    opt : drjit.opt.Adam
        From :func:`sieve_mi.optim.pose_adam` (translations in units of ``scale``).
    best : list of 6 mi.Float
        Each start's best pose so far (:data:`~sieve_mi.optim.POSE_KEYS` order).
    best_loss : mi.Float
        Its loss (K,).
    overflow : mi.Bool
        One entry, or-ed with this step's overflow flag.
    loss : Objective with ``loss_fixed``
        Bound to the K poses.
    holes : tuple
        (stack, pose_hole): the :class:`~sieve_mi.geometry.hole.HoleStack` and each pose's hole
        (mi.UInt32, K).
    key : tuple
        (scale, capacity, K, pairs): the frame's half extent (scene units), ``loss.capacity(q)``,
        and sizes; Python values, so part of the recording's key.
    settle : tuple, optional
        (group, groups, fit_loss): each pose's settling group (mi.UInt32, K;
        :meth:`sieve_mi.game.player_b.PlayerB.attack`'s ``settle``), the number of groups and
        the objective's ``fit_loss`` (Python values, part of the key); None without settling.
    alive : mi.Bool, optional
        (K,): the poses successive halving keeps descending (``[solver] halving``); None: all.
    """
    import drjit as dr

    # Each descent records its first frozen step once (docs/method.md), so a long solve (many A,
    # restarts) passes Dr.Jit's default warning threshold without anything being wrong.
    return dr.freeze(_step, limit=8, warn_after=100_000)


def pays(loss) -> bool:
    """Whether freezing the steps of a descent bound to ``loss`` is possible and pays: the
    objective is ``freezable``, and on the CPU it binds at most :data:`CPU_FREEZE_PAIRS` pairs."""
    import mitsuba as mi

    if not loss.freezable:
        return False
    return not (loss.pair_count > CPU_FREEZE_PAIRS and mi.variant().startswith("llvm"))


def replay(step, descent):
    """The frozen steps of one descent, replaying ``step`` (from :func:`frozen_step`).

    Parameters
    ----------
    step : callable
        A :func:`frozen_step`, shared by a player's descents (each recording is reused).
    descent : sieve_mi.game.descent.Descent
        Its optimiser, objective, holes, scale and settling groups, as they are now.

    Returns
    -------
    callable
        ``steps(best, best_loss) -> (best, best_loss)``, which updates the descent's optimiser;
        ``steps.overflowed()`` tells whether any step's buffer overflowed (its results are then
        wrong).
    """
    import drjit as dr
    import mitsuba as mi

    opt, loss, settle = descent.opt, descent.loss, descent.settle
    settling = None if settle is None else (settle.group, settle.groups, settle.fit_loss)
    holes = (descent.stack, descent.hole_idx)
    capacity = loss.capacity(tuple(opt[name] for name in QUAT_KEYS))
    record = (descent.scale, capacity, loss.pose_count, loss.pair_count)
    state = {"overflow": dr.opaque(mi.Bool, False)}

    def steps(best, best_loss):
        # Literals (Adam's step counter after the traced steps) become evaluated arrays, so
        # the first frozen step has the layout of the later ones (else it is recorded twice).
        dr.make_opaque(opt.state, best, best_loss)
        with collector_held():  # a collection inside a recording may abort (module docstring)
            best, best_loss, state["overflow"] = step(
                opt, best, best_loss, state["overflow"], loss, holes, record, settling,
                descent.alive_mask,
            )  # fmt: skip
        return best, best_loss

    steps.overflowed = lambda: bool(state["overflow"][0])
    return steps
