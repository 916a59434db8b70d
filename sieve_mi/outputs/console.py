"""What sieve-mi prints on the terminal: the result tables and summary lines of solve and check.

One idea: plain text for a person reading a terminal, built from what the run wrote (report.json's
dict for ``solve``, :class:`~sieve_mi.game.check.CheckReport` for ``check``), never computed anew.
``solve`` prints :func:`summary_table` (one row per shape, each A's pass pose in words
(:func:`pose_lines`) and each B's margins (:func:`margin_lines`), then the winner, the time per stage
(:func:`stage_line`), the memory (:func:`memory_line`), a thin plate's caveat
(:func:`sheet_line`) and advice for merged holes (:func:`merge_hint`)); ``check`` prints
:func:`check_summary`. ``shake`` prints its own table (:func:`sieve_mi.shake.outputs.summary`):
its report's fields are defined above this package, in :mod:`sieve_mi.shake`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sieve_mi.game.check import CheckReport

__all__ = [
    "STAGES",
    "certified_word",
    "check_summary",
    "margin_lines",
    "memory_line",
    "merge_hint",
    "pattern_line",
    "pose_lines",
    "rest_lines",
    "section_line",
    "sheet_line",
    "stage_line",
    "summary_table",
]


def summary_table(report: dict) -> str:
    """A short plain-text table of the result, one row per shape."""
    units = report["units"]
    proofs = any("certified" in b for b in report["block"])
    rows = [("role", "shape", "beta", f"protrusion ({units})", "result")]
    rows[0] += ("certified",) if proofs else ()
    thin = any(b.get("thin_plate", {}).get("status", "safe") != "safe" for b in report["block"])
    rows[0] += ("thin plate",) if thin else ()
    for p in report["pass"]:
        rows.append(("pass", p["name"], "-", "-", "passes (part of the hole)"))
        rows[-1] += ("-",) if proofs else ()
        rows[-1] += ("-",) if thin else ()
    for b in report["block"]:
        rows.append(
            (
                "block",
                b["name"],
                f"{b.get('beta', b.get('loss')):.4f}",  # reports before 'beta' say 'loss'
                f"{b['protrusion']:.3f}",
                "blocked" if b["blocked"] else "PASSES",
            )
        )
        if proofs:
            rows[-1] += (_certified_cell(b),)
        if thin:
            rows[-1] += (_thin_cell(b),)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    below = pose_lines(report) + margin_lines(report)
    lines += [""] + below if below else []
    t = report["timings"]
    lines.append("")
    lines.append(
        f"winner: {report['winner']}   search {t.get('search_s', 0):.1f} s, verdict {t.get('verdict_s', 0):.1f} s, "
        f"pixel size {report['pixel_size']:.4g} {units}"
    )
    if "total_s" in t:
        lines.append(stage_line(t))
    memory = memory_line(report)
    if memory:
        lines.append(memory)
    window = report.get("fabrication", {}).get("window")
    if window:
        tries = f", {len(window['bisection'])} verdicts" if "bisection" in window else ""
        lines.append(f"window: ±{window['degrees']:.3g}° ({window['mode']}{tries})")
    plate = sheet_line(report)
    if plate:
        lines.append(plate)
    perforated = pattern_line(report)
    if perforated:
        lines.append(perforated)
    lines += rest_lines(report)
    hint = merge_hint(report)
    if hint:
        lines.append(hint)
    return "\n".join(lines)


def pose_lines(report: dict) -> list[str]:
    """Per A with a ``pose`` entry (report.json's ``pass[i].pose``), its pass pose in words
    (:func:`~sieve_mi.geometry.pose_words.pose_sentence`): ``1x2: passes end on (standing on its
    short end): its 15.8 mm extent upright; 0.0° from resting end on (about 16 % of random drops
    settle end on)``."""
    from sieve_mi.geometry.pose_words import pose_sentence

    u = report["units"]
    return [
        f"{p['name']}: passes {pose_sentence(p['pose'], u)}" for p in report["pass"] if "pose" in p
    ]


def margin_lines(report: dict) -> list[str]:
    """Per blocked B with an ``overhang`` entry (:mod:`sieve_mi.game.overhang`), a maker's line:
    ``letter_R: blocked (proved); overhangs the hole by ≥ 0.80 mm in every pose, 1.60 mm at its
    best pose``. The table's protrusion is at the pose with the least area outside H; these
    lengths are the least overhang over poses (found on the exact polygon) and its proved bound.
    """
    out = []
    for b in report["block"]:
        o = b.get("overhang")
        if o is not None:
            out.append(f"{b['name']}: blocked ({_blocked_by(b, o)}); {o['text']}")
    return out


def _blocked_by(block: dict, overhang: dict) -> str:
    """How a blocked B's block rests: ``proved``, ``proved by a ball inside it``, ``proved for
    straight passage only`` (a plate thinner than B) or ``not proved``."""
    c = block.get("certification") or {}
    if block.get("certified") == "proved":
        return "proved"
    if overhang.get("proof") == "ball" and (overhang.get("proved_at_least") or 0.0) > 0:
        return "proved by a ball inside it"
    if c.get("straight") == "proved":
        return "proved for straight passage only"
    return "not proved"


#: report.json's stage timings, in the order they run, with the console's labels.
STAGES = (
    ("startup_s", "startup"), ("init_s", "init"), ("load_s", "load"), ("screen_s", "screen"),
    ("search_s", "search"), ("window_s", "window"),
    ("verdict_s", "verdict"), ("certify_s", "certify"), ("thin_s", "thin plate"),
    ("margins_s", "margins"),
    ("images_s", "images"),
    ("fabrication_s", "plate"), ("figure_s", "figure"), ("passage_s", "passage"),
    ("animation_s", "gif"), ("page_s", "page"),
)  # fmt: skip


def memory_line(report: dict) -> str | None:
    """``memory: peak 0.72 GB (search 0.72, verdict 0.57, ...)`` from report.json, or None."""
    mem = report.get("memory")
    if not mem:
        return None
    stages = ", ".join(f"{k} {v:.2f}" for k, v in mem["stages_gb"].items() if v >= 0.005)
    return f"memory: peak {mem['peak_gb']:.2f} GB ({stages})"


def stage_line(timings: dict) -> str:
    """``time: 12.3 s = search 4.1 + verdict 3.2 + ...`` from report.json's timings."""
    parts = [f"{label} {timings[key]:.1f}" for key, label in STAGES if timings.get(key, 0) >= 0.05]
    return f"time: {timings['total_s']:.1f} s = " + " + ".join(parts) + " s"


def pattern_line(report: dict) -> str | None:
    """``sheet: hex, 68 holes on 100 x 100 mm (pitch 11.2 mm, web >= 1.2 mm), 53.3 % open`` from
    report.json's ``fabrication.pattern``; None for a single hole."""
    p = report.get("fabrication", {}).get("pattern")
    if p is None:
        return None
    u = report["units"]
    w, h = p["plate_size"]
    turns = (
        "" if len(p["turns"]) < 2 else ", turned " + "/".join(f"{t:g}" for t in p["turns"]) + "°"
    )
    return (f"sheet: {p['kind']}, {p['count']} holes on {w:g} x {h:g} {u} (pitch "
            f"{p['pitch'][0]:.4g} {u}, web >= {p['web']:g} {u}{turns}), "
            f"{100 * p['open_fraction']:.1f} % open")  # fmt: skip


def rest_lines(report: dict) -> list[str]:
    """Per A that ``[solver] rest_poses`` chose for (report.json's ``pass[i].rest.preferred``,
    :mod:`sieve_mi.game.rest`), one line: ``1x2: passes on its side, 0.0° from a resting pose
    (17 % of drops settle on that face), chosen over the search's end on, 0.0° from resting
    (7 %) by [solver] rest_poses``; empty without the setting."""
    out = []
    for p in report["pass"]:
        rest = p.get("rest") or {}
        pref = rest.get("preferred")
        if pref is None:
            continue
        head = (f"{p['name']}: passes {rest['position']}, {rest['angle_deg']:.1f}° from a resting "
                f"pose ({100 * rest['share']:.0f} % of drops settle on that face)")  # fmt: skip
        search = pref["search"]
        if pref["chosen"] == "rest pose":
            out.append(f"{head}, chosen over the search's {search['position']}, "
                       f"{search['angle_deg']:.1f}° from resting ({100 * search['share']:.0f} %) "
                       "by [solver] rest_poses")  # fmt: skip
        else:
            out.append(f"{head}: the search's own; no likelier resting pose blocks every B")
    return out


def sheet_line(report: dict) -> str | None:
    """``plate: 2 mm thick, not proved (safe: 28.4 mm) ...`` when the plate is thinner than the
    safe thickness (:mod:`sieve_mi.game.sheet`); on a proved plate, the B whose slab-section
    proofs failed (:func:`section_line`), else None."""
    sheet = report.get("fabrication", {}).get("sheet")
    if sheet is None:
        return None
    if sheet["proved"]:
        return section_line(report)
    u = report["units"]
    head = f"plate: {sheet['thickness']:g} {u} thick"
    if sheet["mode"] == "thinnest":
        head += f", the thinnest of {len(sheet['bisection'])} tried where no B was found to pass"
    return (
        head
        + f"; not proved (a motion search), the proved plate is {sheet['safe_thickness']:g} {u}"
    )


def section_line(report: dict) -> str | None:
    """``plate: 42.2 mm thick, proved by the blocks' diameters; no slab-section proof at (or
    below) 40.1 mm for letter_R ...; below the proofs: letter_R a passage at 1.2 mm ...``, or
    None when every B's section proof reached the printable minimum."""
    u, failed = report["units"], []
    for b in report["block"]:
        c = b.get("certification")
        bracket = ((c or {}).get("section") or {}).get("bracket") if isinstance(c, dict) else None
        if bracket and bracket.get("proved") is None and bracket.get("unproved") is not None:
            failed.append(f"{bracket['unproved']:g} {u} for {b['name']}")
    sheet = report["fabrication"]["sheet"]
    gaps = sheet.get("bracket") or []
    if not failed and not gaps:
        return None
    line = f"plate: {sheet['thickness']:g} {u} thick"
    if failed:
        line += (", proved by the blocks' diameters; no slab-section proof at (or below) "
                 f"{', '.join(failed)} within [verdict] section_budget")  # fmt: skip
    else:
        line += ", the thinnest proved"
    if gaps:
        line += "; below the proofs: " + "; ".join(_gap_words(g, u) for g in gaps)
    return line


def _gap_words(gap: dict, u: str) -> str:
    """One B's bracket in words: where its proof stopped and what the motion search found."""
    head = f"{gap['name']} unproved at {gap['unproved']:g} {u}"
    if gap["passage"] is not None:
        return head + f", a verified passage at {gap['passage']:g} {u}"
    tried = ", ".join(f"{t:g}" for t in gap["no_passage_found"])
    return head + f", no passage found at {tried} {u} (a motion search, a heuristic)"


def _thin_cell(block: dict) -> str:
    """The console's 'thin plate' cell of one B: safe by diameter, passage or none found."""
    t = block.get("thin_plate")
    if t is None:
        return "-"
    if t["status"] == "safe":
        return f"safe ({t.get('by', 'diameter')})"
    if t["status"] == "not covered":  # a B of several bodies on a perforated sheet
        return "not covered (several bodies)"
    return f"{t['status']} ({t['seconds']:.1f} s)"


def certified_word(block: dict) -> str:
    """A B's ``certified`` answer in a word or three: ``proved``, ``passage``, ``undecided``, or
    ``proved by section`` where its slab-section proof alone proves it (report.json:
    ``"certified": "proved"`` beside ``"straight": "undecided"``: the straight search left cells
    open, so nothing says "100 % excluded"); ``-`` when it was not certified."""
    c = block.get("certification") or {}
    if block.get("certified") == "proved" and c.get("straight") == "undecided":
        return "proved by section"
    return block.get("certified", "-")


def _certified_cell(block: dict) -> str:
    """The console's 'certified' cell of one B: the status and what it rests on."""
    from sieve_mi.certify.certificate import excluded_percent

    c = block.get("certification")
    if c is None:
        return "-"
    if c["status"] == "proved" and c.get("straight") == "undecided":  # the section alone
        return f"{certified_word(block)} ({c['seconds']:.1f} s)"
    if c["status"] == "undecided" and c.get("straight") == "proved":  # a thinner plate
        return f"straight only: plate thinner than B ({c['seconds']:.1f} s)"
    if c["status"] == "undecided":
        shown = excluded_percent(c["excluded_fraction"], False, 1)
        return f"undecided ({shown} % excluded, {c['seconds']:.0f} s)"
    return f"{c['status']} ({c['seconds']:.1f} s)"


def merge_hint(report: dict) -> str | None:
    """Advice when a merged hole of several pass shapes lets some B through but each shape alone did not."""
    passes = report["pass"]
    mode = report.get("settings", {}).get("layout", {}).get("mode", "merged")
    if report["winner"] != "B" or len(passes) < 2 or mode != "merged":
        return None
    alone = [p.get("alone_loss") for p in passes]
    if any(a is None or not a > 0 for a in alone):
        return None
    through = ", ".join(b["name"] for b in report["block"] if not b["blocked"])
    each = ", ".join(f"{p['name']} {a:.3f}" for p, a in zip(passes, alone))
    return (
        f"hint: the merged hole lets {through} through, but each pass shape alone blocked every block shape "
        f'(weakest loss: {each}); set [layout] mode = "separate" for a valid sieve, or try another --seed'
    )


def _check_pose_lines(pose: dict, u: str) -> list[str]:
    """:func:`check_summary`'s two lines on the pose of its result (``CheckReport.pose``): in
    words (:func:`~sieve_mi.geometry.pose_words.pose_sentence`), then as a rotation (one turn
    about an axis, and the quaternion; the Euler angles are in ``--json``)."""
    from sieve_mi.geometry.pose_words import pose_sentence

    head = "pass pose" if pose["of"] == "pass" else "best attempt's pose"
    axis = ", ".join(f"{a:.3f}" for a in pose["turn_axis"])
    q = ", ".join(f"{x:.4f}" for x in pose["quaternion"])
    return [
        f"{head}: {pose_sentence(pose, u)}",
        f"  rotation: {pose['turn_deg']:.1f}° about ({axis}); quaternion (w, x, y, z) ({q})",
    ]


def _check_thin_line(t: dict, u: str) -> str:
    """:func:`check_summary`'s line on the thin-plate answer."""
    note = t.get("plate", {}).get("note")
    head = (note + "\n" if note else "") + (
        f"plate {t['thickness']:.4g} {u} thick, part diameter {t['diameter']:.4g} {u}: "
    )
    if t["status"] == "safe":
        return head + f"safe (the verdict above holds on this plate; by its {t['by']})"
    if t["status"] == "passage":
        return head + (
            f"PASSES by tilting and turning ({t['method']}, verified, "
            f"min clearance {t['min_clearance']:.3g} {u}; motion in --json)"
        )
    return head + f"no passage found by a motion search of {t['seconds']:.1f} s (not a proof)"


def check_summary(rep: CheckReport) -> str:
    """Plain-text result of a check."""
    r, u = rep.result, rep.units
    holes = ", ".join(f"{h['area']:.4g} {u}²" for h in rep.holes)
    lines = [
        f"shape {rep.shape} against {rep.sieve}: {len(rep.holes)} hole(s) of area {holes}, pixel {rep.pixel_size:.4g} {u}",
        f"result: {'PASSES' if r.passes else 'blocked'}   beta {r.beta:.4f}   protrusion {r.protrusion:.3f} {u}   "
        f"({r.fitting_starts} start(s) fit)",
    ]
    if r.exact_outside_area is not None:
        lines.append(
            f"best pose, exact polygons: {r.exact_outside_area:.4g} {u}² of the shape's outline outside the hole"
        )
    if rep.pose is not None:
        lines += _check_pose_lines(rep.pose, u)
    if rep.fit_scale is not None:
        lo, hi = rep.fit_bracket
        if rep.fit_scale == 0:
            lines.append(f"fit scale: below {hi:.4g} (blocked at every scale tried)")
        elif math.isinf(hi):
            lines.append(f"fit scale: at least {lo:.4g} (passed at every scale tried)")
        else:
            lines.append(
                f"fit scale: {rep.fit_scale:.4g}  (passes at {lo:.4g}, blocked at {hi:.4g})"
            )
    t = rep.thin_plate
    if t is not None:
        lines.append(_check_thin_line(t, u))
    lines.append(f"{len(rep.evaluations)} evaluation(s) in {rep.seconds:.1f} s")
    return "\n".join(lines)
