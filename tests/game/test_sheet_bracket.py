"""The passage side of a B's proof bracket (:func:`sieve_mi.game.sheet.passage_bracket`): which
plates are searched, in which order, with the motion search replaced by a known answer (a shape
that passes every plate up to 5 mm thick)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from sieve_mi.game.sheet import BRACKET_TRIES, passage_bracket


class _Known:
    """Searches whose answer is known: a passage on every plate at most ``limit`` thick."""

    def __init__(self, limit: float, n: int = 1):
        self.limit, self.todo, self.asked = limit, list(range(n)), []
        self.blocks = [SimpleNamespace(name=f"b{j}", hull=None) for j in range(n)]
        self.scene = SimpleNamespace(verdict=SimpleNamespace(thin_budget=1.0))

    def at_each(self, tries: dict) -> dict:
        self.asked.append(dict(tries))
        status = {j: "passage" if t <= self.limit else "no passage found" for j, t in tries.items()}
        return {j: SimpleNamespace(status=s) for j, s in status.items()}


def _certified(unproved: float, proved: float):
    section = {
        "status": "proved",
        "thickness": proved,
        "bracket": {"proved": proved, "unproved": unproved},
    }
    return SimpleNamespace(
        section=section, proved_section=section, method="cells", status="proved", straight="proved"
    )


@pytest.mark.parametrize(
    ("limit", "passage", "searched"),
    [
        (9.0, 8.0, [8.0]),  # passes where the proof stopped: the bracket is tight
        (5.0, 4.6, [8.0, 1.2, 4.6]),  # fails at 8, passes at 1.2, then halfway: 4.6 passes
        (3.0, 1.2, [8.0, 1.2, 4.6]),  # ... and halfway fails: the thickest passage is 1.2
        (1.0, None, [8.0, 1.2]),  # no passage even at the minimum: nothing more to search
    ],
)
def test_the_searches_bracket_the_thickest_passage(limit, passage, searched):
    known = _Known(limit)
    (gap,) = passage_bracket(known, [_certified(8.0, 10.0)], 1.2)
    assert [t for ask in known.asked for t in ask.values()] == searched
    assert len(searched) <= BRACKET_TRIES
    assert gap["passage"] == passage and gap["proved"] == 10.0 and gap["unproved"] == 8.0
    assert gap["no_passage_found"] == [t for t in searched if t != passage and t > limit]


def test_no_search_where_the_proof_reached_the_minimum_or_nothing_was_proved_by_cells():
    known = _Known(5.0, n=3)
    ball = SimpleNamespace(section=None, method="ball", status="proved", straight="proved")
    gaps = passage_bracket(known, [_certified(1.2, 2.0), ball, None], 1.2)
    assert gaps == [] and known.asked == []
