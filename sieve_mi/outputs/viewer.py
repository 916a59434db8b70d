"""``report.html``: a self-contained page that shows a solve's result offline (from file://).

The page holds everything it needs: its style sheet and script (the package's ``assets/``, inlined;
a small hand-written WebGL viewer, no third-party code), the passage scene of
:mod:`sieve_mi.outputs.passage` as JSON (mesh positions as base64 little-endian float32, faces as uint32;
meshes over :data:`DISPLAY_FACES` triangles simplified for display, :func:`display_mesh`),
and the 2D hole view and the convergence plot as inline SVG (:mod:`sieve_mi.outputs.svg`). It
makes no network request while it is viewed: its Content-Security-Policy allows only its own
inline script and style and images from its folder (``passage.gif``); links to the other output
files are relative. The viewer owns the page: a later command adds its own card to a written page
with :func:`insert_card` (``shake`` its "Shake trials" card), never by editing the HTML itself.

What it shows: a 3D view (orbit, zoom, touch) of the plate with every A sliding down through the
hole and every B's best attempt coming to rest on the plate, with per-shape toggles; the exact
hole with every A's outline (titled, and captioned under the view, with its pass pose in words)
and every B's best attempt (zoomable); the result table (β,
protrusion, certification), warnings, timings, settings and the convergence of A's search.

Page options after ``#`` in the address (``report.html#view=top&t=0&show=plate,a0``):
``view=top`` (straight down, orthographic, the plate's box fitted to the canvas), ``t=PHASE`` (hold
the animation at phase 0..1), ``show=ID,...`` (only these of ``plate``, ``a<i>``, ``b<j>``) and
``full`` (the 3D view fills the window). The page records script errors in ``#errors`` and sets
``data-ready`` on ``<body>`` once the 3D view has been drawn (or ``data-webgl="none"``).
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
from importlib import resources

import numpy as np

from sieve_mi.outputs.console import certified_word, margin_lines, pose_lines
from sieve_mi.outputs.palette import PALETTE, css_variables
from sieve_mi.outputs.svg import convergence_svg, hole_svg, outline_svg

__all__ = [
    "script_json",
    "COLOURS",
    "DISPLAY_FACES",
    "check_holes",
    "check_table",
    "decode",
    "display_mesh",
    "image_outline",
    "insert_card",
    "page_files",
    "pose_caption",
    "render_check_page",
    "render_page",
    "result_table",
    "scene_data",
    "timings_table",
    "with_card",
    "write_page",
]

#: Colours of the 3D and 2D views (sRGB, 0..1): plate, A, blocked B, B that gets through,
#: background; from :mod:`sieve_mi.outputs.palette`, as every picture's.
COLOURS = {k: PALETTE[k] for k in ("plate", "pass", "blocked", "escaped", "background")}


def script_json(data) -> str:
    """JSON for an inline ``<script>``: ``<``, ``>`` and ``&`` written as ``\\u003c`` etc.

    No name in the data can then open or close a tag or an HTML comment (``</script>``,
    ``<!--``, ``<script``) and change the page's structure; JSON.parse reads the same strings.

    Examples
    --------
    >>> script_json({"name": "<!--<script>"})
    '{"name":"\\\\u003c!--\\\\u003cscript\\\\u003e"}'
    """
    text = json.dumps(data, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _b64(array: np.ndarray, dtype: str) -> str:
    """Base64 of the array's bytes as little-endian ``dtype`` (``"<f4"`` or ``"<u4"``)."""
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def decode(text: str, dtype: str, columns: int = 3) -> np.ndarray:
    """Inverse of the page's mesh encoding: base64 -> (K, columns) array of ``dtype``."""
    return np.frombuffer(base64.b64decode(text), dtype=dtype).reshape(-1, columns)


#: Most triangles of one mesh on the page; larger meshes are simplified for display only.
DISPLAY_FACES = 100_000


def display_mesh(vertices: np.ndarray, faces: np.ndarray, max_faces: int = DISPLAY_FACES):
    """A mesh for the page: itself if it has at most ``max_faces`` triangles, else simplified.

    Simplification clusters vertices on a grid (each cluster becomes its mean vertex) and drops
    the triangles that collapse or repeat; the grid is coarsened until at most ``max_faces``
    remain. Every vertex moves by at most one cell diagonal, reported as ``error``. Only the 3D
    view uses this: the hole, the scores and the plate files come from the full meshes.

    Parameters
    ----------
    vertices : (V, 3) float ndarray
    faces : (F, 3) int ndarray
    max_faces : int

    Returns
    -------
    vertices : (V', 3) float ndarray
    faces : (F', 3) int ndarray
    error : float
        Largest distance a vertex moved (scene units; 0 if unchanged).

    Examples
    --------
    >>> import trimesh
    >>> ball = trimesh.creation.icosphere(5, 10.0)  # 20,480 triangles
    >>> v, f, err = display_mesh(ball.vertices, ball.faces, max_faces=2000)
    >>> len(f) <= 2000 and err < 3.0
    True
    """
    vertices, faces = np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)
    if len(faces) <= max_faces:
        return vertices, faces, 0.0
    lo = vertices.min(0)
    extent = float((vertices.max(0) - lo).max()) or 1.0
    n = max(2, int(np.sqrt(max_faces)))  # a closed surface on an n^3 grid has ~n^2 cells
    while True:
        cell = extent / n
        v, f = _cluster(vertices, faces, lo, cell)
        if len(f) <= max_faces or n <= 2:
            return v, f, float(np.sqrt(3.0) * cell)
        n = max(2, int(n * 0.8))


def _cluster(vertices, faces, lo, cell):
    """Vertices merged per grid cell (their mean) and the triangles left (no repeats)."""
    ijk = np.floor((vertices - lo) / cell).astype(np.int64)
    side = int(ijk.max()) + 1
    _, group = np.unique((ijk[:, 0] * side + ijk[:, 1]) * side + ijk[:, 2], return_inverse=True)
    group = group.ravel()
    count = np.bincount(group)
    merged = np.stack([np.bincount(group, vertices[:, i]) / count for i in range(3)], axis=1)
    f = group[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    s = np.sort(f, axis=1)
    m = len(merged)
    if m**3 < 2**62:  # one int64 per triangle: much faster than rows
        _, first = np.unique((s[:, 0] * m + s[:, 1]) * m + s[:, 2], return_index=True)
    else:
        _, first = np.unique(s, axis=0, return_index=True)
    return merged, f[np.sort(first)]


def _mesh_data(vertices, faces) -> dict:
    """``positions`` and ``faces`` (base64) of a mesh as shown, and ``simplified`` if it is."""
    v, f, error = display_mesh(vertices, faces)
    data = {"positions": _b64(v, "<f4"), "faces": _b64(f, "<u4")}
    if error > 0:
        data["simplified"] = {"faces": int(len(faces)), "shown": int(len(f)), "error": error}
    return data


def scene_data(passage, report: dict) -> dict:
    """The JSON the page's 3D view reads: the plate, every piece and its motion, colours.

    Parameters
    ----------
    passage : sieve_mi.outputs.passage.Passage
    report : dict
        report.json's content (name, units, winner).

    Returns
    -------
    dict
        ``plate`` and each of ``pieces`` have ``positions`` ((V, 3) float32, base64) and ``faces``
        ((F, 3) uint32, base64), simplified for display above :data:`DISPLAY_FACES` triangles
        (then ``simplified`` gives the full and shown triangle counts and the largest vertex
        shift, :func:`display_mesh`); a piece also has ``id`` (``a<i>``/``b<j>``), ``name``, ``role``,
        ``passes``, ``start``, ``end``, ``stop``, ``slot`` (its motion, :class:`~sieve_mi.outputs.passage.Piece`)
        and ``centre`` (xy, scene units). ``bounds`` is the (2, 3) box of the whole motion and
        ``plate_box`` the plate's xy box ``[[x0, y0], [x1, y1]]``.
    """
    pv = passage.plate_vertices
    pieces = []
    for p in passage.pieces:
        kind = "pass" if p.role == "pass" else ("escaped" if p.passes else "blocked")
        pieces.append(
            {
                "id": ("a" if p.role == "pass" else "b") + str(p.index),
                "name": p.name,
                "role": p.role,
                "passes": bool(p.passes),
                "start": float(p.start),
                "end": float(p.end),
                "stop": float(p.stop),
                "slot": [float(x) for x in p.slot],
                "centre": [float(c) for c in p.centre],
                **({"keys": p.keys.tolist()} if p.keys is not None else {}),
                "colour": list(COLOURS[kind]),
                **_mesh_data(p.vertices, p.faces),
            }
        )
    return {
        "name": report["name"],
        "units": report["units"],
        "winner": report["winner"],
        "thickness": float(passage.thickness),
        "bounds": passage.bounds().tolist(),
        "plate_box": [pv[:, :2].min(0).tolist(), pv[:, :2].max(0).tolist()],
        "plate": {"colour": list(COLOURS["plate"]), **_mesh_data(pv, passage.plate_faces)},
        "pieces": pieces,
        "background": list(COLOURS["background"]),
    }


def _table(rows: list[list[str]], head: list[str]) -> str:
    th = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


def result_table(report: dict) -> str:
    """The result per shape: role, name, β, protrusion, result, certification and the plate's
    thickness verdict ("thin plate": safe by diameter or ball, passage, or none found); under it
    each blocked B's overhang line (:func:`sieve_mi.outputs.console.margin_lines`)."""
    units = report["units"]
    rows = [
        ["pass", p["name"], "-", "-", "passes (part of the hole)", "-", "-"] for p in report["pass"]
    ]
    for b in report["block"]:
        thin = b.get("thin_plate")
        if thin is None:
            sheet = "-"
        elif thin["status"] == "safe":
            sheet = f"safe ({thin.get('by', 'diameter')})"
        else:
            sheet = f"{thin['status']} at {thin['thickness']:g} {units}"
        rows.append(
            [
                "block",
                b["name"],
                f"{b['beta']:.4f}",
                f"{b['protrusion']:.3f}",
                "blocked" if b["blocked"] else "PASSES",
                certified_word(b),
                sheet,
            ]
        )
    head = ["role", "shape", "β", f"protrusion ({units})", "result", "certified", "thin plate"]
    lines = "".join(f"<li>{html.escape(x)}</li>" for x in margin_lines(report))
    return _table(rows, head) + (f'<ul class="margins">{lines}</ul>' if lines else "")


def pose_caption(report: dict) -> tuple[list[str] | None, str]:
    """Each A's pass pose in words (:func:`sieve_mi.outputs.console.pose_lines`): the ``<title>``
    of each A outline in the hole view (None when some A has no ``pose``) and the caption under
    it (``<ul class="poses">``, one item per A; empty without poses)."""
    lines = pose_lines(report)
    if not lines:
        return None, ""
    titles = lines if len(lines) == len(report["pass"]) else None
    items = "".join(f"<li>{html.escape(x)}</li>" for x in lines)
    return titles, f'<ul class="poses hint">{items}</ul>'


def timings_table(report: dict) -> str:
    """Seconds per stage."""
    return _table([[k, f"{v:.3f}"] for k, v in report.get("timings", {}).items()], ["stage", "s"])


def _asset(name: str) -> str:
    return resources.files("sieve_mi.outputs").joinpath("assets", name).read_text(encoding="utf-8")


def _toggles(data: dict) -> str:
    """Checkboxes: the plate, each A and each B (each hides the shape in both views)."""
    items = [("plate", "plate" + _simplified(data["plate"], data["units"]), "plate")]
    for p in data["pieces"]:
        kind = "pass" if p["role"] == "pass" else ("escaped" if p["passes"] else "blocked")
        label = f"{'A' if p['role'] == 'pass' else 'B'}: {p['name']}"
        items.append((p["id"], label + _simplified(p, data["units"]), kind))
    return "".join(
        f'<label class="toggle {kind}"><input type="checkbox" checked data-toggle="{i}"> '
        f"{html.escape(label)}</label>"
        for i, label, kind in items
    )


def _simplified(mesh: dict, units: str) -> str:
    """`` (3D: 90,126 of 1,310,720 triangles, within 0.34 mm)`` for a simplified mesh, else ``""``."""
    s = mesh.get("simplified")
    if not s:
        return ""
    return f" (3D: {s['shown']:,} of {s['faces']:,} triangles, within {s['error']:.2g} {units})"


def _files(folder_files: list[str]) -> str:
    """Links to the output files (relative to the page)."""
    links = "".join(
        f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>' for f in folder_files
    )
    return f"<ul class=files>{links}</ul>"


def render_page(result, report: dict, passage, files: list[str]) -> str:
    """The page's HTML (see the module docstring).

    Parameters
    ----------
    result : sieve_mi.game.result.Result
    report : dict
        report.json's content.
    passage : sieve_mi.outputs.passage.Passage
    files : list of str
        Output files to link (relative to the page).
    """
    data = scene_data(passage, report)
    blocked = [bool(b["blocked"]) for b in report["block"]]
    titles, caption = pose_caption(report)
    payload = script_json(data)
    gif = (
        '<figure><img src="passage.gif" alt="Mitsuba-rendered passage animation" '
        'width="300" height="390"><figcaption>passage.gif (Mitsuba)</figcaption></figure>'
        if "passage.gif" in files
        else ""
    )
    warnings = report.get("warnings", []) + report.get("fabrication", {}).get("warnings", [])
    warn = "".join(f"<li>{html.escape(w)}</li>" for w in warnings)
    verdict = (
        "A wins: every B is blocked" if report["winner"] == "A" else "B wins: a B gets through"
    )
    fill = {
        "TITLE": html.escape(f"sieve-mi: {report['name']}"),
        "NAME": html.escape(report["name"]),
        "WINNER": report["winner"],
        "VERDICT": html.escape(verdict),
        "UNITS": html.escape(report["units"]),
        "TOGGLES": _toggles(data),
        "HOLE_SVG": hole_svg(result, blocked, titles),
        "HOLE_CAPTION": caption,
        "RESULT_TABLE": result_table(report),
        "WARNINGS": f"<ul class=warnings>{warn}</ul>" if warn else "",
        "TIMINGS": timings_table(report),
        "SETTINGS": html.escape(json.dumps(report.get("settings", {}), indent=2)),
        "CONVERGENCE": convergence_svg(report.get("convergence", [])),
        "GIF": gif,
        "FILES": _files(files),
        "PIXEL": f"{report['pixel_size']:.4g}",
        "VARIANT": html.escape(str(report.get("variant", ""))),
        "STYLE": css_variables() + _asset("report.css"),
        "SCRIPT": _asset("viewer.js").replace("</", "<\\/"),
        "DATA": payload,
    }
    # One pass: text put in (shape names, settings) is never searched for markers again.
    return re.sub(r"\{\{([A-Z_0-9]+)\}\}", lambda m: fill[m.group(1)], _asset("report.html"))


def write_page(path: str, result, report: dict, passage, files: list[str]) -> None:
    """Write :func:`render_page`'s HTML to ``path`` (UTF-8)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(render_page(result, report, passage, files))


def page_files(folder: str) -> list[str]:
    """The files in an output folder worth linking from the page (sorted, no hidden files)."""
    out = []
    for d, _, names in os.walk(folder):
        for n in names:
            rel = os.path.relpath(os.path.join(d, n), folder).replace(os.sep, "/")
            if not n.startswith(".") and rel != "report.html":
                out.append(rel)
    return sorted(out)


def with_card(page: str, card_id: str, card: str) -> str | None:
    """``page`` with ``card`` (HTML) as its card ``card_id``, between the markers
    ``<!--card_id-->`` and ``<!--/card_id-->``: in place of an earlier one, else before the
    details section, else before ``</body>``; None when there is no such place (or an earlier
    card is cut short: its end marker missing)."""
    begin, end = f"<!--{card_id}-->", f"<!--/{card_id}-->"
    start = page.find(begin)
    if start >= 0:
        stop = page.find(end, start + len(begin))
        return None if stop < 0 else page[:start] + begin + card + end + page[stop + len(end) :]
    anchor = page.find('<section class="card" id="details">')
    if anchor < 0:
        anchor = page.rfind("</body>")
    return None if anchor < 0 else page[:anchor] + begin + card + end + "\n  " + page[anchor:]


def insert_card(folder: str, card_id: str, card: str) -> tuple[str | None, str | None]:
    """``folder``'s report.html with the card ``card_id`` put in (:func:`with_card`); or None and
    a one-line note saying why the page is left as it is. Nothing is written: the caller writes
    the page (:func:`sieve_mi.outputs.outdir.add_files` lists it in the folder's marker)."""
    path = os.path.join(folder, "report.html")
    if not os.path.lexists(path):
        return None, f"{folder} has no report.html, so no page got {card_id}'s card"
    try:
        with open(path, encoding="utf-8") as fh:
            page = fh.read()
    except (OSError, UnicodeError) as exc:
        return None, f"{path}: cannot be read ({exc}); it was left as it was"
    new = with_card(page, card_id, card)
    if new is None:
        return None, f"{path}: has no place for {card_id}'s card (no details section, no </body>)"
    return new, None


# ------------------------------------------------------------------------------------------------
# The page of ``sieve-mi check --out``
# ------------------------------------------------------------------------------------------------


def image_outline(mask: np.ndarray, frame):
    """A hole image's mask (on ``frame``, row 0 at the top) as a CrossSection (marching squares)."""
    import manifold3d
    from skimage.measure import find_contours

    padded = np.pad(np.asarray(mask, dtype=float), 1)
    h, r = frame.pixel_size, frame.half_extent
    polys = []
    for c in find_contours(padded, 0.5):  # (row, col) with the padding's offset of 1
        polys.append(np.column_stack([-r + (c[:, 1] - 0.5) * h, r - (c[:, 0] - 0.5) * h]))
    return manifold3d.CrossSection(polys, manifold3d.FillRule.EvenOdd)


def check_holes(given) -> list:
    """The holes a check used, as CrossSections in the coordinates its poses are reported in.

    Parameters
    ----------
    given : sieve_mi.geometry.sieve.SieveHoles
        The sieve's holes as the check read them (:attr:`sieve_mi.game.check.CheckReport.sieve_holes`):
        a plate's exact holes, or an image's mask drawn as its outline.
    """
    if given.plate is not None:
        return list(given.plate.holes)
    return [image_outline(given.mask, given.frame)]


def check_table(rep: dict) -> str:
    """The check's result: verdict, β, protrusion, the pose in words, fit scale and every
    evaluation."""
    r, u = rep["result"], rep["units"]
    rows = [
        ["result", "PASSES" if r["passes"] else "blocked"],
        ["β", f"{r['beta']:.4f}"],
        [f"protrusion ({u})", f"{r['protrusion']:.3f}"],
        ["hole", str(r["hole"])],
        ["pixel size", f"{rep['pixel_size']:.4g} {u}"],
    ]
    pose = rep.get("pose")
    if pose is not None:  # in words, as the console says it (check_summary)
        from sieve_mi.geometry.pose_words import pose_sentence

        head = "pass pose" if pose["of"] == "pass" else "best attempt's pose"
        rows.append([head, pose_sentence(pose, u)])
    if rep.get("fit_scale") is not None:
        lo, hi = rep["fit_bracket"]
        rows.append(
            ["fit scale", f"{rep['fit_scale']:.4g} (passes at {lo:.4g}, blocked at {hi:.4g})"]
        )
    evals = [
        [
            f"{e['scale']:.4g}",
            "passes" if e["passes"] else "blocked",
            f"{e['beta']:.4f}",
            f"{e['protrusion']:.3f}",
        ]
        for e in rep.get("evaluations", [])
    ]
    return (
        _table(rows, ["", ""])
        + "<h3>Evaluations</h3>"
        + _table(evals, ["scale", "result", "β", f"protrusion ({u})"])
    )


def render_check_page(rep: dict, shape, holes: list) -> str:
    """The page of ``sieve-mi check --out``: the holes, the shape's best attempt, the result.

    Parameters
    ----------
    rep : dict
        The check's report (:meth:`sieve_mi.game.check.CheckReport.to_dict`).
    shape : sieve_mi.geometry.meshes.Shape
        The shape checked (scale 1).
    holes : list of manifold3d.CrossSection
        :func:`check_holes`.
    """
    from sieve_mi.geometry.outline import is_closed, silhouette

    r = rep["result"]
    sec = silhouette(
        shape, np.asarray(r["rotation"]), np.asarray(r["translation"]), is_closed(shape)
    )
    name = os.path.basename(str(rep["shape"]))
    verdict = f"{name} {'passes' if r['passes'] else 'is blocked'} at scale {r['scale']:g}"
    fill = {
        "TITLE": html.escape(f"sieve-mi check: {name}"),
        "NAME": html.escape(f"{name} against {os.path.basename(str(rep['sieve']))}"),
        "WINNER": "B" if r["passes"] else "A",
        "VERDICT": html.escape(verdict),
        "UNITS": html.escape(rep["units"]),
        "HOLE_SVG": outline_svg(holes, [], [sec], [not r["passes"]], shape.radius, rep["units"]),
        "RESULT_TABLE": check_table(rep),
        "REPORT": html.escape(json.dumps(rep, indent=2, default=str)),
        "STYLE": css_variables() + _asset("report.css"),
        "SCRIPT": _asset("viewer.js").replace("</", "<\\/"),
    }
    return re.sub(r"\{\{([A-Z_0-9]+)\}\}", lambda m: fill[m.group(1)], _asset("check.html"))
