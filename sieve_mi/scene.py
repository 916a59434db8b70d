"""Scene files (TOML): what must pass, what must be blocked, and how to search.

See ``docs/scene-format.md`` for every key, its unit and its default. Paths are relative to the
scene file. Every problem is reported as one :class:`~sieve_mi.errors.SieveError` line naming the
file and the key.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.optim import NLOPT_METHODS


@dataclass
class ShapeEntry:
    """One ``[[pass]]`` or ``[[block]]`` table."""

    mesh: str
    scale: float = 1.0
    rotation: list[float] | None = None
    name: str | None = None


@dataclass
class Fabrication:
    """``[fabrication]``: how the hole is made physical."""

    tolerance: float = 1.0
    fill_holes: bool = True
    block_margin: float = 0.0
    thickness: float | None = None
    border: float = 5.0


@dataclass
class Solver:
    """``[solver]``: the search (paper Sec. 6 defaults)."""

    objective: str = "clearance"
    outer: str = "pso"
    resolution: int = 256
    particles: int = 10
    iterations: int = 10
    starts: int = 10
    steps: int = 100
    learning_rate: float = 0.05
    seed: int = 0
    inertia: float = 0.25
    c_personal: float = 0.25
    c_global: float = 0.25


@dataclass
class Verdict:
    """``[verdict]``: the long re-run of player B that declares the winner."""

    starts: int = 100
    steps: int = 500
    resolution: int = 256


@dataclass
class Layout:
    """``[layout]``: how several pass shapes make one hole (paper Sec. 5.3, eq. 14)."""

    mode: str = "merged"
    tau: float = 10.0
    rho: float = 200.0
    eta: float = 0.02
    alpha: float = 5.0
    c_personal: float = 0.05
    c_global: float = 0.05
    rounds: int = 3
    alternatives: int = 2


@dataclass
class Scene:
    """A parsed, validated scene."""

    path: str
    name: str
    units: str
    passes: list[ShapeEntry]
    blocks: list[ShapeEntry]
    fabrication: Fabrication = field(default_factory=Fabrication)
    solver: Solver = field(default_factory=Solver)
    verdict: Verdict = field(default_factory=Verdict)
    layout: Layout = field(default_factory=Layout)

    @property
    def directory(self) -> str:
        return os.path.dirname(os.path.abspath(self.path))

    def resolve(self, mesh: str) -> str:
        """A mesh path relative to the scene file, made absolute."""
        return mesh if os.path.isabs(mesh) else os.path.normpath(os.path.join(self.directory, mesh))

    def settings(self) -> dict:
        """The search and fabrication settings, as stored in ``report.json``."""
        return {
            "units": self.units,
            "fabrication": asdict(self.fabrication),
            "solver": asdict(self.solver),
            "verdict": asdict(self.verdict),
            "layout": asdict(self.layout),
        }


_TOP_KEYS = {"name", "units", "pass", "block", "fabrication", "solver", "verdict", "layout"}
_UNITS = {"mm", "cm", "m", "in", "um"}


class _Reader:
    """Type-checked access to one table of the scene file, with errors that name file and key."""

    def __init__(self, path: str, table: dict, where: str):
        self.path, self.table, self.where = path, table, where

    def error(self, key: str, what: str) -> SieveError:
        return SieveError(f"{self.path}: {self.where}{key}: {what}")

    def check_keys(self, allowed) -> None:
        for key in self.table:
            if key not in allowed:
                raise self.error(key, f"unknown key; known keys here: {', '.join(sorted(allowed))}")

    def number(
        self, key, default, *, integer=False, minimum=None, maximum=None, exclusive_min=False
    ):
        value = self.table.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(
                key, f"expected a {'whole number' if integer else 'number'}, got {value!r}"
            )
        if integer and (isinstance(value, float) and not value.is_integer()):
            raise self.error(key, f"expected a whole number, got {value!r}")
        if not math.isfinite(value):
            raise self.error(key, f"expected a finite number, got {value!r}")
        if minimum is not None and (value <= minimum if exclusive_min else value < minimum):
            raise self.error(
                key, f"must be {'>' if exclusive_min else '>='} {minimum}, got {value!r}"
            )
        if maximum is not None and value > maximum:
            raise self.error(key, f"must be <= {maximum}, got {value!r}")
        return int(value) if integer else float(value)

    def boolean(self, key, default):
        value = self.table.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {value!r}")
        return value

    def string(self, key, default, choices=None):
        value = self.table.get(key, default)
        if not isinstance(value, str) or not value:
            raise self.error(key, f"expected a non-empty string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"'{value}' is not one of: {', '.join(choices)}")
        return value


def _read_shape(path: str, table, where: str) -> ShapeEntry:
    if not isinstance(table, dict):
        raise SieveError(f"{path}: {where}: expected a table like [[pass]] with a 'mesh' key")
    r = _Reader(path, table, where + ".")
    r.check_keys({f.name for f in fields(ShapeEntry)})
    if "mesh" not in table:
        raise r.error("mesh", "missing; give the path of a mesh file (relative to the scene file)")
    entry = ShapeEntry(
        mesh=r.string("mesh", None), scale=r.number("scale", 1.0, minimum=0, exclusive_min=True)
    )
    if "name" in table:
        entry.name = r.string("name", None)
    if "rotation" in table:
        q = table["rotation"]
        if not (
            isinstance(q, list)
            and len(q) == 4
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in q)
        ):
            raise r.error("rotation", f"expected a quaternion [w, x, y, z], got {q!r}")
        qn = np.asarray(q, float)
        norm = float(np.linalg.norm(qn))
        if not np.all(np.isfinite(qn)) or norm < 1e-9:
            raise r.error("rotation", f"quaternion {q!r} has no direction")
        if abs(norm - 1.0) > 1e-3:
            raise r.error(
                "rotation",
                f"quaternion {q!r} is not a unit quaternion (norm {norm:.4g}); divide it by its norm",
            )
        entry.rotation = list(qn / norm)
    return entry


def load_scene(path: str) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str
        The TOML file.

    Raises
    ------
    SieveError
        On a missing file, bad TOML, unknown keys, wrong types or out-of-range values.
    """
    if not os.path.exists(path):
        raise SieveError(f"{path}: scene file not found")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SieveError(f"{path}: not valid TOML ({exc})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SieveError(f"{path}: could not be read ({exc})") from None
    top = _Reader(path, data, "")
    top.check_keys(_TOP_KEYS)
    default_name = os.path.splitext(os.path.basename(path))[0]
    name = top.string("name", default_name)
    if any(c in name for c in "/\\") or name in (".", ".."):
        raise top.error(
            "name", f"'{name}' is used as a folder name; use letters, digits, '-' and '_'"
        )
    units = top.string("units", "mm", choices=sorted(_UNITS))
    for key in ("pass", "block"):
        if key not in data:
            raise top.error(key, f"missing; add at least one [[{key}]] table with a 'mesh' key")
        if not isinstance(data[key], list) or not data[key]:
            raise top.error(key, f"expected one or more [[{key}]] tables")
    passes = [_read_shape(path, t, f"pass[{i}]") for i, t in enumerate(data["pass"])]
    blocks = [_read_shape(path, t, f"block[{i}]") for i, t in enumerate(data["block"])]
    for i, b in enumerate(blocks):
        if b.rotation is not None:
            raise SieveError(
                f"{path}: block[{i}].rotation: shapes to block are tried in every orientation; remove 'rotation'"
            )

    fab_t = _table(path, data, "fabrication")
    r = _Reader(path, fab_t, "fabrication.")
    r.check_keys({f.name for f in fields(Fabrication)})
    fab = Fabrication(
        tolerance=r.number("tolerance", 1.0, minimum=0),
        fill_holes=r.boolean("fill_holes", True),
        block_margin=r.number("block_margin", 0.0, minimum=0),
        border=r.number("border", 5.0, minimum=0, exclusive_min=True),
    )
    if "thickness" in fab_t:
        fab.thickness = r.number("thickness", None, minimum=0, exclusive_min=True)

    sol_t = _table(path, data, "solver")
    r = _Reader(path, sol_t, "solver.")
    r.check_keys({f.name for f in fields(Solver)})
    solver = Solver(
        objective=r.string("objective", "clearance", choices=["clearance", "overlap"]),
        outer=r.string("outer", "pso", choices=["pso", *NLOPT_METHODS]),
        resolution=r.number("resolution", 256, integer=True, minimum=16, maximum=4096),
        particles=r.number("particles", 10, integer=True, minimum=1),
        iterations=r.number("iterations", 10, integer=True, minimum=0),
        starts=r.number("starts", 10, integer=True, minimum=1),
        steps=r.number("steps", 100, integer=True, minimum=0),
        learning_rate=r.number("learning_rate", 0.05, minimum=0, exclusive_min=True),
        seed=r.number("seed", 0, integer=True, minimum=0),
        inertia=r.number("inertia", 0.25, minimum=0),
        c_personal=r.number("c_personal", 0.25, minimum=0),
        c_global=r.number("c_global", 0.25, minimum=0),
    )
    ver_t = _table(path, data, "verdict")
    r = _Reader(path, ver_t, "verdict.")
    r.check_keys({f.name for f in fields(Verdict)})
    verdict = Verdict(
        starts=r.number("starts", 100, integer=True, minimum=1),
        steps=r.number("steps", 500, integer=True, minimum=0),
        resolution=r.number("resolution", 256, integer=True, minimum=16, maximum=4096),
    )
    lay_t = _table(path, data, "layout")
    r = _Reader(path, lay_t, "layout.")
    r.check_keys({f.name for f in fields(Layout)})
    layout = Layout(
        mode=r.string("mode", "merged", choices=["merged", "separate"]),
        tau=r.number("tau", 10.0, minimum=0, exclusive_min=True),
        rho=r.number("rho", 200.0, minimum=0, exclusive_min=True),
        eta=r.number("eta", 0.02, minimum=0),
        alpha=r.number("alpha", 5.0, minimum=0),
        c_personal=r.number("c_personal", 0.05, minimum=0),
        c_global=r.number("c_global", 0.05, minimum=0),
        rounds=r.number("rounds", 3, integer=True, minimum=1, maximum=100),
        alternatives=r.number("alternatives", 2, integer=True, minimum=0, maximum=100),
    )
    return Scene(
        path=path,
        name=name,
        units=units,
        passes=passes,
        blocks=blocks,
        fabrication=fab,
        solver=solver,
        verdict=verdict,
        layout=layout,
    )


def _table(path: str, data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise SieveError(f"{path}: {key}: expected a table [{key}]")
    return value
