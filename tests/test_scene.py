"""The scene reader: defaults, keys, types, bounds, rotations, names and paths; docs agree with code.

``docs/scene-format.md`` is the user's reference. Its tables are parsed here and compared with the
dataclass fields of :mod:`sieve_mi.scene` (key, type, bounds, default, accepted values, unit), and a
minimal scene must load to exactly the defaults the docs state.
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
from dataclasses import MISSING, fields

import pytest
from helpers import REPO

from sieve_mi import scene
from sieve_mi.errors import SieveError
from sieve_mi.game.check_settings import CheckInputs, CheckSettings
from sieve_mi.options import check_options
from sieve_mi.scene import Scene, ShapeEntry, load_scene
from sieve_mi.settings import (
    ANGLES,
    SIZE,
    describe,
    field_of,
    key_of,
    read_value,
    spec_of,
    value_types,
)

DOCS = os.path.join(REPO, "docs", "scene-format.md")
MINIMAL = '[[pass]]\nmesh = "a.stl"\n[[block]]\nmesh = "b.stl"\n'


def _docs_text() -> str:
    with open(DOCS, encoding="utf-8") as fh:
        return fh.read()


def _write(tmp_path, text: str, name: str = "scene.toml") -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def _error(tmp_path, text: str) -> str:
    """The reader's message for a bad scene, less the leading '<path>: ' (checked to be there)."""
    path = _write(tmp_path, text)
    with pytest.raises(SieveError) as exc:
        load_scene(path)
    message = str(exc.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    return message[len(path) + 2 :]


# --- docs/scene-format.md, parsed ------------------------------------------------------------


def _doc_tables(text: str) -> dict[str, list[dict[str, str]]]:
    """Each ``## heading`` with a table: its rows as {column header: cell}."""
    tables: dict[str, list[dict[str, str]]] = {}
    heading, header = None, None
    for line in text.splitlines():
        if line.startswith("## "):
            heading, header = line[3:].strip(), None
        elif line.startswith("|") and heading is not None:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if header is None:
                header, tables[heading] = cells, []
            elif not set(line) <= set("|-: "):
                tables[heading].append(dict(zip(header, cells)))
        else:
            header = None
    return tables


def _sections() -> dict[str, type]:
    """The docs heading (its start) that documents each class of keys."""
    out = {"Top level": Scene, "`[[pass]]` and `[[block]]`": ShapeEntry}
    for f in scene.table_fields():
        out[f"`[{f.name}]`"] = value_types(Scene)[f.name]
    return out


def _doc_rows(text: str) -> dict[type, dict[str, dict[str, str]]]:
    """For each class: its documented rows by key (``[[pass]]`` is key ``pass``)."""
    tables = _doc_tables(text)
    out = {}
    for start, cls in _sections().items():
        rows = next((r for h, r in tables.items() if h.startswith(start)), [])
        out[cls] = {re.fullmatch(r"`\[*(\w+)\]*`", r["key"]).group(1): r for r in rows}
    return out


_TYPE = re.compile(
    r"(number|int|bool|string|tables|\[w, x, y, z\]|\[w, h\]|\[numbers\])"
    r"(?: (≥|>) (-?[\d.]+)(?:, ≤ (-?[\d.]+))?| (-?[\d.]+)–(-?[\d.]+))?"
)
_KINDS = {
    "number": float,
    "int": int,
    "bool": bool,
    "string": str,
    "tables": list[ShapeEntry],
    "[w, x, y, z]": list[float],
    "[w, h]": SIZE,
    "[numbers]": ANGLES,
}
#: The settings that are lists of numbers, and how many each holds in these tests.
_LISTS = {SIZE: 2, ANGLES: 1}


def _doc_type(cell: str):
    """(kind, minimum, exclusive, maximum) from a type cell such as ``int 16–4096``."""
    m = _TYPE.fullmatch(re.sub(r'( or "[a-z]+")+$', "", cell))  # a number or a word
    if m is None:
        return None
    word, op, low, high1, low2, high = m.groups()
    low = low if low is not None else low2
    high = high if high is not None else high1
    return (
        _KINDS[word],
        None if low is None else float(low),
        op == ">",
        None if high is None else float(high),
    )


def _doc_default(cell: str):
    """A backticked TOML value as Python (``"`1.0`"`` gives 1.0), else the words themselves."""
    if cell.startswith("`") and cell.endswith("`"):
        return tomllib.loads(f"v = {cell[1:-1]}")["v"]
    return cell


def _row_disagreements(cls: type, f, row: dict[str, str]) -> list[str]:
    spec, kind, where = spec_of(f), value_types(cls)[f.name], f"{cls.__name__}.{f.name}"
    out = []
    code_type = (
        kind,
        None if spec.minimum is None else float(spec.minimum),
        spec.exclusive_min,
        None if spec.maximum is None else float(spec.maximum),
    )
    if _doc_type(row["type"]) != code_type:
        out.append(f"{where}: docs type {row['type']!r}, code {code_type}")
    words = spec.default_doc or ("required" if f.default is MISSING else None)
    documented = _doc_default(row["default"])
    if words is not None and documented != words:
        out.append(f"{where}: docs default {row['default']!r}, code {words!r}")
    if words is None and (documented != f.default or type(documented) is not type(f.default)):
        out.append(f"{where}: docs default {row['default']!r}, code {f.default!r}")
    for choice in spec.choices or ():
        if f"`{choice}`" not in row["meaning"]:
            out.append(f"{where}: {choice!r} is accepted but not documented")
    if "unit" in row and row["unit"] != (spec.unit or ""):
        out.append(f"{where}: docs unit {row['unit']!r}, code {spec.unit!r}")
    return out


def _disagreements(text: str) -> list[str]:
    """Every way the docs' tables and the dataclasses differ (empty when they agree)."""
    out = []
    for cls, rows in _doc_rows(text).items():
        code = {key_of(f): f for f in fields(cls) if spec_of(f) is not None}
        out += [f"{cls.__name__}: {k} documented, not in code" for k in rows.keys() - code.keys()]
        out += [f"{cls.__name__}: {k} in code, not documented" for k in code.keys() - rows.keys()]
        for key in rows.keys() & code.keys():
            out += _row_disagreements(cls, code[key], rows[key])
    return out


def test_docs_and_dataclasses_agree():
    assert _disagreements(_docs_text()) == []


@pytest.mark.parametrize(
    "old, new",
    [
        ("| `tau` | number > 0 |", "| `tau` | number ≥ 0 |"),  # exclusive vs inclusive bound
        ("| `particles` | int 1–10000 | `10` |", "| `particles` | int 1–10000 | `11` |"),  # default
        (
            "| `tolerance` | number 0–1000000 | `1.0` |",
            "| `tolerance` | number 0–1000000 | `1` |",
        ),  # int vs float
        ("| `resolution` | int 16–4096 |", "| `resolution` | int 16–2048 |"),  # upper bound
        (
            "| `steps` | int 0–1000000 | `500` |",
            "| `steps` | int 1–1000000 | `500` |",
        ),  # lower bound
        ("| `border` |", "| `margin` |"),  # a key the code does not have, and one undocumented
        (", `ags`", ""),  # an accepted outer method left out
        ("| `fill_holes` | bool | `true` |", "| `fill_holes` | bool | `false` |"),
        (
            '| `thickness` | number > 0, ≤ 1000000 or "thinnest" | the thinnest proved',
            '| `thickness` | number > 0, ≤ 1000000 or "thinnest" | the thickest proved',
        ),
        (
            "| `block_margin` | number 0–1000000 | `0.0` | scene units",
            "| `block_margin` | number 0–1000000 | `0.0` | mm",
        ),
        ("## `[verdict]`", "## verdict"),  # a whole table no longer found
    ],
)
def test_docs_check_catches_a_disagreement(old, new):
    text = _docs_text()
    assert text.count(old) >= 1, old
    assert _disagreements(text.replace(old, new, 1)) != []


def test_minimal_scene_loads_to_the_documented_defaults(tmp_path):
    s = load_scene(_write(tmp_path, MINIMAL, "minimal.toml"))
    rows = _doc_rows(_docs_text())
    for f in scene.table_fields():
        table, documented_rows = getattr(s, f.name), rows[value_types(Scene)[f.name]]
        assert documented_rows, f"no [{f.name}] table in the docs"
        for key, row in documented_rows.items():
            documented, value = _doc_default(row["default"]), getattr(table, key)
            if row["default"].startswith("`"):
                assert value == documented and type(value) is type(documented), (f.name, key)
            else:  # a default in words is worked out later (the plate's thickness)
                assert value is None, (f.name, key)
    assert s.name == "minimal" and s.units == _doc_default(rows[Scene]["units"]["default"])
    for entry, mesh in ((s.passes[0], "a.stl"), (s.blocks[0], "b.stl")):
        assert entry == ShapeEntry(mesh=mesh, scale=1.0, rotation=None, name=None)
    assert s.settings() == {
        "units": s.units,
        **{f.name: vars(getattr(s, f.name)) for f in scene.table_fields() if f.name != "shake"},
    }
    assert list(s.settings()) == ["units", "fabrication", "solver", "verdict", "layout"]
    json.dumps(s.settings())  # report.json must be able to hold it


# --- every key of every table ----------------------------------------------------------------


def _toml(value) -> str:
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return json.dumps(value) if isinstance(value, str) else repr(value)


def _settings_keys() -> list:
    """(table, field, kind, spec) for every key of every settings table."""
    out = []
    for t in scene.table_fields():
        cls = value_types(Scene)[t.name]
        for f in fields(cls):
            kind = value_types(cls)[f.name]
            out.append(pytest.param(t.name, f, kind, spec_of(f), id=f"{t.name}.{f.name}"))
    return out


def _other_value(f, kind, spec):
    """A valid value that is not the default."""
    if spec.choices and kind is not float:  # a number field's words are tested on their own
        return next(c for c in spec.choices if c != f.default)
    if kind in _LISTS:
        return (0.0, 30.0) if kind is ANGLES else (50.0, 40.0)
    if kind is bool:
        return not f.default
    if kind is int:
        value = (spec.minimum if f.default is None else f.default) + 1
        return value if spec.maximum is None or value <= spec.maximum else spec.minimum
    number = f.default if isinstance(f.default, (int, float)) else None  # not a word ("auto")
    value = (number or 1.0) * 1.5 + 0.25
    return value if spec.maximum is None or value <= spec.maximum else spec.maximum / 2


@pytest.mark.parametrize("table, f, kind, spec", _settings_keys())
def test_every_key_is_read_into_its_field(tmp_path, table, f, kind, spec):
    value = _other_value(f, kind, spec)
    s = load_scene(_write(tmp_path, MINIMAL + f"[{table}]\n{f.name} = {_toml(value)}\n"))
    read, default = getattr(s, table), value_types(Scene)[table]()
    held = tuple if kind in _LISTS else kind  # a list of numbers is held as a tuple of floats
    assert getattr(read, f.name) == value and type(getattr(read, f.name)) is held
    assert all(
        getattr(read, g.name) == getattr(default, g.name) for g in fields(read) if g is not f
    )


def test_explicit_defaults_are_accepted(tmp_path):
    # Each default written out in the file must pass its own checks and read back the same.
    text = MINIMAL
    for t in scene.table_fields():
        table = value_types(Scene)[t.name]()
        items = [f"{k} = {_toml(v)}" for k, v in vars(table).items() if v is not None]
        text += f"[{t.name}]\n" + "\n".join(items) + "\n"
    s = load_scene(_write(tmp_path, text))
    assert s.settings() == load_scene(_write(tmp_path, MINIMAL, "minimal.toml")).settings()


@pytest.mark.parametrize("table", ["fabrication", "solver", "verdict", "layout", "pass", "block"])
def test_unknown_key_names_table_and_known_keys(tmp_path, table):
    if table in ("pass", "block"):
        text = MINIMAL.replace(f"[[{table}]]\n", f"[[{table}]]\npartciles = 3\n")
        where, cls = f"{table}[0]", ShapeEntry
    else:
        text, where = MINIMAL + f"[{table}]\npartciles = 3\n", table
        cls = value_types(Scene)[table]
    known = ", ".join(sorted(f.name for f in fields(cls)))
    assert _error(tmp_path, text) == f"{where}.partciles: unknown key; known keys here: {known}"


def test_unknown_top_level_key(tmp_path):
    message = _error(tmp_path, MINIMAL.replace("[[pass]]", "colour = 1\n[[pass]]", 1))
    assert message == (
        "colour: unknown key; known keys here: "
        "block, fabrication, layout, name, pass, shake, solver, units, verdict"
    )


@pytest.mark.parametrize("table, f, kind, spec", _settings_keys())
def test_wrong_type_is_one_line_naming_the_key(tmp_path, table, f, kind, spec):
    wrong = {bool: "1", int: '"3"', float: '"1mm"', str: "3", SIZE: "[1]", ANGLES: '"3"'}[kind]
    expected = {
        bool: "expected true or false, got 1",
        int: "expected a whole number, got '3'",
        float: "expected a number, got '1mm'",
        str: "expected a non-empty string, got 3",
        SIZE: "expected a list of 2 numbers, got [1]",
        ANGLES: "expected a list of numbers, got '3'",
    }[kind]
    if spec.choices and kind is float:
        expected = f"expected a number or {' or '.join(map(repr, spec.choices))}, got '1mm'"
    text = MINIMAL + f"[{table}]\n{f.name} = {wrong}\n"
    assert _error(tmp_path, text) == f"{table}.{f.name}: {expected}"


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("particles", "2.5", "expected a whole number, got 2.5"),
        ("particles", "true", "expected a whole number, got True"),
        ("learning_rate", "false", "expected a number, got False"),
        ("learning_rate", "nan", "expected a finite number, got nan"),
        ("inertia", "inf", "expected a finite number, got inf"),
        ("objective", '""', "expected a non-empty string, got ''"),
        ("objective", '"area"', "'area' is not one of: clearance, overlap, overlap-mitsuba"),
        ("outer", '"PSO"', "'PSO' is not one of: pso, crs2, esch, direct, isres, mlsl, ags"),
        ("seed", "[1, 2]", "expected a whole number, got [1, 2]"),
    ],
)
def test_bad_solver_values(tmp_path, key, value, expected):
    assert _error(tmp_path, MINIMAL + f"[solver]\n{key} = {value}\n") == f"solver.{key}: {expected}"


@pytest.mark.parametrize(
    "value, expected",
    [
        ('"thinnest"', None),
        ("2", None),
        ('"thin"', "expected a number or 'thinnest', got 'thin'"),
        ('"2"', "expected a number or 'thinnest', got '2'"),
        ("0", "must be > 0, got 0"),
    ],
)
def test_thickness_is_a_number_or_thinnest(tmp_path, value, expected):
    text = MINIMAL + f"[fabrication]\nthickness = {value}\n"
    if expected is None:
        thickness = load_scene(_write(tmp_path, text)).fabrication.thickness
        assert thickness == tomllib.loads(f"v = {value}")["v"]
    else:
        assert _error(tmp_path, text) == f"fabrication.thickness: {expected}"


def test_whole_float_is_an_int(tmp_path):
    s = load_scene(
        _write(tmp_path, MINIMAL + "[solver]\nparticles = 3.0\n[fabrication]\nborder = 2\n")
    )
    assert s.solver.particles == 3 and type(s.solver.particles) is int
    assert s.fabrication.border == 2.0 and type(s.fabrication.border) is float


def test_booleans(tmp_path):
    s = load_scene(_write(tmp_path, MINIMAL + "[fabrication]\nfill_holes = false\n"))
    assert s.fabrication.fill_holes is False
    text = MINIMAL + '[fabrication]\nfill_holes = "false"\n'
    assert _error(tmp_path, text) == "fabrication.fill_holes: expected true or false, got 'false'"


# --- bounds ----------------------------------------------------------------------------------


def _bounded_keys() -> list:
    return [
        p
        for p in _settings_keys()
        if p.values[3].minimum is not None or p.values[3].maximum is not None
    ]


def _step(kind) -> float:
    return 1 if kind is int else 1e-9


@pytest.mark.parametrize("table, f, kind, spec", _bounded_keys())
def test_lower_bound(tmp_path, table, f, kind, spec):
    low, step = spec.minimum, _step(kind)
    n = _LISTS.get(kind)
    one = float if n else kind  # each number of a list is checked as a number

    def value(x):  # turns hold a 0 (the hole itself) and the value
        return (0.0, x) if kind is ANGLES else (x,) * n if n else x

    on_bound = MINIMAL + f"[{table}]\n{f.name} = {_toml(value(one(low)))}\n"
    below = MINIMAL + f"[{table}]\n{f.name} = {_toml(value(one(low) - step))}\n"
    above = MINIMAL + f"[{table}]\n{f.name} = {_toml(value(one(low) + step))}\n"
    read = getattr(getattr(load_scene(_write(tmp_path, above)), table), f.name)
    assert read == value(low + step)
    assert _error(tmp_path, below).startswith(f"{table}.{f.name}: must be ")
    if spec.exclusive_min:
        assert _error(tmp_path, on_bound) == f"{table}.{f.name}: must be > {low}, got {one(low)!r}"
    else:
        read = getattr(getattr(load_scene(_write(tmp_path, on_bound)), table), f.name)
        assert read == value(low)


@pytest.mark.parametrize(
    "table, key, high",
    [("solver", "resolution", 4096), ("verdict", "resolution", 4096), ("layout", "rounds", 100)],
)
def test_upper_bound_is_inclusive(tmp_path, table, key, high):
    s = load_scene(_write(tmp_path, MINIMAL + f"[{table}]\n{key} = {high}\n"))
    assert getattr(getattr(s, table), key) == high
    text = MINIMAL + f"[{table}]\n{key} = {high + 1}\n"
    assert _error(tmp_path, text) == f"{table}.{key}: must be <= {high}, got {high + 1}"


def test_documented_error_example(tmp_path):
    assert _error(tmp_path, MINIMAL + "[solver]\nparticles = 0\n") == (
        "solver.particles: must be >= 1, got 0"
    )
    assert _error(tmp_path, MINIMAL + "[layout]\ntau = 0\n") == "layout.tau: must be > 0, got 0"


# --- shapes: scale, rotation, name, mesh -----------------------------------------------------


def _pass(extra: str) -> str:
    return MINIMAL.replace('mesh = "a.stl"\n', f'mesh = "a.stl"\n{extra}\n', 1)


def test_shape_keys_are_read(tmp_path):
    s = load_scene(_write(tmp_path, _pass('scale = 2\nname = "cube"\nrotation = [0, 0, 0, 1]')))
    assert s.passes[0] == ShapeEntry(
        mesh="a.stl", scale=2.0, rotation=[0.0, 0.0, 0.0, 1.0], name="cube"
    )


@pytest.mark.parametrize(
    "extra, expected",
    [
        ("scale = 0", "pass[0].scale: must be > 0, got 0"),
        ("scale = -1.5", "pass[0].scale: must be > 0, got -1.5"),
        ('scale = "2"', "pass[0].scale: expected a number, got '2'"),
        ("name = 7", "pass[0].name: expected a non-empty string, got 7"),
    ],
)
def test_bad_shape_values(tmp_path, extra, expected):
    assert _error(tmp_path, _pass(extra)) == expected


def test_empty_mesh_path(tmp_path):
    text = MINIMAL.replace('mesh = "a.stl"', 'mesh = ""', 1)
    assert _error(tmp_path, text) == "pass[0].mesh: expected a non-empty string, got ''"


def test_shape_without_mesh(tmp_path):
    text = MINIMAL.replace('mesh = "b.stl"', "scale = 2.0")
    assert _error(tmp_path, text) == (
        "block[0].mesh: missing; give the path of a mesh file (relative to the scene file)"
    )


def test_near_unit_rotation_is_normalised(tmp_path):
    # 0.6² + 0.8² = 1; times 1.0005 is within the 1e-3 tolerance and comes back of norm 1.
    s = load_scene(_write(tmp_path, _pass("rotation = [0.6003, 0.8004, 0, 0]")))
    q = s.passes[0].rotation
    assert q == pytest.approx([0.6, 0.8, 0.0, 0.0], abs=1e-12)
    assert math.fsum(v * v for v in q) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize(
    "q, expected",
    [
        ("[2, 0, 0, 0]", "is not a unit quaternion (norm 2); divide it by its norm"),
        ("[1, 1, 0, 0]", "is not a unit quaternion (norm 1.414); divide it by its norm"),
        ("[1.002, 0, 0, 0]", "is not a unit quaternion (norm 1.002); divide it by its norm"),
        ("[0, 0, 0, 0]", "has no direction"),
        ("[nan, 0, 0, 0]", "has no direction"),
        ("[inf, 0, 0, 0]", "has no direction"),
    ],
)
def test_bad_rotation(tmp_path, q, expected):
    message = _error(tmp_path, _pass(f"rotation = {q}"))
    assert message.startswith("pass[0].rotation: quaternion [") and message.endswith(expected)


@pytest.mark.parametrize("q", ["[1, 0, 0]", "[1, 0, 0, 0, 0]", '"identity"', "[true, 0, 0, 0]"])
def test_rotation_not_four_numbers(tmp_path, q):
    message = _error(tmp_path, _pass(f"rotation = {q}"))
    assert message.startswith("pass[0].rotation: expected a quaternion [w, x, y, z], got ")


def test_block_rotation_is_refused(tmp_path):
    text = MINIMAL.replace('mesh = "b.stl"', 'mesh = "b.stl"\nrotation = [1, 0, 0, 0]')
    assert _error(tmp_path, text) == (
        "block[0].rotation: shapes to block are tried in every orientation; remove 'rotation'"
    )


@pytest.mark.parametrize("name", ["a/b", "a\\\\b", ".", "..", "a\\u0000b"])
def test_name_that_cannot_be_a_folder(tmp_path, name):
    message = _error(tmp_path, f'name = "{name}"\n' + MINIMAL)
    refused = "is used as a folder name" in message or "has control characters" in message
    assert message.startswith("name: ") and refused, message


@pytest.mark.parametrize("name", ["cube-vs_sphere 2", "v1.2", "..x"])
def test_name_that_is_a_folder(tmp_path, name):
    assert load_scene(_write(tmp_path, f'name = "{name}"\n' + MINIMAL)).name == name


def test_name_defaults_to_the_file_stem(tmp_path):
    assert load_scene(_write(tmp_path, MINIMAL, "my.scene.toml")).name == "my.scene"


def test_relative_mesh_paths_resolve_against_the_scene_file(tmp_path, monkeypatch):
    (tmp_path / "scenes").mkdir()
    absolute = str(tmp_path / "elsewhere" / "b.stl")
    text = f'[[pass]]\nmesh = "../meshes/a.stl"\n[[block]]\nmesh = "{absolute}"\n'
    s = load_scene(_write(tmp_path, text, "scenes/s.toml"))
    monkeypatch.chdir(tmp_path / "scenes")  # not the current directory: the scene file's
    assert s.resolve(s.passes[0].mesh) == str(tmp_path / "meshes" / "a.stl")
    assert s.resolve(s.blocks[0].mesh) == absolute
    relative = load_scene("s.toml")
    monkeypatch.chdir(tmp_path)
    assert relative.resolve("a.stl") == str(tmp_path / "scenes" / "a.stl")


# --- the file and its top level --------------------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        (
            '[[block]]\nmesh = "b.stl"\n',
            "pass: missing; add at least one [[pass]] table with a 'mesh' key",
        ),
        ('pass = []\n[[block]]\nmesh = "b.stl"\n', "pass: expected one or more [[pass]] tables"),
        (
            'pass = "a.stl"\n[[block]]\nmesh = "b.stl"\n',
            "pass: expected one or more [[pass]] tables",
        ),
        (
            'pass = [1]\n[[block]]\nmesh = "b.stl"\n',
            "pass[0]: expected a table like [[pass]] with a 'mesh' key",
        ),
        ("solver = 3\n" + MINIMAL, "solver: expected a table [solver]"),
        ('units = "ft"\n' + MINIMAL, "units: 'ft' is not one of: mm, cm, m, in, um"),
    ],
)
def test_bad_top_level(tmp_path, text, expected):
    assert _error(tmp_path, text) == expected


def test_units(tmp_path):
    assert load_scene(_write(tmp_path, 'units = "in"\n' + MINIMAL)).units == "in"


def test_missing_unreadable_and_invalid_files(tmp_path):
    missing = str(tmp_path / "nope.toml")
    with pytest.raises(SieveError, match=r"nope\.toml: scene file not found$"):
        load_scene(missing)
    with pytest.raises(SieveError, match=r": not a regular file; give a scene file"):
        load_scene(str(tmp_path))  # a folder
    assert _error(tmp_path, "name = \n").startswith("not valid TOML (")
    (tmp_path / "latin1.toml").write_bytes(b'name = "\xe9"\n')
    with pytest.raises(SieveError, match=r"latin1\.toml: could not be read \("):
        load_scene(str(tmp_path / "latin1.toml"))


def test_class_docstrings_list_every_key():
    for cls in [ShapeEntry, *(value_types(Scene)[f.name] for f in scene.table_fields())]:
        for f in fields(cls):
            assert f"\n    {f.name} : " in cls.__doc__, (cls.__name__, f.name)


# --- settings given outside a scene file (sieve-mi check, certify) ----------------------------


@pytest.mark.parametrize(
    "table, key, value",
    [
        ("solver", "learning_rate", "0"),
        ("solver", "particles", "2.5"),
        ("solver", "outer", '"newton"'),
        ("verdict", "resolution", "8"),
        ("verdict", "certify_budget", "nan"),
        ("fabrication", "fill_holes", "1"),
    ],
)
def test_read_value_gives_the_message_of_a_scene_key(tmp_path, table, key, value):
    # One checker for both: a value given elsewhere (a command-line option) gets the message a
    # scene file's key gets, with the option's name for the key.
    message = _error(tmp_path, MINIMAL + f"[{table}]\n{key} = {value}\n")
    cls = value_types(Scene)[table]
    given = tomllib.loads(f"v = {value}")["v"]
    with pytest.raises(SieveError) as exc:
        read_value(cls, key, given, "cmd", f"--{key}")
    assert str(exc.value) == "cmd: " + message.replace(f"{table}.{key}:", f"--{key}:")


def test_read_value_converts_like_the_reader():
    assert read_value(CheckSettings, "starts", 3.0, "check") == 3
    assert type(read_value(CheckSettings, "learning_rate", 1, "check")) is float
    with pytest.raises(SieveError, match=r"^check: starts: expected a whole number, got '3x'$"):
        read_value(CheckSettings, "starts", "3x", "check")


def test_an_exclusive_maximum_is_checked_and_described():
    f = field_of(CheckSettings, "fit_tolerance")
    assert spec_of(f).exclusive_max and describe(CheckSettings, f) == "number ≥ 1e-06, < 1"
    assert read_value(CheckSettings, "fit_tolerance", 0.999, "x") == 0.999
    with pytest.raises(SieveError, match=r"^x: fit_tolerance: must be < 1, got 1.0$"):
        read_value(CheckSettings, "fit_tolerance", 1.0, "x")
    lr = field_of(CheckSettings, "learning_rate")
    assert describe(CheckSettings, lr) == "number > 0, ≤ 1.0"


def test_check_settings_are_declared_once(tmp_path):
    # check's budget is the verdict's, its learning rate and seed the solver's: one default each.
    check, verdict, solver = CheckSettings(), scene.Verdict(), scene.Solver()
    assert (check.starts, check.steps, check.resolution) == (
        verdict.starts,
        verdict.steps,
        verdict.resolution,
    )
    assert (check.learning_rate, check.seed) == (solver.learning_rate, solver.seed)
    same = {"starts": scene.Verdict, "resolution": scene.Verdict, "learning_rate": scene.Solver}
    for name, cls in same.items():
        assert spec_of(field_of(CheckSettings, name)).minimum == (
            spec_of(field_of(cls, name)).minimum
        )
    assert CheckInputs().scale == ShapeEntry.__dataclass_fields__["scale"].default
    # Neither is a table of a scene file.
    assert {CheckSettings, CheckInputs}.isdisjoint(
        value_types(Scene)[f.name] for f in scene.table_fields()
    )
    assert _error(tmp_path, MINIMAL + "[check]\nstarts = 3\n").startswith("check: unknown key")


def test_the_pso_default_lives_in_one_place():
    import inspect

    from sieve_mi.optim import PSO_COEFFICIENT, SwarmSettings

    defaults = inspect.signature(SwarmSettings).parameters
    s = scene.Solver()
    assert (s.inertia, s.c_personal, s.c_global) == (PSO_COEFFICIENT,) * 3
    assert all(
        defaults[k].default == PSO_COEFFICIENT for k in ("inertia", "c_personal", "c_global")
    )


def test_the_testing_settings_are_valid_scene_settings(tmp_path):
    from sieve_mi.testing import settings

    s = load_scene(_write(tmp_path, MINIMAL + settings.TINY))
    assert {k: getattr(s.solver, k) for k in settings.TINY_SOLVER} == dict(settings.TINY_SOLVER)
    assert {k: getattr(s.verdict, k) for k in settings.TINY_VERDICT} == dict(settings.TINY_VERDICT)
    text = settings.settings_toml(
        solver={**settings.CASCADE_SOLVER, "outer": "crs2", "freeze": False},
        layout=settings.TINY_LAYOUT,
    )
    s = load_scene(_write(tmp_path, MINIMAL + text))
    assert (s.solver.outer, s.solver.freeze, s.solver.canonical, s.layout.restarts) == (
        "crs2",
        False,
        6,
        0,
    )
    tiny = settings.tiny_solver(particles=8)
    assert (tiny.particles, tiny.steps, tiny.canonical, tiny.polish) == (8, 20, 0, 0)


@pytest.mark.parametrize(
    "table, key, value, expected",
    [
        # each crashed with a traceback, ran out of memory or never ended (hostile retest)
        ("solver", "learning_rate", "1e300", "must be <= 1"),
        ("solver", "particles", "100000000", "must be <= 10000"),
        ("solver", "starts", "100000000", "must be <= 10000"),
        ("solver", "iterations", "100000000", "must be <= 100000"),
        ("solver", "seed", str(2**64), "must be <= 18446744073709551615"),
        ("verdict", "starts", "100000000", "must be <= 100000"),
        ("verdict", "steps", "1000000000", "must be <= 1000000"),
        ("fabrication", "tolerance", "1e300", "must be <= 1000000"),
        ("fabrication", "border", "1e300", "must be <= 1000000"),
        ("fabrication", "thickness", "1e300", "must be <= 1000000"),
        ("fabrication", "block_margin", "1e300", "must be <= 1000000"),
    ],
)
def test_values_beyond_any_use_are_refused_in_one_line(tmp_path, table, key, value, expected):
    message = _error(tmp_path, MINIMAL + f"[{table}]\n{key} = {value}\n")
    assert message.startswith(f"{table}.{key}: {expected}"), message


def test_a_scale_beyond_any_use_is_refused_in_one_line(tmp_path):
    text = MINIMAL.replace('mesh = "a.stl"', 'mesh = "a.stl"\nscale = 1e20', 1)
    assert "scale = 1e20" in text
    message = _error(tmp_path, text)
    assert "scale: must be <= 1000000" in message, message


@pytest.mark.parametrize(
    "line, expected",
    [
        ('name = "   "', "name: '   ' has control characters or blank space"),
        ('name = "a\\nb"', "name: 'a\\nb' has control characters"),
        ('name = " padded"', "blank space at its ends"),
        (f'name = "{"n" * 300}"', "name: 300 characters; use at most 100"),
    ],
)
def test_names_that_cannot_be_folder_or_file_names_are_refused(tmp_path, line, expected):
    assert expected in _error(tmp_path, line + "\n" + MINIMAL)


def test_a_shape_name_is_checked_too(tmp_path):
    text = MINIMAL + f'name = "{"b" * 101}"\n'
    assert _error(tmp_path, text) == "block[0].name: 101 characters; use at most 100"


def test_a_byte_order_mark_is_read_as_utf8(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + ('name = "é"\n' + MINIMAL).encode("utf-8"))
    assert load_scene(str(path)).name == "é"


@pytest.mark.parametrize("special", ["/dev/zero", "folder"])
def test_a_scene_path_that_is_not_a_file_is_refused_at_once(tmp_path, special):
    path = str(tmp_path) if special == "folder" else special
    with pytest.raises(SieveError, match="not a regular file"):
        load_scene(path)


# --- numbers and nesting no reader can hold (issue 40, rows 11 and 18) ---------------------------


def _refused_by_the_cli(capsys, argv: list[str], *files: str) -> str:
    """``sieve-mi ARGV`` in process: exit 2, one stderr line (returned), ``files`` unchanged."""
    import hashlib

    from sieve_mi.cli import main

    def digest(path):
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()

    before = {f: digest(f) for f in files}
    code = main(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("sieve-mi: error: "), err
    assert {f: digest(f) for f in files} == before
    return lines[0].removeprefix("sieve-mi: error: ")


#: (text after MINIMAL's four lines, where the message says it is, what it says).
HUGE = [
    ("[solver]\nparticles = " + "9" * 5000, "solver.particles (line 6)",
     "an integer of more than 4,300 digits"),
    ("[solver]\nparticles = 0x" + "f" * 5000, "solver.particles", "an integer of 6,021 digits"),
    ("[solver]\nlearning_rate = " + "9" * 400 + ".0", "solver.learning_rate",
     "9" * 19 + "… is beyond a number's range (±1.8e308)"),
    ("[solver]\nlearning_rate = 1e400", "solver.learning_rate", "1e400 is beyond a number's range"),
    ("[solver]\ninertia = " + "9" * 400, "solver.inertia",
     "an integer of 400 digits is beyond a number's range"),
    ("[solver]\nseed = " + "9" * 400, "solver.seed", "must be <= 18446744073709551615, got an integer of 400 digits"),
    ("[[pass]]\nmesh = " + "[" * 50_000 + "]" * 50_000, "pass.mesh (line 6)",
     "arrays or tables nested more than 32 deep"),
    ("[[pass]]\nmesh = " + "[" * 40 + "]" * 40, "pass[1].mesh[0][0][0].…",
     "arrays or tables nested more than 32 deep"),
    ("[solver]\n" + "a." * 1000 + "b = 1", "solver.a.a.a.a.a.…", "nested more than 32 deep"),
    ('[[pass]]\nmesh = "a.stl"\nrotation = [' + "9" * 400 + ", 0, 0, 0]", "pass[1].rotation",
     "has a number beyond ±1.8e308"),
]  # fmt: skip


@pytest.mark.parametrize("text, where, words", HUGE, ids=range(len(HUGE)))
def test_numbers_and_nesting_beyond_any_use_are_one_line_naming_file_and_key(
    tmp_path, capsys, text, where, words
):
    # Python's own limits (4,300 digits, 1.8e308, its recursion) surfaced as ValueError,
    # OverflowError and RecursionError tracebacks; now the one line every bad key gets.
    path = _write(tmp_path, MINIMAL + text + "\n")
    out = tmp_path / "out"
    line = _refused_by_the_cli(capsys, ["solve", path, "--out", str(out)], path)
    assert line.startswith(f"{path}: {where}: ") and words in line, line
    assert not out.exists()
    assert _error(tmp_path, MINIMAL + text + "\n") == line[len(path) + 2 :]  # the API's, too


def test_a_mixture_is_read_by_the_same_guarded_reader(tmp_path, capsys):
    path = _write(tmp_path, '[[shape]]\nmesh = "a.stl"\n[[shape]]\nmesh = "b.stl"\n[solver]\n'
                  f"steps = {'9' * 5000}\n", "mix.toml")  # fmt: skip
    line = _refused_by_the_cli(capsys, ["sort", path, "--out", str(tmp_path / "o")], path)
    assert line.startswith(f"{path}: solver.steps (line 6): an integer of more than 4,300 digits")


@pytest.mark.parametrize(
    "value, expected", [("2.0", 2), ("2", 2), ("1e2", 100), ("2.5", None), ("2.000001", None)]
)
def test_a_float_for_an_integer_key_is_whole_or_refused(tmp_path, capsys, value, expected):
    # One rule for files, code and options: a whole number (2 or 2.0) is the integer; any other
    # float is refused naming the key.
    text = MINIMAL + f"[solver]\nstarts = {value}\n"
    argv = ["check", "a.stl", "--sieve", "p.stl", "--starts", value]
    if expected is None:
        assert (
            _error(tmp_path, text) == f"solver.starts: expected a whole number, got {float(value)}"
        )
        with pytest.raises(SieveError, match=r"^check: starts: expected a whole number, got 2\."):
            CheckSettings(starts=float(value))
        assert _refused_by_the_cli(capsys, argv) == (
            f"check: --starts: expected a whole number, got {float(value)}"
        )
        return
    starts = load_scene(_write(tmp_path, text)).solver.starts
    assert starts == expected and type(starts) is int
    assert type(CheckSettings(starts=float(value)).starts) is int
    from sieve_mi.cli import _parser

    args = _parser().parse_args(argv)
    check_options(args)
    assert args.starts == expected and type(args.starts) is int
