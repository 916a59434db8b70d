"""Exact verdicts: scoring and polishing poses of B against the polygon H that gets printed.

The search works on rasters; everything that decides a result is computed here on polygons
(manifold3d cross-sections, see :mod:`sieve_mi.geometry.outline`):

* :func:`score` gives a pose's exact β = area(S \\ H) / area(S), with S the union of B's projected
  triangles, and its protrusion: the largest distance from the boundary of S \\ H to H (the
  boundary sampled finely; a pocket of S \\ H enclosed by H on all sides could hide a larger
  interior value, so it is a lower bound there). A pose fits iff the protrusion is at most
  :data:`FIT_EPS` times the hole's size, i.e. only floating-point noise sticks out.
* :func:`polish` is player B's sub-pixel endgame: from a raster attack's pose it minimises the
  squared outside distances of B's outline points to the exact boundary of H (scipy's
  least-squares on rotation vector and translation). A slot whose margin is a small fraction of a
  pixel is found this way; the raster alone cannot see it.
* :func:`polish_margin` then slides the best blocked pose to where it sticks out least (a minimax
  over the outline points: the margin a user prints against, not a sum of squares);
* :func:`best_exact` scores a shape's candidate poses, polishes the best few and keeps the best;
  :func:`exact_rescore` does it for every shape of a raster attack (the verdict and ``check``).

Scores use exact point-in-polygon tests and exact point-to-segment distances. The polish, which
evaluates its residual hundreds of times, uses a dense sampling of H's boundary instead (a k-d
tree; at most half the sample spacing off, the sign from the nearest sample's outward normal); its
result is then scored exactly, so the approximation can cost a passage found, never a wrong score.
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d
import numpy as np

from sieve_mi.game.attack import Attack
from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.outline import (
    Boundary,
    along,
    is_closed,
    placed_vertices,
    silhouette,
)
from sieve_mi.geometry.rotations import (
    angle_between,
    from_rotvec,
    normalize,
    quat_multiply,
    to_matrix,
)

__all__ = [
    "MAX_SAMPLES",
    "CANDIDATES",
    "ExactAttempt",
    "ExactScore",
    "FIT_EPS",
    "best_exact",
    "exact_rescore",
    "outline_points",
    "polish",
    "polish_margin",
    "score",
]

#: A pose fits when nothing sticks out by more than this fraction of the hole's size (float noise).
FIT_EPS = 1e-7
#: Most samples on the outline of S \\ H for the protrusion (normal shapes need thousands; only a
#: shape thousands of holes across gets a coarser spacing, the protrusion still a lower bound).
MAX_SAMPLES = 1_000_000
#: Raster candidates kept per shape and hole for exact scoring (the best three are polished).
CANDIDATES = 8


@dataclass
class ExactScore:
    """A pose's exact score against H.

    Attributes
    ----------
    beta : float
        area(S \\ H) / area(S); 0 when the pose fits.
    protrusion : float
        Largest distance from S \\ H to H, scene units; 0 when the pose fits.
    outside_area : float
        area(S \\ H), square scene units.
    """

    beta: float
    protrusion: float
    outside_area: float

    @property
    def fits(self) -> bool:
        return self.protrusion == 0.0


def score(
    shape: Shape,
    quat,
    trans,
    hole: manifold3d.CrossSection,
    boundary: Boundary,
    closed: bool = False,
) -> ExactScore:
    """Exact β and protrusion of one pose of ``shape`` against the polygon ``hole``.

    Parameters
    ----------
    shape : Shape
    quat : (4,) array_like
        Rotation (w, x, y, z).
    trans : (2,) array_like
        Translation in the hole's plane, scene units.
    hole : manifold3d.CrossSection
        H.
    boundary : Boundary
        ``Boundary(hole)``.
    closed : bool
        The mesh is watertight (projection shortcut, see :func:`sieve_mi.geometry.outline.projection`).

    Returns
    -------
    ExactScore

    Examples
    --------
    A 1 x 1 square peg turned 45° in a 1.2 x 1.2 square hole sticks out at its four corners by
    sqrt(2)/2 - 0.6 each (see ``tests/game/test_exact.py``).
    """
    s = silhouette(shape, quat, trans, closed)
    eps = FIT_EPS * max(boundary.size, shape.radius)
    area = float(s.area())
    if area <= 0.0:  # seen edge-on: a flat shape's silhouette is a segment; use its vertices
        v = placed_vertices(shape, quat, trans)[:, :2]
        prot = float(max(0.0, boundary.signed(v).max()))
        prot = 0.0 if prot <= eps else prot
        return ExactScore(beta=0.0 if prot == 0 else 1.0, protrusion=prot, outside_area=0.0)
    out = s - hole
    out_area = float(out.area())
    prot = 0.0
    if not out.is_empty():
        edges = Boundary(out)
        perimeter = float(np.linalg.norm(edges.b - edges.a, axis=1).sum())
        spacing = max(boundary.spacing, perimeter / MAX_SAMPLES)  # a shape kilometres across
        pts = along(edges.a, edges.b, spacing)[0]
        prot = float(max(0.0, boundary.signed(pts).max())) if len(pts) else 0.0
    if prot <= eps:
        return ExactScore(beta=0.0, protrusion=0.0, outside_area=out_area)
    return ExactScore(beta=out_area / area, protrusion=prot, outside_area=out_area)


def outline_points(
    shape: Shape, quat, trans, spacing: float, closed: bool = False, most: int = 800
) -> np.ndarray:
    """Body-frame points (P, 3) whose projections trace B's silhouette outline at a pose.

    Mesh vertices and edge samples (``spacing`` apart) that project within two spacings of the
    outline of S (at most ``most`` of them, evenly thinned); for a small change of pose they still
    trace it, which is what :func:`polish` needs.
    """
    from sieve_mi.geometry.meshes import edge_topology

    v = shape.vertices
    edges = edge_topology(v, shape.faces)[0]
    samples = along(v[edges[:, 0]], v[edges[:, 1]], spacing, most=64)[0]
    body = np.concatenate([v, samples])
    xy = (body @ to_matrix(np.asarray(quat, dtype=np.float64)).T)[:, :2] + np.asarray(trans)
    outline = Boundary(silhouette(shape, quat, trans, closed), spacing)
    if len(outline.a) == 0:
        return body
    near = np.flatnonzero(outline.approx_signed(xy) > -2 * spacing)
    if len(near) > most:  # evenly thinned: the polish is a heuristic, the exact score decides
        near = near[np.linspace(0, len(near) - 1, most).astype(int)]
    return body[near]


class _Local:
    """Poses near a start, for the polishes: x = (rotation vector applied before the start's
    rotation, translation in units of B's radius, ...), and the signed distances to H of B's
    outline points (:func:`outline_points`) at such a pose."""

    def __init__(self, shape: Shape, quat, trans, boundary: Boundary, closed: bool, spacing):
        self.quat = normalize(np.asarray(quat, dtype=np.float64))
        self.trans = np.asarray(trans, dtype=np.float64)
        spacing = spacing if spacing is not None else shape.radius / 100
        self.body = outline_points(shape, self.quat, self.trans, spacing, closed)
        self.scale = max(shape.radius, 1e-12)
        self.boundary = boundary

    def pose(self, x):
        """(quat, trans) of the parameters ``x`` (only ``x[:5]`` are the pose's)."""
        q = normalize(quat_multiply(self.quat, from_rotvec(x[:3])))
        return q, self.trans + x[3:5] * self.scale

    def distances(self, x) -> np.ndarray:
        """(P,) signed distances of the outline points to H at pose ``x`` (positive outside)."""
        q, t = self.pose(x)
        return self.boundary.approx_signed((self.body @ to_matrix(q).T)[:, :2] + t)


def polish(
    shape: Shape,
    quat,
    trans,
    boundary: Boundary,
    *,
    closed: bool = False,
    spacing: float | None = None,
    max_nfev: int = 30,
) -> tuple[np.ndarray, np.ndarray]:
    """Slide one pose of ``shape`` into H using exact distances (player B's sub-pixel endgame).

    Minimises the sum over B's outline points of max(0, d_H(p) + m)^2, with d_H the signed
    distance to H and m a small clearance target (a thousandth of the sample spacing), over a
    rotation vector applied before ``quat`` and a translation.

    Parameters
    ----------
    shape : Shape
    quat : (4,) ndarray
    trans : (2,) ndarray
        Starting pose (scene units).
    boundary : Boundary
        H's boundary.
    closed : bool
    spacing : float, optional
        Spacing of B's outline points, scene units (default: 1/200 of B's diameter).
    max_nfev : int
        Most residual evaluations.

    Returns
    -------
    quat : (4,) ndarray
    trans : (2,) ndarray
        The polished pose (the start when nothing improved).
    """
    from scipy.optimize import least_squares

    local = _Local(shape, quat, trans, boundary, closed, spacing)
    quat, trans, scale, pose = local.quat, local.trans, local.scale, local.pose
    margin = 1e-3 * boundary.spacing

    def residual(x):
        return np.maximum(0.0, local.distances(x) + margin) / scale

    r0 = residual(np.zeros(5))
    if not np.any(r0 > 0):
        return quat, trans
    fit = least_squares(
        residual, np.zeros(5), method="trf", diff_step=1e-6, max_nfev=max_nfev, x_scale=1.0
    )
    if fit.cost >= 0.5 * float(r0 @ r0):
        return quat, trans
    return pose(fit.x)


def polish_margin(
    shape: Shape,
    quat,
    trans,
    boundary: Boundary,
    *,
    closed: bool = False,
    spacing: float | None = None,
    max_iter: int = 60,
) -> tuple[np.ndarray, np.ndarray]:
    """Slide a blocked pose to where it sticks out least: minimise the largest outside distance.

    :func:`polish` minimises a sum of squares, which spreads the protrusion over many points; the
    margin a user prints against is the smallest *largest* protrusion over poses. This solves
    min s subject to d_H(p_i) <= s for B's outline points p_i (SLSQP on a rotation vector, a
    translation and s), starting from ``quat``, ``trans``.

    Parameters
    ----------
    shape, quat, trans, boundary, closed, spacing
        As :func:`polish`.
    max_iter : int
        SLSQP iterations.

    Returns
    -------
    quat : (4,) ndarray
    trans : (2,) ndarray
        The pose found (the start when SLSQP failed); score it exactly before use.
    """
    from scipy.optimize import minimize

    local = _Local(shape, quat, trans, boundary, closed, spacing)

    def signed(x):
        return local.distances(x) / local.scale

    x0 = np.zeros(6)
    x0[5] = float(signed(x0).max())
    fit = minimize(lambda x: x[5], x0, method="SLSQP",
                   constraints=[{"type": "ineq", "fun": lambda x: x[5] - signed(x)}],
                   options={"maxiter": max_iter, "ftol": 1e-12})  # fmt: skip
    if not np.all(np.isfinite(fit.x)):
        return local.quat, local.trans
    return local.pose(fit.x)


def _same_pose(q1, t1, q2, t2, radius: float, rel: float = 1e-3) -> bool:
    """Two poses move no point of a shape of ``radius`` by more than ``rel * radius``."""
    angle = angle_between(q1, q2)
    return angle * radius + float(np.linalg.norm(np.subtract(t1, t2))) <= rel * radius


@dataclass
class ExactAttempt:
    """The best exactly scored pose of one shape."""

    quat: np.ndarray
    trans: np.ndarray
    score: ExactScore


def best_exact(
    shape: Shape,
    quats: np.ndarray,
    trans: np.ndarray,
    hole: manifold3d.CrossSection,
    boundary: Boundary,
    *,
    closed: bool = False,
    reach: float = np.inf,
    polished: int = 3,
    least_margin: bool = True,
) -> ExactAttempt:
    """Score every candidate pose exactly, polish the best few, keep the best by (β, protrusion).

    Parameters
    ----------
    shape : Shape
    quats : (K, 4) ndarray
    trans : (K, 2) ndarray
        Candidate poses (e.g. a raster attack's best starts), scene units.
    hole : manifold3d.CrossSection
    boundary : Boundary
        ``Boundary(hole)``.
    closed : bool
    reach : float
        Polish only poses that stick out by at most this much (scene units); the raster attack
        already resolved larger protrusions, the polish is for what a pixel cannot show.
    polished : int
        Polish at most this many distinct candidates, best exact score first.
    least_margin : bool
        Slide a blocked best pose to where it sticks out least (:func:`polish_margin`); off
        where only whether it fits matters (``check``'s fit-scale probes).

    Returns
    -------
    ExactAttempt
    """
    poses: list[tuple[np.ndarray, np.ndarray, ExactScore]] = []
    for q, t in zip(np.atleast_2d(quats), np.atleast_2d(trans)):
        if any(_same_pose(q, t, p[0], p[1], shape.radius) for p in poses):
            continue  # starts that converged to one pose are scored once
        sc = score(shape, q, t, hole, boundary, closed)
        if sc.fits:
            return ExactAttempt(np.asarray(q, float), np.asarray(t, float), sc)
        poses.append((q, t, sc))
    poses.sort(key=lambda p: (p[2].beta, p[2].protrusion))
    best = ExactAttempt(np.asarray(poses[0][0], float), np.asarray(poses[0][1], float), poses[0][2])
    for q, t, _sc in [p for p in poses if p[2].protrusion <= reach][:polished]:
        qq, tt = polish(shape, q, t, boundary, closed=closed)
        got = score(shape, qq, tt, hole, boundary, closed)
        if (got.beta, got.protrusion) < (best.score.beta, best.score.protrusion):
            best = ExactAttempt(np.asarray(qq, float), np.asarray(tt, float), got)
        if got.fits:
            break
    if least_margin and not best.score.fits and best.score.protrusion <= reach:
        qq, tt = polish_margin(shape, best.quat, best.trans, boundary, closed=closed)
        got = score(shape, qq, tt, hole, boundary, closed)
        if got.fits or got.protrusion < best.score.protrusion:
            best = ExactAttempt(np.asarray(qq, float), np.asarray(tt, float), got)
    return best


def exact_rescore(
    attack, blocks: list[Shape], target, report_against=None, reach=np.inf, least_margin=True
):
    """Polish and score every candidate pose of ``attack`` exactly; one row per shape.

    Parameters
    ----------
    attack : Attack
        A raster attack that kept candidates (``keep > 0``), on any number of holes.
    blocks : list of Shape
    target : manifold3d.CrossSection
        The polygon that decides (H, or H grown by the block margin).
    report_against : manifold3d.CrossSection, optional
        H itself when ``target`` is grown: the best pose is scored against it too, and the
        target's scores go to ``margin_beta`` / ``margin_protrusion``.
    reach : float
        :func:`best_exact`'s ``reach``, scene units.
    least_margin : bool
        :func:`best_exact`'s ``least_margin``.

    Returns
    -------
    Attack
        One row: per shape, its best exact attempt over all holes and candidates.
    """
    cq, ct = attack.candidates
    boundary = Boundary(target)
    n_b = len(blocks)
    beta, prot = np.ones((1, n_b)), np.zeros((1, n_b))
    quats, trans = np.zeros((1, n_b, 4)), np.zeros((1, n_b, 2))
    for j, shape in enumerate(blocks):
        best = best_exact(
            shape,
            cq[:, j].reshape(-1, 4),
            ct[:, j].reshape(-1, 2),
            target,
            boundary,
            closed=is_closed(shape),
            reach=reach,
            least_margin=least_margin,
        )
        beta[0, j], prot[0, j] = best.score.beta, best.score.protrusion
        quats[0, j], trans[0, j] = best.quat, best.trans
    out = Attack(beta, prot, quats, trans, fits=attack.fits.sum(axis=0)[None])
    if report_against is not None:
        out.margin_beta, out.margin_protrusion = beta.copy(), prot.copy()
        hole_boundary = Boundary(report_against)
        for j, shape in enumerate(blocks):
            sc = score(
                shape, quats[0, j], trans[0, j], report_against, hole_boundary, is_closed(shape)
            )
            out.beta[0, j], out.protrusion[0, j] = sc.beta, sc.protrusion
    return out
