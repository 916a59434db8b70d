"""A run's record (telemetry.Run): stages' seconds in order, the process's start, memory marks."""

from __future__ import annotations

import doctest

import pytest

from sieve_mi import telemetry
from sieve_mi.telemetry import Run


def test_docstring_examples_run():
    failed, attempted = doctest.testmod(telemetry, raise_on_error=False, verbose=False)
    assert attempted >= 2 and failed == 0


def test_a_run_counted_from_the_process_start_has_startup_first():
    # made 2 s into the process: the time before start() is the stage "startup", and the total
    # counts from the process's start, so it covers the startup and every stage after it
    run = Run(startup=2.0)
    assert run.timings == {} and run.started is not None
    run.start()
    with run.stage("load"):
        pass
    with run.stage("search"):
        pass
    assert list(run.timings) == ["startup_s", "load_s", "search_s"]
    assert run.timings["startup_s"] >= 2.0
    assert run.elapsed() >= sum(run.timings.values())


def test_a_plain_run_counts_from_its_start():
    run = Run()
    assert run.started is None  # nothing counts before start()
    assert run.start() is run and run.started is not None
    with run.stage("init"):
        pass
    assert list(run.timings) == ["init_s"] and run.memory is None
    run.mark("init")  # without a watch: nothing to end, no error
    run.stop()


def test_a_stage_that_raises_is_not_recorded():
    run = Run().start(memory=True)
    with pytest.raises(KeyError), run.stage("verdict"):
        raise KeyError("stop")
    with run.stage("certify"):
        pass
    run.stop()
    assert list(run.timings) == ["certify_s"]
    assert list(run.memory.peaks) == ["certify"]


def test_stages_end_the_memory_watch_in_order():
    run = Run().start(memory=True)
    with run.stage("search"):
        pass
    with run.stage("thin", mark=False):  # its memory stage ends later, at mark()
        pass
    assert list(run.memory.peaks) == ["search"]
    run.mark("thin")
    run.stop()
    assert list(run.memory.peaks) == ["search", "thin"]
    assert list(run.timings) == ["search_s", "thin_s"]


def test_a_call_after_a_stage_runs_once_when_it_ends_and_not_when_it_raises():
    run = Run().start()
    calls = []
    run.after("screen", lambda: calls.append(dict(run.timings)))
    with run.stage("load"):
        pass
    assert calls == []  # another stage's end calls nothing
    with pytest.raises(ValueError), run.stage("screen"):
        raise ValueError("stopped")
    assert calls == []  # a stage that raised did not end
    with run.stage("screen"):
        pass
    assert len(calls) == 1 and "screen_s" in calls[0]  # after its time was recorded
    with run.stage("screen"):
        pass
    assert len(calls) == 1  # once
