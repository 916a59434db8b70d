"""sieve-mi: computational design of shape-aware sieves on Mitsuba 3 and Dr.Jit.

Importing the package only points Dr.Jit at a usable libLLVM (see :mod:`sieve_mi.backend`);
Mitsuba and Dr.Jit themselves are imported lazily by the modules that need them.
"""

from sieve_mi import backend as _backend

__version__ = "0.1.0"

_backend.configure_llvm()
