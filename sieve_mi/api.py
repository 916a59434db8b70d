"""The Python API behind ``import sieve_mi as sm`` (see ``docs/api.md``).

:func:`solve` plays the game (:mod:`sieve_mi.game`, which writes no files) and returns a
:class:`Result` whose :meth:`~Result.save` writes the outputs (:mod:`sieve_mi.outputs`);
:func:`check` tests parts against a plate or a hole image; scenes and shapes are read with
:func:`load_scene` and :func:`load_shape`. Every error is a one-line :class:`SieveError`.
"""

from __future__ import annotations

import dataclasses
import os

from sieve_mi import scene as _scene
from sieve_mi.authors_config import is_authors_config, load_authors_config
from sieve_mi.errors import SieveError
from sieve_mi.game import result as _game_result
from sieve_mi.game import solver as _solver
from sieve_mi.game.check import check
from sieve_mi.geometry import meshes as _meshes
from sieve_mi.outputs.report import write_outputs
from sieve_mi.scene import Scene
from sieve_mi.settings import SEED_MAX, read_value, shown

__all__ = [
    "Result",
    "Scene",
    "SieveError",
    "check",
    "check_seed",
    "load_scene",
    "load_shape",
    "solve",
]


def _path(value, what: str) -> str:
    """``value`` as a file path, or a one-line SieveError naming ``what``."""
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or not value.strip():
        raise SieveError(f"{what}: expected a file path (str), got {value!r:.60}")
    return value


def check_seed(seed, what: str = "seed") -> int | None:
    """``seed`` if it is None or an integer in [0, :data:`sieve_mi.settings.SEED_MAX`]; else a one-line SieveError."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise SieveError(f"{what} {seed!r:.60}: must be an integer >= 0")
    if not 0 <= seed <= SEED_MAX:
        raise SieveError(f"{what} {seed}: must be an integer from 0 to 2**64 - 1")
    return seed


def load_scene(path) -> Scene:
    """Read and validate a scene: a TOML scene file (``docs/scene-format.md``) or, for a
    ``.json`` path, a configuration of the paper authors' code (``docs/authors-config.md``).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Scene
        Every setting the file does not give at its default.

    Raises
    ------
    SieveError
        One line naming the file and the key: a missing file, an unknown key, a wrong value.
    """
    path = _path(path, "load_scene")
    if is_authors_config(path):
        return load_authors_config(path)
    return _scene.load_scene(path)


def load_shape(path, *, scale: float = 1.0, name: str | None = None) -> _meshes.Shape:
    """Read, validate, scale and centre a mesh file (STL, OBJ, PLY, OFF, GLB, ... as trimesh
    reads), as ``sieve-mi check SHAPE --scale S`` does.

    Parameters
    ----------
    path : str or os.PathLike
        Mesh file.
    scale : float
        Uniform scale from file units to scene units (> 0), checked as ``--scale`` is.
    name : str, optional
        Label in reports; default the file's stem.

    Returns
    -------
    sieve_mi.geometry.meshes.Shape

    Raises
    ------
    SieveError
        One line: a bad argument, a missing or unreadable file, a file with no triangles.
    """
    path = _path(path, "load_shape")
    scale = read_value(_scene.ShapeEntry, "scale", scale, "load_shape")
    if name is not None:
        if not isinstance(name, str):
            raise SieveError(f"load_shape: name: expected a string, got {shown(name)}")
        _scene.check_name("load_shape", "name", name)
    return _meshes.load_shape(path, scale=scale, name=name)


class Result(_game_result.Result):
    """What a solve produced (:class:`sieve_mi.game.result.Result`), with :meth:`save`."""

    @classmethod
    def of(cls, result: _game_result.Result) -> Result:
        """The same outcome as a public :class:`Result` (no copy of its arrays)."""
        return cls(**{f.name: getattr(result, f.name) for f in dataclasses.fields(result)})

    def save(
        self, out_dir: str, *, fabricate: bool = True, figure: bool = True, animation: bool = True
    ) -> dict:
        """Write every output into ``out_dir`` (as ``sieve-mi solve --out``); returns report.json's dict.

        A folder that sieve-mi did not write is refused, never replaced (:mod:`sieve_mi.outputs.outdir`).
        ``fabricate=False`` skips the plate files, ``figure=False`` figure.png (as
        ``--no-figure``), ``animation=False`` passage.gif (as ``--no-animation``).
        """
        out_dir = _path(out_dir, "Result.save")
        return write_outputs(self, out_dir, fabricate=fabricate, figure=figure, animation=animation)


def solve(
    scene: Scene, *, variant: str | None = None, seed: int | None = None, progress: bool = True
) -> Result:
    """Play the sieve game for a scene: player A's search, then the exact verdict.

    Parameters
    ----------
    scene : Scene
    variant : str, optional
        Mitsuba variant ("llvm_ad_mono" or "cuda_ad_mono"); default ``$SIEVE_MI_VARIANT`` or
        "llvm_ad_mono".
    seed : int, optional
        Overrides ``[solver] seed``.
    progress : bool
        Show progress bars on stderr.

    Returns
    -------
    Result
    """
    if not isinstance(scene, Scene):
        hint = " (read a file with sieve_mi.load_scene(path))" if isinstance(scene, str) else ""
        raise SieveError(f"solve: expected a Scene, got {scene!r:.60}{hint}")
    if variant is not None and not isinstance(variant, str):
        raise SieveError(f"solve: variant {variant!r:.60} must be a string such as 'llvm_ad_mono'")
    seed = check_seed(seed, "solve: seed")
    return Result.of(_solver.solve(scene, variant=variant, seed=seed, progress=progress))
