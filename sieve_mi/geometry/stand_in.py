"""Simplified stand-ins for big meshes during the search (``[solver] stand_in``).

Player B's attacks during player A's search cost time in proportion to B's silhouette edges; a
closed B of thousands of faces can be replaced there by a coarser copy whose surface lies within
a given distance of the original (:func:`stand_in`, Manifold's edge-collapse simplification: the
copy keeps a subset of the original's vertices, and every surface moves by less than the
tolerance, so every silhouette moves by less than it too). The verdict and every proof use the
full meshes: a stand-in only steers the search.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sieve_mi.geometry.meshes import Shape

__all__ = ["AUTO_FACES", "AUTO_PIXELS", "STAND_IN", "stand_in", "stand_ins", "tolerance"]

#: The meaning of ``[solver] stand_in`` (scene units, or "auto"; 0: off).
STAND_IN = (
    "player A's search plays against each closed B simplified so that no surface moves more "
    "than this (fewer silhouette edges, faster attacks); the verdict and every proof use the "
    'full meshes; "auto": half a pixel of the search\'s finest raster, for B of more than '
    "5,000 faces; 0: the full meshes throughout"
)
#: ``[solver] stand_in = "auto"`` (off by default) simplifies within this many pixels of the finest
#: raster the search plays on: no silhouette moves by more than half a pixel, less than the
#: raster itself resolves (a hole's pixels are those whose centres lie inside it).
AUTO_PIXELS = 0.5
#: ... and only B of more faces than this: small meshes cost little per step, and simplifying
#: them changed the letters' search (β up to 11 % lower) for no gain. Not the default: on the
#: fandisk row of the authors' table it lowered β by 39 % (docs/performance.md, "Knobs").
AUTO_FACES = 5000


def tolerance(setting: float | str, pixel: float) -> float:
    """The stand-in tolerance of a ``[solver] stand_in`` setting, scene units.

    Parameters
    ----------
    setting : float or "auto"
        The scene's value: a distance (scene units; 0: off), or "auto".
    pixel : float
        The smallest pixel of the rasters the search plays on, scene units.

    Returns
    -------
    float
        ``setting`` itself, or :data:`AUTO_PIXELS` times ``pixel`` for "auto" (which
        :func:`stand_ins` applies to B of more than :data:`AUTO_FACES` faces only).

    Examples
    --------
    >>> tolerance("auto", 0.2), tolerance(0.3, 0.2), tolerance(0.0, 0.2)
    (0.1, 0.3, 0.0)
    """
    return AUTO_PIXELS * float(pixel) if setting == "auto" else float(setting)


def stand_in(shape: Shape, tolerance: float) -> Shape:
    """A coarser copy of ``shape`` whose surface lies within ``tolerance`` of the original.

    Parameters
    ----------
    shape : Shape
        A closed (manifold) mesh; any other mesh is returned as it is.
    tolerance : float
        Largest distance any surface point may move, scene units (mm); 0 returns ``shape``.

    Returns
    -------
    Shape
        The same name, path and centre; vertices a subset of ``shape``'s (exactly, float64),
        fewer faces, radius and hull recomputed. ``shape`` itself where the simplification
        removes nothing or the mesh is not a closed manifold.
    """
    if tolerance <= 0:
        return shape
    import manifold3d
    from scipy.spatial import cKDTree

    mesh = manifold3d.Mesh(
        vert_properties=np.asarray(shape.vertices, dtype=np.float32),
        tri_verts=np.asarray(shape.faces, dtype=np.uint32),
    )
    solid = manifold3d.Manifold(mesh)
    if solid.status() != manifold3d.Error.NoError or solid.is_empty():
        return shape
    out = solid.simplify(float(tolerance)).to_mesh()
    faces = np.asarray(out.tri_verts, dtype=np.int64)
    if len(faces) == 0 or len(faces) >= shape.face_count:
        return shape
    # the kept vertices are the original's, rounded to float32: take the float64 originals back
    _, index = cKDTree(shape.vertices).query(np.asarray(out.vert_properties)[:, :3])
    used, faces = np.unique(index[faces], return_inverse=True)
    v = shape.vertices[used]
    return dataclasses.replace(
        shape,
        vertices=v,
        faces=faces.reshape(-1, 3),
        radius=float(np.linalg.norm(v, axis=1).max()),
        hull=_hull(v),
    )


def stand_ins(shapes: list[Shape], tolerance: float, faces: int = 0) -> list[Shape]:
    """:func:`stand_in` of each of ``shapes`` with more than ``faces`` faces (the others, and all
    of them when ``tolerance`` is 0, as they are)."""
    if tolerance <= 0:
        return list(shapes)
    return [stand_in(s, tolerance) if s.face_count > faces else s for s in shapes]


def _hull(v: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of ``v`` (all of ``v`` where the hull is degenerate)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return v[ConvexHull(v).vertices]
    except (QhullError, ValueError):  # flat or too few points: every point
        return v
