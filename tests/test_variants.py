"""Both Mitsuba variants give the same answers (the GPU one is skipped where no CUDA device exists)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import rng, sphere

from sieve_mi.backend import default_variant, find_llvm, gpu_available, use_variant
from sieve_mi.errors import SieveError


def _attack(cube20):
    from sieve_mi.game.player_a import PlayerA
    from sieve_mi.game.player_b import PlayerB
    from sieve_mi.geometry.raster import Frame

    f = Frame.covering(cube20.radius + 1.0, 128)
    hole = PlayerA(cube20, f, 1.0).holes(np.array([[1.0, 0, 0, 0]]))[0]
    return hole, PlayerB([sphere(10.0), sphere(12.0)], f).attack([hole], 10, 100, 0.05, rng())


@pytest.mark.parametrize(
    "variant", ["llvm_ad_mono", pytest.param("cuda_ad_mono", marks=pytest.mark.gpu)]
)
def test_known_answer_on_each_variant(variant, cube20):
    if variant.startswith("cuda") and not gpu_available():
        pytest.skip("no CUDA device on this machine")
    if variant.startswith("llvm") and find_llvm() is None and default_variant() != variant:
        pytest.skip("no libLLVM >= 17 on this GPU machine")
    try:
        use_variant(variant)
        hole, attack = _attack(cube20)
        assert attack.beta[0, 0] == 0.0 and attack.beta[0, 1] > 0
        # The 24 mm ball sticks out of the 22 mm hole by 1 mm per side; protrusion is measured from pixel
        # centres of B's mask to the hole raster, so it is quantised to the pixel (0.3 mm here): a
        # centred ball reads 1.2 mm, one shifted by a pixel 1.5 mm. Never less than 1 mm less a pixel.
        px = hole.frame.pixel_size
        assert 1.0 - px <= attack.protrusion[0, 1] <= 1.0 + 2 * px
    finally:
        use_variant(default_variant())


def test_unknown_variant_is_a_clear_error():
    with pytest.raises(SieveError, match="not supported"):
        use_variant("scalar_rgb")


def test_cuda_variant_without_gpu_is_a_clear_error():
    if gpu_available():
        pytest.skip("a CUDA device is present")
    with pytest.raises(SieveError, match="NVIDIA GPU"):
        use_variant("cuda_ad_mono")


def test_variant_from_environment(monkeypatch):
    monkeypatch.setenv("SIEVE_MI_VARIANT", "scalar_rgb")
    with pytest.raises(SieveError, match="SIEVE_MI_VARIANT=scalar_rgb"):
        use_variant()
    monkeypatch.setenv("SIEVE_MI_VARIANT", "llvm_ad_mono")
    assert default_variant() == "llvm_ad_mono"
    monkeypatch.delenv("SIEVE_MI_VARIANT")
    assert default_variant() == "llvm_ad_mono"


def test_llvm_library_is_found():
    from sieve_mi.backend import _llvm_major

    if default_variant().startswith("cuda") and find_llvm() is None:
        pytest.skip("GPU run on a machine without libLLVM")
    path = find_llvm()
    assert path is not None and _llvm_major(path) >= 17
    assert _llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert _llvm_major("/usr/lib/llvm-17/lib/libLLVM.so.1") == 17
