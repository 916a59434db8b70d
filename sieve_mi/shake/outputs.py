"""Shake outputs: ``shake.json``, ``shake.png`` (fraction passed against time) and a summary table.

Into a solve's folder the two files are written atomically (a temporary file, then a rename)
and added to the folder's ``.sieve-mi`` marker, so a later ``solve --out`` may still replace it.
"""

from __future__ import annotations

import json
import os

import numpy as np

from sieve_mi.errors import SieveError
from sieve_mi.outputs.outdir import MARKER, read_marker, writing
from sieve_mi.shake.stats import pass_curve

__all__ = [
    "FILES",
    "ROLE_COLOURS",
    "add_html_section",
    "add_to_folder",
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
    path : str
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
    fig.savefig(path)
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
    ok = "all within" if report["fidelity_ok"] else "NOT all within"
    rows.append(f"fidelity: resting sink {ok} the bound {bound} mm; hausdorff in {report['units']}")
    return "\n".join(rows)


def _write_atomic(folder: str, name: str, write) -> None:
    """Call ``write(path)`` on a temporary file beside ``name`` (same extension), then rename."""
    stem, ext = os.path.splitext(name)
    tmp = os.path.join(folder, f".{stem}.tmp-{os.getpid()}{ext}")
    try:
        write(tmp)
        os.replace(tmp, os.path.join(folder, name))
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def _write_files(report: dict, folder: str, clip: str | None = None) -> list[str]:
    def write_json(path):
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(to_json(report))

    _write_atomic(folder, "shake.json", write_json)
    _write_atomic(folder, "shake.png", lambda path: plot(report, path))
    names = ["shake.json", "shake.png"]
    if clip is not None:
        os.replace(clip, os.path.join(folder, "shake.gif"))
        names.append("shake.gif")
    return names


def add_to_folder(report: dict, folder: str, clip: str | None = None) -> list[str]:
    """Write ``shake.json`` and ``shake.png`` (and move the rendered ``clip`` in as ``shake.gif``)
    into a solve's output folder and list them in its marker; a folder sieve-mi did not write is
    refused (one line)."""
    marker = read_marker(folder)
    if marker is None:
        raise SieveError(
            f"{folder}: has no {MARKER} marker, so sieve-mi did not write it; "
            "use shake --sieve PLATE PART... --out DIR instead"
        )
    names = _write_files(report, folder, clip)
    if "report.html" in marker["files"]:
        add_html_section(report, folder)
    marker["files"] = sorted(set(marker["files"]) | set(names))

    def write_marker(path):
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(marker, fh, indent=1)

    _write_atomic(folder, MARKER, write_marker)
    return names


def write_new_folder(report: dict, out_dir: str, inputs: list[str], clip: str | None = None):
    """``--out DIR`` of ``shake --sieve``: a fresh sieve-mi output folder (same rules as
    ``solve --out``) holding ``shake.json``, ``shake.png``, ``shake.gif`` (when ``clip`` is
    given) and ``report.json`` (= shake.json)."""
    with writing(out_dir, command="shake", inputs=inputs) as tmp:
        _write_files(report, tmp, clip)
        with open(os.path.join(tmp, "report.json"), "w", encoding="utf-8") as fh:
            fh.write(to_json(report))


_BEGIN, _END = "<!--shake-->", "<!--/shake-->"


def html_section(report: dict, png: bytes) -> str:
    """report.html's "Shake trials" card: the curves (inlined PNG), one row per shape, fidelity."""
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
    return (
        f'{_BEGIN}<section class="card wide" id="shake"><h2>Shake trials</h2>'
        f'<img alt="fraction passed against time" style="max-width:100%" '
        f'src="data:image/png;base64,{img}">'
        "<table><thead><tr><th>shape</th><th>set</th><th>passed</th><th>fraction</th>"
        "<th>95 % interval</th><th>median s</th>"
        f"<th>Hausdorff ({escape(report['units'])})</th><th>sink mm</th></tr></thead>"
        f"<tbody>{rows}</tbody></table>"
        f"<p>{st['trials']} trials per shape, {st['duration']:g} s each; plate shaken "
        f"{st['amplitude']:g} mm at {st['frequency']:g} Hz{_twist_words(st['twist'])}; "
        f"seed {st['seed']}. Resting sink bound {report['engine']['sink_bound_mm']} mm: "
        f"{'kept' if report['fidelity_ok'] else 'NOT kept'}. Details: shake.json.</p>"
        f"</section>{_END}"
    )


def _twist_words(twist: float) -> str:
    """The twist in the card's sentence: nothing when the plate does not twist."""
    return f" with a {twist:g} degree twist" if twist else ""


def add_html_section(report: dict, folder: str) -> None:
    """Put the shake card into ``folder``'s report.html (replacing an earlier one)."""
    path = os.path.join(folder, "report.html")
    with open(path, encoding="utf-8") as fh:
        page = fh.read()
    with open(os.path.join(folder, "shake.png"), "rb") as fh:
        card = html_section(report, fh.read())
    start, end = page.find(_BEGIN), page.find(_END)
    if start >= 0 and end > start:
        page = page[:start] + card + page[end + len(_END) :]
    else:
        anchor = page.find('<section class="card" id="details">')
        if anchor < 0:
            anchor = page.rfind("</body>")
        if anchor < 0:
            return
        page = page[:anchor] + card + "\n  " + page[anchor:]

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(page)

    _write_atomic(folder, "report.html", write)
