"""Fuzz the scene schema: random types, extremes, NaN/inf, unicode and huge strings, in files and
assigned through the API. Every outcome is a loaded scene or one line of SieveError, never a
traceback of another kind."""

from __future__ import annotations

import dataclasses
import random

import pytest
import trimesh

import sieve_mi as sm
from sieve_mi.scene import Scene, table_fields
from sieve_mi.settings import key_of, spec_of, value_types

VALUES = ["0", "-1", "1", "3", "1e300", "-1e300", "nan", "inf", "-inf", "1e-300", "true", "false",
          '""', '"x"', '"\\u00e9\\u4e2d"', '"' + "a" * 5000 + '"', "[]", "[1, 2]", "{}", "{a = 1}",
          "2.5", "64.0", "9" * 30, '"\\n"', '"   "', '"../x"', '"<!--<script>"',
          "18446744073709551616", "1979-05-27", '"\\u0000"', '"clearance"', '"pso"',
          "9" * 5000, "0x" + "f" * 5000, "9" * 400, "9" * 400 + ".5", "-1e400", "1e-400",
          "[" * 40 + "]" * 40, "[" * 2000 + "]" * 2000, '"\\u0000"', "{a.b.c = 1}"]  # fmt: skip
PY_VALUES = [0, -1, 1, 3, 1e300, -1e300, float("nan"), float("inf"), 1e-300, True, False, "",
             "x", "é中", "a" * 5000, [], [1, 2], {}, 2.5, 64.0, 10**30, None, b"x", object(),
             "clearance", "pso", "merged", 2**64, 10**400, -(10**4000), 2.0, [[[[1.0]]]],
             float("-inf")]  # fmt: skip
TABLES = {key_of(f): value_types(Scene)[f.name] for f in table_fields()}


def _keys(cls) -> list[str]:
    return [key_of(f) for f in dataclasses.fields(cls) if spec_of(f) is not None]


def _random_scene(rng: random.Random) -> str:
    lines = []
    if rng.random() < 0.9:
        lines.append("name = " + rng.choice(['"s"', '"   "', '"a\\nb"', '"../x"', "3", '"é"',
                                             '"' + "n" * 300 + '"']))  # fmt: skip
    for kind in ("pass", "block"):
        for _ in range(rng.choice([0, 1, 1, 2])):
            lines += [f"[[{kind}]]", "mesh = " + rng.choice(['"a.stl"', '"missing.stl"', '""',
                                                            "3", '"/dev/zero"', '"."'])]  # fmt: skip
            for key, p in (("scale", 0.5), ("rotation", 0.3), ("name", 0.3)):
                if rng.random() < p:
                    extra = ["[1,0,0,0]", "[0,0,0,0]", "[nan,0,0,0]"] if key == "rotation" else []
                    lines.append(f"{key} = {rng.choice(VALUES + extra)}")
    for table, cls in TABLES.items():
        if rng.random() < 0.5:
            lines.append(f"[{table}]")
            lines += [f"{k} = {rng.choice(VALUES)}" for k in _keys(cls) if rng.random() < 0.3]
    if rng.random() < 0.1:
        lines.append(rng.choice(["[bogus]", "x = ", "= 3", "[[pass]", "\ufeff", "[solver]"]))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", range(4))
def test_random_scene_files_load_or_fail_in_one_line(tmp_path, seed):
    rng = random.Random(seed)
    trimesh.creation.box((10, 10, 10)).export(str(tmp_path / "a.stl"))
    path = tmp_path / "s.toml"
    loaded = refused = 0
    for _ in range(500):
        path.write_text(_random_scene(rng), encoding="utf-8")
        try:
            sm.load_scene(str(path))
            loaded += 1
        except sm.SieveError as e:
            assert "\n" not in str(e) and str(e).startswith(str(path)), str(e)
            refused += 1
    assert refused > 0 and loaded + refused == 500


@pytest.mark.parametrize("seed", range(2))
def test_random_assignments_set_or_fail_in_one_line(seed):
    rng = random.Random(seed)
    scene = sm.Scene.from_meshes([trimesh.creation.box((10, 10, 10))],
                                 [trimesh.creation.icosphere(radius=8)])  # fmt: skip
    for _ in range(400):
        table = rng.choice(list(TABLES))
        settings = getattr(scene, table)
        key = rng.choice(_keys(TABLES[table]))
        name = next(f.name for f in dataclasses.fields(settings) if key_of(f) == key)
        if rng.random() < 0.1:  # a typo: refused, never kept
            name = name[:-1]
        value = rng.choice(PY_VALUES)
        _set_or_one_line(table, setattr, settings, name, value)  # a value set in code
        _set_or_one_line(table, TABLES[table], **{name: value})  # a table made in code


def _set_or_one_line(table: str, act, *args, **kwargs) -> None:
    """``act(*args, **kwargs)`` works or raises one line of SieveError naming ``table``."""
    try:
        act(*args, **kwargs)
    except sm.SieveError as e:
        assert "\n" not in str(e) and str(e).startswith(f"{table}: "), str(e)
