"""Player B's Adam step, recorded once with :func:`drjit.freeze` and replayed.

A step of :meth:`sieve_mi.game.players.PlayerB.descend` is loss, gradient, "keep the best pose" and
Adam's update: about fifteen kernel launches, re-traced in Python every time. Frozen, the first
call records the launches and later calls replay them with new inputs, skipping the tracing. For
that, a step may neither read values back nor make arrays whose size depends on data, so the
objective must offer ``loss_fixed(q, t, holes, pose_hole, capacity)`` (a fixed-size version of
``loss`` that also returns an overflow flag, see
:meth:`sieve_mi.objectives.clearance.ClearanceObjective.loss_fixed`) and ``capacity(q)``, and say so with
``freezable = True``; its Dr.Jit arrays must be listed in ``DRJIT_STRUCT`` (frozen functions see
only what they can traverse).

The first two steps of a descent are traced: their inputs are laid out differently (the best
poses are Adam's parameters themselves, then Adam's state is new), and would be recorded anew
in every descent. A recording is reused by every call with the same Python values (frame scale, buffer capacity,
pose count): every Adam step of an attack, and the attacks of later PSO iterations of the same
size. The results are the same as unfrozen (a test holds them together); when the buffer
overflows, :meth:`~sieve_mi.game.players.PlayerB.descend` runs the descent again unfrozen.
"""

from __future__ import annotations

from sieve_mi.optim import POSE_KEYS, QUAT_KEYS, live_poses, renormalise_quaternions

__all__ = ["frozen_step"]


def _step(opt, best, best_loss, overflow, loss, stack, pose_hole, key, group=None):
    """One Adam step; ``key`` = (scale, capacity, poses, pairs[, groups, fit_loss]) are Python
    values (recording key); ``group`` (mi.UInt32, K) the poses' settling groups, if any."""
    import drjit as dr

    scale, capacity = key[0], key[1]
    q = tuple(opt[k] for k in QUAT_KEYS)
    t = (opt["tx"] * scale, opt["ty"] * scale)
    live = None if group is None else live_poses(best_loss, group, key[4], key[5])
    total, per_pose, over = loss.loss_fixed(q, t, stack, pose_hole, capacity, live=live)
    if live is not None:
        per_pose = dr.select(live, per_pose, float("inf"))  # a settled pose keeps its best
    # every pose settled between two checks: nothing depends on the poses any more
    dr.backward(total, flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
    # Each start keeps the best pose it visited (Adam may step past a fit).
    improved = per_pose < best_loss
    best = [dr.select(improved, dr.detach(opt[k]), b) for k, b in zip(POSE_KEYS, best)]
    best_loss = dr.select(improved, per_pose, best_loss)
    opt.step(eval=False)
    renormalise_quaternions(opt, best, best_loss)
    return best, best_loss, overflow | over


def frozen_step():
    """A new frozen Adam step: ``step(opt, best, best_loss, overflow, loss, stack, pose_hole,
    key)`` returns the new ``(best, best_loss, overflow)`` and updates ``opt`` in place.

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
    stack : HoleStack
    pose_hole : mi.UInt32
    key : tuple
        (scale, capacity, K, pairs): the frame's half extent, ``loss.capacity(q)``, and sizes;
        with settling, then the number of groups and the objective's ``fit_loss``.
    group : mi.UInt32, optional
        Each pose's settling group (:meth:`sieve_mi.game.players.PlayerB.attack`'s ``settle``).
    """
    import drjit as dr

    # Each descent records its first frozen step once (docs/method.md), so a long solve (many A,
    # restarts) passes Dr.Jit's default warning threshold without anything being wrong.
    return dr.freeze(_step, limit=8, warn_after=100_000)
