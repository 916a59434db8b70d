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
import tempfile
from dataclasses import dataclass, field

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import Shape, mesh_sha256

__all__ = [
    "Certification",
    "FORMAT",
    "MAX_CERTIFICATE_BYTES",
    "REQUIRED",
    "build",
    "is_certificate",
    "mesh_hash",
    "read_certificate_file",
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
        """Write the certificate (JSON) to ``path``, atomically.

        ``path`` is checked first with :func:`writable_certificate` (never a file sieve-mi did
        not write, never one of ``inputs``). The JSON goes to a new temporary file in the same
        folder (created exclusively, so no file of the user's is touched), is flushed to disk and
        then renamed over ``path`` (``os.replace``): an interrupted or failed write leaves
        ``path`` as it was and no temporary file behind.

        Raises
        ------
        SieveError
            If ``path`` is refused or cannot be written.
        """
        writable_certificate(path, inputs)
        folder = os.path.dirname(os.path.abspath(path))
        try:
            fd, tmp = tempfile.mkstemp(
                prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=folder
            )
        except OSError as e:
            raise SieveError(
                f"--certificate {path}: cannot write the certificate ({e.strerror})"
            ) from None
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(self.certificate, fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(tmp, _new_file_mode())
            os.replace(tmp, path)
        except OSError as e:
            raise SieveError(
                f"--certificate {path}: cannot write the certificate ({e.strerror})"
            ) from None
        finally:
            if os.path.lexists(tmp):
                os.remove(tmp)


def _new_file_mode() -> int:
    """The permission bits ``open(path, "w")`` would give a new file (0o666 less the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


#: The keys every certificate has, at the top level and in ``shape`` and ``settings`` (those of
#: the first certificates too: ``on_edge`` and ``settings.bound`` came later).
REQUIRED = {
    "": ("format", "status", "shape", "hole", "symmetry", "root", "tree", "settings", "passage"),
    "shape": ("sha256", "vertices", "faces", "points"),
    "settings": ("kappa", "directions"),
}


def is_certificate(data) -> bool:
    """Whether parsed JSON ``data`` is a sieve-mi certificate: a JSON object whose top-level
    ``format`` is :data:`FORMAT` and that has a certificate's structure (the keys of
    :data:`REQUIRED`; ``shape`` and ``settings`` objects, ``hole`` and ``tree`` lists).

    A file is recognised only by parsing it, never by a string it contains: a note that quotes
    the format line, or a JSON collection holding a certificate, is not a certificate.
    """
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        return False
    if not all(k in data for k in REQUIRED[""]):
        return False
    for part in ("shape", "settings"):
        if not isinstance(data[part], dict) or not all(k in data[part] for k in REQUIRED[part]):
            return False
    return isinstance(data["hole"], list) and isinstance(data["tree"], list)


#: Largest file :func:`read_certificate_file` parses (bytes); a larger one is not taken for one.
MAX_CERTIFICATE_BYTES = 1 << 30


def read_certificate_file(path: str):
    """The parsed JSON of the file at ``path``, or None when it is not JSON text.

    Only a file whose first non-blank character is ``{`` and of at most
    :data:`MAX_CERTIFICATE_BYTES` is parsed (a binary file, a note, a mesh or a large data set
    is never read whole); too deep a nesting or too long an integer reads as not JSON.
    """
    try:
        if os.path.getsize(path) > MAX_CERTIFICATE_BYTES:
            return None
        with open(path, "rb") as fh:
            head = fh.read(64).lstrip()
            if not head.startswith(b"{"):
                return None
            fh.seek(0)
            return json.loads(fh.read().decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError, MemoryError):
        return None


def writable_certificate(path: str, inputs: tuple[str, ...] = ()) -> None:
    """Refuse, in one line, a certificate path that writing would lose data at.

    The same rule as ``--out``: sieve-mi replaces only a certificate it wrote itself (recognised
    by parsing it, :func:`is_certificate`), never one of the run's ``inputs`` (mesh, plate, SVG),
    a folder, a symbolic link, a read-only file, any other file, or a file in a folder it cannot
    write to. Called before any work and again just before the write.

    Raises
    ------
    SieveError
    """
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise SieveError(f"--certificate {path!r}: name a file (e.g. cert.json)")
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path) or path.endswith((os.sep, "/")):
        example = os.path.join(path.rstrip("/" + os.sep) or os.sep, "cert.json")
        raise SieveError(f"--certificate {path}: is a folder; name a file (e.g. {example})")
    if os.path.islink(path):
        raise SieveError(f"--certificate {path}: is a symbolic link; name a regular file")
    if not os.path.isdir(folder):
        raise SieveError(f"--certificate {path}: its folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise SieveError(f"--certificate {path}: its folder {folder} is not writable")
    if not os.path.lexists(path):
        return
    _existing_is_replaceable(path, inputs)


def _existing_is_replaceable(path: str, inputs: tuple[str, ...]) -> None:
    """Refuse an existing ``path`` unless it is a writable certificate that is no input."""
    for given in inputs:
        if given and os.path.exists(given) and os.path.samefile(path, given):
            raise SieveError(f"--certificate {path}: is an input of this run; name another file")
    if not os.path.isfile(path) or not is_certificate(read_certificate_file(path)):
        raise SieveError(
            f"--certificate {path}: exists and is not a sieve-mi certificate; name another file "
            "(sieve-mi never overwrites a file it did not write)"
        )
    if not os.access(path, os.W_OK):
        raise SieveError(f"--certificate {path}: is read-only; name another file")


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
