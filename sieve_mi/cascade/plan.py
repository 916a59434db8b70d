"""Planning a cascade: which sieve holds which shapes, in which order.

The shapes are ordered coarsest first by their passage radius (:mod:`sieve_mi.cascade.size`).
Sieve k holds the k-th unit (a shape, or shapes that cannot be split) and passes every unit
below it. The games of the planned order are independent and run together; the first lost game
is replaced by its alternatives (hold another of the remaining units there), run together too.
When no unit can be held while the rest falls through, every pair of remaining units is played
both ways: a pair that neither way can split is *inseparable* and becomes one unit, and the
reason is measured (each one's best attempt on the other's best hole). Several shapes share a
tray only then.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sieve_mi.errors import SieveError

__all__ = ["Inseparable", "Plan", "Sieve", "flat", "plan_cascade", "won"]


@dataclass
class Sieve:
    """One accepted sieve: ``holds`` stay on it (their tray), ``passes`` fall through."""

    holds: list
    passes: list
    key: str
    record: dict


@dataclass
class Inseparable:
    """A pair that no sieve found can split, with the measured reason."""

    pair: tuple
    reason: str
    keys: list


@dataclass
class Plan:
    """The planned cascade: sieves from top to bottom and the bottom tray."""

    sieves: list
    bottom: list
    inseparable: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def trays(self) -> list:
        """Shape names per tray, top to bottom (the last tray is under the last sieve)."""
        return [list(s.holds) for s in self.sieves] + [list(self.bottom)]


def flat(units) -> list:
    """The names of a list of units, in order."""
    return [n for u in units for n in u]


def won(record: dict) -> bool:
    """Whether a game's sieve holds what it must hold and passes the rest."""
    return record["summary"]["winner"] == "A"


def plan_cascade(order: list, play_games, make_spec, *, parallel: bool = True) -> Plan:
    """Plan the cascade for shape names ``order`` (coarsest first).

    Parameters
    ----------
    order : list of str
    play_games : callable
        ``play_games(specs) -> {key: record}`` (a :class:`~sieve_mi.cascade.games.Runner`'s run).
    make_spec : callable
        ``make_spec(holds, passes) -> GameSpec``.
    parallel : bool
        Play each round's games together (speculatively, for parallel workers). When False, play
        them one at a time and stop at the first that decides the round: the planned games up
        to the first lost one, the alternatives up to the first won one.
    """
    if len(order) < 2:
        raise SieveError("a cascade needs at least two shapes")
    units = [[n] for n in order]
    plan = Plan(sieves=[], bottom=[])
    play = _together(play_games) if parallel else _one_by_one(play_games)
    while len(units) > 1:
        k = _accept_planned(units, plan, play, make_spec)
        units = units[k:]
        if len(units) == 1:
            break
        j = _alternative(units, play, make_spec)
        if j is not None:
            units.insert(0, units.pop(j))
            continue
        units = _merge_inseparable(units, plan, play_games, make_spec)
    plan.bottom = units[0]
    return plan


def _one_by_one(play_games):
    """A ``play(specs, stop)`` that plays the specs in order until ``stop(record)`` holds."""

    def play(specs, stop=None):
        records = {}
        for spec in specs:
            records.update(play_games([spec]))
            if stop is not None and stop(records[spec.key]):
                break
        return records

    return play


def _together(play_games):
    """A ``play(specs, stop)`` that plays all specs at once (``stop`` is not needed)."""

    def play(specs, stop=None):
        return play_games(specs)

    return play


def _accept_planned(units, plan, play, make_spec) -> int:
    """Play the planned order's games; accept the won ones from the top; return how many."""
    specs = [make_spec(units[k], flat(units[k + 1 :])) for k in range(len(units) - 1)]
    records = play(specs, stop=lambda r: not won(r))
    for k, spec in enumerate(specs):
        record = records.get(spec.key)
        if record is None or not won(record):
            return k
        plan.sieves.append(Sieve(units[k], flat(units[k + 1 :]), spec.key, record))
    return len(units) - 1


def _alternative(units, play, make_spec) -> int | None:
    """The first unit after the top one that a sieve can hold while the rest pass, or None."""
    specs = [make_spec(units[j], flat(units[:j] + units[j + 1 :])) for j in range(1, len(units))]
    records = play(specs, stop=won)
    for j, spec in enumerate(specs, start=1):
        if spec.key in records and won(records[spec.key]):
            return j
    return None


def _merge_inseparable(units, plan, play_games, make_spec) -> list:
    """Play every pair both ways; join inseparable pairs into one unit (or, if there is none,
    the top two units, with a warning)."""
    pairs = [(a, b) for a in range(len(units)) for b in range(len(units)) if a != b]
    specs = {(a, b): make_spec(units[a], units[b]) for a, b in pairs}
    records = play_games(list(specs.values()))
    parent = list(range(len(units)))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in pairs:
        if a < b and not won(records[specs[a, b].key]) and not won(records[specs[b, a].key]):
            parent[root(b)] = root(a)
            plan.inseparable.append(
                Inseparable(
                    ("+".join(units[a]), "+".join(units[b])),
                    _reason(units[a], units[b], records[specs[a, b].key], records[specs[b, a].key]),
                    [specs[a, b].key, specs[b, a].key],
                )
            )
    groups: dict = {}
    for i, u in enumerate(units):
        groups.setdefault(root(i), []).extend(u)
    merged = list(groups.values())
    if len(merged) == len(units):
        plan.warnings.append(
            f"no sieve found holds {'+'.join(units[0])} while {', '.join(flat(units[1:]))} pass, "
            f"though every pair can be split; {'+'.join(units[0])} and {'+'.join(units[1])} "
            "share a tray"
        )
        merged = [units[0] + units[1], *units[2:]]
    return merged


def _reason(a, b, a_held, b_held) -> str:
    """Why a and b cannot be split, from the two lost games (a held, b passing; and reverse)."""

    def escape(record, names):
        worst = [x for x in record["summary"]["block"] if x["name"] in names and not x["blocked"]]
        x = worst[0] if worst else record["summary"]["block"][0]
        return f"{x['name']} passes (beta {x['beta']:.4f}, protrusion {x['protrusion']:.3g})"

    return (
        f"on the best hole for {'+'.join(b)}, {escape(a_held, a)}; "
        f"on the best hole for {'+'.join(a)}, {escape(b_held, b)}"
    )
