"""Exact collision and distance queries between a shape's triangle mesh and a sieve plate (coal).

The plate is the extrusion of (a rectangle minus the hole H) over z in [-thickness, 0], given to
coal as convex prisms (:func:`sieve_mi.geometry.plate.convex_pieces`), so every query is exact up to
GJK's tolerance. The shape goes in as its triangle surface. For a closed shape that surface meets
the plate's material whenever the solid does: the material is connected and too wide for the
shape to swallow (the plate's margin exceeds the shape's diameter), so a solid overlap without a
surface crossing is impossible.
"""

from __future__ import annotations

import coal
import manifold3d
import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.plate import convex_pieces, plate_region, prism_vertices

__all__ = ["MeshWorld", "PlateWorld", "edge_pairs", "place", "plate_prisms"]


def plate_prisms(
    outline: manifold3d.CrossSection, thickness: float, margin: float
) -> list[np.ndarray]:
    """The plate's convex prisms: each (2k, 3) float array of corners, scene units.

    Parameters
    ----------
    outline : manifold3d.CrossSection
        The hole H.
    thickness : float
        Plate thickness (z from ``-thickness`` to 0), scene units.
    margin : float
        Material between H's bounding box and the plate's edge, scene units.
    """
    region = plate_region(outline, margin)
    return [prism_vertices(p, -thickness, 0.0) for p in convex_pieces(region)]


def edge_pairs(faces: np.ndarray) -> np.ndarray:
    """The mesh's unique undirected edges, (E, 2) int."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0)


def _convex(points: np.ndarray):
    pts = coal.StdVec_Vec3s()
    for p in np.asarray(points, dtype=np.float64):
        pts.append(p)
    return coal.Convex.convexHull(pts, False, None)


def _bvh(vertices: np.ndarray, faces: np.ndarray):
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(faces), len(vertices))
    model.addVertices(np.ascontiguousarray(vertices, dtype=np.float64))
    model.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    model.endModel()
    return model


class PlateWorld:
    """One shape and one plate, with exact queries at the shape's poses.

    A pose is ``(quat, trans)``: the shape's vertices (relative to its centre) rotated by the
    quaternion (w, x, y, z) and moved by ``trans`` ((3,) float, scene units).

    Parameters
    ----------
    shape : Shape
    outline : manifold3d.CrossSection
        The hole H, scene units.
    thickness : float
        Plate thickness, scene units.
    """

    def __init__(self, shape: Shape, outline: manifold3d.CrossSection, thickness: float):
        self.shape = shape
        self.thickness = float(thickness)
        self.radius = float(shape.radius)
        self.margin = 2.0 * self.radius + 1.0
        self.manager = coal.DynamicAABBTreeCollisionManager()
        self._pieces = []
        for prism in plate_prisms(outline, self.thickness, self.margin):
            obj = coal.CollisionObject(_convex(prism), coal.Transform3s())
            self._pieces.append(obj)
            self.manager.registerObject(obj)
        self.manager.setup()
        self.edges = edge_pairs(shape.faces)
        self.body = coal.CollisionObject(_bvh(shape.vertices, shape.faces), coal.Transform3s())
        self.checks = 0

    @property
    def piece_count(self) -> int:
        """Number of convex prisms the plate was split into."""
        return len(self._pieces)

    def _place(self, quat, trans) -> None:
        place(self.body, quat, trans)
        self.body.computeAABB()
        self.checks += 1

    def collides(self, quat, trans) -> bool:
        """Whether the shape at this pose meets the plate's material (touching counts)."""
        self._place(quat, trans)
        callback = coal.CollisionCallBackDefault()
        self.manager.collide(self.body, callback)
        return bool(callback.data.result.isCollision())

    def distance(self, quat, trans) -> float:
        """Distance from the shape at this pose to the plate's material, scene units (≤ 0: they meet)."""
        self._place(quat, trans)
        callback = coal.DistanceCallBackDefault()
        self.manager.distance(self.body, callback)
        return float(callback.data.result.min_distance)


def place(body, quat, trans) -> None:
    """Put a coal collision object at the pose ``(quat, trans)``: (w, x, y, z), normalised here,
    and (3,) scene units."""
    w, x, y, z = (float(v) for v in quat)
    n = (w * w + x * x + y * y + z * z) ** 0.5
    rot = coal.Quaternion(w / n, x / n, y / n, z / n)  # Eigen's order: w, x, y, z
    body.setTransform(coal.Transform3s(rot, np.asarray(trans, dtype=np.float64)))


class MeshWorld:
    """One shape against a plate's own triangle mesh (coal BVHs), as
    :func:`~sieve_mi.motion.path.verify` queries it: ``radius`` and ``distance(quat, trans)``
    (0 where they meet).

    For a plate that is more than its slab (a post, a raised rim): surfaces that never meet
    along a continuous motion that starts apart keep the solids apart, so the surface distance
    decides for a closed shape and a closed plate.

    Parameters
    ----------
    shape : Shape
    vertices : (V, 3) float
        The plate mesh's vertices, scene units.
    faces : (F, 3) int
    """

    def __init__(self, shape: Shape, vertices: np.ndarray, faces: np.ndarray):
        self.radius = float(shape.radius)
        self.plate = coal.CollisionObject(_bvh(vertices, faces), coal.Transform3s())
        self.body = coal.CollisionObject(_bvh(shape.vertices, shape.faces), coal.Transform3s())

    def distance(self, quat, trans) -> float:
        """Distance between the shape at this pose and the plate, scene units (0: they meet)."""
        place(self.body, quat, trans)
        if coal.collide(self.body, self.plate, coal.CollisionRequest(), coal.CollisionResult()):
            return 0.0
        result = coal.DistanceResult()
        coal.distance(self.body, self.plate, coal.DistanceRequest(), result)
        return float(result.min_distance)
