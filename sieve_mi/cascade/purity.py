"""Shake trials of a cascade (``sort --shake N``): in which tray each shape really ends.

The model: **independent shapes, no interaction between parts.** Trial ``i`` of a shape is one
part going down the cascade alone. It is dropped on the top sieve in a random pose and shaken
(:mod:`sieve_mi.shake`); if it falls through within the shaking time, it is dropped afresh (a
new random pose, independent of what happened above) on the next sieve, and so on. It ends on
the tray of the first sieve it does not pass (a part that escaped over the frame counts as not
passed, as in ``shake``), or in the bottom tray when it passed every sieve.

So each sieve is shaken with the trials that reach it: the top sieve with all N trials of every
shape, a lower one with the trials that passed every sieve above (a shape that no trial got past
some sieve is not shaken below it). Sieve k draws its drops from a seed derived from (seed, k)
(:func:`sieve_seed`), so the drops on different sieves are independent. A shape's fraction in
tray k, count / N with its 95 % Wilson interval, is then exactly the product of its pass
fractions on the sieves above times its block fraction on sieve k (the counts telescope).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

import numpy as np

from sieve_mi.cascade.mixture import Mixture
from sieve_mi.cascade.plan import Plan, flat
from sieve_mi.shake.geometry import part_from_mesh, plate_from_mesh
from sieve_mi.shake.run import engine_doc, motion_doc, shape_entry, trial_bar
from sieve_mi.shake.settings import ShakeSettings, metres_per_unit
from sieve_mi.shake.stats import wilson
from sieve_mi.telemetry import Run

__all__ = [
    "MODEL",
    "Stage",
    "purity_table",
    "shake_cascade",
    "shake_plan",
    "sieve_seed",
]

#: The model of a cascade's shake trials, in words (recorded in ``cascade.json``).
MODEL = (
    "independent shapes, no interaction between parts: each of the N parts of a shape goes down "
    "the cascade alone, dropped afresh in a random pose on each sieve it reaches and shaken for "
    "the set time; it stays on the tray of the first sieve it does not pass"
)


@dataclass
class Stage:
    """One sieve of a cascade to shake.

    Attributes
    ----------
    plate : trimesh.Trimesh
        The plate, scene units, holes along z.
    path : str
        Where it came from (for the output).
    holds, passes : list of str
        The shapes the sieve was designed to hold (its tray) and to let through.
    """

    plate: object
    path: str
    holds: list
    passes: list


def sieve_seed(seed: int, k: int) -> int:
    """The seed of sieve ``k``'s drops: 63 bits of the seed sequence (``seed``, ``k``).

    Examples
    --------
    >>> sieve_seed(0, 0) == sieve_seed(0, 0) != sieve_seed(0, 1)
    True
    """
    state = np.random.SeedSequence([seed, k]).generate_state(1, np.uint64)[0]
    return int(state >> np.uint64(1))


def _role(name: str, stage: Stage) -> str | None:
    """A shape's role on a sieve: A (designed to pass), B (to be held), None (from above)."""
    return "B" if name in stage.holds else "A" if name in stage.passes else None


def _shake_sieve(k, stage, parts, reaching, settings, unit_m, progress):
    """Shake sieve ``k`` with the trials ``reaching`` it (``{name: [trial, ...]}``).

    Returns
    -------
    (dict, dict)
        The sieve's entry of the output, and ``{name: [trial, ...]}`` of the trials that passed.
    """
    plate = plate_from_mesh(stage.plate, stage.path)
    here = replace(settings, seed=sieve_seed(settings.seed, k))
    arriving = [n for n in parts if reaching[n]]
    total = sum(len(reaching[n]) for n in arriving)
    bar = trial_bar(progress, total, desc=f"shake sieve {k + 1}")
    rows, passed = [], {n: [] for n in parts}
    try:
        for n in arriving:
            entry, _ = shape_entry(
                parts[n], _role(n, stage), None, plate, here, unit_m, bar, reaching[n]
            )
            times = entry.pop("pass_times_s")
            passed[n] = [i for i, t in zip(reaching[n], times) if t is not None]
            for key in ("file", "geometry", "warnings"):
                entry.pop(key)
            rows.append(entry)
    finally:
        bar.close()
    sieve = {
        "index": k,
        "holds": list(stage.holds),
        "passes": list(stage.passes),
        "seed": here.seed,
        "plate": {"file": stage.path, **plate.to_dict()},
        "shapes": rows,
    }
    return sieve, passed


def _tray_rows(names, ends, belongs, trays: int, n: int) -> tuple[list, list]:
    """Per shape: its count and fraction in each tray; per tray: parts and purity."""
    counts = {m: np.bincount(ends[m], minlength=trays) for m in names}
    shapes = [
        {
            "name": m,
            "belongs": belongs[m],
            "trays": [
                {"count": int(c), "fraction": int(c) / n, "ci95": list(wilson(int(c), n))}
                for c in counts[m]
            ],
        }
        for m in names
    ]
    rows = []
    for t in range(trays):
        here = sum(int(counts[m][t]) for m in names)
        own = sum(int(counts[m][t]) for m in names if belongs[m] == t)
        rows.append({"index": t, "parts": here, "purity": own / here if here else None})
    return shapes, rows


def shake_cascade(
    stages: list, meshes: dict, units: str, settings: ShakeSettings, progress: bool = True
) -> dict:
    """Shake the sieves of a cascade, top to bottom, with the parts that reach each one.

    Parameters
    ----------
    stages : list of Stage
        The sieves, top first; tray k is on sieve k, the last tray under the last sieve.
    meshes : dict of str to trimesh.Trimesh
        Every shape of the mixture by name (scene units), in the order of the trays.
    units : str
        The scene's length unit.
    settings : ShakeSettings
        ``trials`` parts of each shape go down the cascade (:data:`MODEL`).
    progress : bool
        Progress on stderr, a bar per sieve.

    Returns
    -------
    dict
        ``cascade.json``'s ``shake``: ``model``, ``trials``, ``settings`` (with ``units``),
        ``motion``, ``engine``, ``sieves`` (per sieve: ``seed``, ``plate``, and per arriving shape
        the counts, ``fraction`` passed, ``ci95``, ``median_time_s``, ``fidelity``), ``shapes``
        (per shape: ``belongs`` (its tray), ``trays`` (count, fraction, ``ci95`` in each tray),
        ``geometry``, ``warnings``), ``trays`` (``parts`` landing there, ``purity``), ``fidelity_ok``,
        ``timings`` (seconds).
    """
    unit_m, run = metres_per_unit(units), Run().start()
    with run.stage("geometry"):
        bound = settings.hausdorff_bound * 1e-3 / unit_m
        parts = {
            n: part_from_mesh(m, n, None, settings.coacd_threshold, bound=bound)
            for n, m in meshes.items()
        }
    reaching = {n: list(range(settings.trials)) for n in parts}
    ends = {n: np.full(settings.trials, len(stages)) for n in parts}
    sieves = []
    for k, stage in enumerate(stages):
        with run.stage(f"sieve_{k}"):
            sieve, passed = _shake_sieve(k, stage, parts, reaching, settings, unit_m, progress)
            for n in parts:
                ends[n][sorted(set(reaching[n]) - set(passed[n]))] = k
            sieves.append(sieve)
            reaching = passed
    belongs = {n: len(stages) for n in parts}
    belongs.update({n: k for k, s in enumerate(stages) for n in s.holds})
    shapes, trays = _tray_rows(list(parts), ends, belongs, len(stages) + 1, settings.trials)
    for row in shapes:
        part = parts[row["name"]]
        row.update(geometry=part.to_dict(), warnings=list(part.warnings))
    run.timings["total_s"] = run.elapsed()
    return {
        "model": MODEL,
        "trials": settings.trials,
        "settings": {**settings.to_dict(), "units": ShakeSettings.units()},
        "motion": motion_doc(settings),
        "engine": engine_doc(),
        "sieves": sieves,
        "shapes": shapes,
        "trays": trays,
        "fidelity_ok": all(r["fidelity"]["within_bound"] for s in sieves for r in s["shapes"]),
        "warnings": list(
            dict.fromkeys(
                f"sieve {s['index'] + 1}: {w}"
                for s in sieves
                for r in s["shapes"]
                for w in r.get("warnings", [])
            )
        ),
        "timings": run.timings,
    }


def shake_plan(
    plan: Plan, folders: dict, mixture: Mixture, settings: ShakeSettings, progress: bool = True
) -> dict:
    """Shake a planned cascade: each sieve's plate is its game's ``sieve.stl``.

    Parameters
    ----------
    plan : Plan
    folders : dict of str to str
        Every game's folder by key (:meth:`~sieve_mi.cascade.games.Engine.folders`).
    mixture : Mixture
        With its meshes loaded (:func:`~sieve_mi.cascade.sort.prepare`).
    settings : ShakeSettings
    progress : bool

    Returns
    -------
    dict
        :func:`shake_cascade`'s result; each plate's file is given relative to the cascade's
        folder (``games/<key>/sieve.stl``).
    """
    import trimesh

    stages = [
        Stage(
            trimesh.load(os.path.join(folders[s.key], "sieve.stl"), force="mesh"),
            f"games/{s.key}/sieve.stl",
            list(s.holds),
            list(s.passes),
        )
        for s in plan.sieves
    ]
    meshes = {}
    for name in flat(plan.trays):
        entry = mixture.shape(name)
        meshes[name] = entry.data.copy().apply_scale(entry.scale)
    return shake_cascade(stages, meshes, mixture.units, settings, progress)


def _cell(tray: dict, own: bool) -> str:
    lo, hi = tray["ci95"]
    return f"{'*' if own else ' '} {tray['fraction']:.3f} [{lo:.3f}, {hi:.3f}]"


def purity_table(shake: dict) -> str:
    """The shake trials of a cascade as text: the trays each shape ends in (``*``: its own), the
    trays' purity, then each sieve's pass fractions."""
    import textwrap

    st = shake["settings"]
    lines = [
        f"shake trials: {shake['trials']} parts of each shape, shaken up to {st['duration']:g} s "
        f"on each sieve (seed {st['seed']})",
        *textwrap.wrap(f"model: {shake['model']}", 100),
        f"{'shape':<16}" + "".join(f"  {f'tray {t + 1}':<22}" for t in range(len(shake["trays"]))),
    ]
    for s in shake["shapes"]:
        cells = [_cell(c, t == s["belongs"]) for t, c in enumerate(s["trays"])]
        lines.append(f"{s['name'][:16]:<16}" + "".join(f"{c:<24}" for c in cells))
    purity = ["-" if t["purity"] is None else f"{t['purity']:.3f}" for t in shake["trays"]]
    lines.append(f"{'purity':<16}" + "".join(f"  {p:<22}" for p in purity))
    lines.append(f"{'sieve':<6}{'shape':<16}{'designed':<11}{'passed':>9}  {'fraction':>8}  95 %")
    for sieve in shake["sieves"]:
        for r in sieve["shapes"]:
            designed = {"A": "to pass", "B": "to hold"}.get(r["role"], "from above")
            lo, hi = r["ci95"]
            lines.append(
                f"{sieve['index'] + 1:<6}{r['name'][:16]:<16}{designed:<11}"
                f"{r['passed']:>4}/{r['trials']:<4}  {r['fraction']:>8.3f}  [{lo:.3f}, {hi:.3f}]"
            )
    ok = "all held" if shake["fidelity_ok"] else "NOT all held"
    lines.append(
        "purity: the share of a tray's parts that belong there (equal numbers of each shape)"
    )
    lines.append(
        f"fidelity: resting sink under {shake['engine']['sink_bound_mm']} mm, penetration while "
        f"shaken within its bound, no engine warning: {ok}"
    )
    lines += [f"warning: {w}" for w in shake.get("warnings", [])]
    return "\n".join(line.rstrip() for line in lines)
