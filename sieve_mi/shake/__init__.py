"""Shake trials (MuJoCo): how often each shape really falls through its vibrating sieve plate.

Rule: every trial depends only on (seed, trial index, settings), never on workers or batching.

MuJoCo's own OpenGL rendering is switched off (``MUJOCO_GL=disable``, unless the user set it)
before MuJoCo is imported: sieve-mi renders with Mitsuba, and MuJoCo's import otherwise probes
for GLFW by starting a Python subprocess per candidate library in every worker, which prints a
traceback (EOFError, BrokenPipeError) when a run is stopped while it waits.
"""

import os

os.environ.setdefault("MUJOCO_GL", "disable")

from sieve_mi.shake.commands import shake_folder
from sieve_mi.shake.inputs import ShakeInput, from_files, from_folder
from sieve_mi.shake.run import shake
from sieve_mi.shake.settings import ShakeSettings
from sieve_mi.shake.stats import wilson

__all__ = [
    "ShakeInput",
    "ShakeSettings",
    "from_files",
    "from_folder",
    "shake",
    "shake_folder",
    "wilson",
]
