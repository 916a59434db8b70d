"""The pictures' worker (sieve_mi.outputs.pictures): a forked process renders on the parent's threads."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from sieve_mi.outputs import pictures
from sieve_mi.workers import worker_pool

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux only")


def _threads_in_worker() -> tuple[int, int, str]:
    """Dr.Jit's thread count, the threads running beside this one, and the variant."""
    import drjit as dr
    import mitsuba as mi

    return dr.thread_count(), len(os.listdir("/proc/self/task")) - 1, mi.variant()


def test_the_worker_renders_on_as_many_threads_as_its_parent(mi):
    # A fork keeps only the forking thread: without _rgb_once's restart the worker's Dr.Jit
    # pool counts the parent's workers but none runs (every kernel on one thread).
    import drjit as dr

    before = mi.variant()
    if before.startswith("cuda"):
        pytest.skip("the pictures render in-process with a CUDA variant")
    threads = dr.thread_count()
    dr.set_thread_count(2)
    try:
        assert np.asarray(dr.sum(mi.Float(np.arange(1000.0)))).item() == 499500.0  # pool busy
        with worker_pool(1, initializer=pictures._rgb_once, what="test") as pool:
            count, running, variant = pool.submit(_threads_in_worker).result()
    finally:
        dr.set_thread_count(threads)
    assert running >= 2 and count >= 2
    if "llvm_ad_rgb" in mi.variants():
        assert variant == "llvm_ad_rgb"  # switched once, in the worker only
    assert mi.variant() == before
