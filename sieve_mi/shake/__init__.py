"""Shake trials (MuJoCo): how often each shape really falls through its vibrating sieve plate.

Rule: every trial depends only on (seed, trial index, settings), never on workers or batching.
"""

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
