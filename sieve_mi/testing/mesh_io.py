"""Read back the files sieve-mi writes (for tests and tools)."""

from __future__ import annotations

import zipfile

import numpy as np
import trimesh

__all__ = ["read_3mf"]


def read_3mf(path: str) -> trimesh.Trimesh:
    """Read the first mesh object of a 3MF package written by :func:`write_3mf` (or a simple one)."""
    import xml.etree.ElementTree as ET

    ns = {"m": "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"}
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("3D/3dmodel.model"))
    mesh = root.find(".//m:object/m:mesh", ns)
    v = np.array(
        [[float(e.get(k)) for k in "xyz"] for e in mesh.find("m:vertices", ns)], dtype=np.float64
    )
    f = np.array(
        [[int(e.get(k)) for k in ("v1", "v2", "v3")] for e in mesh.find("m:triangles", ns)],
        dtype=np.int64,
    )
    return trimesh.Trimesh(v, f, process=False)
