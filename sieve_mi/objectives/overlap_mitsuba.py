"""The overlap objective of the paper (eq. 8, Sec. 6.1), differentiated by Mitsuba's projective sampling.

For a pose (R, t) of a shape B, the loss is the fraction of B's silhouette that lies outside the
hole H,

    beta(R, t) = sum_pixels img * outside / sum_pixels img,

where ``img`` is B's anti-aliased silhouette on the hole's pixel grid (pixel coverage in [0, 1], box
filter) and ``outside`` is 1 on pixel centres outside H (hole texture > 0). The image is rendered by
Mitsuba 3 with a projective-sampling integrator: its explicit sampling of the primary silhouette
edges gives unbiased derivatives of ``img`` with respect to the vertex positions, and the vertex
positions are a differentiable Dr.Jit function of the quaternion and the translation.

How the image is made (one Mitsuba scene per shape, built once):

* **Integrator.** By default (``integrator="silhouette"``) a minimal subclass of Mitsuba's
  ``DirectProjectiveIntegrator`` that keeps all of its projective machinery (silhouette-edge
  sampling, boundary Jacobian, splatting) and replaces only the shading: a ray carries 1 if it hits
  the mesh, else 0 (one any-hit ray per sample, no emitter or BSDF sampling). With
  ``integrator="direct_projective"`` the stock integrator renders a black mesh in front of a uniform
  white environment emitter and ``img = 1 - render``; it gives the same images and gradients for
  the same seeds, 1.2-3x slower. Neither depends on how the faces are oriented (an area emitter on
  the mesh would: Mitsuba's area emitters are one-sided, so inverted faces would render black).
  Both run with ``guiding="none"``, ``sppi=0`` (no indirect discontinuities exist here) and
  ``sppc=0``: the radiance depends on the vertices only through visibility, so the
  continuous-derivative pass would only add zeros.
* **Orthographic projection from a perspective camera.** Mitsuba's projective integrators reject
  orthographic sensors, so a perspective camera sits on the +z axis at distance ``D`` looking at
  the origin with +y up; its film is the frame's N x N grid (plus an optional margin) and its field
  of view covers exactly the frame's square at z = 0. To make the projection *exact* rather than
  approximately orthographic, every transformed vertex (x, y, z) is moved to
  (x (D - z) / D, y (D - z) / D, z) before rendering: the camera then projects it exactly onto
  (x, y). Each rendered triangle projects to the triangle of its vertices' projections, and a
  triangle faces the camera iff its projection is counter-clockwise, so both the silhouette and
  the silhouette edges Mitsuba samples are those of the orthographic projection.

Gradients. ``mi.render`` records a custom AD operation whose backward pass re-renders the scene *as
it is when the backward pass runs*. Poses are rendered one after another in the same scene, so a
lazily recorded graph would differentiate every pose at the last pose's geometry.
:meth:`OverlapObjective.loss` therefore differentiates each pose right after rendering it (with a
detached copy of the vertex buffer as the AD leaf) and returns a *surrogate* total:

    total = sum_k beta_k (detached) + sum_k <g_k, V_k(q, t) - detach(V_k(q, t))>,

whose value is the sum of the losses and whose gradient with respect to q and t is exactly
sum_k g_k . dV_k/d(q, t), with g_k = d beta_k / dV_k from Mitsuba. A later ``dr.backward(total)``
by the caller therefore reaches the quaternion and translation arrays as usual.

Cost per pose: one primal render (``spp`` samples per pixel), one derivative render
(``spp_grad`` silhouette samples per pixel), and a rebuild of the mesh's ray-tracing BVH (about
1.5 microseconds per face on two CPU cores), plus about 2 ms of Python/tracing overhead; see
``docs/overlap-notes.md``.
"""

from __future__ import annotations

import math

import numpy as np

from sieve_mi.geometry.meshes import Shape
from sieve_mi.geometry.raster import Frame
from sieve_mi.geometry.rotations import quat_rows
from sieve_mi.objectives.base import Objective

__all__ = ["INTEGRATORS", "OverlapObjective"]

#: Ways of rendering the silhouette: a minimal subclass of Mitsuba's ``direct_projective`` whose
#: shading is "1 if the camera ray hits the mesh, else 0" (one ray per sample), or the stock
#: ``direct_projective`` integrator with a black mesh in front of a uniform white emitter.
INTEGRATORS = ("silhouette", "direct_projective")

_PLUGIN = "sieve_silhouette_projective"
_registered: set[str] = set()


def _silhouette_plugin(mi) -> str:
    """Register (once per variant) the silhouette integrator and return its plugin name.

    It inherits everything projective from Mitsuba's ``DirectProjectiveIntegrator`` (primary
    silhouette sampling, the boundary Jacobian, splatting of the derivative samples) and only
    replaces the shading model, ``sample()``: a camera ray or a boundary "background" ray carries
    1 if it hits the mesh and 0 otherwise (an any-hit ``ray_test``, no emitter or BSDF sampling);
    a boundary "foreground" sample (given as ``si_shade``, a point on the mesh) carries 1. The
    radiance difference across a silhouette edge is then 1 where the edge is on the outline of the
    projection and 0 where another part of the mesh lies behind it, as it should be.
    """
    import drjit as dr

    variant = mi.variant()
    if variant in _registered:
        return _PLUGIN
    from mitsuba.ad.integrators.direct_projective import DirectProjectiveIntegrator

    class SilhouetteProjectiveIntegrator(DirectProjectiveIntegrator):
        # Mitsuba's interface (``ADIntegrator.sample``), not sieve-mi's: Mitsuba calls it with
        # these ten arguments, by position or by name, so the signature is the library's.
        def sample(
            self,
            mode,
            scene,
            sampler,
            ray,
            depth,
            δL,
            state_in,
            active,
            project=False,
            si_shade=None,
            **kwargs,
        ):
            if project:
                raise RuntimeError(
                    "the silhouette integrator does not sample indirect discontinuities (use sppi=0)"
                )
            active = mi.Bool(active)
            hit = active if si_shade is not None else scene.ray_test(ray, active)
            return mi.Spectrum(dr.select(hit, 1.0, 0.0)), hit, [], None

    mi.register_integrator(_PLUGIN, lambda props: SilhouetteProjectiveIntegrator(props))
    _registered.add(variant)
    return _PLUGIN


class OverlapObjective(Objective):
    """Overlap loss (fraction of the silhouette outside H) of several shapes, pose by pose.

    An :class:`~sieve_mi.objectives.Objective` (see there for :meth:`bind` and :meth:`loss`).

    Parameters
    ----------
    shapes : list of Shape
        Player B's shapes.
    frame : Frame
        The hole's raster frame; the silhouettes are rendered on its pixel grid.
    spp : int
        Samples per pixel of the anti-aliased silhouette (primal image).
    spp_grad : int
        Silhouette-edge samples per pixel for the derivative pass (``spp_grad * M^2`` edge samples
        per render, M the film side, all of them on the silhouette's outline). One is plenty: at
        64^2 the gradient's relative noise is about 5 %, at 256^2 about 1 %.
    margin : int
        Extra pixels of the frame's lattice rendered on each side of the frame (film side
        N + 2 margin). They count as outside H, so the part of a silhouette that leaves the frame
        still counts against the pose; with 0 (the paper's setting) it is simply not seen.
    seed : int
        Base seed; each call of :meth:`loss` uses fresh seeds derived from it unless one is given.
    """

    def __init__(
        self,
        shapes: list[Shape],
        frame: Frame,
        spp: int = 4,
        spp_grad: int = 1,
        margin: int = 0,
        seed: int = 0,
        integrator: str = "silhouette",
    ):
        import drjit as dr
        import mitsuba as mi

        if not shapes:
            raise ValueError("OverlapObjective needs at least one shape")
        if spp < 1 or spp_grad < 1:
            raise ValueError("spp and spp_grad must be at least 1")
        if margin < 0:
            raise ValueError("margin must be >= 0")
        self.dr, self.mi = dr, mi
        self.frame = frame
        self.spp = int(spp)
        self.spp_grad = int(spp_grad)
        self.margin = int(margin)
        self.size = frame.resolution + 2 * self.margin
        self._seed = int(seed)
        self._calls = 0
        n, m, h = frame.resolution, self.margin, frame.pixel_size
        extent = frame.half_extent + m * h
        radius = max(s.radius for s in shapes)
        # Camera distance: far enough that (D - z) / D stays well away from 0 for every vertex.
        self.distance = 20.0 * (radius + extent)
        d = self.distance
        fov = math.degrees(2.0 * math.atan(extent / d))
        self._verts = [mi.Vector3f(*(s.vertices.astype(np.float32).T)) for s in shapes]
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}; use one of {INTEGRATORS}")
        self.integrator = integrator
        # The stock integrator renders 1 - silhouette (black mesh in front of a white background).
        self._complement = integrator == "direct_projective"
        plugin = _silhouette_plugin(mi) if integrator == "silhouette" else "direct_projective"
        self._scenes, self._params = [], []
        for shape in shapes:
            scene = mi.load_dict(self._scene_description(shape, plugin, fov))
            params = mi.traverse(scene)
            if self._complement:
                params["shape.bsdf.reflectance.value"] = 0.0
                params.update()
            params.keep(["shape.vertex_positions"])
            self._scenes.append(scene)
            self._params.append(params)
        # Film pixel (r, c) is frame lattice pixel (r - m, c - m); outside the frame it counts as outside H.
        rr, cc = np.divmod(np.arange(self.size * self.size), self.size)
        fr, fc = rr - m, cc - m
        inside = (fr >= 0) & (fr < n) & (fc >= 0) & (fc < n)
        self._row = mi.UInt32(np.where(inside, fr, 0).astype(np.uint32))
        self._col = mi.UInt32(np.where(inside, fc, 0).astype(np.uint32))
        self._in_frame = mi.Bool(inside)
        self._pose_shape = None
        self.pose_count = 0

    def _scene_description(self, shape: Shape, plugin: str, fov: float) -> dict:
        """The Mitsuba scene dictionary that renders ``shape``'s silhouette on the film."""
        mi, d = self.mi, self.distance
        mesh = mi.Mesh(
            shape.name or "shape", len(shape.vertices), len(shape.faces), has_vertex_normals=False
        )
        mp = mi.traverse(mesh)
        mp["vertex_positions"] = mi.Float(shape.vertices.astype(np.float32).ravel())
        mp["faces"] = mi.UInt32(shape.faces.astype(np.uint32).ravel())
        mp.update()
        desc = {
            "type": "scene",
            # sppc = 0: the radiance never depends on the vertices except through visibility, so
            # the continuous-derivative pass would add zeros; sppi = 0 and no guiding: there are
            # no indirectly observed discontinuities to sample.
            "integrator": {"type": plugin, "guiding": "none", "sppi": 0, "sppc": 0},
            "sensor": {
                "type": "perspective",
                "fov": fov,
                "fov_axis": "x",
                "near_clip": 0.5 * d,
                "far_clip": 2.0 * d,
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=[0, 0, d], target=[0, 0, 0], up=[0, 1, 0]
                ),
                "film": {
                    "type": "hdrfilm",
                    "width": self.size,
                    "height": self.size,
                    "rfilter": {"type": "box"},
                    "pixel_format": "luminance",
                    "sample_border": True,
                },
                "sampler": {"type": "independent", "sample_count": self.spp},
            },
            "shape": mesh,
        }
        if self._complement:
            desc["background"] = {"type": "constant", "radiance": {"type": "uniform", "value": 1.0}}
        return desc

    def bind(self, pose_shape: np.ndarray) -> None:
        """See :meth:`sieve_mi.objectives.Objective.bind`.

        Raises ValueError when an index lies outside the shape list.
        """
        pose_shape = np.asarray(pose_shape, dtype=np.int64)
        if pose_shape.size and (pose_shape.min() < 0 or pose_shape.max() >= len(self._scenes)):
            raise ValueError("pose_shape holds an index outside the shape list")
        self._pose_shape = [int(s) for s in pose_shape]
        self.pose_count = len(self._pose_shape)

    def _vertices(self, rows, t, k: int, shape: int):
        """Flat vertex buffer of pose ``k`` (differentiable in rows and t), pre-warped for the camera."""
        dr, mi = self.dr, self.mi
        idx = mi.UInt32(k)
        g = [dr.gather(mi.Float, r, idx) for r in rows]
        tx, ty = dr.gather(mi.Float, t[0], idx), dr.gather(mi.Float, t[1], idx)
        p = self._verts[shape]
        x = g[0] * p.x + g[1] * p.y + g[2] * p.z + tx
        y = g[3] * p.x + g[4] * p.y + g[5] * p.z + ty
        z = g[6] * p.x + g[7] * p.y + g[8] * p.z
        w = (
            self.distance - z
        ) / self.distance  # the camera at z = D then projects (x', y', z) onto (x, y)
        return dr.ravel(mi.Point3f(x * w, y * w, z))

    def _outside(self, holes, pose_hole, k: int):
        """1 on film pixels outside pose ``k``'s hole (or outside the frame), else 0."""
        dr, mi = self.dr, self.mi
        hole = dr.gather(mi.UInt32, pose_hole, mi.UInt32(k))
        dist = holes.gather(hole, self._row, self._col, self._in_frame)
        return dr.select(self._in_frame & (dist <= 0), mi.Float(0), mi.Float(1))

    def _coverage(self, rendered):
        """Flat per-pixel silhouette coverage from a rendered (M, M, 1) tensor."""
        return 1.0 - rendered.array if self._complement else rendered.array

    def silhouette(self, q, t, k: int = 0, seed: int = 0):
        """Pose ``k``'s rendered silhouette as an (M, M) mi.TensorXf (M = N + 2 margin), detached.

        For inspection and tests; rows run from +y (top) to -y, columns from -x to +x.
        """
        dr, mi = self.dr, self.mi
        shape = self._pose_shape[k] if self._pose_shape is not None else 0
        with dr.suspend_grad():
            rows = quat_rows(*q)
            params = self._params[shape]
            params["shape.vertex_positions"] = dr.detach(self._vertices(rows, t, k, shape))
            params.update()
            img = mi.render(self._scenes[shape], spp=self.spp, seed=seed)
            return mi.TensorXf(self._coverage(img), (self.size, self.size))

    def loss(self, q, t, holes, pose_hole, live=None, seed: int | None = None):
        """See :meth:`sieve_mi.objectives.Objective.loss` (no ``fit_loss``: ``live`` is refused).

        ``per_pose`` is the fraction of each silhouette outside its hole, in [0, 1]. The gradient
        of ``total`` with respect to ``q`` and ``t`` is Mitsuba's (see the module docstring: the
        derivatives are computed here, pose by pose, and attached to ``total``). Raises
        RuntimeError before :meth:`bind` and ValueError when ``holes`` is on another frame.

        Parameters
        ----------
        seed : int, optional
            Seed of the Monte Carlo estimates (fixed seeds give common random numbers, e.g. for
            finite differences); by default every call uses new seeds.
        """
        dr, mi = self.dr, self.mi
        self._no_live(live)
        if self._pose_shape is None:
            raise RuntimeError("call bind(pose_shape) before loss()")
        if holes.frame != self.frame:
            raise ValueError("the hole stack's frame differs from the objective's frame")
        if seed is None:
            seed = self._seed + 2 * self._calls
            self._calls += 1
        seed = int(seed) & 0x3FFFFFFF
        if self.pose_count == 0:
            zero = mi.Float(0.0)
            return zero, dr.zeros(mi.Float, 0)
        need_grad = any(dr.grad_enabled(a) for a in (*q, *t))
        rows = quat_rows(*q)
        per_pose = dr.zeros(mi.Float, self.pose_count)
        surrogate = mi.Float(0.0)
        for k, shape in enumerate(self._pose_shape):
            params = self._params[shape]
            flat = self._vertices(rows, t, k, shape)
            leaf = dr.detach(flat)
            if need_grad:
                dr.enable_grad(leaf)
            params["shape.vertex_positions"] = leaf
            params.update()
            rendered = mi.render(
                self._scenes[shape],
                params,
                spp=self.spp,
                spp_grad=self.spp_grad,
                seed=seed,
                seed_grad=seed + 1,
            )
            img = self._coverage(rendered)
            outside = self._outside(holes, pose_hole, k)
            covered = dr.sum(img)
            # A silhouette entirely off the film counts as entirely outside (no gradient there).
            value = dr.select(
                covered > 1e-6, dr.sum(img * outside) / dr.maximum(covered, 1e-6), mi.Float(1.0)
            )
            if need_grad:
                dr.backward(value)
                g = dr.grad(leaf)
                surrogate = surrogate + dr.sum(g * (flat - dr.detach(flat)))
                dr.disable_grad(leaf)
            dr.scatter(per_pose, dr.detach(value), mi.UInt32(k))
            # Evaluate now: the next pose overwrites the scene's vertex buffer.
            dr.eval(per_pose, surrogate)
        total = dr.sum(per_pose) + surrogate
        return total, per_pose
