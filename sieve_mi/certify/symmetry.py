"""Rotational symmetries of a shape that shrink the rotation domain of the search.

If a rotation S maps the mesh onto itself (S B = B), the poses R and R S place the same set, so
a pose q and q s (s the quaternion of S) are interchangeable. Two groups are detected, exactly:

* ``"klein"``: the half turns about the x, y and z axes (quaternions i, j, k). Right-multiplying by
  i, j or k permutes the absolute values of q's components (|w|<->|x|, |y|<->|z| for i, and so
  on), so every pose has an equivalent one whose largest component is w: face 0 alone suffices.
* ``"octahedral"``: additionally the quarter turns about the axes (the 24 rotations of a cube).
  With the 48 quaternions g of that group, the pose q s maximising |q . g| lies in the region
  {|w| >= |q . g| for all g} (right multiplication is an isometry of R^4), which in face 0 is
  |x|, |y|, |z| <= (sqrt 2 - 1) and |x| + |y| + |z| <= 1: the box of half-width
  :data:`OCTA_HALF` > sqrt 2 - 1 covers it.

Only the vertex set needs to be symmetric, not the triangles (a cube's triangulated faces are
not): every exclusion is a statement about vertices only ("no translation puts these vertices
inside H"). If B passed in a pose q, all its vertices V would fit in pose q; in pose q s they are
R(q) S V = R(q) V, the same set, so they would fit too, contradicting the exclusion of the cell
holding q s. Passages are checked in the pose found, on the whole mesh. The matrices have entries
0 and +-1, so the test is exact in floating point.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.meshes import Shape

__all__ = [
    "HALF_TURNS",
    "OCTA_HALF",
    "QUARTER_TURNS",
    "detect",
    "domain",
    "maps_onto_itself",
    "symmetric_edges",
]

#: Half-width of the face-0 box that holds the octahedral group's fundamental region.
OCTA_HALF = 0.41422  # > sqrt(2) - 1 = 0.414213...

HALF_TURNS = [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
QUARTER_TURNS = [
    np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
    np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
]


def maps_onto_itself(vertices: np.ndarray, matrix: np.ndarray) -> bool:
    """Whether ``matrix`` (a signed permutation) maps the vertex set onto itself, exactly.

    Parameters
    ----------
    vertices : (V, 3) float ndarray
        Distinct vertices.
    matrix : (3, 3) ndarray with entries 0, +-1
    """
    moved = vertices @ matrix.T
    a = vertices[np.lexsort(vertices.T[::-1])]
    b = moved[np.lexsort(moved.T[::-1])]
    return bool(np.array_equal(a, b))


def detect(shape: Shape) -> str:
    """The largest of the groups ``"octahedral"`` > ``"klein"`` > ``"none"`` that maps the shape onto itself."""
    v = shape.vertices[np.unique(shape.faces)]
    if not all(maps_onto_itself(v, m) for m in HALF_TURNS):
        return "none"
    if all(maps_onto_itself(v, m) for m in QUARTER_TURNS):
        return "octahedral"
    return "klein"


def symmetric_edges(shape: Shape, group: str) -> np.ndarray:
    """The mesh edges whose images under ``group`` are all mesh edges, (k, 2) vertex indices.

    The largest edge set closed under the group's generators (removing, until none is left, every
    edge that a generator maps off the set). A finite group then maps the union of these edges
    (as a point set) onto itself, so the symmetry argument holds for evidence points on them as
    it does for vertices. With ``"none"``, every edge.
    """
    mats = {"none": [], "klein": HALF_TURNS, "octahedral": HALF_TURNS + QUARTER_TURNS}[group]
    f = shape.faces
    pairs = np.unique(
        np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1), axis=0
    )
    v = shape.vertices
    if not mats:
        return pairs

    def key(a: np.ndarray, b: np.ndarray) -> tuple:
        return tuple(sorted((tuple(a), tuple(b))))

    keep = {key(v[i], v[j]): (i, j) for i, j in pairs}
    changed = True
    while changed:
        changed = False
        for k in list(keep):
            a, b = np.array(k[0]), np.array(k[1])
            if any(key(m @ a, m @ b) not in keep for m in mats):
                del keep[k]
                changed = True
    return np.array(sorted(keep.values()), dtype=np.int64).reshape(-1, 2)


def domain(group: str) -> tuple[list[int], float]:
    """Faces and box half-width that cover SO(3) modulo ``group``."""
    if group == "octahedral":
        return [0], OCTA_HALF
    if group == "klein":
        return [0], 1.0
    return [0, 1, 2, 3], 1.0
