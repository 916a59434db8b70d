"""Canonical orientations: the views in which man-made parts have their thin optima.

A coin blocks a thicker coin only within a fraction of a degree of edge-on, a box gives its smallest
hole only face-on. A swarm of ten random particles lands near such orientations but rarely on
them, so player A's search also evaluates a few *canonical* views of each shape (as an extra first
generation, :meth:`sieve_mi.game.player_a.PlayerA.search`):

* the three principal axes of the convex hull (its inertia frame; the 24 axis-aligned frames
  :func:`principal_frames` give every signed permutation of them);
* the direction of minimum width and the direction of minimum projected area among the hull's
  facet normals and principal axes (for a convex polytope the width is smallest at a facet normal
  or an edge-edge direction; the area is checked on the same candidates);
* the normals of the hull's largest facets, largest first. A part resting on a table rests on one of
  them (its stable poses, which ``trimesh.poses.compute_stable_poses`` estimates by random
  sampling, are hull facets), so they are taken directly and deterministically.

Only the view direction matters for the hole: turning the shape about z turns H with it, and B may
turn the same way; a view and its opposite give mirror-image holes, which B passes alike (turned
upside down). Directions are therefore de-duplicated up to sign.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.rotations import align, from_matrix

__all__ = [
    "SAME_VIEW",
    "canonical_orientations",
    "principal_axes",
    "principal_frames",
    "proper_signed_permutations",
    "view_directions",
]

#: Two view directions closer than this (radians, up to sign) count as one.
SAME_VIEW = np.radians(0.5)


def _hull(shape: Shape):
    """The convex hull of the shape as a trimesh, or None when it is flat or degenerate."""
    import trimesh

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")  # trimesh warns about flat hulls; we check below
            hull = trimesh.convex.convex_hull(shape.hull)
            return hull if hull.volume > 1e-12 * shape.radius**3 else None
    except Exception:  # noqa: BLE001 - a flat or degenerate point set has no 3D hull
        return None


def principal_axes(shape: Shape) -> np.ndarray:
    """Principal axes of the shape, (3, 3) with one unit axis per row, a right-handed frame.

    From the inertia of the convex hull (a solid, whatever the mesh), or of the vertices for a flat
    shape. Rows are sorted by increasing moment.
    """
    hull = _hull(shape)
    if hull is not None:
        moments, axes = np.linalg.eigh(hull.moment_inertia)
    else:
        pts = shape.vertices - shape.vertices.mean(axis=0)
        moments, axes = np.linalg.eigh(-(pts.T @ pts))
    axes = axes.T
    axes[2] = np.cross(axes[0], axes[1])  # right-handed
    return axes


def principal_frames(shape: Shape) -> np.ndarray:
    """The 24 rotations that put the principal axes onto the coordinate axes, (24, 4) (w, x, y, z).

    Every proper signed permutation of the principal frame: for a box, its 24 axis-aligned poses.
    """
    axes = principal_axes(shape)
    return np.array([from_matrix(p @ axes) for p in proper_signed_permutations()])


def proper_signed_permutations() -> list[np.ndarray]:
    """The 24 rotation matrices with entries 0 and +-1 (a cube's rotations), each (3, 3)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            p = np.zeros((3, 3))
            p[np.arange(3), perm] = signs
            if np.linalg.det(p) > 0:
                out.append(p)
    return out


def _facets(hull) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals of the hull's planar facets and their areas, largest first."""
    key = np.round(hull.face_normals, 6)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    area = np.bincount(inverse.ravel(), weights=hull.area_faces, minlength=len(uniq))
    normal = uniq / np.linalg.norm(uniq, axis=1, keepdims=True)
    order = np.argsort(-area, kind="stable")
    return normal[order], area[order]


def view_directions(shape: Shape, count: int = 20) -> np.ndarray:
    """Up to ``count`` distinct canonical view directions (unit, body frame), (K, 3).

    Principal axes first, then the minimum-width and minimum-area directions, then the normals of
    the largest hull facets.
    """
    axes = principal_axes(shape)
    hull = _hull(shape)
    candidates = [*axes]
    if hull is not None:
        normals, areas = _facets(hull)
        pool = np.concatenate([normals, axes])
        proj = shape.hull @ pool.T
        width = proj.max(axis=0) - proj.min(axis=0)
        # projected area of a convex body along n: half the sum of |facet area * n_f . n|
        shadow = 0.5 * (np.abs(pool @ (normals * areas[:, None]).T)).sum(axis=1)
        candidates += [pool[np.argmin(width)], pool[np.argmin(shadow)], *normals]
    out: list[np.ndarray] = []
    for d in candidates:
        d = np.asarray(d, dtype=np.float64) / np.linalg.norm(d)
        if all(abs(float(np.dot(d, e))) < np.cos(SAME_VIEW) for e in out):
            out.append(d)
        if len(out) == count:
            break
    return np.array(out)


def canonical_orientations(shape: Shape, count: int = 20) -> np.ndarray:
    """Rotations (K, 4) that look along each canonical view direction (it goes to +z).

    Examples
    --------
    For a box, the three face-on views: ``len(canonical_orientations(box_shape)) == 3``.
    """
    z = np.array([0.0, 0.0, 1.0])
    return np.array([align(d, z) for d in view_directions(shape, count)])
