"""The Python API: public names, the package docstring's example as a doctest, Result and check."""

from __future__ import annotations

import doctest
import json
import os

import pytest
import trimesh

import sieve_mi as sm

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def test_public_names_resolve_to_the_api_not_to_modules():
    for name in sm.__all__:
        obj = getattr(sm, name)
        assert callable(obj), name
    assert set(sm.__all__) <= set(dir(sm))
    with pytest.raises(AttributeError):
        sm.no_such_name  # noqa: B018


def test_package_docstring_examples_run(monkeypatch):
    monkeypatch.chdir(ROOT)
    failed, attempted = doctest.testmod(sm, raise_on_error=False, verbose=False)
    assert attempted >= 4 and failed == 0


def test_result_blocks_and_save_match_report_json(tmp_path):
    # Prince Rupert's cube: A fixed, so only the verdict runs; the 1 % larger cube passes.
    result = sm.solve(sm.load_scene(os.path.join(ROOT, "scenes", "rupert.toml")), progress=False)
    rep = result.save(str(tmp_path / "out"), fabricate=False)
    on_disk = json.loads((tmp_path / "out" / "report.json").read_text())
    assert on_disk["winner"] == rep["winner"] == result.winner == "B"
    assert [(b.name, b.blocked) for b in result.blocks] == [("cube-1.01", False)]
    for b, row in zip(result.blocks, on_disk["block"]):
        assert (b.name, b.blocked, b.beta, b.protrusion) == (
            row["name"], row["blocked"], row["beta"], row["protrusion"],
        )  # fmt: skip
        assert list(b.rotation) == row["rotation"] and list(b.translation) == row["translation"]


def test_check_takes_a_mesh_or_a_path(tmp_path):
    # A 15 mm square hole in a plate: a 10 mm cube passes face-on; a 16 mm cube cannot, since
    # its width in every direction is at least 16 (a cube's smallest width is its side) while the
    # hole is 15 wide across.
    from sieve_mi.checker import CheckSettings

    plate = trimesh.creation.box((40.0, 40.0, 4.0)).difference(
        trimesh.creation.box((15.0, 15.0, 10.0))
    )
    plate_path = str(tmp_path / "plate.stl")
    plate.export(plate_path)
    small = trimesh.creation.box((10.0, 10.0, 10.0))
    small_path = str(tmp_path / "small.stl")
    small.export(small_path)
    fast = CheckSettings(starts=16, steps=120, fit=False)
    assert sm.check(small, sieve=plate_path, settings=fast).passes
    assert sm.check(small_path, sieve=plate_path, settings=fast).passes
    big = trimesh.creation.box((16.0, 16.0, 16.0))
    assert not sm.check(big, sieve=plate_path, settings=fast).passes
