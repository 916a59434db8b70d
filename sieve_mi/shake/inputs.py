"""What a shake run reads: a solve's output folder, or a plate mesh and part meshes.

A solve folder gives the plate ``sieve.stl`` (at its real thickness) and the shapes
``pass_<i>.stl`` (set A) and ``block_<j>.stl`` (set B); ``report.json`` gives their names and
the scene's units. Every problem is one :class:`~sieve_mi.errors.SieveError` line.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import load_trimesh
from sieve_mi.parsing import parse_json
from sieve_mi.settings import shown
from sieve_mi.shake.settings import UNIT_TO_M

__all__ = [
    "REPORT_MAX",
    "ShakeInput",
    "from_files",
    "from_folder",
    "only_names",
    "read_report",
    "report_shapes",
    "report_units",
    "select",
]


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


#: Largest ``report.json`` shake reads, bytes (a solve's is a few kilobytes per shape).
REPORT_MAX = 64 * 2**20


def read_report(folder: str) -> tuple[str, dict]:
    """The solve's ``report.json`` in ``folder``, parsed with every number and nesting checked
    (:func:`~sieve_mi.parsing.parse_json`): its path and the object."""
    path = os.path.join(folder, "report.json")
    if not os.path.isfile(path):
        raise SieveError(f"{folder}: has no report.json; give a solve's output folder")
    if os.path.getsize(path) > REPORT_MAX:
        raise SieveError(
            f"{path}: {os.path.getsize(path):,} bytes; a solve's report is at most "
            f"{REPORT_MAX:,}: give a solve's output folder"
        )
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise SieveError(f"{path}: cannot be read ({exc})") from None
    report = parse_json(text, path)
    if not isinstance(report, dict):
        raise SieveError(
            f"{path}: expected a solve's report (a JSON object), got {shown(report, 40, 'json')}"
        )
    return path, report


def _unit(value, path: str, key: str) -> str:
    """A report's unit, one of :data:`~sieve_mi.shake.settings.UNIT_TO_M`."""
    if not isinstance(value, str) or value not in UNIT_TO_M:
        raise SieveError(
            f"{path}: {key}: {shown(value, 40, 'json')} is not one of: {', '.join(UNIT_TO_M)}"
        )
    return value


def report_units(report: dict, path: str) -> str:
    """The scene's units a solve's report gives (``units``, else ``settings.units``, else mm).

    Raises
    ------
    SieveError
        A unit shake does not know, or ``settings`` that is not an object: one line naming the
        file and the key.
    """
    if "units" in report:
        return _unit(report["units"], path, "units")
    settings = report.get("settings")
    if settings is None:
        return "mm"
    if not isinstance(settings, dict):
        raise SieveError(
            f"{path}: settings: expected an object (the solve's settings), got "
            f"{shown(settings, 40, 'json')}"
        )
    return _unit(settings["units"], path, "settings.units") if "units" in settings else "mm"


def report_shapes(report: dict, path: str) -> list[tuple[str, str, str]]:
    """The shapes a solve's report lists: ``(name, role, file name)`` for each entry of
    ``pass`` (role A, ``pass_<i>.stl``) and ``block`` (role B, ``block_<j>.stl``); an entry
    without a ``name`` is named by its file.

    Raises
    ------
    SieveError
        No ``pass`` list, a ``block`` that is not a list, an entry that is not an object or a
        name that is not a non-empty string: one line naming the file and the key.
    """
    if not isinstance(report.get("pass"), list):
        raise SieveError(f"{path}: is not a solve's report (no 'pass' list)")
    shapes = []
    for role, key in (("A", "pass"), ("B", "block")):
        entries = report.get(key, [])
        if not isinstance(entries, list):
            raise SieveError(
                f"{path}: {key}: expected a list of shapes, got {shown(entries, 40, 'json')}"
            )
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict):
                raise SieveError(
                    f"{path}: {key}[{i}]: expected an object (a shape's entry), got "
                    f"{shown(entry, 40, 'json')}"
                )
            name = entry.get("name", f"{key}_{i}")
            if not isinstance(name, str) or not name.strip():
                raise SieveError(
                    f"{path}: {key}[{i}].name: expected a non-empty string, got "
                    f"{shown(name, 40, 'json')}"
                )
            shapes.append((name, role, f"{key}_{i}.stl"))
    return shapes


def _missing(folder: str, shapes: list, only: list[str] | None) -> None:
    """Refuse a shape the report lists (and ``only`` selects) whose mesh file is gone."""
    here = [name for name, _, file in shapes if os.path.isfile(os.path.join(folder, file))]
    for name, _, file in shapes:
        if name in here or (only is not None and name not in only):
            continue
        others = f", or shake the others with --only {','.join(here)}" if here else ""
        raise SieveError(
            f"{folder}: has no {file} (the shape {shown(name, 40)} of report.json); restore "
            f"it{others}"
        )


def from_folder(folder: str, only: list[str] | None = None) -> ShakeInput:
    """A solve's output folder: ``sieve.stl``, ``pass_*.stl``, ``block_*.stl``, ``report.json``.

    Parameters
    ----------
    folder : str
    only : list of str, optional
        The names of the shapes to be shaken (default every one): only their files must be
        there (:func:`select` then picks them from the shapes whose files are there).

    Raises
    ------
    SieveError
        Before any mesh is read: no ``report.json`` or one that is not a solve's (each field
        shake reads checked: :func:`report_shapes`, :func:`report_units`), no ``sieve.stl``, a
        listed shape's file gone. Then a mesh that cannot be read.
    """
    if not os.path.isdir(folder):
        raise SieveError(f"{folder}: no such folder; give a solve's output folder")
    path, report = read_report(folder)
    shapes = report_shapes(report, path)
    units = report_units(report, path)
    plate = os.path.join(folder, "sieve.stl")
    if not os.path.isfile(plate):
        raise SieveError(f"{folder}: has no sieve.stl (did the solve find a hole?)")
    if not shapes:
        raise SieveError(f"{path}: lists no shape (pass or block) to shake")
    _missing(folder, shapes, only)
    files = [(n, r, os.path.join(folder, f)) for n, r, f in shapes]
    parts = [(n, r, p, _mesh(p)) for n, r, p in files if os.path.isfile(p)]
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
