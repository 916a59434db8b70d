"""CoACD's convex pieces of a part, refined to a Hausdorff bound, measured against the part, and
kept on disk by the mesh's hash so a part is split once.

:func:`hausdorff` measures the distance between a part and the union of its pieces, both ways
(a piece bulging out makes the part fatter in the engine, a gap thinner); :func:`refine` splits
again each piece that bulges out further than a bound (:func:`bulge`).

Splitting a hollow part is most of a shake run's time (three hollow toy bricks: 686 of 742 s), and
the same part is shaken again and again. :func:`coacd_pieces` keys each decomposition by a
SHA-256 of the mesh's vertex and face bytes, CoACD's settings and version, the bound, and keeps it in one
``.npz`` file under :func:`cache_dir`: ``$SIEVE_MI_CACHE/coacd`` when that variable is set, else
``$XDG_CACHE_HOME/sieve-mi/coacd`` (``~/.cache/sieve-mi/coacd``). Nothing is written next to the
user's files; a folder that cannot be written, or a file that cannot be read, only costs the
decomposition again. CoACD is deterministic for a given seed, so a cached run gives the bits of an
uncached one.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from sieve_mi.geometry.solid import triangle_distance, winding_numbers

__all__ = ["CACHE_ENV", "bulge", "cache_dir", "cache_key", "coacd_pieces", "hausdorff", "refine"]

#: Environment variable naming the cache's root folder (``coacd/`` is made inside it).
CACHE_ENV = "SIEVE_MI_CACHE"
#: Bumped when what is stored changes meaning (3: :func:`refine` splits without CoACD's
#: manifold preprocessing).
_FORMAT = b"sieve-mi coacd cache 3"
#: Surface samples per mesh for the sampled Hausdorff distance.
HAUSDORFF_SAMPLES = 20_000
#: Each surface's samples that the other's are measured to: this many times
#: ``HAUSDORFF_SAMPLES`` (a point on the other surface is then within half a millimetre's tenth
#: of one on a 30 mm letter, where 20,000 left it 0.4 mm away, so an exact split read 0.6 mm).
REFERENCE_SAMPLES = 10
#: Rounds of :func:`refine` at most.
REFINE_ROUNDS = 3
#: Surface samples per piece for its bulge in :func:`refine`.
PIECE_SAMPLES = 2000


def cache_dir() -> Path:
    """The folder of cached decompositions (not created here)."""
    root = os.environ.get(CACHE_ENV)
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "sieve-mi")
    return Path(root) / "coacd"


def cache_key(vertices: np.ndarray, faces: np.ndarray, options: dict) -> str:
    """SHA-256 (hex) of a mesh's bytes and the decomposition's options.

    Parameters
    ----------
    vertices : (n, 3) float
        Scene units (hashed as little-endian float64).
    faces : (m, 3) int
        Hashed as little-endian int64.
    options : dict
        CoACD's keyword arguments and anything else that changes the result (its version).
    """
    h = hashlib.sha256(_FORMAT)
    h.update(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(faces, dtype="<i8").tobytes())
    h.update(repr(sorted(options.items())).encode())
    return h.hexdigest()


def coacd_pieces(
    vertices: np.ndarray, faces: np.ndarray, bound: float = 0.0, **options
) -> list[np.ndarray]:
    """CoACD's convex pieces of a mesh, refined to ``bound`` (:func:`refine`), from the cache
    when it has them.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    bound : float
        Largest bulge of a piece out of the mesh (scene units) before it is split again; 0: CoACD's
        pieces as they are. Part of the cache key.
    **options
        Keyword arguments of ``coacd.run_coacd`` (threshold, seed, pca, ...).

    Returns
    -------
    list of (k, 3) float
        Each piece's vertices (pieces of fewer than 4 vertices left out), the mesh's frame.
    """
    from importlib.metadata import version

    import coacd

    key = cache_key(vertices, faces, {**options, "bound": float(bound), "coacd": version("coacd")})
    path = cache_dir() / f"{key}.npz"
    pieces = _load(path)
    if pieces is None:
        coacd.set_log_level("error")
        mesh = coacd.Mesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
        parts = coacd.run_coacd(mesh, **options)
        pieces = [np.asarray(v, dtype=np.float64) for v, _ in parts if len(v) >= 4]
        if bound > 0:
            pieces = refine(vertices, faces, pieces, bound, **options)
        _store(path, pieces)
    return pieces


def refine(vertices, faces, pieces: list[np.ndarray], bound: float, **options) -> list[np.ndarray]:
    """Split again, with CoACD, each piece that bulges more than ``bound`` out of the mesh.

    A piece's bulge is the largest distance of a sample of its hull's surface outside the mesh
    (:func:`bulge`). A piece over ``bound`` is replaced by CoACD's pieces of the mesh inside its
    hull (manifold3d's intersection), which CoACD measures against that smaller solid, so its
    threshold is finer in scene units; every new piece lies inside the old hull, and together
    they cover the mesh inside it, so the union still covers the mesh and only shrinks towards
    it. A bound below the bulge's sample spacing is raised to it (a piece over it could not be
    told from one that fits). At most :data:`REFINE_ROUNDS` rounds; a heuristic, so the
    result's Hausdorff distance is measured and reported, never assumed.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    pieces : list of (k, 3) float
        Convex pieces' vertices, the mesh's frame.
    bound : float
        Scene units, > 0.
    **options
        CoACD's keyword arguments, for the new splits.

    Returns
    -------
    list of (k, 3) float
    """
    import coacd
    import manifold3d
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    solid = manifold3d.Manifold(
        manifold3d.Mesh(np.asarray(vertices, np.float32), np.asarray(faces, np.uint32))
    )
    # a bulge is measured to samples this far apart: below it, splitting again cannot be judged
    floor = float(np.sqrt(mesh.area / (REFERENCE_SAMPLES * PIECE_SAMPLES)))
    bound = max(bound, floor)
    for _ in range(REFINE_ROUNDS):
        over = {k for k, p in enumerate(pieces) if bulge(mesh, p, PIECE_SAMPLES) > bound}
        if not over:
            break
        out = [p for k, p in enumerate(pieces) if k not in over]
        for k in sorted(over):
            sub = (solid ^ manifold3d.Manifold.hull_points(pieces[k])).to_mesh()
            v = np.asarray(sub.vert_properties, np.float64)[:, :3]
            f = np.asarray(sub.tri_verts, np.int64)
            if len(f) < 4:
                out.append(pieces[k])
                continue
            # manifold3d's solid is closed and manifold: CoACD's manifold preprocessing has
            # nothing to mend, and on some of these solids it aborts the process (a C++
            # logic_error, "unexpected code path was hit": the letters' R at one pose)
            parts = coacd.run_coacd(coacd.Mesh(v, f), **{**options, "preprocess_mode": "off"})
            new = [np.asarray(a, np.float64) for a, _ in parts if len(a) >= 4]
            out += new if new else [pieces[k]]
        pieces = out
    return pieces


def _load(path: Path) -> list[np.ndarray] | None:
    """The pieces stored at ``path``, or None (absent, unreadable, damaged)."""
    try:
        with np.load(path, allow_pickle=False) as f:
            verts, counts = f["vertices"], f["counts"]
    except (OSError, ValueError, KeyError):
        return None
    if verts.ndim != 2 or verts.shape[1] != 3 or counts.sum() != len(verts):
        return None
    return [p.astype(np.float64) for p in np.split(verts, np.cumsum(counts)[:-1])]


def _store(path: Path, pieces: list[np.ndarray]) -> None:
    """Write ``pieces`` to ``path`` atomically (a temporary file renamed); on any error, skip."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(
                f,
                vertices=np.concatenate(pieces) if pieces else np.zeros((0, 3)),
                counts=np.array([len(p) for p in pieces], dtype=np.int64),
            )
        os.replace(tmp, path)
    except OSError:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def hausdorff(mesh, hulls: list[np.ndarray], com: np.ndarray, samples: int = HAUSDORFF_SAMPLES):
    """Hausdorff distance between a solid and the union of convex pieces standing in for it.

    For two solids it is attained on a boundary point of one that lies outside the other, so
    both surfaces are sampled evenly (a fixed seed) and each sample outside the other solid is
    measured to the other's nearest sample. A sample farther than the sample spacing from the
    other surface is inside or outside by its winding number about the other mesh
    (:func:`~sieve_mi.geometry.solid.winding_numbers`): this ignores the union's internal seams
    and voids, which no collision sees, and which lie deep inside the part (two pieces of an H that meet a thousandth of a
    millimetre apart leave a wall 2.9 mm from the part's surface, which the earlier test, the
    sign along the nearest sample's normal, counted as error). A sample nearer than the spacing
    is outside when it lies in front of that nearest sample's normal. The result is within the
    sample spacing of the exact one.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The part, scene units.
    hulls : list of (n, 3) float
        Convex pieces relative to ``com``.
    com : (3,) float
        Where ``hulls``' origin lies in ``mesh``'s frame.
    samples : int
        Samples per surface.

    Returns
    -------
    (float, float)
        The distance and the sample spacing, scene units.
    """
    import manifold3d
    import trimesh

    union = manifold3d.Manifold.batch_boolean(
        [manifold3d.Manifold.hull_points(h + com) for h in hulls], manifold3d.OpType.Add
    )
    um = union.to_mesh()
    union_mesh = trimesh.Trimesh(np.asarray(um.vert_properties)[:, :3], np.asarray(um.tri_verts))
    a, na = _samples(mesh, REFERENCE_SAMPLES * samples)
    b, nb = _samples(union_mesh, REFERENCE_SAMPLES * samples)
    fine = float(np.sqrt(max(mesh.area, union_mesh.area) / (REFERENCE_SAMPLES * samples)))
    d = max(
        _outside_distance(a[::REFERENCE_SAMPLES], b, nb, union_mesh.triangles, fine),
        _outside_distance(b[::REFERENCE_SAMPLES], a, na, np.asarray(mesh.triangles), fine),
    )
    spacing = float(np.sqrt(max(mesh.area, union_mesh.area) / samples))
    return float(d), spacing


def bulge(mesh, points: np.ndarray, samples: int = 2000) -> float:
    """How far a convex piece reaches out of a solid: the largest distance to ``mesh``'s
    surface of a sample of the piece's hull's surface outside ``mesh`` (as :func:`hausdorff`
    measures, on ``samples`` points of the piece against ten times as many of the mesh).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The solid, scene units.
    points : (k, 3) float
        The piece's vertices, ``mesh``'s frame.
    samples : int

    Returns
    -------
    float
        Scene units.
    """
    import trimesh

    hull = trimesh.convex.convex_hull(points)
    q, nq = _samples(mesh, REFERENCE_SAMPLES * samples)
    fine = float(np.sqrt(mesh.area / (REFERENCE_SAMPLES * samples)))
    p, _ = _samples(hull, samples)
    return _outside_distance(p, q, nq, np.asarray(mesh.triangles), fine)


def _outside_distance(p, q, nq, triangles, spacing: float) -> float:
    """Largest distance from a point of ``p`` (n, 3) to the samples ``q`` (m, 3) of a solid's
    surface, among the points outside that solid (outward normals ``nq``, bounded by
    ``triangles`` (F, 3, 3)): a point farther than ``spacing`` from ``q`` is outside when its
    winding number is under 1/2 (:func:`~sieve_mi.geometry.solid.winding_numbers`), a nearer
    one when it lies in front of its nearest sample's normal."""
    from scipy.spatial import cKDTree

    dist, idx = cKDTree(q).query(p)
    near = dist <= spacing
    outside = near & (np.einsum("ij,ij->i", p - q[idx], nq[idx]) > 0)
    best = float(dist[outside].max()) if outside.any() else 0.0
    tri = np.asarray(triangles, np.float64)
    far = np.nonzero(~near)[0]
    far = far[np.argsort(-dist[far])]  # the farthest first: stop where none can beat ``best``
    for s in range(0, len(far), 64):
        idx = far[s : s + 64]
        if dist[idx[0]] <= best:
            break
        idx = idx[winding_numbers(p[idx], tri) < 0.5]
        if len(idx):
            best = max(best, float(triangle_distance(p[idx], tri).min(axis=1).max()))
    return best


def _samples(mesh, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points on a mesh's surface, area-weighted, from a fixed seed, and their normals."""
    import trimesh

    pts, face = trimesh.sample.sample_surface(mesh, n, seed=0)
    return np.asarray(pts, dtype=np.float64), np.asarray(mesh.face_normals)[face]
