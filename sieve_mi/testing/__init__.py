"""Helpers for tests, benchmarks and tools, not used by the solver itself.

:mod:`sieve_mi.testing.shapes` builds test solids with known answers (letters, Nieuwland's cube,
prisms, coins); :mod:`sieve_mi.testing.mesh_io` reads back what the solver writes.
"""
