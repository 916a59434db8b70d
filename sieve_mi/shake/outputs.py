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
    "add_to_folder",
    "check_folder",
    "html_section",
    "plot",
    "summary",
    "to_json",
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
        lo, hi = s["ci95"]
        rows.append(
            f"{s['name'][:16]:<16} {s['role'] or '?':<4} {s['passed']:>4}/{s['trials']:<4} "
            f"{s['fraction']:>8.3f} {f'[{lo:.3f}, {hi:.3f}]':>16} {med:>8} "
            f"{s['geometry']['hausdorff']:>9.3f} {s['fidelity']['sink_mm']:>8.4f}"
        )
    bound = report["engine"]["sink_bound_mm"]
    ok = "all held" if report["fidelity_ok"] else "NOT all held"
    rows.append(
        f"fidelity: resting sink under {bound} mm, penetration while shaken within its bound, "
        f"no engine warning: {ok}; hausdorff in {report['units']}"
    )
    rows += [f"warning: {w}" for w in report.get("warnings", [])]
    return "\n".join(rows)


#: What to do instead when ``shake DIR`` is given a folder sieve-mi did not write.
_HINT = "use shake --sieve PLATE PART... --out DIR instead"


def _contents(report: dict, clip: str | None = None) -> dict[str, bytes]:
    """``shake.json``, ``shake.png`` and (from the rendered ``clip``) ``shake.gif`` as bytes."""
    png = io.BytesIO()
    plot(report, png)
    contents = {"shake.json": to_json(report).encode("utf-8"), "shake.png": png.getvalue()}
    if clip is not None:
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
    solve's output folder, put the card into its ``report.html``, and list them in its marker.

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
    add_files(folder, contents, hint=_HINT)
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
