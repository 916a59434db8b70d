"""Exact binary silhouettes by ray casting in Mitsuba 3.

A silhouette is sampled by one ray per pixel centre along +z, exactly what an orthographic sensor
looking down the z-axis with pixel-centre sampling produces. Instead of moving the mesh for every
pose (a new BVH each time), the rays are moved into the mesh's frame: for a pose (R, t) the ray
through world point P starts at R^T (P - t) and runs along R^T e_z. One scene (one BVH) per shape
then serves any number of poses in a single batched ``ray_test`` call.
"""

from __future__ import annotations

import numpy as np

from sieve_mi.meshes import Shape
from sieve_mi.raster import Frame
from sieve_mi.rotations import to_matrix


class SilhouetteRenderer:
    """Renders binary silhouettes of one shape under many poses.

    Parameters
    ----------
    shape : Shape
        The mesh, centred, in scene units.
    """

    def __init__(self, shape: Shape):
        import drjit as dr
        import mitsuba as mi

        self.shape = shape
        mesh = mi.Mesh(shape.name or "shape", len(shape.vertices), len(shape.faces), has_vertex_normals=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(shape.vertices.astype(np.float32).ravel())
        params["faces"] = mi.UInt32(shape.faces.astype(np.uint32).ravel())
        params.update()
        self._scene = mi.load_dict({"type": "scene", "shape": mesh})
        self._mi, self._dr = mi, dr

    def masks(self, quats: np.ndarray, trans: np.ndarray, frame: Frame, row0: np.ndarray, col0: np.ndarray, size: int,
              chunk_rays: int = 1 << 24) -> np.ndarray:
        """Binary silhouettes of K poses, each in a size x size window of the frame's pixel lattice.

        Parameters
        ----------
        quats : (K, 4) ndarray
            Rotations (w, x, y, z) about the shape's centre.
        trans : (K, 2) ndarray
            Translations in the xy-plane, scene units.
        frame : Frame
            Defines the pixel lattice (pixel size and origin).
        row0, col0 : (K,) ndarrays of int
            Lattice index of each window's top-left pixel (0, 0 is the frame's top-left pixel).
        size : int
            Window side in pixels.
        chunk_rays : int
            Largest number of rays traced in one call (bounds memory).

        Returns
        -------
        (K, size, size) ndarray of bool
            True where the pixel-centre ray hits the mesh.
        """
        mi, dr = self._mi, self._dr
        quats = np.atleast_2d(quats)
        trans = np.atleast_2d(trans)
        k_total = len(quats)
        x, y = frame.window_centres(np.asarray(row0), np.asarray(col0), size)
        rot = to_matrix(quats)  # (K, 3, 3)
        out = np.zeros((k_total, size, size), dtype=bool)
        per = max(1, chunk_rays // (size * size))
        reach = self.shape.radius * 1.01 + frame.pixel_size
        for s in range(0, k_total, per):
            sl = slice(s, min(k_total, s + per))
            k = sl.stop - sl.start
            rt = np.transpose(rot[sl], (0, 2, 1))  # R^T
            # World points relative to the pose's centre, at z = -reach.
            px = np.broadcast_to((x[sl] - trans[sl, 0:1])[:, None, :], (k, size, size))
            py = np.broadcast_to((y[sl] - trans[sl, 1:2])[:, :, None], (k, size, size))
            origin = (rt[:, None, None, :, 0] * px[..., None] + rt[:, None, None, :, 1] * py[..., None]
                      + rt[:, None, None, :, 2] * (-reach))
            direction = np.broadcast_to(rt[:, None, None, :, 2], (k, size, size, 3))
            o = origin.reshape(-1, 3).astype(np.float32)
            d = np.ascontiguousarray(direction.reshape(-1, 3), dtype=np.float32)
            ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
            ray.maxt = mi.Float(2.0 * reach)
            hit = self._scene.ray_test(ray)
            out[sl] = np.asarray(hit, dtype=bool).reshape(k, size, size)
        return out

    def frame_mask(self, quat: np.ndarray, trans: np.ndarray, frame: Frame) -> np.ndarray:
        """The silhouette of one pose over the whole frame, (N, N) bool."""
        n = frame.resolution
        return self.masks(np.asarray(quat)[None], np.asarray(trans)[None], frame, np.zeros(1, int), np.zeros(1, int), n)[0]

    def projected_extent(self, quats: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of each pose's projection, from the convex hull's vertices.

        Returns
        -------
        lo, hi : (K, 2) ndarrays
            Lower and upper (x, y) corners in scene units.
        """
        p = np.einsum("kij,hj->khi", to_matrix(np.atleast_2d(quats))[:, :2, :], self.shape.hull)
        p = p + np.atleast_2d(trans)[:, None, :]
        return p.min(1), p.max(1)
