"""Fidelity (how far parts sink into the plate), statistics and determinism of shake trials."""

from __future__ import annotations

import math

import pytest
import trimesh
from shake_helpers import ball, quick

from sieve_mi.shake.fidelity import judge, measure_sink
from sieve_mi.shake.settings import SINK_BOUND_MM
from sieve_mi.shake.stats import pass_curve, summarize, wilson
from sieve_mi.shake.trials import Outcome, run_trials


@pytest.mark.parametrize(
    "mesh", [ball(20.0), trimesh.creation.box((20.0, 20.0, 20.0)), trimesh.creation.box((30, 8, 3))]
)
def test_a_resting_part_sinks_less_than_the_stated_bound(ball_plate, part_of, mesh):
    """The contact parameters (time constant 1 ms, impedance 0.95-0.99) and the 0.25 ms step are
    chosen so that a part at rest on the plate sits less than SINK_BOUND_MM (0.02 mm) inside it,
    far below a print's accuracy; a shaken part's impacts go deeper but stay under 0.3 mm, within
    the shaken bound (0.5 mm on this 2 mm plate), and the engine does not warn."""
    f, lines = judge("part", measure_sink(ball_plate, part_of(mesh), quick(), 1e-3), [])
    assert 0.0 <= f["sink_mm"] < SINK_BOUND_MM and f["within_bound"] and lines == []
    assert f["bound_mm"] == SINK_BOUND_MM and f["shaken_bound_mm"] == 0.5
    assert f["shaken_penetration_mm"] < 0.3 and f["engine_warnings"] == {}


def test_wilson_interval_matches_known_values():
    lo, hi = wilson(0, 200)
    assert lo == 0.0 and hi == pytest.approx(0.01884, abs=1e-4)
    lo, hi = wilson(50, 100)
    assert lo == pytest.approx(0.4038, abs=1e-4) and hi == pytest.approx(0.5962, abs=1e-4)
    assert wilson(7, 7)[1] == 1.0


def test_summary_counts_and_curve():
    out = [
        Outcome(True, 1.0),
        Outcome(False, math.nan),
        Outcome(True, 3.0),
        Outcome(False, math.nan, True),
    ]
    s = summarize(out)
    assert (s["trials"], s["passed"], s["escaped"]) == (4, 2, 1)
    assert s["fraction"] == 0.5 and s["median_time_s"] == 2.0
    assert s["pass_times_s"] == [1.0, None, 3.0, None]
    assert list(pass_curve(s["pass_times_s"], 4, [0.5, 1.0, 2.9, 3.0])) == [0, 0.25, 0.25, 0.5]


def test_same_seed_same_numbers_whatever_the_workers(ball_plate, part_of):
    """A trial depends only on (seed, trial index, settings): one process or two, same outcomes;
    another seed gives other drops."""
    part = part_of(ball(20.0))
    one = run_trials(ball_plate, part, quick(trials=4, duration=1.0), 1e-3)
    again = run_trials(ball_plate, part, quick(trials=4, duration=1.0), 1e-3)
    two = run_trials(ball_plate, part, quick(trials=4, duration=1.0, workers=2), 1e-3)
    other = run_trials(ball_plate, part, quick(trials=4, duration=1.0, seed=7), 1e-3)

    def key(outcomes):
        return [(o.passed, o.time if o.passed else None, o.escaped) for o in outcomes]

    assert key(one) == key(again) == key(two)
    assert key(one) != key(other)
