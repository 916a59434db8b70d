"""A second chance for a lost search (``[solver] retries``): search A again from another seed.

The search plays on a raster and with short attacks, so a hole can look blocking there and still
let some B through in the verdict's long attack on the exact polygon. For a merged hole of several
A, :func:`sieve_mi.game.solver._merge_with_restarts` searches again (``[layout] restarts``); for a
single A and for separate holes, :func:`with_retries` does: while the verdict finds some B passing
(one that the feasibility test did not prove impossible to block), player A searches again from
the seed ``seed + k`` (generator ``numpy.random.default_rng([seed, k])``, as the merged restarts
derive theirs), the verdict judges that hole, and the better attempt is kept: more B blocked, then
the higher game value (the verdict's least β). It stops at the first attempt that blocks every B
it can, so a solve won at once costs nothing more. The verdict stays the exact one; the same scene
and seed give the same attempts, hence the same result.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["Attempt", "applies", "passing", "with_retries"]


@dataclass
class Attempt:
    """One search and its verdict (the solver's parts, kept together so the better is kept whole).

    Attributes
    ----------
    found : SearchOutcome
        Player A's choice (:class:`sieve_mi.game.solver.SearchOutcome`).
    play : Scene
        The scene the verdict played (its window a number).
    window : dict
        report.json's window record.
    judgement : Judgement
        The verdict (:class:`sieve_mi.game.verdict.Judgement`), a column per B.
    certified : list of Certification or None
        Per B, the proof made before the game (None elsewhere).
    sure : dict
        The B proved blocked before the game whose proof held on this hole.
    seed : int
        The seed of this attempt's search.
    """

    found: object
    play: object
    window: dict
    judgement: object
    certified: list
    sure: dict
    seed: int


def applies(scene, open_blocks: list) -> bool:
    """Whether ``[solver] retries`` can apply: some A is searched, some B is played, and the A are
    not merged into one hole (``[layout] restarts`` covers that)."""
    searched = any(e.rotation is None for e in scene.passes)
    merged = len(scene.passes) > 1 and scene.layout.mode == "merged"
    return scene.solver.retries > 0 and searched and bool(open_blocks) and not merged


def passing(attempt: Attempt, impossible=()) -> list[int]:
    """Indices of the B that pass the attempt's hole in its verdict (those in ``impossible``, which
    no hole can block, left out)."""
    blocked, skip = attempt.judgement.attack.blocked()[0], set(impossible)
    return [j for j, b in enumerate(blocked) if not b and j not in skip]


def _key(attempt: Attempt, impossible) -> tuple:
    """Order of attempts: more B blocked, then the higher game value (least β of the verdict)."""
    return (-len(passing(attempt, impossible)), _least(attempt, impossible))


def _least(attempt: Attempt, impossible) -> float:
    """The verdict's least β over the B that some hole can block."""
    beta, skip = attempt.judgement.attack.beta[0], set(impossible)
    return float(min((b for j, b in enumerate(beta) if j not in skip), default=np.nan))


def _record(attempt: Attempt, names: list[str], impossible, retry: int) -> dict:
    """report.json's ``retries`` entry of one attempt."""
    return {
        "retry": retry,
        "seed": attempt.seed,
        "search_value": None if np.isnan(attempt.found.value) else float(attempt.found.value),
        "passed": [names[j] for j in passing(attempt, impossible)],
        "min_beta": _least(attempt, impossible),
        "kept": False,
    }


def with_retries(
    first: Attempt,
    again: Callable[[int], Attempt],
    retries: int,
    names: list[str],
    impossible=(),
    progress: bool = True,
) -> tuple[Attempt, list[dict]]:
    """The first attempt, or up to ``retries`` more while the kept one lets some B through.

    Parameters
    ----------
    first : Attempt
        The solve's own search and verdict.
    again : callable
        ``again(k)`` runs the search from seed ``seed + k`` and its verdict (k = 1, 2, ...).
    retries : int
        ``[solver] retries``.
    names : list of str
        Each B's name (for the records and the message).
    impossible : collection of int
        B that no hole can block (the feasibility test's): they never ask for a retry.
    progress : bool
        Say each retry on stderr before its search's progress bar.

    Returns
    -------
    kept : Attempt
        The best attempt; its judgement's warnings say what the retries found.
    records : list of dict
        Per attempt (the first included), report.json's ``retries`` entries; empty when the first
        attempt blocked every B (no retry ran).
    """
    kept, records = first, []
    for k in range(1, retries + 1):
        lost = passing(kept, impossible)
        if not lost:
            break
        if not records:
            records.append(_record(first, names, impossible, 0))
        if progress:
            print(f"retry {k}: the hole let {', '.join(names[j] for j in lost)} through in the "
                  f"verdict; searching A again from seed {first.seed + k}", file=sys.stderr,
                  flush=True)  # fmt: skip
        got = again(k)
        records.append(_record(got, names, impossible, k))
        if _key(got, impossible) > _key(kept, impossible):
            kept = got
    if records:
        chosen = next(r for r in records if r["seed"] == kept.seed)
        chosen["kept"] = True
        kept.judgement.warnings.append(_message(records, chosen))
    return kept, records


def _message(records: list[dict], chosen: dict) -> str:
    """The console's and report.json's line on the retries."""
    first, tries = records[0], len(records) - 1
    said = (f"the first search's hole let {', '.join(first['passed'])} through in the verdict "
            f"(least β {first['min_beta']:.4g}); {tries} more search{'es' * (tries > 1)} "
            "([solver] retries)")  # fmt: skip
    if chosen is first:
        return f"{said} did no better: the first hole kept"
    verdict = (f"lets {', '.join(chosen['passed'])} through" if chosen["passed"] else
               "blocks every B")  # fmt: skip
    least = f"least β {chosen['min_beta']:.4g}"
    return f"{said}: the one from seed {chosen['seed']} {verdict} ({least}): kept"
