"""Exact binary silhouettes by ray casting in Mitsuba 3.

A silhouette is sampled by one ray per pixel centre along z: the rays of Mitsuba's orthographic
sensor that frames the raster (:meth:`sieve_mi.geometry.raster.Frame.sensor`), sampled at its film's pixel
centres (``sensor.sample_ray``). Instead of moving the mesh for every
pose (a new BVH each time), the rays are moved into the mesh's frame: for a pose (R, t) the ray
through world point P starts at R^T (P - t) and runs along R^T e_z. One scene (one BVH) per shape
then serves any number of poses in a single batched ``ray_test`` call; the rays are generated in
Dr.Jit, in the same kernel as the intersection test.

The masks that are written to disk are rendered by Mitsuba itself: ``mi.render`` with the
:class:`silhouette <SilhouetteIntegrator>` integrator under the same kind of orthographic sensor
(:meth:`SilhouetteRenderer.render`), one sample at each pixel centre. They equal the traced masks
pixel for pixel (a test holds them together).
"""

from __future__ import annotations

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import to_matrix

__all__ = ["CORE_MARGIN", "SilhouetteRenderer", "mesh_scene", "register_integrator"]

#: A pixel centre is taken as covered without a ray when it lies within (1 - CORE_MARGIN) times the
#: core ball's radius of the ball's shadow's centre (float32 rays and poses: a relative 1e-4 is
#: some 1000 roundings away).
CORE_MARGIN = 1e-4
#: Variants in which the ``silhouette`` integrator has been registered with Mitsuba.
_REGISTERED: set = set()


def register_integrator() -> None:
    """Register the ``silhouette`` integrator with Mitsuba for the current variant (idempotent).

    After this, ``mi.load_dict({"type": "silhouette"})`` gives a :class:`SilhouetteIntegrator`.
    """
    import mitsuba as mi

    if mi.variant() in _REGISTERED:
        return

    class SilhouetteIntegrator(mi.SamplingIntegrator):
        """Binary coverage: 1 where the camera ray hits any shape, 0 elsewhere.

        One shadow-ray test per sample (``scene.ray_test``): no shading, no emitters, no
        bounces. Rendered with one centred sample per pixel (the sensors of
        :meth:`sieve_mi.geometry.raster.Frame.window_sensor`), the image is the exact silhouette at the
        pixel centres.
        """

        def sample(self, scene, sampler, ray, medium=None, active=True):
            import drjit as dr

            hit = scene.ray_test(ray, active)
            return mi.Spectrum(dr.select(hit, 1.0, 0.0)), mi.Bool(True), []

        def aov_names(self):
            return []

    mi.register_integrator("silhouette", lambda props: SilhouetteIntegrator(props))
    _REGISTERED.add(mi.variant())


def mesh_scene(vertices: np.ndarray, faces: np.ndarray, name: str = "shape", **extra):
    """A Mitsuba scene holding one triangle mesh (one BVH), for ray tests and renders.

    Parameters
    ----------
    vertices : (n, 3) ndarray
        Scene units (stored as float32).
    faces : (m, 3) ndarray of int
    name : str
        The mesh's id.
    **extra
        Further scene entries (e.g. ``integrator={"type": "silhouette"}``).
    """
    import mitsuba as mi

    mesh = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.asarray(vertices, dtype=np.float32).ravel())
    params["faces"] = mi.UInt32(np.asarray(faces, dtype=np.uint32).ravel())
    params.update()
    return mi.load_dict({"type": "scene", "shape": mesh, **extra})


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
        self._scene = mesh_scene(shape.vertices, shape.faces, shape.name or "shape")
        self._mi, self._dr = mi, dr
        #: ``(centre (3,), radius)``: a ball inside the closed solid, or None; set by the caller
        #: (:func:`sieve_mi.certify.bounds.inscribed_ball`). Pixel centres in its shadow are hits
        #: without a ray (:meth:`trace`).
        self.core = None

    def trace(
        self,
        quats: np.ndarray,
        trans: np.ndarray,
        frame: Frame,
        row0: np.ndarray,
        col0: np.ndarray,
        size,
        cols=None,
    ):
        """Trace one ray per pixel centre of K windows of the frame's pixel lattice (Dr.Jit arrays).

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
        size : int or (K,) ndarray of int
            Window side in pixels, or each window's number of rows.
        cols : (K,) ndarray of int, optional
            Each window's number of columns (default: ``size``, square windows).

        Returns
        -------
        hit : mi.Bool
            One entry per window pixel, pose-major, then row, then column (pose k's entries
            start at the sum of the earlier windows' pixel counts). With a :attr:`core`, the
            pixels in its shadow are hits without a ray (the same answer: such a ray enters the
            core, inside the closed solid, so it crosses the surface).
        pose, row, col : mi.UInt32, mi.Int32, mi.Int32
            Pose index and lattice row and column of every entry.
        """
        mi, dr = self._mi, self._dr
        quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
        k = len(quats)
        rows = np.broadcast_to(np.asarray(size, dtype=np.int64), k)
        cols = rows if cols is None else np.broadcast_to(np.asarray(cols, dtype=np.int64), k)
        pose, row, col = _window_pixels(mi, dr, row0, col0, rows, cols)
        return (
            self._pixel_hits(self._pose_arrays(quats, trans), pose, row, col, frame),
            pose,
            row,
            col,
        )

    def walk_rows(self, quats, trans, frame: Frame, window: tuple, visit, start: list, extra=()):
        """One thread per window row, walking its pixel centres left to right (a Dr.Jit loop).

        The same rays and hits as :meth:`trace` (the same arithmetic per pixel), but each row
        gathers its pose's rotation, translation and window once, not once per pixel; what is
        wanted of the hits is accumulated per row by ``visit``.

        Parameters
        ----------
        quats, trans, frame
            As for :meth:`trace`.
        window : (row0, col0, rows, cols)
            The K windows: lattice index of each one's top-left pixel, its number of rows and of
            columns ((K,) arrays of int each, as for :meth:`trace`).
        visit : callable
            ``visit(hit, row, col, extra, acc) -> acc``: folds one pixel (mi.Bool, mi.Int32,
            mi.Int32) into the row's accumulators ``acc`` (a list of Dr.Jit arrays); ``extra``
            is the list of ``extra`` arrays at the row's pose.
        start : list
            The accumulators' initial values, one entry per row each.
        extra : sequence of Dr.Jit arrays
            Per-pose values (K entries each) that ``visit`` needs, gathered once per row.

        Returns
        -------
        acc : list
            The accumulators after each row's last pixel (one entry per window row, pose-major).
        pose : mi.UInt32
            Each row's pose.
        """
        mi, dr = self._mi, self._dr
        row0, col0, rows, cols = window
        quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
        k = len(quats)
        rows = np.broadcast_to(np.asarray(rows, dtype=np.int64), k)
        cols = np.broadcast_to(np.asarray(cols, dtype=np.int64), k)
        pose, row, first = _window_pixels(mi, dr, row0, col0, rows, np.ones(k, dtype=np.int64))
        end = first + dr.gather(mi.Int32, mi.Int32(cols.astype(np.int32)), pose)
        per_pose = [dr.gather(mi.Float, a, pose) for a in self._pose_arrays(quats, trans)]
        at_row = [dr.gather(type(a), a, pose) for a in extra]

        def body(col, *acc):
            hit = self._pixel_hits(per_pose, None, row, col, frame)
            return (col + 1, *visit(hit, row, col, at_row, list(acc)))

        out = dr.while_loop((first, *start), lambda col, *_: col < end, body, label="rows")
        return list(out[1:]), pose

    def _pose_arrays(self, quats: np.ndarray, trans: np.ndarray) -> list:
        """Per pose: R^T row-major (9 mi.Float), then the translation (2 mi.Float)."""
        from sieve_mi.backend import aligned

        mi = self._mi
        rt = np.transpose(to_matrix(quats), (0, 2, 1)).reshape(len(quats), 9)
        columns = [rt[:, i] for i in range(9)] + [trans[:, i] for i in range(2)]
        return [mi.Float(aligned(c, np.float32)) for c in columns]  # one kernel source: aligned

    def _pixel_hits(self, per_pose: list, pose, row, col, frame: Frame):
        """Whether the rays through lattice pixels (row, col) hit: ``per_pose`` from
        :meth:`_pose_arrays`, gathered by ``pose`` (None: already one entry per ray)."""
        mi, dr = self._mi, self._dr
        if pose is not None:
            per_pose = [dr.gather(mi.Float, a, pose) for a in per_pose]
        g, (tx, ty) = per_pose[:9], per_pose[9:]
        h, n = frame.pixel_size, frame.resolution
        film = mi.Point2f((mi.Float(col) + 0.5) / n, (mi.Float(row) + 0.5) / n)
        world, _ = frame.sensor().sample_ray(0.0, 0.5, film, mi.Point2f(0.5, 0.5))
        x, y = world.o.x - tx, world.o.y - ty
        reach = self.shape.radius * 1.01 + h
        origin = mi.Point3f(
            g[0] * x + g[1] * y - g[2] * reach,
            g[3] * x + g[4] * y - g[5] * reach,
            g[6] * x + g[7] * y - g[8] * reach,
        )
        ray = mi.Ray3f(origin, mi.Vector3f(g[2], g[5], g[8]))
        ray.maxt = mi.Float(2.0 * reach)
        if self.core is None:
            return self._scene.ray_test(ray)
        # A ray through the core's shadow enters the core, so it crosses the surface: a hit.
        (cx, cy, cz), radius = self.core
        cx, cy, cz = float(cx), float(cy), float(cz)
        # the core's centre in the ray's coordinates: R c (rows of R are the columns of R^T)
        px = g[0] * cx + g[3] * cy + g[6] * cz
        py = g[1] * cx + g[4] * cy + g[7] * cz
        inner = dr.square(x - px) + dr.square(y - py) < (radius * (1.0 - CORE_MARGIN)) ** 2
        return inner | self._scene.ray_test(ray, ~inner)

    def masks(
        self,
        quats: np.ndarray,
        trans: np.ndarray,
        frame: Frame,
        row0: np.ndarray,
        col0: np.ndarray,
        size: int,
        chunk_rays: int = 1 << 24,
    ) -> np.ndarray:
        """Binary silhouettes of K poses, each in a size x size window of the frame's pixel lattice.

        Parameters are those of :meth:`trace`; ``chunk_rays`` bounds the rays traced in one call.

        Returns
        -------
        (K, size, size) ndarray of bool
            True where the pixel-centre ray hits the mesh.
        """
        quats, trans = np.atleast_2d(quats), np.atleast_2d(trans)
        row0, col0 = np.broadcast_to(row0, len(quats)), np.broadcast_to(col0, len(quats))
        out = np.zeros((len(quats), size, size), dtype=bool)
        per = max(1, chunk_rays // (size * size))
        for s in range(0, len(quats), per):
            sl = slice(s, min(len(quats), s + per))
            hit = self.trace(quats[sl], trans[sl], frame, row0[sl], col0[sl], size)[0]
            out[sl] = np.asarray(hit, dtype=bool).reshape(-1, size, size)
        return out

    def frame_mask(self, quat: np.ndarray, trans: np.ndarray, frame: Frame) -> np.ndarray:
        """The silhouette of one pose over the whole frame, (N, N) bool."""
        n = frame.resolution
        return self.masks(
            np.asarray(quat)[None],
            np.asarray(trans)[None],
            frame,
            np.zeros(1, int),
            np.zeros(1, int),
            n,
        )[0]

    def render(
        self,
        quat: np.ndarray,
        trans: np.ndarray,
        frame: Frame,
        row0: int = 0,
        col0: int = 0,
        size: int | None = None,
    ) -> np.ndarray:
        """One pose's silhouette rendered by ``mi.render``, on a window of the frame's lattice.

        The mesh is moved into the pose (its top at z = -max(1, radius)) and rendered with the
        ``silhouette`` integrator under :meth:`~sieve_mi.geometry.raster.Frame.window_sensor`. This builds a BVH per call, so it serves
        the masks that are written, not the search (use :meth:`masks` for many poses).

        Parameters
        ----------
        quat : (4,) ndarray
            Rotation (w, x, y, z) about the shape's centre.
        trans : (2,) ndarray
            Translation in the xy-plane, scene units.
        frame : Frame
        row0, col0 : int
            Lattice index of the window's top-left pixel (default: the frame's).
        size : int, optional
            Window side in pixels (default: the frame's resolution).

        Returns
        -------
        (size, size) ndarray of bool
            True where the pixel centre is covered; row 0 at the top.
        """
        import mitsuba as mi

        register_integrator()
        size = frame.resolution if size is None else size
        v = self.shape.vertices @ to_matrix(np.asarray(quat)[None])[0].T
        v[:, :2] += np.asarray(trans, dtype=np.float64)
        v[:, 2] -= v[:, 2].max() + max(1.0, self.shape.radius)
        scene = mesh_scene(v, self.shape.faces, "posed", integrator={"type": "silhouette"})
        image = mi.render(scene, sensor=frame.window_sensor(row0, col0, size), spp=1)
        return np.asarray(image, dtype=np.float32).reshape(size, size) > 0.5

    def projected_extent(
        self, quats: np.ndarray, trans: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of each pose's projection, from the convex hull's vertices.

        Returns
        -------
        lo, hi : (K, 2) ndarrays
            Lower and upper (x, y) corners in scene units.
        """
        r, hull = to_matrix(np.atleast_2d(quats)), self.shape.hull
        trans = np.atleast_2d(trans)
        # (K, H) per axis, products summed left to right (einsum took ten times as long)
        x = (
            r[:, 0, 0, None] * hull[:, 0]
            + r[:, 0, 1, None] * hull[:, 1]
            + r[:, 0, 2, None] * hull[:, 2]
        )
        y = (
            r[:, 1, 0, None] * hull[:, 0]
            + r[:, 1, 1, None] * hull[:, 1]
            + r[:, 1, 2, None] * hull[:, 2]
        )
        x, y = x + trans[:, :1], y + trans[:, 1:2]
        return np.column_stack([x.min(1), y.min(1)]), np.column_stack([x.max(1), y.max(1)])


def _window_pixels(mi, dr, row0, col0, rows, cols):
    """Pose, lattice row and lattice column of every pixel of K windows (Dr.Jit arrays).

    Window k has ``rows[k] x cols[k]`` pixels from lattice pixel (``row0[k]``, ``col0[k]``);
    its entries follow those of windows 0..k-1, row by row. Sizes are arrays, not literals, so
    windows of any sizes share one kernel; each entry finds its pose from a table of buckets of
    entries no longer than the smallest window (two gathers; a binary search over the windows'
    running pixel counts took four times as long).
    """
    k = len(rows)
    ends = np.concatenate([[0], np.cumsum(np.asarray(rows) * np.asarray(cols))])
    if ends[-1] >= 2**32:
        raise ValueError("more than 2**32 window pixels in one trace; trace fewer poses at once")
    ends_d = mi.UInt32(ends.astype(np.uint32))  # K + 1 entries: the last one is the total
    idx = dr.arange(mi.UInt32, int(ends[-1]))
    # Buckets of 2**shift entries, no bigger than the smallest window: at most one window starts
    # inside a bucket, so an entry's window is its bucket's first one or the next.
    smallest = int(np.min(ends[1:] - ends[:-1])) if k else 1
    shift = max(smallest.bit_length() - 1, 0)  # 0 where a window is empty: buckets of one entry
    starts = np.arange(0, int(ends[-1]) + 1, 1 << shift, dtype=np.int64)
    first = np.searchsorted(ends[1:], starts, side="right")  # each bucket's first entry's window
    # opaque: a literal shift would make one kernel per window size
    bucket = idx >> dr.opaque(mi.UInt32, shift)
    pose = dr.gather(mi.UInt32, mi.UInt32(first.astype(np.uint32)), bucket)
    pose += mi.UInt32(dr.gather(mi.UInt32, ends_d, pose + 1) <= idx)
    p = mi.Int32(idx - dr.gather(mi.UInt32, ends_d, pose))
    # at least 1: the vectorised division also runs in the padding lanes past the last entry,
    # whose masked gathers read 0 (an integer division by zero stops the process)
    width = dr.maximum(dr.gather(mi.Int32, mi.Int32(np.asarray(cols, dtype=np.int32)), pose), 1)
    row = dr.gather(mi.Int32, mi.Int32(np.asarray(row0, dtype=np.int32)), pose) + p // width
    col = dr.gather(mi.Int32, mi.Int32(np.asarray(col0, dtype=np.int32)), pose) + p % width
    return pose, row, col
