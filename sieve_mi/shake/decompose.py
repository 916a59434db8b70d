"""CoACD's convex pieces of a part, kept on disk by the mesh's hash so a part is split once.

Splitting a hollow part is most of a shake run's time (three hollow toy bricks: 686 of 742 s), and
the same part is shaken again and again. :func:`coacd_pieces` keys each decomposition by a
SHA-256 of the mesh's vertex and face bytes, CoACD's settings and version, and keeps it in one
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

__all__ = ["CACHE_ENV", "cache_dir", "cache_key", "coacd_pieces", "refine"]

#: Environment variable naming the cache's root folder (``coacd/`` is made inside it).
CACHE_ENV = "SIEVE_MI_CACHE"
#: Bumped when what is stored changes meaning.
_FORMAT = b"sieve-mi coacd cache 2"
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
    (:func:`sieve_mi.shake.geometry.bulge`). A piece over ``bound`` is replaced by CoACD's pieces
    of the mesh inside its hull (manifold3d's intersection), which CoACD measures against that
    smaller solid, so its threshold is finer in scene units; every new piece lies inside the old
    hull, and together they cover the mesh inside it, so the union still covers the mesh and
    only shrinks towards it. At most :data:`REFINE_ROUNDS` rounds; a heuristic, so the result's
    Hausdorff distance is measured and reported, never assumed.

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

    from sieve_mi.shake.geometry import bulge

    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64))
    solid = manifold3d.Manifold(
        manifold3d.Mesh(np.asarray(vertices, np.float32), np.asarray(faces, np.uint32))
    )
    for _ in range(REFINE_ROUNDS):
        over = [k for k, p in enumerate(pieces) if bulge(mesh, p, PIECE_SAMPLES) > bound]
        if not over:
            break
        out = [p for k, p in enumerate(pieces) if k not in set(over)]
        for k in over:
            sub = (solid ^ manifold3d.Manifold.hull_points(pieces[k])).to_mesh()
            v = np.asarray(sub.vert_properties, np.float64)[:, :3]
            f = np.asarray(sub.tri_verts, np.int64)
            if len(f) < 4:
                out.append(pieces[k])
                continue
            parts = coacd.run_coacd(coacd.Mesh(v, f), **options)
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
