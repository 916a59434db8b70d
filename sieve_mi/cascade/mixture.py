"""Mixture files: the K shapes to sort and the settings every sieve's game uses.

A mixture file is a scene file (see ``docs/scene-format.md``) whose shapes are ``[[shape]]``
tables (``mesh``, optional ``name`` and ``scale``) instead of ``[[pass]]``/``[[block]]``; the
``[fabrication]``, ``[solver]``, ``[verdict]`` and ``[layout]`` tables mean what they mean there.
An optional ``[shake]`` table sets the shake trials of ``sort --shake N`` (the keys of
:class:`~sieve_mi.shake.settings.ShakeSettings`, checked as every key is; the number of trials is
the option's N).
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, field, fields

from sieve_mi.errors import SieveError
from sieve_mi.scene import (
    Scene,
    ShapeEntry,
    check_folder_name,
    read_file,
    read_shape,
    read_tables,
    table_fields,
)
from sieve_mi.settings import Reader
from sieve_mi.shake.settings import ShakeSettings

__all__ = ["Mixture", "load_mixture"]


@dataclass
class Mixture:
    """A parsed, validated mixture.

    Attributes
    ----------
    path : str
        The mixture file.
    name : str
        Output folder name (``out/<name>/``).
    shapes : list of ShapeEntry
        The K >= 2 shapes, names unique.
    units : str
    tables : dict
        The settings tables by TOML key (``{"fabrication": Fabrication(...), ...}``).
    shake : ShakeSettings
        The ``[shake]`` table: the settings of ``sort --shake N``'s trials (their number aside).
    """

    path: str
    name: str
    shapes: list
    units: str
    tables: dict
    shake: ShakeSettings = field(default_factory=ShakeSettings)

    def resolve(self, mesh: str) -> str:
        """A mesh path relative to the mixture file, made absolute."""
        return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(self.path)), mesh))

    def shape(self, name: str) -> ShapeEntry:
        """The entry called ``name``."""
        return next(s for s in self.shapes if s.name == name)

    def scene(self, passes, holds, *, name: str, seed: int | None = None) -> Scene:
        """The scene of one sieve: ``passes`` must fall through, ``holds`` must be held.

        Parameters
        ----------
        passes, holds : sequence of str
            Shape names.
        name : str
            The scene's name (its output folder).
        seed : int, optional
            Overrides ``[solver] seed``.
        """
        tables = copy.deepcopy(self.tables)
        if seed is not None:
            tables["solver"].seed = seed
        return Scene(
            path=self.path,
            name=name,
            passes=[copy.copy(self.shape(n)) for n in passes],
            blocks=[copy.copy(self.shape(n)) for n in holds],
            units=self.units,
            **tables,
        )


def load_mixture(path: str) -> Mixture:
    """Read and validate a mixture file.

    Raises
    ------
    SieveError
        One line naming the file and key: missing file, bad TOML, fewer than two shapes,
        duplicate names, unknown keys, bad values, a mesh file that does not exist.
    """
    data = read_file(path)
    allowed = {"name", "units", "shape", "shake"} | {f.name for f in table_fields()}
    unknown = sorted(set(data) - allowed)
    if unknown:
        hint = (
            " (a mixture lists its shapes as [[shape]] tables)"
            if {"pass", "block"} & set(unknown)
            else ""
        )
        raise SieveError(f"{path}: {unknown[0]}: unknown key{hint}; allowed: {sorted(allowed)}")
    values = Reader(path, data, "").read(Scene)  # name and units, checked
    name = values.get("name", os.path.splitext(os.path.basename(path))[0])
    check_folder_name(path, name)
    units = values.get("units", Scene.__dataclass_fields__["units"].default)
    raw = data.get("shape")
    if not isinstance(raw, list) or len(raw) < 2:
        count = len(raw) if isinstance(raw, list) else 0
        raise SieveError(
            f"{path}: shape: {count} [[shape]] table(s); a mixture needs at least two to sort"
        )
    shapes = [_shape(path, t, i) for i, t in enumerate(raw)]
    seen = {}
    for i, s in enumerate(shapes):
        if s.name in seen:
            raise SieveError(
                f"{path}: shape[{i}].name: {s.name!r} is also shape[{seen[s.name]}]'s name; "
                "give every shape its own name"
            )
        seen[s.name] = i
    # a mixture's [shake] is the shaker's whole table (below), not a scene's trials and target
    scene_tables = {k: v for k, v in data.items() if k != "shake"}
    tables, shake = read_tables(path, scene_tables), _shake_table(path, data)
    mixture = Mixture(path=path, name=name, shapes=shapes, units=units, tables=tables, shake=shake)
    for i, s in enumerate(shapes):
        if not os.path.isfile(mixture.resolve(s.mesh)):
            raise SieveError(f"{path}: shape[{i}].mesh: {s.mesh} not found")
    return mixture


def _shape(path: str, table, i: int) -> ShapeEntry:
    where = f"shape[{i}]"
    if isinstance(table, dict) and "rotation" in table:
        raise SieveError(
            f"{path}: {where}.rotation: every shape is tried in every orientation; remove it"
        )
    entry = read_shape(path, table, where)
    if entry.name is None:
        entry.name = os.path.splitext(os.path.basename(entry.mesh))[0]
    check_folder_name(path, entry.name, f"{where}.name")
    return entry


def _shake_table(path: str, data: dict) -> ShakeSettings:
    """The ``[shake]`` table, checked key by key as a scene's tables are; ``trials`` is refused
    (``sort --shake N`` gives it)."""
    table = data.get("shake", {})
    if not isinstance(table, dict):
        raise SieveError(f"{path}: shake: expected a table [shake]")
    r = Reader(path, table, "shake.")
    if "trials" in table:
        raise r.error("trials", "give the number of trials as sort --shake N; remove the key")
    r.check_keys({f.name for f in fields(ShakeSettings)} - {"trials"})
    return ShakeSettings(**r.read(ShakeSettings))
