"""sieve-mi: computational design of shape-aware sieves on Mitsuba 3 and Dr.Jit.

The Python API (the command line does the same; see ``docs/api.md``)::

    import sieve_mi as sm

    scene = sm.load_scene("scenes/default.toml")   # a TOML scene (see docs/scene-format.md)
    result = sm.solve(scene, seed=0)               # player A's search, then the exact verdict
    result.winner                                  # "A": every B is blocked
    result.blocks                                  # per B: name, blocked, beta, protrusion, pose
    result.outline.area()                          # the exact hole that gets printed (mm²)
    result.save("out/default")                     # report.json, masks.exr, plate files, ...
    sm.check("part.stl", sieve="out/default/sieve.stl").passes

Examples
--------
Prince Rupert's cube (A's rotation is fixed in the scene, so only the verdict runs): a cube 1 %
larger passes through the hole of a cube seen along its space diagonal.

>>> import sieve_mi as sm
>>> result = sm.solve(sm.load_scene("scenes/rupert.toml"), progress=False)
>>> result.winner
'B'
>>> [(b.name, b.blocked) for b in result.blocks]
[('cube-1.01', False)]

Importing the package only points Dr.Jit at a usable libLLVM (see :mod:`sieve_mi.backend`);
Mitsuba, Dr.Jit and the solver are imported on first use of a public name.
"""

from sieve_mi import backend as _backend
from sieve_mi._version import VERSION

__version__ = VERSION

__all__ = ["Result", "Scene", "SieveError", "check", "load_scene", "load_shape", "solve"]

#: Public name -> module that defines it (imported on first use).
_LAZY = {
    "Result": "sieve_mi.api",
    "solve": "sieve_mi.api",
    "Scene": "sieve_mi.api",
    "load_scene": "sieve_mi.api",
    "SieveError": "sieve_mi.api",
    "check": "sieve_mi.api",
    "load_shape": "sieve_mi.api",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'sieve_mi' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)


_backend.configure_llvm()
