"""Shake outputs: ``shake.json``, ``shake.png`` (fraction passed against time) and a summary table.

Into a solve's folder the files go through :func:`sieve_mi.outputs.outdir.add_files`, the one
marker-checked way into an existing folder: the folder must carry sieve-mi's ``.sieve-mi`` marker
and hold nothing it does not list (checked before the trials, :func:`check_folder`, and again
before writing), each file is written atomically (a temporary file, then a rename) and listed in
the marker, so a later ``solve --out`` may still replace the folder. The "Shake trials" card goes
into ``report.html`` when there is one to put it in (the viewer places it,
:func:`sieve_mi.outputs.viewer.insert_card`); else the run says so in one line.
"""

from __future__ import annotations

import io
import json
import os

import numpy as np

from sieve_mi.outputs.outdir import add_files, check_addition, writing
from sieve_mi.outputs.viewer import insert_card
from sieve_mi.shake.stats import pass_curve

__all__ = [
    "CARD",
    "FILES",
    "ROLE_COLOURS",
    "TARGET_CARD",
    "add_to_folder",
    "check_folder",
    "html_section",
    "plot",
    "record",
    "report_entry",
    "shape_lines",
    "summary",
    "target_card",
    "to_json",
    "tradeoff_figure",
    "tradeoff_plot",
    "write_new_folder",
]

#: The files a shake run writes.
FILES = ("shake.json", "shake.png", "shake.gif")
#: Curve colour of each role: set A green, set B red, a part of unknown role blue.
ROLE_COLOURS = {"A": "#1a9850", "B": "#d73027", None: "#4575b4"}


def to_json(report: dict) -> str:
    """``shake.json``'s text (NaN written as null)."""
    return json.dumps(report, indent=2, default=lambda x: None) + "\n"


def plot(report: dict, path: str) -> None:
    """``shake.png``: the fraction of trials passed by each time, one curve per shape.

    Parameters
    ----------
    report : dict
        :func:`~sieve_mi.shake.run.shake`'s result.
    path : str or file
        The PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    duration = float(report["settings"]["duration"])
    grid = np.linspace(0.0, duration, 400)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for s in report["shapes"]:
        curve = pass_curve(s["pass_times_s"], s["trials"], grid)
        lo, hi = s["ci95"]
        label = (
            f"{s['name']} ({s['role'] or '?'}): {s['passed']}/{s['trials']} [{lo:.2f}, {hi:.2f}]"
        )
        colour = ROLE_COLOURS.get(s["role"], ROLE_COLOURS[None])
        ax.step(grid, curve, where="post", color=colour, label=label, lw=1.8)
    ax.set_xlim(0, duration)
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("shaking time (s)")
    ax.set_ylabel("fraction of trials passed")
    st = report["settings"]
    ax.set_title(
        f"{st['trials']} trials per shape, {st['amplitude']:g} mm at {st['frequency']:g} Hz, "
        f"seed {st['seed']}",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


def summary(report: dict) -> str:
    """A plain-text table: one line per shape, then the fidelity line."""
    rows = [
        f"{'shape':<16} {'role':<4} {'passed':>9} {'fraction':>8} {'95 % interval':>16} "
        f"{'median s':>8} {'hausdorff':>9} {'sink mm':>8}"
    ]
    for s in report["shapes"]:
        med = "-" if s["median_time_s"] is None else f"{s['median_time_s']:.2f}"
        over = "!" if s["geometry"].get("within_bound") is False else ""
        h = f"{s['geometry']['hausdorff']:.3f}{over}"
        lo, hi = s["ci95"]
        rows.append(
            f"{s['name'][:16]:<16} {s['role'] or '?':<4} {s['passed']:>4}/{s['trials']:<4} "
            f"{s['fraction']:>8.3f} {f'[{lo:.3f}, {hi:.3f}]':>16} {med:>8} "
            f"{h:>9} {s['fidelity']['sink_mm']:>8.4f}"
        )
    bound = report["engine"]["sink_bound_mm"]
    ok = "all held" if report["fidelity_ok"] else "NOT all held"
    rows.append(
        f"fidelity: resting sink under {bound} mm, penetration while shaken within its bound, "
        f"no engine warning: {ok}; hausdorff in {report['units']}"
        + (
            f" (!: over the bound of {report['settings']['hausdorff_bound']} mm)"
            if any(s["geometry"].get("within_bound") is False for s in report["shapes"])
            else ""
        )
    )
    rows += [f"warning: {w}" for w in report.get("warnings", [])]
    return "\n".join(rows)


#: What to do instead when ``shake DIR`` is given a folder sieve-mi did not write.
_HINT = "use shake --sieve PLATE PART... --out DIR instead"


def _contents(report: dict, clip: str | None = None) -> dict[str, bytes]:
    """``shake.json``, ``shake.png`` and (from the rendered ``clip``, where the run made it:
    its ``clip`` entry) ``shake.gif`` as bytes."""
    png = io.BytesIO()
    plot(report, png)
    contents = {"shake.json": to_json(report).encode("utf-8"), "shake.png": png.getvalue()}
    if clip is not None and "clip" in report:
        with open(clip, "rb") as fh:
            contents["shake.gif"] = fh.read()
    return contents


def check_folder(folder: str) -> str | None:
    """Check, before any trial, that shake may write into the solve folder ``folder``; touch
    nothing.

    Returns
    -------
    str or None
        A one-line note when ``report.html`` will not get the card (missing, unreadable, no
        place for it); None when it will.

    Raises
    ------
    SieveError
        The folder is refused (:func:`~sieve_mi.outputs.outdir.check_addition`: no marker, a file
        the marker does not list, not writable).
    """
    check_addition(folder, (*FILES, "report.html"), hint=_HINT)
    return insert_card(folder, CARD, "")[1]


def add_to_folder(report: dict, folder: str, clip: str | None = None) -> str | None:
    """Write ``shake.json`` and ``shake.png`` (and the rendered ``clip`` as ``shake.gif``) into a
    solve's output folder, put the card into its ``report.html``, and list them in its marker;
    without a clip, an earlier shake's ``shake.gif`` is removed (it showed other trials).

    Returns
    -------
    str or None
        :func:`check_folder`'s note when the page was not updated.

    Raises
    ------
    SieveError
        The folder is refused (one line; nothing written).
    """
    contents = _contents(report, clip)
    page, note = insert_card(folder, CARD, html_section(report, contents["shake.png"]))
    if page is not None:
        contents["report.html"] = page.encode("utf-8")
    add_files(folder, contents, hint=_HINT, drop=FILES)  # no clip now: an earlier shake.gif goes
    return note


def write_new_folder(report: dict, out_dir: str, inputs: list[str], clip: str | None = None):
    """``--out DIR`` of ``shake --sieve``: a fresh sieve-mi output folder (same rules as
    ``solve --out``) holding ``shake.json``, ``shake.png``, ``shake.gif`` (when ``clip`` is
    given) and ``report.json`` (= shake.json)."""
    contents = _contents(report, clip)
    contents["report.json"] = contents["shake.json"]
    with writing(out_dir, command="shake", inputs=inputs) as tmp:
        for name, data in contents.items():
            with open(os.path.join(tmp, name), "wb") as fh:
                fh.write(data)


#: The name of shake's card in report.html (:func:`sieve_mi.outputs.viewer.insert_card`).
CARD = "shake"


def html_section(report: dict, png: bytes) -> str:
    """report.html's "Shake trials" card (:data:`CARD`): the curves (inlined PNG), one row per
    shape, fidelity."""
    import base64
    from html import escape

    rows = ""
    for s in report["shapes"]:
        med = "-" if s["median_time_s"] is None else f"{s['median_time_s']:.2f}"
        rows += (
            f"<tr><td>{escape(s['name'])}</td><td>{escape(s['role'] or '?')}</td>"
            f"<td>{s['passed']} / {s['trials']}</td><td>{s['fraction']:.3f}</td>"
            f"<td>[{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}]</td><td>{med}</td>"
            f"<td>{s['geometry']['hausdorff']:.3f}</td><td>{s['fidelity']['sink_mm']:.4f}</td></tr>"
        )
    st = report["settings"]
    img = base64.b64encode(png).decode("ascii")
    items = "".join(f"<li>{escape(w)}</li>" for w in report.get("warnings", []))
    warnings = f"<ul>{items}</ul>" if items else ""
    return (
        '<section class="card wide" id="shake"><h2>Shake trials</h2>'
        f'<img alt="fraction passed against time" style="max-width:100%" '
        f'src="data:image/png;base64,{img}">'
        "<table><thead><tr><th>shape</th><th>set</th><th>passed</th><th>fraction</th>"
        "<th>95 % interval</th><th>median s</th>"
        f"<th>Hausdorff ({escape(report['units'])})</th><th>sink mm</th></tr></thead>"
        f"<tbody>{rows}</tbody></table>"
        f"<p>{st['trials']} trials per shape, {st['duration']:g} s each; plate shaken "
        f"{st['amplitude']:g} mm at {st['frequency']:g} Hz{_twist_words(st['twist'])}; "
        f"seed {st['seed']}. Fidelity (resting sink under "
        f"{report['engine']['sink_bound_mm']} mm, penetration while shaken within its bound, "
        f"no engine warning): {'held' if report['fidelity_ok'] else 'NOT held'}. "
        f"Details: shake.json.</p>{warnings}</section>"
    )


def _twist_words(twist: float) -> str:
    """The twist in the card's sentence: nothing when the plate does not twist."""
    return f" with a {twist:g} degree twist" if twist else ""


def report_entry(run: dict, report: dict) -> dict:
    """report.json's ``shake`` entry after a solve: per shape its trials, or a B's proof.

    Parameters
    ----------
    run : dict
        The shake run (:func:`~sieve_mi.shake.run.shake`); a B certify proved may be absent
        from it (its 0 is the proof's, not the trials').
    report : dict
        The solve's report.json.

    Returns
    -------
    dict
        ``trials``, ``duration_s``, ``seed``, ``fidelity_ok``, ``file`` (``shake.json``) and
        ``shapes`` (per A and B of report.json: ``name``, ``role``, ``evidence`` (``"trials"``,
        or ``"proof"`` for a B not shaken), ``trials``, ``passed``, ``fraction``, ``ci95``,
        ``median_time_s``; for a B also ``proof``, its ``certified`` status or None).
    """
    shaken = {s["name"]: s for s in run["shapes"]}
    keys = ("trials", "passed", "fraction", "ci95", "median_time_s")
    shapes = []
    for role, key in (("A", "pass"), ("B", "block")):
        for e in report[key]:
            s = shaken.get(e["name"])
            row = {"name": e["name"], "role": role, "evidence": "trials" if s else "proof"}
            row.update({k: s[k] for k in keys} if s else dict(zip(keys, (0, 0, 0.0, None, None))))
            if role == "B":
                row["proof"] = e.get("certified")
            shapes.append(row)
    st = run["settings"]
    return {"trials": st["trials"], "duration_s": st["duration"], "seed": st["seed"],
            "fidelity_ok": run["fidelity_ok"], "file": "shake.json", "shapes": shapes}  # fmt: skip


def shape_lines(entry: dict) -> list[str]:
    """One console line per shape of a :func:`report_entry`: an A's pass count, fraction, 95 %
    interval and median time to pass; a B's count and its proof."""
    out = []
    for s in entry["shapes"]:
        head = f"shake: {s['name']} ({s['role']}): "
        if s["evidence"] == "proof":
            out.append(head + "0 passed: proved blocked (certify), not shaken")
            continue
        lo, hi = s["ci95"]
        text = (f"{s['passed']} of {s['trials']} passed ({100 * s['fraction']:.1f} %, 95 % "
                f"interval {100 * lo:.1f}–{100 * hi:.1f} %)")  # fmt: skip
        if s["median_time_s"] is not None:
            text += f", median {s['median_time_s']:.2f} s to pass"
        if s["role"] == "B":
            text += f"; certify: {s['proof'] or 'not run'}"
        out.append(head + text)
    return out


def record(folder: str, entry: dict, card: str | None = None) -> None:
    """Put ``entry`` into the solve folder's report.json as ``shake`` (and ``card``, the target's,
    into its report.html), through :func:`~sieve_mi.outputs.outdir.add_files`."""
    from sieve_mi.shake.inputs import read_report

    report = read_report(folder)[1]
    report["shake"] = entry
    contents = {"report.json": (json.dumps(report, indent=2) + "\n").encode("utf-8")}
    if card is not None:
        page = insert_card(folder, TARGET_CARD, card)[0]
        if page is not None:
            contents["report.html"] = page.encode("utf-8")
    add_files(folder, contents, hint=_HINT)


#: The name of the pass-rate target's card in report.html.
TARGET_CARD = "target"


def tradeoff_plot(tries: list[dict], target: float, units: str) -> bytes:
    """A small PNG: each try's least A pass fraction (with its 95 % interval) against the least
    B margin found (scene units; the try's number where no B has one), the target dashed
    (:func:`tradeoff_figure`)."""
    buf = io.BytesIO()
    tradeoff_figure(tries, target, units).savefig(buf, format="png")
    return buf.getvalue()


def tradeoff_figure(tries: list[dict], target: float, units: str):
    """The figure of :func:`tradeoff_plot`, its labels laid out (:func:`_unstack`): tries of
    nearly equal margin and pass rate (a window, its sheet and its mirrored sheet) get labels
    one above the other, each joined to its point by a thin line, not printed over each other.

    Returns
    -------
    matplotlib.figure.Figure
        Its layout fixed after the labels were placed.
    """
    from sieve_mi.outputs.plots import new_figure

    fig = new_figure(4.8, 3.2, 110)
    ax = fig.add_subplot()
    labels = []
    for k, t in enumerate(tries):
        a = min(t["pass"], key=lambda s: s["fraction"])
        x = k if t["b_margin"] is None else t["b_margin"]
        err = [[max(0.0, a["fraction"] - a["ci95"][0])], [max(0.0, a["ci95"][1] - a["fraction"])]]
        ax.errorbar([x], [a["fraction"]], yerr=err, fmt="o", color="#1a9850" if t["blocked"]
                    else "#d73027", capsize=3)  # fmt: skip
        labels.append(ax.annotate(f"{k}: {t['step']}", (x, a["fraction"]), fontsize=7,
                                  xytext=(4, 4), textcoords="offset points"))  # fmt: skip
    ax.axhline(target, ls="--", color="grey", lw=1)
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlabel(f"B margin: least overhang found ({units})")
    ax.set_ylabel("least A pass fraction")
    _unstack(fig, labels)
    return fig


#: The thin line that joins a moved label to its point.
_LEADER = {"arrowstyle": "-", "lw": 0.5, "color": "grey", "shrinkA": 0, "shrinkB": 3}


def _unstack(fig, labels: list) -> None:
    """Move each label of ``labels`` (annotations offset in points) up, or down in the upper
    half of the plot, until its box overlaps no label placed before it; then fix the figure's
    layout so the saved picture keeps the places."""
    from matplotlib.text import Text

    fig.canvas.draw()  # the constrained layout sets the axes first
    renderer = fig.canvas.get_renderer()
    placed = []

    def box_of(ann):  # the text's box, not its leader line
        ann.update_positions(renderer)
        return Text.get_window_extent(ann, renderer)

    for ann in labels:
        x0, x1 = ann.axes.get_xlim()
        if (ann.xy[0] - x0) > 0.75 * (x1 - x0):  # near the right edge: the label on the left
            ann.set_horizontalalignment("right")
            ann.xyann = (-4, 4)
        box = box_of(ann)
        step = (box.height + 1.0) * 72.0 / fig.dpi  # a line, in points
        up = ann.xy[1] < 0.5
        moved = False
        while any(box.overlaps(b) for b in placed):
            dx, dy = ann.xyann
            ann.xyann = (dx, dy + step if up else dy - step)
            box, moved = box_of(ann), True
        if moved:  # the same label, joined to its point
            ax = ann.axes
            ann.remove()
            ann = ax.annotate(ann.get_text(), ann.xy, xytext=ann.xyann, fontsize=7,
                              textcoords="offset points", arrowprops=_LEADER,
                              ha=ann.get_horizontalalignment())  # fmt: skip
            box = box_of(ann)
        placed.append(box)
    fig.set_layout_engine("none")


def target_card(target: dict, units: str) -> str:
    """report.html's pass-rate target card: one row per try and :func:`tradeoff_plot`."""
    import base64
    from html import escape

    rows = ""
    for k, t in enumerate(target["tries"]):
        rate = ", ".join(f"{escape(a['name'])} {a['passed']}/{a['trials']} [{a['ci95'][0]:.3f}, "
                         f"{a['ci95'][1]:.3f}]" for a in t["pass"])  # fmt: skip
        margin = "-" if t["b_margin"] is None else f"{t['b_margin']:.3f}"
        mark = " (in this folder)" if k == target["chosen"] else ""
        holes = f"{t['holes']}{', every other class mirrored' if t.get('mirror') else ''}"
        if None not in t.get("plate_size", [None]):
            holes += " on {:.4g} x {:.4g}".format(*t["plate_size"])
        tol = "-" if t.get("tolerance") is None else f"{t['tolerance']:g}"
        if None not in t.get("tolerances", [None]):  # each separate hole its own
            tol = "/".join(f"{x:g}" for x in t["tolerances"])
        rows += (f"<tr><td>{k}{mark}</td><td>{escape(t['step'])}</td><td>{tol}</td>"
                 f"<td>±{t['window_deg']:g}°</td><td>{holes}</td><td>{rate}</td><td>{margin}</td>"
                 f"<td>{'yes' if t['b_proved'] else 'no'}</td></tr>")  # fmt: skip
    png = base64.b64encode(tradeoff_plot(target["tries"], target["fraction"], units))
    met = "met" if target["met"] else "not met: the best trade-off is kept"
    return (
        f'<section class="card wide" id="{TARGET_CARD}"><h2>Pass-rate target</h2>'
        f"<p>Target {100 * target['fraction']:g} % of each A within the shaking time: {met}.</p>"
        f'<img alt="pass rate against B margin" src="data:image/png;base64,{png.decode()}">'
        f"<table><thead><tr><th>try</th><th>step</th><th>tolerance ({escape(units)})</th>"
        "<th>window</th><th>holes</th>"
        f"<th>A passed [95 %]</th><th>B margin: least overhang found ({escape(units)})</th><th>B proved</th></tr>"
        f"</thead><tbody>{rows}</tbody></table></section>"
    )
