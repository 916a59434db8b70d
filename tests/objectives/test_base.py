"""What player B reads of an objective is declared once (sieve_mi.objectives.base.Objective)."""

from __future__ import annotations

import pytest

from sieve_mi.objectives import Objective
from sieve_mi.objectives.clearance import ClearanceObjective
from sieve_mi.objectives.overlap import EdgeOverlapObjective
from sieve_mi.objectives.overlap_mitsuba import OverlapObjective


@pytest.mark.parametrize("cls", [ClearanceObjective, EdgeOverlapObjective, OverlapObjective])
def test_every_objective_is_an_objective(cls):
    assert issubclass(cls, Objective)
    for name in ("fit_loss", "freezable", "hole_corners", "counts", "pair_count"):
        assert hasattr(cls, name), name


def test_only_the_clearance_settles_freezes_and_reads_corners():
    assert ClearanceObjective.fit_loss == 1e-6
    assert ClearanceObjective.freezable and ClearanceObjective.hole_corners
    for cls in (EdgeOverlapObjective, OverlapObjective):
        assert cls.fit_loss is None and not cls.freezable and not cls.hole_corners
    assert OverlapObjective.counts is None  # not edge-sampled: an attack is one chunk


def test_an_objective_without_fit_loss_refuses_live():
    Objective._no_live(None)
    with pytest.raises(ValueError, match="fit_loss"):
        Objective._no_live(object())
