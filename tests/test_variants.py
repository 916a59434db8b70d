"""Both Mitsuba variants give the same answers (the GPU one is skipped where no CUDA device exists)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import rng, sphere
from sieve_mi.backend import gpu_available, use_variant
from sieve_mi.errors import SieveError


def _attack(cube20):
    from sieve_mi.players import PlayerA, PlayerB
    from sieve_mi.raster import Frame

    f = Frame.covering(cube20.radius + 1.0, 128)
    hole = PlayerA(cube20, f, 1.0).holes(np.array([[1.0, 0, 0, 0]]))[0]
    return hole, PlayerB([sphere(10.0), sphere(12.0)], f).attack([hole], 10, 100, 0.05, rng())


@pytest.mark.parametrize("variant", ["llvm_ad_mono", pytest.param("cuda_ad_mono", marks=pytest.mark.gpu)])
def test_known_answer_on_each_variant(variant, cube20):
    if variant.startswith("cuda") and not gpu_available():
        pytest.skip("no CUDA device on this machine")
    try:
        use_variant(variant)
        hole, attack = _attack(cube20)
        assert attack.beta[0, 0] == 0.0 and attack.beta[0, 1] > 0
        assert attack.protrusion[0, 1] == pytest.approx(1.0, abs=1.5 * hole.frame.pixel_size)
    finally:
        use_variant("llvm_ad_mono")


def test_unknown_variant_is_a_clear_error():
    with pytest.raises(SieveError, match="not supported"):
        use_variant("scalar_rgb")


def test_cuda_variant_without_gpu_is_a_clear_error():
    if gpu_available():
        pytest.skip("a CUDA device is present")
    with pytest.raises(SieveError, match="NVIDIA GPU"):
        use_variant("cuda_ad_mono")


def test_llvm_library_is_found():
    from sieve_mi.backend import _llvm_major, find_llvm

    path = find_llvm()
    assert path is not None and _llvm_major(path) >= 17
    assert _llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert _llvm_major("/usr/lib/llvm-17/lib/libLLVM.so.1") == 17
