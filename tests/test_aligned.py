"""sieve_mi.backend.aligned: NumPy arrays that Dr.Jit's CPU kernels read as aligned, whatever
the address NumPy gave the values (one kernel source, so the kernel cache hits)."""

from __future__ import annotations

import numpy as np
import pytest

from sieve_mi.backend import ALIGNMENT, aligned


def test_aligned_keeps_the_values_and_starts_on_the_boundary():
    base = np.arange(40, dtype=np.float64)
    for start in range(4):
        column = base[start : start + 30].reshape(10, 3)[:, 1]  # strided, any address
        got = aligned(column, np.float32)
        assert got.ctypes.data % ALIGNMENT == 0 and got.flags.c_contiguous
        assert got.dtype == np.float32 and np.array_equal(got, column.astype(np.float32))
    ready = aligned(np.ones(16, np.float32), np.float32)
    assert aligned(ready, np.float32) is ready  # already aligned: no copy
    assert aligned([], np.uint32).shape == (0,)


def _kernel_sources(mi, values: np.ndarray) -> set:
    """The hashes of the kernels that evaluate ``2 * x + 1`` on ``mi.Float(values)``."""
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        y = mi.Float(values) * 2.0 + 1.0
        dr.eval(y)
        return {k["hash"] for k in dr.kernel_history() if "hash" in k}
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def test_one_kernel_source_whatever_numpy_address(mi):
    # Dr.Jit reads NumPy's memory in place on the CPU and compiles for its alignment: an array
    # 4 bytes off a 64-byte boundary makes another kernel than an aligned one; aligned() not.
    if not mi.variant().startswith("llvm"):
        pytest.skip("the CPU backend reads NumPy arrays in place")
    base = np.zeros(256, dtype=np.float32)
    at = (-base.ctypes.data % ALIGNMENT) // 4
    on, off = base[at : at + 70], base[at + 1 : at + 71]
    assert _kernel_sources(mi, on) != _kernel_sources(mi, off)  # why the helper exists
    assert _kernel_sources(mi, aligned(on, np.float32)) == _kernel_sources(
        mi, aligned(off, np.float32)
    )
