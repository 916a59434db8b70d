"""Planning a cascade: which sieve holds which shapes, in which order — planned before played.

Sieve k holds one unit (a shape, or shapes that cannot be split) and passes every unit below
it. Going down, each sieve is decided in three steps, the cheap ones first:

1. **Rules** (no game). A hold that an exact rule shows hopeless (the held shape passes every
   hole that one of the passing shapes passes: :mod:`sieve_mi.cascade.rules`) is never played.
   The units left are the *candidates*; often there is one (eight euro coins: at every sieve
   but one). With none, the remaining units are split pairwise (step 4).
2. **Ranking** (no game). The candidates are ordered by a guess of their margin from all three
   canonical extents (:func:`sieve_mi.geometry.size.predicted_margin`): the 5 cent coin (1.5 mm
   wider) before the 10 cent coin (0.26 mm thicker) over the 10, 2 and 1 cent coins. Ties keep
   the base order (passage radius, coarsest first).
3. **Screening games**. Where several candidates remain, each is played in that order at
   reduced settings (:mod:`sieve_mi.cascade.stages`), and the first that wins is planned (the
   first by rank if none does). A screening game only picks; it never rules a hold out.

The sieves so planned down to the last tray are then played as **full games** (the mixture's
settings): they are the cascade. With parallel workers they run together; serially one by one
until one is lost. A lost full game marks that hold lost at that sieve, and the cascade is
planned again from there (the next candidate).

4. **Inseparable units.** When no unit can be held while the rest falls through, every pair is
   decided both ways, by a rule or a full game: a pair that neither way can split is
   *inseparable* and becomes one unit, with the reason (the rule's, or each one's best attempt on
   the other's best hole). Several shapes share a tray only then.

Every decision is recorded in :attr:`Plan.levels` (``cascade.json``'s ``levels``): the shapes
at that sieve, the holds ruled out and why, the candidates with their predicted margins, the
screening games, the choice, and its full game.
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
    """A pair that no sieve found can split, with the reason (measured in games, or a rule's)
    and the keys of the games that decided it (none where the rules did)."""

    pair: tuple
    reason: str
    keys: list


@dataclass
class Plan:
    """The planned cascade: sieves from top to bottom and the bottom tray; ``levels``: every
    decision, in order (see the module docstring)."""

    sieves: list
    bottom: list
    inseparable: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    levels: list = field(default_factory=list)

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


def plan_cascade(
    order: list,
    play_games,
    make_spec,
    *,
    parallel: bool = True,
    screen_spec=None,
    hopeless=None,
    margin=None,
) -> Plan:
    """Plan the cascade for shape names ``order`` (coarsest first).

    Parameters
    ----------
    order : list of str
        The base order: ties of ``margin`` and the order of shared trays follow it.
    play_games : callable
        ``play_games(specs) -> {key: record}`` (a :class:`~sieve_mi.cascade.games.Runner`'s run).
    make_spec : callable
        ``make_spec(holds, passes) -> GameSpec``: a full game, whose verdict is the sieve's.
    parallel : bool
        Play each batch of games together (speculatively, for parallel workers). When False, play
        them one at a time and stop at the first that decides: the screening games of a sieve up
        to the first won one, the full games of the planned sieves up to the first lost one.
    screen_spec : callable, optional
        ``screen_spec(holds, passes) -> GameSpec`` at reduced settings: where several units may be
        held at a sieve, they are screened (in ``margin`` order) and the first that wins is
        planned; the full game still decides. None: no screening.
    hopeless : callable, optional
        ``hopeless(holds, passes) -> dict or None``: an exact reason (``"reason"``) why no sieve
        holds ``holds`` while ``passes`` fall through (:meth:`sieve_mi.cascade.rules.Rules.hopeless`);
        such a hold is never played.
    margin : callable, optional
        ``margin(holds, passes) -> float``: larger first (a guess; it only orders candidates).
    """
    if len(order) < 2:
        raise SieveError("a cascade needs at least two shapes")
    planner = _Planner(play_games, make_spec, screen_spec, hopeless, margin, parallel)
    units = [[n] for n in order]
    while len(units) > 1:
        if not planner.candidates(units)[0]:
            units = _merge_inseparable(units, planner)
            continue
        units = planner.verify(planner.path(units))
    planner.plan.bottom = units[0]
    return planner.plan


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
        return play_games(specs) if specs else {}

    return play


def _rest(units: list, unit: list) -> list:
    """The units other than ``unit``, in order."""
    return [u for u in units if u is not unit]


class _Planner:
    """The planner's state: the games' players, the holds lost in full games, the plan so far."""

    def __init__(self, play_games, make_spec, screen_spec, hopeless, margin, parallel):
        self.play_games, self.make_spec, self.screen_spec = play_games, make_spec, screen_spec
        self.hopeless = hopeless or (lambda holds, passes: None)
        self.margin = margin
        self.play = _together(play_games) if parallel else _one_by_one(play_games)
        self.lost: dict = {}  # frozenset of the level's shapes -> {(held unit, full game key)}
        self.screened: dict = {}  # screening game key -> record
        self.plan = Plan(sieves=[], bottom=[])

    def candidates(self, units: list) -> tuple[list, list, list]:
        """The units that a sieve above ``units`` may hold, most promising first, and why the
        others may not: (candidates, ruled out by a rule, lost in a full game)."""
        level = frozenset(flat(units))
        lost_here = dict(self.lost.get(level, ()))
        cands, ruled, lost = [], [], []
        for u in units:
            why = self.hopeless(list(u), flat(_rest(units, u)))
            if why is not None:
                ruled.append(why)
            elif tuple(u) in lost_here:
                lost.append({"holds": list(u), "game": lost_here[tuple(u)]})
            else:
                cands.append(u)
        if self.margin is not None:
            score = {id(u): self.margin(list(u), flat(_rest(units, u))) for u in cands}
            cands.sort(key=lambda u: -score[id(u)])  # stable: ties keep the base order
        return cands, ruled, lost

    def choose(self, units: list) -> tuple[list, dict]:
        """The unit planned above ``units``: the only candidate, else the first (by margin) that
        wins its screening game, else the first by margin; and the decision, appended to
        ``plan.levels``."""
        cands, ruled, lost = self.candidates(units)
        entry = {"shapes": flat(units), "ruled_out": ruled, "lost": lost}
        if self.margin is not None:
            entry["candidates"] = [
                {"holds": list(u), "predicted_margin": self.margin(list(u), flat(_rest(units, u)))}
                for u in cands
            ]
        chosen, how = cands[0], "only candidate" if len(cands) == 1 else "first by margin"
        if len(cands) > 1 and self.screen_spec is not None:
            specs = [self.screen_spec(list(u), flat(_rest(units, u))) for u in cands]
            records = self._screen(specs)
            entry["screening"] = [
                {"holds": list(u), "game": sp.key, "winner": records[sp.key]["summary"]["winner"]}
                for u, sp in zip(cands, specs)
                if sp.key in records
            ]
            winners = [
                u for u, sp in zip(cands, specs) if sp.key in records and won(records[sp.key])
            ]
            if winners:
                chosen, how = winners[0], "won its screening game"
            else:
                how = "first by margin (no screening game won)"
        entry["chosen"], entry["by"] = list(chosen), how
        self.plan.levels.append(entry)
        return chosen, entry

    def _screen(self, specs: list) -> dict:
        """Screening games, each played once per run (stopping at the first won one when
        serial)."""
        todo = [s for s in specs if s.key not in self.screened]
        if any(won(self.screened[s.key]) for s in specs if s.key in self.screened):
            todo = []
        self.screened.update(self.play(todo, stop=won))
        return {s.key: self.screened[s.key] for s in specs if s.key in self.screened}

    def path(self, units: list) -> list:
        """The planned sieves from ``units`` down: (units at that sieve, held unit, decision)
        triples, until one unit is left or no unit can be held."""
        steps = []
        while len(units) > 1 and self.candidates(units)[0]:
            held, entry = self.choose(units)
            steps.append((units, held, entry))
            units = _rest(units, held)
        return steps

    def verify(self, steps: list) -> list:
        """Play the planned sieves' full games; accept them from the top while won. Returns the
        units left: below the last accepted sieve, or at the first lost one (re-planned)."""
        specs = [self.make_spec(list(held), flat(_rest(units, held))) for units, held, _ in steps]
        records = self.play(specs, stop=lambda r: not won(r))
        for (_, _, entry), spec in zip(steps, specs):
            if spec.key in records:
                entry["full"] = {"game": spec.key, "winner": records[spec.key]["summary"]["winner"]}
            else:
                entry["full"] = "not played: a full game above it was lost"
        for (units, held, _), spec in zip(steps, specs):
            if not won(records[spec.key]):
                level = frozenset(flat(units))
                self.lost.setdefault(level, {})[tuple(held)] = spec.key
                return units
            rest = flat(_rest(units, held))
            self.plan.sieves.append(Sieve(list(held), rest, spec.key, records[spec.key]))
        units, held, _ = steps[-1]
        return _rest(units, held)


def _merge_inseparable(units: list, planner: _Planner) -> list:
    """Every pair both ways: a rule or a full game each. Join inseparable pairs into one unit
    (or, if there is none, the top two units, with a warning)."""
    plan = planner.plan
    pairs = [(a, b) for a in range(len(units)) for b in range(len(units)) if a != b]
    ruled = {(a, b): planner.hopeless(list(units[a]), list(units[b])) for a, b in pairs}
    specs = {
        p: planner.make_spec(list(units[p[0]]), list(units[p[1]])) for p in pairs if not ruled[p]
    }
    records = planner.play_games(list(specs.values())) if specs else {}
    outcome = {p: ruled[p] or records[specs[p].key] for p in pairs}
    parent = list(range(len(units)))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in pairs:
        if a < b and not _split(outcome[a, b]) and not _split(outcome[b, a]):
            parent[root(b)] = root(a)
            plan.inseparable.append(
                Inseparable(
                    ("+".join(units[a]), "+".join(units[b])),
                    _reason(units[a], units[b], outcome[a, b], outcome[b, a]),
                    [specs[p].key for p in ((a, b), (b, a)) if p in specs],
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


def _split(outcome: dict) -> bool:
    """Whether a pair's direction can be split: a won game (a ruling never can)."""
    return "summary" in outcome and won(outcome)


def _reason(a, b, a_held, b_held) -> str:
    """Why a and b cannot be split, from the two directions (a held, b passing; and reverse):
    each a lost game or a rule's reason."""

    def side(outcome, names, other):
        if "summary" not in outcome:
            return outcome["reason"] + " (ruled out before any game)"
        block = outcome["summary"]["block"]
        worst = [x for x in block if x["name"] in names and not x["blocked"]]
        x = worst[0] if worst else block[0]
        return (
            f"on the best hole for {'+'.join(other)}, {x['name']} passes "
            f"(beta {x['beta']:.4f}, protrusion {x['protrusion']:.3g})"
        )

    return f"{side(a_held, a, b)}; {side(b_held, b, a)}"
