"""Generate the meshes of the like-for-like scenes in ``benchmarks/authors/`` (deterministic).

Usage: ``python benchmarks/authors/make_meshes.py [--force]`` (``python -m benchmarks.authors``
calls it when a mesh is missing). The meshes are written to ``benchmarks/authors/meshes/``
(ignored by git) from the bundled meshes in ``scenes/meshes/`` and ``benchmarks/meshes/``:

* ``uv_sphere96.ply``: a UV sphere of radius 1 with 8 segments and 7 bands, 50 vertices and
  96 faces (the face count of the authors' ``sphere.stl``).
* ``beetle_front.ply``: the beetle's +z 58 % (its "front" here: 42 % of its length along z cut
  off; an open shell like the beetle itself; about the face count of their ``591211.stl``).
* ``fandisk_cut.ply``: the fandisk with the bottom 7 % of its height (its thinnest extent) cut
  off and the cut capped (closed; like their ``62526_cut.stl``, a cut-down version of the B
  mesh; 12,564 faces against their 12,560).
* ``cow_front.ply``: the 40 % of the cow's length at +x, capped (about the face count of their
  ``67523.stl``).
* ``<name>_x4.ply``, ``<name>_x16.ply``: a mesh split by midpoint subdivision once or twice (4x
  or 16x the faces, the same surface), to reach the face counts of their larger meshes.
* ``bunny_twist.ply``, ``bunny_bend.ply``, ``bunny_stretch.ply``: the Stanford bunny deformed
  (same connectivity, 69,451 faces), standing in for their cat in other poses.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
OUT = os.path.join(HERE, "meshes")
SOURCES = {
    "beetle": os.path.join(ROOT, "benchmarks", "meshes", "beetle.obj"),
    "fandisk": os.path.join(ROOT, "benchmarks", "meshes", "fandisk.obj"),
    "bunny": os.path.join(ROOT, "benchmarks", "meshes", "stanford-bunny.obj"),
    "spot": os.path.join(ROOT, "scenes", "meshes", "spot.obj"),
    "cow": os.path.join(ROOT, "scenes", "meshes", "cow.obj"),
    "suzanne": os.path.join(ROOT, "scenes", "meshes", "suzanne.obj"),
}


def _load(name: str):
    import trimesh

    return trimesh.load(SOURCES[name], force="mesh", process=True)


def uv_sphere(segments: int = 8, bands: int = 7):
    """A UV sphere of radius 1 with poles on z.

    Parameters
    ----------
    segments : int
        Vertices around each ring.
    bands : int
        Latitude bands (``bands - 1`` rings between the poles).

    Returns
    -------
    trimesh.Trimesh
        ``2 + segments * (bands - 1)`` vertices, ``2 * segments * (bands - 1)`` faces.
    """
    import trimesh

    theta = np.pi * np.arange(1, bands) / bands
    phi = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack(
        [
            np.outer(np.sin(theta), np.cos(phi)).ravel(),
            np.outer(np.sin(theta), np.sin(phi)).ravel(),
            np.repeat(np.cos(theta), segments),
        ],
        axis=1,
    )
    verts = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    south = len(verts) - 1
    faces = []
    for j in range(segments):
        k = (j + 1) % segments
        faces.append([0, 1 + j, 1 + k])
        last = 1 + (bands - 2) * segments
        faces.append([south, last + k, last + j])
        for i in range(bands - 2):
            a, b = 1 + i * segments + j, 1 + i * segments + k
            c, d = a + segments, b + segments
            faces += [[a, c, b], [b, c, d]]
    mesh = trimesh.Trimesh(verts, np.array(faces), process=False)
    mesh.fix_normals()
    return mesh


def cut(mesh, axis: int, fraction: float, keep_low: bool, cap: bool):
    """Cut ``mesh`` by a plane normal to ``axis``.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The mesh to cut.
    axis : int
        0, 1 or 2: the plane's normal.
    fraction : float
        Where the plane lies, as a fraction of the extent along ``axis`` from its low end.
    keep_low : bool
        Keep the part below the plane (else the part above).
    cap : bool
        Close the cut with a cap (the mesh must be watertight).

    Returns
    -------
    trimesh.Trimesh
        The kept part.
    """
    lo, hi = mesh.bounds[:, axis]
    origin = np.zeros(3)
    origin[axis] = lo + fraction * (hi - lo)
    normal = np.zeros(3)
    normal[axis] = -1.0 if keep_low else 1.0
    return mesh.slice_plane(origin, normal, cap=cap)


def subdivided(name: str, times: int):
    """``name``'s mesh split ``times`` times by midpoint subdivision (4**times the faces)."""
    import trimesh

    m = _load(name)
    v, f = m.vertices, m.faces
    for _ in range(times):
        v, f = trimesh.remesh.subdivide(v, f)
    return trimesh.Trimesh(v, f, process=False)


def bunny_variants():
    """The bunny deformed three ways (same vertices and faces, other positions).

    Returns
    -------
    dict
        ``{"bunny_twist": mesh, "bunny_bend": mesh, "bunny_stretch": mesh}``: a 25° twist about
        the vertical (y) axis over the height, a bend of the vertical axis towards +x, and a
        stretch of 8 % along x with 4 % along z.
    """
    m = _load("bunny")
    v = m.vertices - m.bounds.mean(axis=0)
    h = np.ptp(v[:, 1])
    t = (v[:, 1] - v[:, 1].min()) / h
    angle = np.radians(25.0) * (t - 0.5)
    c, s = np.cos(angle), np.sin(angle)
    twist = np.column_stack([c * v[:, 0] + s * v[:, 2], v[:, 1], -s * v[:, 0] + c * v[:, 2]])
    bend = v.copy()
    bend[:, 0] += 0.25 * h * (t - 0.5) ** 2
    stretch = v * np.array([1.08, 1.0, 1.04])
    out = {}
    for name, verts in (("bunny_twist", twist), ("bunny_bend", bend), ("bunny_stretch", stretch)):
        out[name] = m.copy()
        out[name].vertices = verts
    return out


def build() -> dict:
    """Every generated mesh, by file stem."""
    meshes = {"uv_sphere96": uv_sphere()}
    meshes["beetle_front"] = cut(_load("beetle"), 2, 0.42, keep_low=False, cap=False)
    meshes["fandisk_cut"] = cut(_load("fandisk"), 2, 0.07, keep_low=False, cap=True)
    meshes["cow_front"] = cut(_load("cow"), 0, 0.60, keep_low=False, cap=True)
    for name, times in (("spot", 1), ("cow", 1), ("beetle", 2), ("suzanne", 2)):
        meshes[f"{name}_x{4**times}"] = subdivided(name, times)
    meshes.update(bunny_variants())
    return meshes


def main(argv=None) -> int:
    """Write the meshes that are missing (or all with ``--force``); print their face counts."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--force", action="store_true", help="rewrite existing meshes")
    args = p.parse_args(argv)
    os.makedirs(OUT, exist_ok=True)
    for name, mesh in build().items():
        path = os.path.join(OUT, f"{name}.ply")
        if args.force or not os.path.exists(path):
            mesh.export(path)
        print(f"{name}: {len(mesh.faces):,} faces, watertight {mesh.is_watertight}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
