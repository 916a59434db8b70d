"""Helpers for tests, benchmarks and tools. Rule: nothing in sieve_mi outside testing imports it.

:mod:`sieve_mi.testing.shapes` builds test solids with known answers (letters, Nieuwland's cube,
prisms, coins); :mod:`sieve_mi.testing.mesh_io` reads back what the solver writes.
"""

__all__ = ["mesh_io", "shapes"]
