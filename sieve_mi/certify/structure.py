"""A certificate's form, checked before any geometry: read, recognised, every field typed.

The replay (:mod:`sieve_mi.certify.replay`) trusts nothing of a certificate: before it re-proves
anything, the file is read as JSON (:func:`load_certificate`; a missing key is named), and every
field the replay reads is checked for its type, shape and range (:func:`check_structure`: every
number finite and at most :data:`MAX_COORDINATE`, every index in range). Each problem is one
SieveError naming the field.
"""

from __future__ import annotations

import json
import os

import numpy as np

from sieve_mi.errors import SieveError

__all__ = [
    "MAX_COORDINATE",
    "MAX_DIRECTIONS",
    "certificate_where",
    "check_structure",
    "load_certificate",
]

#: Largest magnitude of a coordinate, radius or translation in a certificate (scene units).
MAX_COORDINATE = 1e12
#: Most width directions a certificate may name (the search uses 36).
MAX_DIRECTIONS = 100_000


def certificate_where(source) -> str:
    """How messages name a certificate: its path, or ``certificate`` for a dict."""
    if isinstance(source, dict):
        return "certificate"
    if isinstance(source, (str, os.PathLike)):
        return os.fspath(source)
    raise SieveError(f"certificate: expected a file path or a dict, got {type(source).__name__}")


def load_certificate(source, where: str) -> dict:
    """The certificate as a dict; SieveError unless it is a sieve-mi certificate (parsed)."""
    from sieve_mi.certify.certificate import FORMAT, is_certificate

    if isinstance(source, dict):
        cert = source
    else:
        cert = _read_json(where)
    if not is_certificate(cert):
        if isinstance(cert, dict) and cert.get("format") == FORMAT:
            missing = _missing_key(cert)
            raise SieveError(f"{where}: not a sieve-mi certificate ({missing})")
        raise SieveError(
            f'{where}: not a sieve-mi certificate (a JSON object whose "format" is {FORMAT!r})'
        )
    return cert


def _read_json(path: str):
    if not os.path.exists(path):
        raise SieveError(f"{path}: certificate not found")
    if not os.path.isfile(path):
        raise SieveError(f"{path}: is not a regular file; name a certificate file")
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except RecursionError:
        raise SieveError(f"{path}: not a readable JSON certificate (nested too deeply)") from None
    except (OSError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "integer string conversion" in first:
            first = "an integer with too many digits"
        raise SieveError(f"{path}: not a readable JSON certificate ({first})") from None


def _missing_key(cert: dict) -> str:
    from sieve_mi.certify.certificate import REQUIRED

    for part, keys in REQUIRED.items():
        block = cert if not part else cert.get(part)
        if not isinstance(block, dict):
            return f"{part} is not an object"
        for k in keys:
            if k not in block:
                return f"no key {(part + '.' if part else '') + k!r}"
    return "hole and tree must be lists"


def check_structure(cert: dict, where: str = "certificate") -> None:
    """Types, shapes and ranges of every field the replay reads (before any geometry).

    Raises
    ------
    SieveError
        One line naming the field: not a string, not an array of the right shape, a number not
        finite or above :data:`MAX_COORDINATE`, an index out of range.
    """
    shape, settings = cert["shape"], cert["settings"]
    for key, value in (("status", cert["status"]), ("symmetry", cert["symmetry"]),
                       ("shape.sha256", shape["sha256"])):  # fmt: skip
        if not isinstance(value, str):
            raise SieveError(f"{where}: {key} must be a string, not {type(value).__name__}")
    for key in ("path", "name"):
        if not isinstance(shape.get(key, ""), str):
            raise SieveError(f"{where}: shape.{key} must be a string")
    vertices = _numbers(shape["vertices"], "shape.vertices", (-1, 3), where)
    faces = _indices(shape["faces"], "shape.faces", (-1, 3), len(vertices), where)
    if len(vertices) == 0 or len(faces) == 0:
        raise SieveError(f"{where}: shape: the mesh has no vertices or no faces")
    _numbers(shape["points"], "shape.points", (-1, 3), where, allow_empty=True)
    _check_on_edge(shape.get("on_edge"), len(vertices), where)
    if "scale" in shape:
        _positive(shape["scale"], "shape.scale", where)
    if not cert["hole"]:
        raise SieveError(f"{where}: hole: no contour")
    for i, c in enumerate(cert["hole"]):
        if len(_numbers(c, f"hole[{i}]", (-1, 2), where)) < 3:
            raise SieveError(f"{where}: hole[{i}]: a contour needs at least 3 points")
    _positive(settings["kappa"], "settings.kappa", where)
    d = settings["directions"]
    if isinstance(d, bool) or not isinstance(d, int) or not 1 <= d <= MAX_DIRECTIONS:
        raise SieveError(f"{where}: settings.directions must be an integer in 1..{MAX_DIRECTIONS}")
    if not isinstance(settings.get("bound", "isotropic"), str):
        raise SieveError(f"{where}: settings.bound must be a string")
    _check_root_and_passage(cert, where)
    _check_plate(cert.get("plate"), where)
    _check_section(cert.get("section"), len(vertices), where)


def _check_section(section, n_vertices: int, where: str) -> None:
    """``section`` (only with a slab-section proof): pin, thickness, band, kappa, points,
    on_edge, a tree of six roots, and the link test's ``loops`` where a leaf uses them."""
    if section is None:
        return
    if not isinstance(section, dict):
        raise SieveError(f"{where}: section must be an object")
    if not isinstance(section.get("status"), str):
        raise SieveError(f"{where}: section.status must be a string")
    _numbers(section.get("pin"), "section.pin", (3,), where)
    for key in ("thickness", "band", "kappa"):
        _positive(section.get(key), f"section.{key}", where)
    _numbers(section.get("points"), "section.points", (-1, 3), where, allow_empty=True)
    refs = section.get("on_edge")
    if not isinstance(refs, list) or len(refs) != len(section["points"]):
        raise SieveError(f"{where}: section.on_edge must be a list, one entry per point")
    _check_on_edge(refs, n_vertices, where, "section.on_edge")
    for i, c in enumerate(section.get("hole") or []):  # a sheet's copies (absent: the hole)
        if len(_numbers(c, f"section.hole[{i}]", (-1, 2), where)) < 3:
            raise SieveError(f"{where}: section.hole[{i}]: a contour needs at least 3 points")
    if "hole" in section and not section["hole"]:
        raise SieveError(f"{where}: section.hole: no contour")
    for i, q in enumerate(section.get("loops") or []):  # the link test's loops, if any
        if len(_numbers(q, f"section.loops[{i}]", (-1, 3), where)) < 3:
            raise SieveError(f"{where}: section.loops[{i}]: a loop needs at least 3 vertices")
    if not isinstance(section.get("tree"), list) or len(section["tree"]) != 6:
        raise SieveError(f"{where}: section.tree must be a list of 6 nodes (the cube's faces)")


def _check_plate(plate, where: str) -> None:
    """``plate`` (absent in older certificates): an object with a thickness (null or >= 0), a
    positive diameter and ``holds_for`` (null or a string)."""
    if plate is None:
        return
    if not isinstance(plate, dict):
        raise SieveError(f"{where}: plate must be an object")
    t = plate.get("thickness")
    if t is not None and not (
        isinstance(t, (int, float)) and not isinstance(t, bool) and 0 <= t <= MAX_COORDINATE
    ):
        raise SieveError(f"{where}: plate.thickness must be null or a finite number >= 0")
    _positive(plate.get("diameter"), "plate.diameter", where)
    if not isinstance(plate.get("holds_for"), (str, type(None))):
        raise SieveError(f"{where}: plate.holds_for must be null or a string")


def _check_root_and_passage(cert: dict, where: str) -> None:
    root, passage = cert["root"], cert["passage"]
    if root is not None and not isinstance(root, dict):
        raise SieveError(f"{where}: root must be null or an object")
    if root:
        if root.get("kind", "ball") != "ball":
            raise SieveError(f"{where}: root.kind {root.get('kind')!r}: only 'ball' is known")
        _numbers(root.get("centre"), "root.centre", (3,), where)
        _positive(root.get("radius"), "root.radius", where)
    if passage is not None and not isinstance(passage, dict):
        raise SieveError(f"{where}: passage must be null or an object")
    if passage:
        q = _numbers(passage.get("quaternion"), "passage.quaternion", (4,), where)
        _numbers(passage.get("translation"), "passage.translation", (2,), where)
        if not np.linalg.norm(q) > 1e-12:
            raise SieveError(f"{where}: passage.quaternion is zero, not a rotation")


def _check_on_edge(refs, n_vertices: int, where: str, key: str = "shape.on_edge") -> None:
    if refs is None:
        return
    if not isinstance(refs, list):
        raise SieveError(f"{where}: {key} must be a list")
    for k, ref in enumerate(refs):
        if ref is None:
            continue
        ok = isinstance(ref, list) and len(ref) == 3
        ok = ok and all(isinstance(i, int) and not isinstance(i, bool) for i in ref[:2])
        ok = ok and all(0 <= i < n_vertices for i in ref[:2])
        ok = ok and isinstance(ref[2], (int, float)) and abs(ref[2]) <= MAX_COORDINATE
        if not ok:
            raise SieveError(
                f"{where}: {key}[{k}] must be null or [i, j, lam] with vertex indices i, j"
            )


def _numbers(value, key: str, shape: tuple, where: str, allow_empty: bool = False) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (-1: any length), finite and bounded."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise SieveError(f"{where}: {key} must be an array of numbers") from None
    if allow_empty and a.size == 0:
        return a.reshape(0, *shape[1:])
    if a.ndim != len(shape) or any(n != -1 and n != m for n, m in zip(shape, a.shape)):
        want = " x ".join("n" if n == -1 else str(n) for n in shape)
        raise SieveError(f"{where}: {key} must be an array of {want} numbers")
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > MAX_COORDINATE):
        raise SieveError(
            f"{where}: {key} holds a number that is not finite or exceeds {MAX_COORDINATE:g}"
        )
    return a


def _indices(value, key: str, shape: tuple, n: int, where: str) -> np.ndarray:
    """``value`` as an int64 array of ``shape``, every entry in [0, n)."""
    try:
        a = np.asarray(value)
        ok = a.dtype.kind in "iu" and a.ndim == len(shape) and a.shape[1:] == shape[1:]
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise SieveError(f"{where}: {key} must be an array of n x 3 integer indices")
    if a.size and (a.min() < 0 or a.max() >= n):
        raise SieveError(f"{where}: {key}: an index is outside 0..{n - 1}")
    return a.astype(np.int64)


def _positive(value, key: str, where: str) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not (ok and 0 < value <= MAX_COORDINATE):  # NaN fails; no float() of a huge int
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        raise SieveError(f"{where}: {key} must be a positive finite number, not {shown}")
    return float(value)
