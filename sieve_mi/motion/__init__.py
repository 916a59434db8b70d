"""Thin plates: can a shape pass a plate thinner than its diameter by tilting and turning on the way?
Rule: motion decides with exact collisions (coal) between the mesh and the plate's convex prisms, plans
with OMPL, and counts a passage only after a conservative continuous re-check; never a raster.

A plate at least as thick as a shape's diameter blocks it iff no projection fits the hole
(:func:`sieve_mi.geometry.plate.safe_thickness`); on a thinner plate the shape may thread through.
:func:`thin_plate` answers ``"safe"``, ``"passage"`` (with a verified motion) or
``"no passage found"`` (with what was searched: a heuristic answer, never a proof).

Modules
-------
collide
    Exact collision and distance queries: a shape's mesh against the plate's convex prisms (coal).
planner
    The motion search: seeded straight descents, then OMPL's RRT-Connect via crossing poses.
path
    Rigid motions as pose sequences, and their conservative continuous re-check.
thin
    One shape's thin-plate answer; the B of a solve searched in parallel processes.
"""

from __future__ import annotations

from sieve_mi.motion.thin import ThinPlate, each_thin_plate, thin_plate, thin_plates

__all__ = ["ThinPlate", "each_thin_plate", "thin_plate", "thin_plates"]
