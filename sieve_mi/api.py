"""The Python API behind ``import sieve_mi as sm`` (see ``docs/api.md``).

:func:`solve` plays the game (:mod:`sieve_mi.game`, which writes no files) and returns a
:class:`Result` whose :meth:`~Result.save` writes the outputs (:mod:`sieve_mi.outputs`);
:func:`check` tests parts against a plate or a hole image; scenes and shapes are read with
:func:`load_scene` and :func:`load_shape`. Every error is a one-line :class:`SieveError`.
"""

from __future__ import annotations

import dataclasses

from sieve_mi.errors import SieveError
from sieve_mi.game import result as _game_result
from sieve_mi.game import solver as _solver
from sieve_mi.game.check import check
from sieve_mi.geometry.meshes import load_shape
from sieve_mi.outputs.report import write_outputs
from sieve_mi.scene import Scene, load_scene

__all__ = ["Result", "Scene", "SieveError", "check", "load_scene", "load_shape", "solve"]


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
    return Result.of(_solver.solve(scene, variant=variant, seed=seed, progress=progress))
