"""What a shake run reads: a solve's output folder, or a plate mesh and part meshes.

A solve folder gives the plate ``sieve.stl`` (at its real thickness) and the shapes
``pass_<i>.stl`` (set A) and ``block_<j>.stl`` (set B); ``report.json`` gives their names and
the scene's units. Every problem is one :class:`~sieve_mi.errors.SieveError` line.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import load_trimesh

__all__ = ["ShakeInput", "from_files", "from_folder", "only_names", "select"]


@dataclass
class ShakeInput:
    """The meshes of one shake run (not yet converted for the engine).

    Attributes
    ----------
    plate_path : str
    plate : trimesh.Trimesh
        Scene units.
    parts : list of (name, role, path, trimesh.Trimesh)
        ``role`` is ``"A"``, ``"B"`` or None.
    units : str
        The scene's length unit.
    folder : str or None
        The solve folder it came from.
    """

    plate_path: str
    plate: object
    parts: list = field(default_factory=list)
    units: str = "mm"
    folder: str | None = None


def _mesh(path: str):
    import numpy as np

    mesh = load_trimesh(path)
    if len(mesh.faces) == 0:
        raise SieveError(f"{path}: holds no triangles; give a triangle mesh")
    if not np.all(np.isfinite(mesh.vertices)):
        raise SieveError(f"{path}: has NaN or infinite vertex coordinates")
    return mesh


def from_files(plate: str, parts: list[str], units: str = "mm") -> ShakeInput:
    """A plate mesh and part meshes given on the command line (roles unknown)."""
    if not parts:
        raise SieveError("shake --sieve PLATE needs at least one PART mesh to shake")
    names = [os.path.splitext(os.path.basename(p))[0] for p in parts]
    loaded = [(n, None, p, _mesh(p)) for n, p in zip(names, parts)]
    return ShakeInput(plate, _mesh(plate), loaded, units)


def from_folder(folder: str) -> ShakeInput:
    """A solve's output folder: ``sieve.stl``, ``pass_*.stl``, ``block_*.stl``, ``report.json``."""
    if not os.path.isdir(folder):
        raise SieveError(f"{folder}: no such folder; give a solve's output folder")
    report_path = os.path.join(folder, "report.json")
    try:
        with open(report_path, encoding="utf-8") as fh:
            report = json.load(fh)
    except FileNotFoundError:
        raise SieveError(f"{folder}: has no report.json; give a solve's output folder") from None
    except (OSError, ValueError) as exc:
        raise SieveError(f"{report_path}: cannot be read ({exc})") from None
    if not isinstance(report, dict) or not isinstance(report.get("pass"), list):
        raise SieveError(f"{report_path}: is not a solve's report (no 'pass' list)")
    plate = os.path.join(folder, "sieve.stl")
    if not os.path.isfile(plate):
        raise SieveError(f"{folder}: has no sieve.stl (did the solve find a hole?)")
    parts = []
    for role, key, stem in (("A", "pass", "pass"), ("B", "block", "block")):
        for i, entry in enumerate(report.get(key) or []):
            path = os.path.join(folder, f"{stem}_{i}.stl")
            name = entry.get("name") if isinstance(entry, dict) else None
            if os.path.isfile(path):
                parts.append((str(name or f"{stem}_{i}"), role, path, _mesh(path)))
    if not parts:
        raise SieveError(f"{folder}: has no pass_<i>.stl or block_<j>.stl to shake")
    units = str(report.get("units") or report.get("settings", {}).get("units") or "mm")
    return ShakeInput(plate, _mesh(plate), parts, units, folder)


def only_names(text: str | None) -> list[str] | None:
    """``--only``'s text as a list of names (comma-separated, blanks around them dropped); None
    without the option; a one-line SieveError for a list with no name in it."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise SieveError(f"shake: --only: expected shape names separated by commas, got {text!r}")
    return names


def select(inp: ShakeInput, names: list[str] | None) -> ShakeInput:
    """``inp`` with only the parts named ``names`` (in ``inp``'s order); every part for None.

    Raises
    ------
    SieveError
        A name that is no part's, in one line that lists the parts' names.
    """
    if names is None:
        return inp
    known = [p[0] for p in inp.parts]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise SieveError(
            f"shake: --only: no shape named {', '.join(map(repr, unknown))}; "
            f"the shapes are {', '.join(known)}"
        )
    parts = [p for p in inp.parts if p[0] in names]
    return ShakeInput(inp.plate_path, inp.plate, parts, inp.units, inp.folder)
