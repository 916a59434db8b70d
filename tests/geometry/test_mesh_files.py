"""Mesh files that are not what they claim are refused in one line naming the file."""

from __future__ import annotations

import os

import pytest
import trimesh
from helpers import REPO

from sieve_mi.errors import SieveError
from sieve_mi.geometry.meshes import load_shape

CUBE = os.path.join(REPO, "scenes", "meshes", "cube.stl")  # binary STL, 12 triangles


@pytest.mark.parametrize("keep", [84, 300, 683])
def test_a_truncated_binary_stl_says_so(tmp_path, keep):
    cut = tmp_path / "cut.stl"
    cut.write_bytes(open(CUBE, "rb").read()[:keep])
    with pytest.raises(SieveError) as e:
        load_shape(str(cut))
    msg = str(e.value)
    assert "truncated binary STL" in msg and "12 triangles (684 bytes)" in msg
    assert f"has {keep} bytes" in msg and "\n" not in msg


def test_a_whole_binary_stl_and_an_ascii_stl_load(tmp_path):
    assert load_shape(CUBE).face_count == 12
    ascii_path = tmp_path / "box.stl"
    trimesh.creation.box((1, 2, 3)).export(str(ascii_path), file_type="stl_ascii")
    assert load_shape(str(ascii_path)).face_count == 12


def test_a_mesh_path_that_is_not_a_regular_file(tmp_path):
    with pytest.raises(SieveError, match="is not a regular file"):
        load_shape("/dev/zero")
