"""Shake trials of a cascade (``sort --shake N``, sieve_mi.cascade.purity): which tray each shape
ends in, as fractions with Wilson intervals, under the independent-shapes model."""

from __future__ import annotations

import math

import pytest
from shake_helpers import ball, plate_mesh, quick, round_hole

from sieve_mi.cascade import purity
from sieve_mi.cascade.purity import Stage, purity_table, shake_cascade, sieve_seed
from sieve_mi.shake.stats import wilson


def _balls_cascade():
    """Balls of 24, 20 and 14 mm over a 22 mm round hole, then a 17 mm one (2 mm plates, 5 mm
    border, as solve makes them)."""
    stages = [
        Stage(plate_mesh(round_hole(22.0), 5.0, 2.0), "p22.stl", ["ball24"], ["ball20", "ball14"]),
        Stage(plate_mesh(round_hole(17.0), 5.0, 2.0), "p17.stl", ["ball20"], ["ball14"]),
    ]
    meshes = {"ball24": ball(24.0), "ball20": ball(20.0), "ball14": ball(14.0)}
    return stages, meshes


def _assert_consistent(report: dict) -> None:
    """Counts add up to N per shape; each fraction is count / N inside its Wilson interval; a
    lower sieve sees exactly the trials that passed the one above; and the fraction in tray k is
    the product of the pass fractions above times the block fraction at k."""
    n = report["trials"]
    sieves = report["sieves"]
    for shape in report["shapes"]:
        name, trays = shape["name"], shape["trays"]
        assert sum(t["count"] for t in trays) == n
        for t in trays:
            assert t["fraction"] == t["count"] / n
            assert t["ci95"] == list(wilson(t["count"], n))
            assert t["ci95"][0] <= t["fraction"] <= t["ci95"][1]
        rows = [next((r for r in s["shapes"] if r["name"] == name), None) for s in sieves]
        reaching = n
        for k, row in enumerate(rows):
            if row is None:  # no trial reached this sieve
                assert reaching == 0 and trays[k]["count"] == 0
                continue
            assert row["trials"] == reaching
            assert row["ci95"] == list(wilson(row["passed"], row["trials"]))
            above = math.prod(r["fraction"] for r in rows[:k])
            assert trays[k]["fraction"] == pytest.approx(above * (1 - row["fraction"]))
            reaching = row["passed"]
        assert trays[-1]["count"] == reaching


def test_three_balls_end_in_their_trays(capsys):
    """On paper: every projection of the 24 mm ball is a 24 mm disc, wider than the 22 mm hole,
    so no trial gets it through sieve 1: all of it stays on tray 1 and it never reaches sieve 2.
    The 20 mm ball fits the 22 mm hole in every pose (1 mm all round) but never the 17 mm one:
    it cannot reach the bottom tray. The 14 mm ball fits both holes and falls through as soon as
    shaking walks it over them (the 20 mm ball through 22 mm: median 0.5 s), so most of its
    trials end in the bottom tray. 10 parts per shape, 2 s of shaking per sieve."""
    stages, meshes = _balls_cascade()
    report = shake_cascade(stages, meshes, "mm", quick(trials=10, duration=2.0), progress=False)
    _assert_consistent(report)
    shapes = {s["name"]: s for s in report["shapes"]}
    assert [s["belongs"] for s in report["shapes"]] == [0, 1, 2]
    counts = {name: [t["count"] for t in s["trays"]] for name, s in shapes.items()}
    assert counts["ball24"] == [10, 0, 0]
    assert counts["ball20"][2] == 0
    assert counts["ball14"][2] >= 7
    top, second = report["sieves"]
    assert [r["name"] for r in top["shapes"]] == ["ball24", "ball20", "ball14"]
    assert [r["role"] for r in top["shapes"]] == ["B", "A", "A"]
    assert top["shapes"][0]["passed"] == 0 and top["shapes"][0]["ci95"][1] < 0.3
    assert "ball24" not in [r["name"] for r in second["shapes"]]  # no trial reached sieve 2
    assert next(r for r in second["shapes"] if r["name"] == "ball20")["passed"] == 0
    assert (top["seed"], second["seed"]) == (sieve_seed(0, 0), sieve_seed(0, 1))
    assert report["trays"][0]["purity"] == 1.0 and report["fidelity_ok"]
    assert report["warnings"] == []  # every per-sieve warning comes up here
    assert "independent shapes, no interaction between parts" in report["model"]
    text = purity_table(report)
    assert "* 1.000 [0.722, 1.000]" in text and "to hold" in text and "purity" in text


def test_a_shape_that_leaks_through_is_shaken_below_and_the_fractions_multiply(monkeypatch):
    """With made-up outcomes (trial i of "big" passes sieve k unless (i + k) % 3 == 0; "mid"
    passes sieve 1 only, "small" every sieve), the bookkeeping is checked exactly: the trials of
    "big" that leaked through sieve 1 are shaken on sieve 2 as coming "from above" (role None),
    and its tray fractions are the products of its per-sieve fractions."""

    def fake_entry(part, role, path, plate, settings, unit_m, progress, trials=None):
        name = part.name
        k = [sieve_seed(0, j) for j in range(3)].index(settings.seed)
        rule = {"big": lambda i: (i + k) % 3 != 0, "mid": lambda i: k == 0, "small": lambda i: True}
        passes = [rule[name](i) for i in trials]
        entry = {
            "name": name,
            "role": role,
            "file": path,
            "geometry": {},
            "warnings": [],
            "trials": len(trials),
            "passed": sum(passes),
            "escaped": 0,
            "fraction": sum(passes) / len(trials),
            "ci95": list(wilson(sum(passes), len(trials))),
            "median_time_s": None,
            "pass_times_s": [1.0 if p else None for p in passes],
            "fidelity": {"within_bound": True},
        }
        return entry, 0.0

    monkeypatch.setattr(purity, "shape_entry", fake_entry)
    stages, meshes = _balls_cascade()
    meshes = {"big": meshes["ball24"], "mid": meshes["ball20"], "small": meshes["ball14"]}
    stages[0].holds, stages[0].passes = ["big"], ["mid", "small"]
    stages[1].holds, stages[1].passes = ["mid"], ["small"]
    report = shake_cascade(stages, meshes, "mm", quick(trials=9), progress=False)
    _assert_consistent(report)
    big = report["shapes"][0]["trays"]
    assert [t["count"] for t in big] == [3, 3, 3]  # 0, 3, 6 stay; then 2, 5, 8; 1, 4, 7 pass
    below = next(r for r in report["sieves"][1]["shapes"] if r["name"] == "big")
    assert below["role"] is None and (below["trials"], below["passed"]) == (6, 3)
    assert [t["purity"] for t in report["trays"]] == [1.0, 0.75, 0.75]  # 9 of 12 belong
    assert [t["parts"] for t in report["trays"]] == [3, 12, 12]
