"""Helpers for tests, benchmarks and tools. Rule: nothing in sieve_mi outside testing imports it.

:mod:`sieve_mi.testing.shapes` builds test solids with known answers (letters, Nieuwland's cube,
prisms, coins); :mod:`sieve_mi.testing.catalogue` builds parts from catalogue dimensions (toy
bricks, AAA and AA cells); :mod:`sieve_mi.testing.mesh_io` reads back what the solver writes;
:mod:`sieve_mi.testing.settings` holds the small solver settings tests and benchmarks run with;
:mod:`sieve_mi.testing.pictures` checks that a drawn picture keeps its text off its shapes.

Modules
-------
shapes
    Test solids with known answers.
catalogue
    Parts from catalogue dimensions: toy bricks, cylindrical cells.
mesh_io
    Reading back the files sieve-mi writes.
settings
    Small solver settings for tests and benchmarks.
pictures
    Checks that a drawn picture keeps its text off its shapes.
"""

__all__ = ["catalogue", "mesh_io", "pictures", "settings", "shapes"]
