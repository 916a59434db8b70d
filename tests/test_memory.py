"""Peak memory per stage (backend.MemoryWatch) and Dr.Jit's cache handed back between attacks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sieve_mi.backend import MemoryWatch, release_cached_memory, use_variant

pytestmark = pytest.mark.skipif(
    not __import__("os").path.exists("/proc/self/statm"), reason="needs /proc (Linux)"
)

MB = 2**20 / 2**30  # one MB in GB


def _resident() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**30


def test_a_stage_that_touches_200_mb_peaks_200_mb_above_the_one_before():
    """200 MB of pages written in one stage and freed in it: that stage's peak is at least
    the resident memory before plus 200 MB (less a 10 % allowance for pages the allocator
    returned early), and the next stage, which allocates nothing, peaks lower."""
    watch = MemoryWatch(interval=0.005)
    try:
        base = watch.mark("before")
        block = np.ones(200 * 2**20 // 8)  # written, so resident
        block.sum()
        del block
        grew = watch.mark("grow")
        after = watch.mark("after")
    finally:
        watch.stop()
    assert grew >= base + 180 * MB
    assert after < grew - 150 * MB
    assert watch.peak >= grew


def test_the_process_peak_is_not_reset():
    """The watch reads getrusage and never resets it: the process's peak stays what it was."""
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    watch = MemoryWatch()
    watch.mark("x")
    watch.stop()
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss >= before


def test_releasing_dr_jit_s_cache_hands_a_freed_array_back():
    """A 400 MB Dr.Jit array, freed, stays in Dr.Jit's allocation cache (resident) until
    release_cached_memory(); after it the process is at least 300 MB smaller than with it.
    (On one thread: Linux counts pages that pool threads touch in the resident set lazily.)"""
    use_variant("llvm_ad_mono")
    import drjit as dr
    import mitsuba as mi

    release_cached_memory()
    threads = dr.thread_count()
    dr.set_thread_count(1)  # pages written by this thread: counted in the resident set at once
    try:
        before = _resident()
        x = dr.sqrt(dr.arange(mi.Float, 100 * 2**20)) + 1.0  # 400 MB, computed
        dr.eval(x)
        del x  # freed, but held in Dr.Jit's cache
        with_it = _resident()
        assert with_it > before + 300 * MB
        release_cached_memory()
    finally:
        dr.set_thread_count(threads)
    assert _resident() < with_it - 300 * MB


def test_report_json_names_every_stage_s_peak(tmp_path):
    """A whole solve's report.json gives each timed stage a peak, none above the process's."""
    import os

    from sieve_mi.api import solve
    from sieve_mi.scene import load_scene
    from sieve_mi.testing.settings import TINY

    meshes = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "scenes", "meshes"))
    path = tmp_path / "scene.toml"
    path.write_text(f'[[pass]]\nmesh = "{meshes}/cube.stl"\n[[block]]\nmesh = "{meshes}/sphere.stl"\n'
                    + TINY)  # fmt: skip
    result = solve(load_scene(str(path)), progress=False)
    result.save(str(tmp_path / "out"), figure=False, animation=False)
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    stages = report["memory"]["stages_gb"]
    for stage in ("load", "search", "verdict", "images", "page"):
        assert 0.05 < stages[stage] <= report["memory"]["peak_gb"]
