"""Shake trials (MuJoCo): how often each shape really falls through its vibrating sieve plate.

Rule: every trial depends only on (seed, trial index, settings), never on workers or batching.

MuJoCo's own OpenGL rendering is switched off (``MUJOCO_GL=disable``, unless the user set it)
before MuJoCo is imported: sieve-mi renders with Mitsuba, and MuJoCo's import otherwise probes
for GLFW by starting a Python subprocess per candidate library in every worker, which prints a
traceback (EOFError, BrokenPipeError) when a run is stopped while it waits.

MuJoCo and CoACD are an optional extra (``pip install 'sieve-mi[shake]'``): the public names
below are imported on first use, and only the engine's modules (``model``, ``fidelity``,
``trials``, ``run``, ``clip``) import MuJoCo; :func:`~sieve_mi.shake.commands.need_engine` turns
their absence into one line.

Modules
-------
settings
    The settings of a shake run (shaker motion, physics, trials) and the engine's constants.
inputs
    What a run reads: a solve's output folder, or a plate mesh and part meshes.
geometry
    Solids for the engine: the plate as exact convex prisms, each part as convex pieces.
decompose
    A part's convex pieces (CoACD), cached on disk by the mesh's hash.
model
    The MuJoCo model of one trial: a plate driven along a shaker motion, a frame, a part.
fidelity
    How far a part sinks into the plate in the engine, measured.
trials
    One trial: drop a part at random, shake, record whether and when it fell through.
stats
    Pass fractions with Wilson intervals, times to pass, curves.
run
    One shake run: every part's geometry, fidelity and trials, gathered into ``shake.json``'s dict.
outputs
    ``shake.json``, ``shake.png`` and a summary table.
clip
    ``shake.gif``: a short Mitsuba-rendered clip of one trial per shape.
commands
    The ``shake`` subcommand of the command line.
target
    A pass-rate target (``[shake] target``): grow the tolerance, widen the window, add turned
    copies, mirror them, until met.
"""

import os

os.environ.setdefault("MUJOCO_GL", "disable")

__all__ = [
    "ShakeInput",
    "ShakeSettings",
    "from_files",
    "from_folder",
    "shake",
    "shake_folder",
    "solve_shaken",
    "wilson",
]

#: Public name -> module that defines it, imported on first use: MuJoCo and CoACD are an
#: optional extra (``pip install 'sieve-mi[shake]'``), so importing this package (the command
#: line does, for ``shake``'s options) must not import them.
_LAZY = {
    "ShakeInput": "sieve_mi.shake.inputs",
    "ShakeSettings": "sieve_mi.shake.settings",
    "from_files": "sieve_mi.shake.inputs",
    "from_folder": "sieve_mi.shake.inputs",
    "shake": "sieve_mi.shake.run",
    "shake_folder": "sieve_mi.shake.commands",
    "solve_shaken": "sieve_mi.shake.commands",
    "wilson": "sieve_mi.shake.stats",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'sieve_mi.shake' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
