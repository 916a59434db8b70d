"""Size measures of a mixture's shapes, for the cascade: they live in
:mod:`sieve_mi.geometry.size` (the solver's feasibility test uses them too) and are re-exported
here under their old names."""

from __future__ import annotations

from sieve_mi.geometry.size import (
    canonical_extents,
    enclosing_circle,
    end_first_radius,
    inscribed_radius,
    passage_radius,
    predicted_margin,
    rectangle_fits,
)

__all__ = [
    "canonical_extents",
    "enclosing_circle",
    "end_first_radius",
    "inscribed_radius",
    "passage_radius",
    "predicted_margin",
    "rectangle_fits",
]
