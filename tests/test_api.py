"""Result's Python conveniences: per-B attempts and saving, checked against report.json."""

from __future__ import annotations

import json
import os

from sieve_mi.scene import load_scene
from sieve_mi.solve import solve

ROOT = os.path.join(os.path.dirname(__file__), "..")


def test_result_blocks_and_save_match_report_json(tmp_path):
    # Prince Rupert's cube: A fixed, so only the verdict runs; the 1 % larger cube passes.
    result = solve(load_scene(os.path.join(ROOT, "scenes", "rupert.toml")), progress=False)
    rep = result.save(str(tmp_path / "out"), fabricate=False)
    on_disk = json.loads((tmp_path / "out" / "report.json").read_text())
    assert on_disk["winner"] == rep["winner"] == result.winner == "B"
    assert [(b.name, b.blocked) for b in result.blocks] == [("cube-1.01", False)]
    for b, row in zip(result.blocks, on_disk["block"]):
        assert (b.name, b.blocked, b.beta, b.protrusion) == (
            row["name"], row["blocked"], row["beta"], row["protrusion"],
        )  # fmt: skip
        assert list(b.rotation) == row["rotation"] and list(b.translation) == row["translation"]
