"""Rest poses in the game: player A prefers a pass pose that a shaken part already lies in.

A part shaken on a sieve spends its time lying on the plate in one of its resting poses
(:func:`sieve_mi.geometry.pose_words.resting_poses`: the hull faces it can rest on, each with the
quasi-static share of random drops that settle on it). The hole is A's silhouette along z, and
a part resting on face k, turned by any angle about z and shifted, shows the silhouette of the
rotation that puts face k down turned and shifted in the plane: the same hole, turned. So each
rest pose is one candidate rotation of A (:func:`likely_rests`), and the turn about z is free
(player B's attack turns and shifts B in the plane anyway).

With ``[solver] rest_poses = true`` the likely rest poses (share at least :data:`LIKELY_SHARE`)
join the canonical views of player A's search, and among the rotations that win (every B
blocked by the attack) A takes the one with the least share-weighted angle
``(angle + EXACT_DEG) / share`` to a likely rest pose (:func:`rest_cost`, :func:`prefer`):
an exact rest pose costs ``1 / share``, so of two winning rest poses the more frequent one is
taken, and the search's own rotation is kept only when it is itself that close to a frequent
rest pose. A rest pose chosen over the search's rotation is first judged by an attack as strong
as the verdict's (``[verdict] starts`` and ``steps``); one that lets a B through there is passed
over. This is a preference among holes that block, not a proof: the verdict and certify judge
the chosen hole as any other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.pose_words import positions_of, resting_poses
from sieve_mi.geometry.rotations import align, normalize, to_matrix

__all__ = [
    "EXACT_DEG",
    "LIKELY_SHARE",
    "SAME_COST",
    "Rests",
    "likely_rests",
    "nearest_rest",
    "prefer",
    "rest_cost",
    "rest_records",
]

#: A rest pose is *likely* when at least this share of random drops settles on it (5 %: a
#: brick's six faces are likely, its tilted rests on a stud's edge, under 1 % each, are not).
LIKELY_SHARE = 0.05
#: Costs within this fraction of each other are equal (the search's exact face-on rotation and
#: the same rest pose's differ by rounding).
SAME_COST = 1e-6
#: Degrees added to the angle in :func:`rest_cost`, so that exact rest poses are ranked by share
#: (a pose within about a degree of a rest pose is, for a part on a plate, that rest pose).
EXACT_DEG = 1.0


@dataclass
class Rests:
    """A part's resting poses on a flat plate.

    Attributes
    ----------
    normals : (R, 3) ndarray
        The body direction that points down in each (a hull face's outward normal), unit.
    shares : (R,) ndarray
        The quasi-static share of random drops that settle in each, summing to 1.
    positions : list of str
        Each one's position in words (one of
        :data:`~sieve_mi.geometry.pose_words.POSITIONS`, :func:`~sieve_mi.geometry.pose_words.
        positions_of`).
    """

    normals: np.ndarray
    shares: np.ndarray
    positions: list

    @classmethod
    def of(cls, shape: Shape) -> Rests | None:
        """The resting poses of ``shape``; None for a flat part (it has none)."""
        got = resting_poses(shape)
        if got is None:
            return None
        normals, shares = got
        positions = positions_of(shape, normals)
        return cls(np.asarray(normals, dtype=np.float64), np.asarray(shares), positions)

    def likely(self, threshold: float = LIKELY_SHARE) -> np.ndarray:
        """Indices of the rest poses with a share of at least ``threshold``, most frequent first
        (at least the most frequent one)."""
        order = np.argsort(-self.shares, kind="stable")
        keep = order[self.shares[order] >= threshold]
        return keep if len(keep) else order[:1]

    def quaternions(self, index) -> np.ndarray:
        """Rotations (K, 4) that put rest pose ``index`` (K indices) face down: each takes its
        normal to -z by the shortest turn (any turn about z after it is the same hole, turned)."""
        return np.stack([align(self.normals[k], [0.0, 0.0, -1.0]) for k in index])

    def angles(self, quat) -> np.ndarray:
        """Angle (R,) between the down direction of rotation ``quat`` and each rest pose's,
        degrees (a turn about z changes none)."""
        down = to_matrix(normalize(np.asarray(quat, dtype=np.float64))).T @ [0.0, 0.0, -1.0]
        return np.degrees(np.arccos(np.clip(self.normals @ down, -1.0, 1.0)))


def likely_rests(shape: Shape, threshold: float = LIKELY_SHARE) -> tuple[Rests | None, np.ndarray]:
    """The part's resting poses and the rotations (K, 4) of its likely ones, most frequent first
    ((None, empty (0, 4)) for a flat part)."""
    rests = Rests.of(shape)
    if rests is None:
        return None, np.zeros((0, 4))
    return rests, rests.quaternions(rests.likely(threshold))


def rest_cost(rests: Rests, quat, threshold: float = LIKELY_SHARE) -> tuple[float, int]:
    """The share-weighted angle of ``quat`` to the likely rest poses, and the one it is nearest
    by that measure: min over likely k of ``(angle_k + EXACT_DEG) / share_k`` (degrees)."""
    likely = rests.likely(threshold)
    costs = (rests.angles(quat)[likely] + EXACT_DEG) / rests.shares[likely]
    k = int(np.argmin(costs))
    return float(costs[k]), int(likely[k])


def nearest_rest(shape: Shape, quat, rests: Rests | None = None) -> dict | None:
    """report.json's ``rest`` of a pass pose: the nearest resting pose and how far it is.

    Returns
    -------
    dict or None
        ``position`` (words), ``down`` (the body direction pointing down in it, (3,)),
        ``share`` (the share of random drops that settle on that face), ``position_share``
        (on any face in that position), ``angle_deg`` (between the pose's down direction and
        its, degrees) and ``likely`` (share at least :data:`LIKELY_SHARE`); None for a flat
        part.
    """
    rests = Rests.of(shape) if rests is None else rests
    if rests is None:
        return None
    angles = rests.angles(quat)
    k = int(np.argmin(angles))
    position = rests.positions[k]
    same = [p == position for p in rests.positions]
    return {
        "position": position,
        "down": [float(x) + 0.0 for x in np.round(rests.normals[k], 6)],
        "share": float(rests.shares[k]),
        "position_share": float(rests.shares[same].sum()),
        "angle_deg": float(angles[k]),
        "likely": bool(rests.shares[k] >= LIKELY_SHARE),
    }


def prefer(
    rests: Rests, found: tuple, rest_quats: np.ndarray, rest_values: np.ndarray,
    verify: Callable[[np.ndarray], float],
) -> tuple[np.ndarray, float, dict]:  # fmt: skip
    """Player A's rotation among the winning ones: the least :func:`rest_cost`.

    Parameters
    ----------
    rests : Rests
    found : (quat (4,), value float)
        The search's own best rotation and its game value.
    rest_quats : (K, 4) ndarray
        The likely rest poses' rotations, as :func:`likely_rests` gives them.
    rest_values : (K,) ndarray
        Their game values from the search's attack (> 0: every B blocked).
    verify : callable
        ``verify(quat)``: the game value of a rotation under a stronger attack; called on a rest
        pose before it replaces the search's rotation.

    Returns
    -------
    quat : (4,) ndarray
    value : float
        The search's value for it (the stronger attack's for a rest pose that was verified).
    record : dict
        ``chosen`` ("search" or "rest pose"), its ``cost`` (share-weighted degrees), the
        ``search``'s rotation (its nearest rest pose's ``position``, ``angle_deg`` and
        ``share``, its ``value`` and ``cost``), and ``tried``, per rest pose judged by
        ``verify`` in turn: its ``share``, ``value`` and ``verified`` value.
    """
    q0, f0 = np.asarray(found[0], dtype=np.float64), float(found[1])
    cost0 = rest_cost(rests, q0)[0]
    angles = rests.angles(q0)
    near = int(np.argmin(angles))
    search = {"position": rests.positions[near], "angle_deg": float(angles[near]),
              "share": float(rests.shares[near]), "value": f0, "cost": cost0}  # fmt: skip
    tried = []
    options = sorted(
        (rest_cost(rests, q)[0], i) for i, q in enumerate(rest_quats) if rest_values[i] > 0
    )
    for cost, i in options:
        if cost >= cost0 * (1 - SAME_COST) and f0 > 0:  # no better than the search's own
            break
        checked = float(verify(rest_quats[i]))
        k = rest_cost(rests, rest_quats[i])[1]
        tried.append({"share": float(rests.shares[k]), "value": float(rest_values[i]),
                      "verified": checked})  # fmt: skip
        if checked > 0:
            record = {"chosen": "rest pose", "cost": cost, "search": search, "tried": tried}
            return normalize(rest_quats[i]), checked, record
    record = {"chosen": "search", "cost": cost0, "search": search, "tried": tried}
    return q0, f0, record


def rest_records(passes: list, quats: np.ndarray, choices: dict) -> list:
    """report.json's ``rest`` per A: :func:`nearest_rest` of its rotation (None for a flat
    part), with ``preferred``, the record of :func:`prefer`, where ``choices`` (index to record,
    from ``[solver] rest_poses``) has one."""
    out = []
    for i, (shape, q) in enumerate(zip(passes, quats)):
        row = nearest_rest(shape, q)
        if row is not None and i in choices:
            row["preferred"] = choices[i]
        out.append(row)
    return out
