"""Hole images for ``check --hole``: every bit depth and transparency reads as the same hole."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from sieve_mi.errors import SieveError
from sieve_mi.geometry.hole_image import mask_from_image

N = 64


def _disk() -> np.ndarray:
    """A disk of radius 20 px centred in a 64 x 64 image, plus a grey ring (30 % level) around it."""
    yy, xx = np.mgrid[:N, :N] - (N - 1) / 2
    r = np.hypot(xx, yy)
    return r < 20, (r >= 20) & (r < 24)


@pytest.mark.parametrize("depth", [8, 16])
def test_greyscale_of_any_depth_reads_the_same_hole(tmp_path, depth):
    # The grey ring (30 % of full scale) is not hole at either depth: a 16-bit image must not be
    # clipped to 8 bits (every value above 255 turned white).
    hole, ring = _disk()
    top = 255 if depth == 8 else 65535
    img = np.where(hole, top, np.where(ring, round(0.3 * top), 0))
    img = img.astype(np.uint8 if depth == 8 else np.uint16)
    Image.fromarray(img).save(tmp_path / "h.png")
    mask = mask_from_image(str(tmp_path / "h.png"))
    np.testing.assert_array_equal(mask, hole)
    assert mask.sum() == pytest.approx(np.pi * 20**2, rel=0.02)  # the disk's area in pixels


@pytest.mark.parametrize("colour", [(0, 0, 0), (255, 255, 255), (200, 30, 30)])
def test_an_opaque_hole_on_transparent_is_the_hole_whatever_its_colour(tmp_path, colour):
    hole, _ = _disk()
    rgba = np.zeros((N, N, 4), np.uint8)  # transparent black background
    rgba[hole] = (*colour, 255)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "h.png")
    np.testing.assert_array_equal(mask_from_image(str(tmp_path / "h.png")), hole)


def test_white_on_black_with_an_opaque_alpha_channel(tmp_path):
    hole, _ = _disk()
    rgba = np.zeros((N, N, 4), np.uint8)
    rgba[..., 3] = 255
    rgba[hole, :3] = 255
    Image.fromarray(rgba, "RGBA").save(tmp_path / "h.png")
    np.testing.assert_array_equal(mask_from_image(str(tmp_path / "h.png")), hole)


def test_a_white_hole_drawn_on_an_opaque_black_plate_with_a_transparent_margin(tmp_path):
    hole, ring = _disk()
    plate = hole | ring
    rgba = np.zeros((N, N, 4), np.uint8)
    rgba[plate, 3] = 255  # opaque plate (black) ...
    rgba[hole, :3] = 255  # ... with the white hole in it
    Image.fromarray(rgba, "RGBA").save(tmp_path / "h.png")
    np.testing.assert_array_equal(mask_from_image(str(tmp_path / "h.png")), hole)


def test_an_image_without_a_hole_is_one_clear_error(tmp_path):
    Image.fromarray(np.zeros((N, N), np.uint16)).save(tmp_path / "h.png")
    with pytest.raises(SieveError, match="no hole pixels"):
        mask_from_image(str(tmp_path / "h.png"))
