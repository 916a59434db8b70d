"""Scoring poses with binary masks: the normalised outside area beta (paper eq. 12) and the
protrusion, the largest distance by which a pose's silhouette sticks out of the hole."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sieve_mi.hole import Hole
from sieve_mi.silhouettes import SilhouetteRenderer


@dataclass
class PoseScores:
    """Binary scores of K poses of one shape against one hole.

    Attributes
    ----------
    beta : (K,) ndarray
        area(proj(B') minus H) / area(proj(B')), from pixel-centre masks; 0 means the pose fits.
    protrusion : (K,) ndarray
        Largest distance (scene units) from a silhouette pixel centre of the pose to H; 0 if it fits.
    """

    beta: np.ndarray
    protrusion: np.ndarray


def window_for(renderer: SilhouetteRenderer, hole: Hole, trans: np.ndarray, cap: int | None = None):
    """Lattice windows covering each pose's bounding disk: (row0, col0, size)."""
    f = hole.frame
    h = f.pixel_size
    r = renderer.shape.radius
    size = int(np.ceil(2 * r / h)) + 3
    cap = cap or 2 * f.resolution + 3
    size = min(size, cap)
    corner = f.to_pixel(np.asarray(trans) + np.array([-r, r]))
    centre = f.to_pixel(np.asarray(trans))
    # Centre the window on the pose when it is capped, else put its corner at the disk's corner.
    start = np.where(size < int(np.ceil(2 * r / h)) + 3, centre - size / 2, corner)
    start = np.floor(start).astype(np.int64) - 1
    return start[:, 1], start[:, 0], size


def score_poses(renderer: SilhouetteRenderer, hole: Hole, quats: np.ndarray, trans: np.ndarray,
                return_masks: bool = False):
    """Beta and protrusion of poses of one shape against one hole.

    Parameters
    ----------
    renderer : SilhouetteRenderer
        The shape's renderer.
    hole : Hole
    quats : (K, 4) ndarray
        Rotations (w, x, y, z).
    trans : (K, 2) ndarray
        Translations, scene units.
    return_masks : bool
        Also return the windows and masks (for figures).

    Returns
    -------
    PoseScores, and if asked (row0, col0, size, masks)
    """
    quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
    row0, col0, size = window_for(renderer, hole, trans)
    masks = renderer.masks(quats, trans, hole.frame, row0, col0, size)
    beta = np.zeros(len(quats))
    prot = np.zeros(len(quats))
    lo, hi = renderer.projected_extent(quats, trans)
    h = hole.frame.pixel_size
    for k in range(len(quats)):
        inside, dist = hole.window(int(row0[k]), int(col0[k]), size)
        m = masks[k]
        area = m.sum()
        out = m & ~inside
        beta[k] = out.sum() / area if area else 1.0
        prot[k] = float(dist[out].max()) if out.any() else 0.0
        # A projection larger than the (capped) window cannot fit; never call it a fit.
        x, y = hole.frame.window_centres(row0[k : k + 1], col0[k : k + 1], size)
        clipped = lo[k, 0] < x[0, 0] - h or hi[k, 0] > x[0, -1] + h or hi[k, 1] > y[0, 0] + h or lo[k, 1] < y[0, -1] - h
        if clipped:
            corners = np.array([[lo[k, 0], lo[k, 1]], [lo[k, 0], hi[k, 1]], [hi[k, 0], lo[k, 1]], [hi[k, 0], hi[k, 1]]])
            prot[k] = max(prot[k], float(hole.outside_distance(corners).max()))
            beta[k] = max(beta[k], 1.0 / max(area, 1))
    scores = PoseScores(beta=beta, protrusion=prot)
    if return_masks:
        return scores, (row0, col0, size, masks)
    return scores
