"""The result of a certification and its certificate file (JSON).

Certificate format (``"format": "sieve-mi-certificate/1"``; lengths in scene units):

* ``shape``: ``path``, ``scale``, the centred mesh (``vertices`` (V, 3), ``faces`` (F, 3)), its
  ``sha256`` (see :func:`mesh_hash`; the replay compares it with the file at ``path`` when that
  exists), ``points``: the (k, 3) points the evidence refers to by index, and ``on_edge``: per
  point null (a vertex) or ``[i, j, lam]`` (the point v_i + lam (v_j - v_i) on the mesh edge
  (i, j), 0 <= lam <= 1; only with symmetry "none").
* ``hole``: the contours of H (list of (m, 2) lists; outer counter-clockwise, holes clockwise).
* ``symmetry``: ``"none"``, ``"klein"`` or ``"octahedral"``: the domain searched (module
  :mod:`sieve_mi.certify.symmetry`).
* ``root``: ``{"kind": "ball", "centre", "radius"}`` when the shape is blocked for all rotations at
  once, else null.
* ``tree``: one node per domain face, in order; a node is ``{"e": evidence}`` (an excluded leaf),
  ``{"c": [8 nodes]}`` (split into octants: child c takes the upper half of component j iff bit
  (2 - j) of c is set) or ``{"open": true}``. Evidence is ``{"kind": "width", "direction": m,
  "points": [...]}`` (direction m of ``directions`` unit vectors over a half circle) or
  ``{"kind": "translations", "points": [...]}``.
* ``settings``: ``kappa`` (slack, see :class:`~sieve_mi.certify.search.Settings`), ``directions``,
  ``bound``: ``"first-order"`` (each point's displacement bound over a cell is the smaller of the
  first-order bound and 2 sin(theta) |p|; docs/certify.md) or ``"isotropic"`` (2 sin(theta) |p|
  only; certificates without ``bound`` were written before the first-order bound and mean this).
* ``status`` and ``passage`` (quaternion, translation) as found.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape, mesh_sha256

__all__ = [
    "Certification",
    "FORMAT",
    "build",
    "mesh_hash",
    "tree_to_dict",
    "writable_certificate",
]

FORMAT = "sieve-mi-certificate/1"


def mesh_hash(shape: Shape) -> str:
    """SHA-256 of the shape's centred vertices (float64) and faces (int64), hex."""
    return mesh_sha256(shape.vertices, shape.faces)


@dataclass
class Certification:
    """Whether a shape can pass a hole, with the evidence.

    Attributes
    ----------
    status : str
        ``"proved"`` (no rotation and translation lets it through), ``"passage"`` (a pose that
        fits was found) or ``"undecided"`` (the budget or the smallest cell size was reached).
    seconds : float
    method : str
        ``"ball"`` (root-level inscribed-ball test) or ``"cells"`` (branch and bound).
    cells_examined, cells_excluded, cells_open : int
    excluded_fraction : float
        Excluded share of the searched rotation domain, measured by volume in face coordinates.
    depth : int
        Levels of the cell tree.
    symmetry : str
        Symmetry group used to shrink the domain.
    passage : dict or None
        ``quaternion`` (w, x, y, z) about the shape's centre and ``translation`` (x, y) in the
        hole's frame, scene units.
    margin : float or None
        A proved margin m >= 0, scene units: the shape is also proved blocked by the hole grown
        by m, so every pose sticks out of the hole by more than m (:func:`prove_margin`; None when
        not tried or not proved).
    margin_certificate : dict
        The certificate of that proof against the grown hole (empty when m = 0 or None).
    """

    status: str
    seconds: float
    method: str
    cells_examined: int = 0
    cells_excluded: int = 0
    cells_open: int = 0
    excluded_fraction: float = 0.0
    depth: int = 0
    symmetry: str = "none"
    passage: dict | None = None
    certificate: dict = field(default_factory=dict, repr=False)
    margin: float | None = None
    margin_certificate: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """The result as plain JSON-ready data (without the certificate)."""
        return {
            "status": self.status,
            "seconds": self.seconds,
            "method": self.method,
            "cells_examined": self.cells_examined,
            "cells_excluded": self.cells_excluded,
            "cells_open": self.cells_open,
            "excluded_fraction": self.excluded_fraction,
            "depth": self.depth,
            "symmetry": self.symmetry,
            "passage": self.passage,
            "margin": self.margin,
        }

    def write_certificate(self, path: str, inputs: tuple[str, ...] = ()) -> None:
        """Write the certificate (JSON) to ``path``, atomically (a temporary file, then renamed).

        ``path`` is checked first with :func:`writable_certificate` (never a file sieve-mi did
        not write, never one of ``inputs``); a failed write leaves no temporary file behind.
        """
        writable_certificate(path, inputs)
        tmp = f"{path}.tmp{os.getpid()}"
        try:
            with open(tmp, "w") as fh:
                json.dump(self.certificate, fh)
            os.replace(tmp, path)
        except OSError as e:
            raise SieveError(f"{path}: cannot write the certificate ({e.strerror})") from None
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)


def _is_certificate(path: str) -> bool:
    """Whether the file at ``path`` is a certificate sieve-mi wrote (its JSON names :data:`FORMAT`)."""
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
            if f'"format": "{FORMAT}"' not in head and f'"format":"{FORMAT}"' not in head:
                return json.loads(head + fh.read()).get("format") == FORMAT
            return True
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        return False


def writable_certificate(path: str, inputs: tuple[str, ...] = ()) -> None:
    """Refuse, in one line, a certificate path that writing would lose data at.

    The same rule as ``--out``: sieve-mi replaces only a certificate it wrote itself, never one of
    the run's ``inputs`` (mesh, plate, SVG), a folder, or any other file.

    Raises
    ------
    SieveError
    """
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise SieveError(f"--certificate {path}: is a folder; name a file (e.g. {path}/cert.json)")
    if not os.path.isdir(folder):
        raise SieveError(f"--certificate {path}: its folder {folder} does not exist")
    if not os.path.lexists(path):
        return
    for given in inputs:
        if given and os.path.exists(given) and os.path.samefile(path, given):
            raise SieveError(f"--certificate {path}: is an input of this run; name another file")
    if not os.path.isfile(path) or not _is_certificate(path):
        raise SieveError(
            f"--certificate {path}: exists and is not a sieve-mi certificate; name another file "
            "(sieve-mi never overwrites a file it did not write)"
        )


def tree_to_dict(node) -> dict:
    """A search :class:`~sieve_mi.certify.search.Node` as a certificate node."""
    if node.children:
        return {"c": [tree_to_dict(c) for c in node.children]}
    if node.evidence is not None:
        return {"e": node.evidence}
    return {"open": True}


def build(
    shape: Shape,
    contours: list,
    status: str,
    symmetry: str,
    root: dict | None,
    outcome,
    settings,
    scale: float = 1.0,
) -> dict:
    """The certificate dictionary (format in the module docstring).

    Point indices in the evidence are renumbered into ``shape.points``.
    """
    used = sorted(outcome.points) if outcome is not None else []
    renumber = {old: new for new, old in enumerate(used)}
    vertices = shape.vertices[np.unique(shape.faces)]
    if outcome is not None and outcome.candidates is not None:
        vertices = outcome.candidates
    on_edge = [outcome.on_edge.get(u) for u in used] if outcome is not None else []

    def renum(node: dict) -> dict:
        if "c" in node:
            return {"c": [renum(c) for c in node["c"]]}
        if "e" in node:
            e = dict(node["e"])
            e["points"] = [renumber[p] for p in e["points"]]
            return {"e": e}
        return node

    tree = [renum(tree_to_dict(n)) for n in outcome.roots] if outcome is not None else []
    return {
        "format": FORMAT,
        "status": status,
        "shape": {
            "name": shape.name,
            "path": os.path.abspath(shape.path) if shape.path else "",
            "scale": scale,
            "sha256": mesh_hash(shape),
            "vertices": shape.vertices.tolist(),
            "faces": shape.faces.tolist(),
            "points": vertices[used].tolist(),
            "on_edge": on_edge,
        },
        "hole": [np.asarray(c, dtype=np.float64).tolist() for c in contours],
        "symmetry": symmetry,
        "root": root,
        "tree": tree,
        "settings": {
            "kappa": settings.kappa,
            "directions": settings.directions,
            "bound": settings.bound,
        },
        "passage": outcome.passage if outcome is not None else None,
    }
