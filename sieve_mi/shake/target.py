"""A pass-rate target (``[shake] target``): the solve's loop closed by shake trials.

After the solve, every A is shaken on its plate (:func:`~sieve_mi.shake.run.shake`). While an A
passes in less than ``target`` of its trials within ``duration``, the solver takes the next step
of :data:`PLAN`, each a whole solve with A's rotations fixed at the first solve's:

1. ``tolerance``: the first solve's B margin spent on ``[fabrication] tolerance``
   (:mod:`sieve_mi.game.tolerance`): the widest tolerance at which the verdict's attack and
   certify's search still block every B, bisected below the first solve's tolerance plus its
   least overhang found (skipped when that bracket is empty or no wider tolerance holds);
   with separate holes (``[layout] mode = "separate"``), each hole's own tolerance
   (``[[pass]] tolerance``, :func:`~sieve_mi.game.tolerance.widest_tolerances`): each A alone on
   its hole, against B's least overhang on that hole;
2. ``window``: the first solve's tolerance with ``[fabrication] window = "auto"``
   (:mod:`sieve_mi.game.window`): the widest turn ±δ at which every B is still blocked (the
   same margin spent on the turn instead);
3. ``sheet``: copies of the window's hole on a hexagonal sheet (``[fabrication] pattern``; the
   default plate is a tray, :data:`sieve_mi.geometry.pattern.TRAY_MM` square), turned by
   multiples of about 2δ so a part lying at any turn finds a copy it passes (:func:`sheet_turns`);
4. ``mirror``: that sheet with every other class of copies mirrored (``[fabrication] mirror``),
   so a flat part lying upside down (an S face up shows Ƨ) finds a copy of its silhouette too;
   each verdict and proof of the hole holds for its mirror image (turning a B over mirrors its
   projection).

The loop stops when every A meets the target (the trial's point estimate; its Wilson interval is
reported) or when no step is left; then the folder holds the best try (:func:`best_try`: every B
blocked, the highest least pass fraction, then the widest B margin) and report.json's
``shake.target`` lists every try (the trade-off of pass rate against B's margin: the least
overhang found over B, :mod:`sieve_mi.game.overhang`). A B's 0 is its proof where certify proved
it (no trials); a B not proved is shaken on the chosen plate, as its trials are then the only
evidence.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import replace

from sieve_mi.settings import ANGLES_MAX

__all__ = ["PLAN", "best_try", "next_step", "reach_target", "sheet_turns", "try_row"]

#: The steps tried in turn while an A is under its target.
PLAN = ("tolerance", "window", "sheet", "mirror")


def next_step(tries: list[dict], target: float, skip: tuple = ()) -> str:
    """What the loop does after ``tries``: ``"met"``, a step of :data:`PLAN`, or ``"stop"``.

    Parameters
    ----------
    tries : list of dict
        Each try's :func:`try_row` (only ``step``, ``blocked`` and ``pass`` are read: every B
        blocked, and per A its ``passed`` and ``trials``).
    target : float
        The fraction each A must reach, in (0, 1].
    skip : tuple of str
        Steps of :data:`PLAN` that do not apply (a window already "auto", a tolerance that
        cannot grow).

    Returns
    -------
    str
        ``"met"`` when the last try blocks every B and every A passed in at least ``target`` of
        its trials; ``"stop"`` when the first try lets a B through (no step blocks it better),
        when the sheet lets one through (its mirrored copies would too) or every step was
        taken; else the next step.
    """
    last = tries[-1]
    if last["blocked"] and all(a["passed"] >= target * a["trials"] for a in last["pass"]):
        return "met"
    if not tries[0]["blocked"]:
        return "stop"
    done = {t["step"] for t in tries}
    step = next((s for s in PLAN if s not in done and s not in skip), "stop")
    # mirrored copies block exactly what the sheet's copies block: never after a sheet that leaks
    return "stop" if step == "mirror" and not last["blocked"] else step


def best_try(tries: list[dict]) -> int:
    """The index of the best try: every B blocked first, then the least A pass fraction, then
    the least B margin found (wider is better; None counts as 0)."""

    def key(k: int):
        t = tries[k]
        least = min((a["passed"] / a["trials"] for a in t["pass"]), default=0.0)
        return (t["blocked"], least, t["b_margin"] or 0.0, -k)

    return max(range(len(tries)), key=key)


def sheet_turns(degrees: float) -> tuple | None:
    """The turns of a sheet's copies for a window of ±``degrees``: multiples of 360 / k degrees
    with k = ceil(360 / (2 δ)) (each turn of a part then lies within δ of a copy's), at most
    :data:`~sieve_mi.settings.ANGLES_MAX` of them; None (every copy as the hole) for k = 1."""
    k = ANGLES_MAX if degrees <= 0 else min(ANGLES_MAX, math.ceil(180.0 / degrees - 1e-9))
    return None if k <= 1 else tuple(round(i * 360.0 / k, 4) for i in range(k))


def try_row(step: str, report: dict, shaken: dict) -> dict:
    """One try's row of report.json's ``shake.target.tries``.

    Parameters
    ----------
    step : str
        ``"solved"`` or a step of :data:`PLAN`.
    report : dict
        The try's report.json.
    shaken : dict
        Its shake run (:func:`~sieve_mi.shake.run.shake`) of the A.

    Returns
    -------
    dict
        ``step``, ``blocked`` (the winner is A), ``window_deg``, ``holes``, ``turns``,
        ``mirror`` (the sheet's copies mirrored in turn), ``open_fraction``, ``plate_size``
        (width and height of the plate or sheet, scene units; None where report.json has
        none), ``pass`` (per A:
        ``name``, ``passed``, ``trials``, ``fraction``, ``ci95``, ``median_time_s``), ``tolerance``
        (``[fabrication] tolerance``, scene units), ``tolerances`` (per A its own
        ``[[pass]] tolerance``, None where it has none), ``b_margin`` (the least overhang found over
        B, :func:`_least_overhang`, scene units), ``b_margin_proved`` (the least
        ``margin.proved_at_least``; None where one is missing), ``b_proved`` (every B certified
        proved).
    """
    fab = report.get("fabrication", {})
    pattern, window = fab.get("pattern") or {}, fab.get("window") or {}
    margins = [b.get("margin") or {} for b in report["block"]]
    found = [_least_overhang(b) for b in report["block"]]
    proved = [m.get("proved_at_least") for m in margins]
    keys = ("name", "passed", "trials", "fraction", "ci95", "median_time_s")
    return {
        "step": step,
        "blocked": report["winner"] == "A",
        "tolerance": (report.get("settings") or {}).get("fabrication", {}).get("tolerance"),
        "tolerances": [p.get("tolerance") for p in report["pass"]],
        "window_deg": window.get("degrees", 0.0),
        "holes": pattern.get("count", 1),
        "turns": pattern.get("turns", [0.0]),
        "mirror": bool(pattern.get("mirror", False)),
        "open_fraction": pattern.get("open_fraction"),
        "plate_size": (pattern.get("plate_size") or fab.get("plate_size") or [None, None])[:2],
        "pass": [{k: s[k] for k in keys} for s in shaken["shapes"] if s["role"] == "A"],
        "b_margin": min(found) if found and None not in found else None,
        "b_margin_proved": min(proved) if proved and None not in proved else None,
        "b_proved": all(b.get("certified") == "proved" for b in report["block"]),
    }


def _least_overhang(block: dict) -> float | None:
    """A blocked B's least overhang found over poses (report.json's ``overhang.at_best_pose``,
    :mod:`sieve_mi.game.overhang`), else the protrusion of the verdict's pose
    (``margin.found_at_most``), which ranks poses by the area outside H first and can stick out
    much further: the letters' P overhangs by 1.63 mm on its side over the I's hole while its
    verdict pose sticks out 3.33 mm."""
    over = (block.get("overhang") or {}).get("at_best_pose")
    return over if over is not None else (block.get("margin") or {}).get("found_at_most")


def _scene_for(scene, step: str, quats, degrees: float, tolerance: float | None = None):
    """A copy of ``scene`` for ``step``: A's rotations fixed at ``quats`` (no search), and the
    ``tolerance`` given at the window ``degrees`` (``tolerance``), the window bisected (``window``) or the sheet of
    :func:`sheet_turns` at ``degrees`` (``sheet``, and ``mirror`` with every other class of
    copies mirrored)."""
    out, fab = copy.copy(scene), copy.copy(scene.fabrication)
    passes = [replace(e, rotation=[float(x) for x in q]) for e, q in zip(scene.passes, quats)]
    if step == "tolerance" and isinstance(tolerance, list):  # each separate hole its own
        passes = [replace(e, tolerance=float(t)) for e, t in zip(passes, tolerance)]
        fab.window = float(degrees)
    elif step == "tolerance":  # at the first solve's window
        fab.tolerance, fab.window = float(tolerance), float(degrees)
    elif step == "window":
        fab.window = "auto"
    else:
        fab.window = float(degrees)
        fab.pattern = "hex" if fab.pattern == "single" else fab.pattern
        fab.turns = sheet_turns(degrees)
        fab.mirror = step == "mirror" or fab.mirror
    object.__setattr__(out, "passes", passes)
    object.__setattr__(out, "fabrication", fab)
    return out


def _shake_names(folder: str, names: list, settings, progress: bool) -> dict:
    """Shake the shapes ``names`` of a solve's ``folder`` (nothing written)."""
    from sieve_mi.shake.inputs import from_folder, select
    from sieve_mi.shake.run import shake

    return shake(select(from_folder(folder, names), names), settings, progress=progress)


def _say(line: str, to_stderr: bool) -> None:
    print(line, file=sys.stderr if to_stderr else sys.stdout, flush=True)


def _tell(k: int, row: dict, target: float, to_stderr: bool) -> None:
    """One line per try: its step, window, holes and each A's pass count against the target."""
    parts = [f"{a['name']} {a['passed']}/{a['trials']} ({100 * a['fraction']:.1f} %)"
             for a in row["pass"]]  # fmt: skip
    where = f"±{row['window_deg']:g}°, {row['holes']} hole{'s' * (row['holes'] != 1)}"
    if None not in row.get("tolerances", [None]):  # each hole its own
        where = "tolerances " + "/".join(f"{t:g}" for t in row["tolerances"]) + ", " + where
    elif row.get("tolerance") is not None:
        where = f"tolerance {row['tolerance']:g}, " + where
    if None not in row.get("plate_size", [None]):  # the tray a shaken part must search
        where += " on {:.4g} x {:.4g}".format(*row["plate_size"])
    where += ", every other class mirrored" if row.get("mirror") else ""
    _say(f"target {100 * target:g} %: try {k} ({row['step']}; {where}): " + ", ".join(parts)
         + ("" if row["blocked"] else "; a B passes"), to_stderr)  # fmt: skip


def reach_target(scene, result, out_dir: str, settings, flags: dict) -> dict:
    """Shake the solved ``result`` (saved in ``out_dir``) and take the steps of :data:`PLAN`
    until every A meets ``scene.shake.target`` (module docstring).

    Parameters
    ----------
    scene : Scene
    result : sieve_mi.api.Result
        The first solve, saved in ``out_dir``.
    out_dir : str
    settings : ShakeSettings
    flags : dict
        ``variant``, ``seed``, ``quiet``, ``to_stderr`` (results on stderr: ``--json``),
        ``figure``, ``animation`` (the saves of the later tries).

    Returns
    -------
    dict
        ``run`` (the chosen try's shake run, with the B certify did not prove), ``report`` (its
        report.json), ``met``, ``chosen`` (the try the folder holds) and ``tries`` (each try's
        :func:`try_row`); the folder holds the chosen try, its shake.json and shake.png.
    """
    from sieve_mi import api
    from sieve_mi.shake.inputs import read_report
    from sieve_mi.shake.outputs import add_to_folder

    target, progress, loud = scene.shake.target, not flags["quiet"], flags["to_stderr"]
    names = [s.name for s in result.pass_shapes]
    results, rows, shaken = [result], [], []
    fab = scene.fabrication
    skip = tuple(
        s for s, done in (("window", fab.window == "auto"), ("mirror", fab.mirror)) if done
    )
    step, bisection, widest = "solved", [], fab.tolerance
    while True:
        report = read_report(out_dir)[1]
        shaken.append(_shake_names(out_dir, names, settings, progress))
        rows.append(try_row(step, report, shaken[-1]))
        if step == "tolerance":
            rows[-1]["bisection"] = bisection
        _tell(len(rows) - 1, rows[-1], target, loud)
        step = next_step(rows, target, skip)
        if step == "tolerance":
            widest, bisection = _widest_tolerance(scene, result, rows[0], flags)
            if _no_wider(scene, widest):
                _say(f"target: no tolerance above {fab.tolerance:g} keeps every B blocked", loud)
                skip += ("tolerance",)
                step = next_step(rows, target, skip)
        if step in ("met", "stop"):
            break
        # the sheet lays the window's hole (the tolerance's try spends the margin otherwise)
        base = [r for r in rows if r["step"] != "tolerance"][-1]
        degrees = base["window_deg"] if base["blocked"] else 0.0
        if step == "tolerance":
            degrees = rows[0]["window_deg"]
        try_scene = _scene_for(scene, step, result.pass_quats, degrees, widest)
        results.append(api.solve(try_scene, variant=flags["variant"], seed=flags["seed"],
                                 progress=progress))  # fmt: skip
        results[-1].save(out_dir, figure=flags["figure"], animation=flags["animation"])
    chosen = len(rows) - 1 if step == "met" else best_try(rows)
    if chosen != len(rows) - 1:
        results[chosen].save(out_dir, figure=flags["figure"], animation=flags["animation"])
    report = read_report(out_dir)[1]
    run = _with_unproved(out_dir, report, shaken[chosen], settings, progress)
    add_to_folder(run, out_dir)
    return {"run": run, "report": report, "met": step == "met", "chosen": chosen, "tries": rows}


def _no_wider(scene, widest) -> bool:
    """Whether the tolerance step found nothing wider than the scene's (each hole's own)."""
    from sieve_mi.game.holes import hole_tolerances

    if isinstance(widest, list):
        return all(w <= t for w, t in zip(widest, hole_tolerances(scene)))
    return widest <= scene.fabrication.tolerance


def _widest_tolerance(scene, result, first: dict, flags: dict) -> tuple[float | list, list]:
    """The tolerance step's bisection (:func:`~sieve_mi.game.tolerance.widest_tolerance`) on the
    first solve ``result`` (its rotations, translations and window; ``first`` its
    :func:`try_row`): the widest tolerance and the tries; the scene's tolerance and no tries
    when the first try has no B margin. Several separate holes: each hole's widest
    (:func:`~sieve_mi.game.tolerance.widest_tolerances`, a list) and per hole its tries."""
    from sieve_mi.game.tolerance import widest_tolerance, widest_tolerances

    margin = first["b_margin"]
    if not first["blocked"] or margin is None or margin <= 0:
        return scene.fabrication.tolerance, []
    play = _scene_for(scene, "tolerance", result.pass_quats, first["window_deg"],
                      scene.fabrication.tolerance)  # fmt: skip
    seed = flags["seed"] if flags["seed"] is not None else scene.solver.seed
    if scene.layout.mode == "separate" and len(result.pass_shapes) > 1:
        return widest_tolerances(play, result.pass_shapes, result.block_shapes,
                                 result.pass_quats, seed or 0, not flags["quiet"])  # fmt: skip
    return widest_tolerance(play, result.pass_shapes, result.block_shapes, result.pass_quats,
                            result.pass_trans, margin, seed or 0, not flags["quiet"])  # fmt: skip


def _with_unproved(folder: str, report: dict, run: dict, settings, progress: bool) -> dict:
    """``run`` (the A's trials) with the trials of each B that certify did not prove."""
    names = [b["name"] for b in report["block"] if b.get("certified") != "proved"]
    if not names:
        return run
    more = _shake_names(folder, names, settings, progress)
    out = dict(run, shapes=run["shapes"] + more["shapes"])
    out["fidelity_ok"] = run["fidelity_ok"] and more["fidelity_ok"]
    out["warnings"] = run["warnings"] + more["warnings"]
    out["timings"] = {**run["timings"], "b_total_s": more["timings"]["total_s"]}
    return out
