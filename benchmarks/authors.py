"""Side by side with the paper authors' published runs (their ``results/*/results.json``).

Usage::

    python -m benchmarks.authors [--only NAME[,NAME]] [--timeout S] [--reduced NAME[,NAME]]
                                 [--variant llvm_ad_mono|cuda_ad_mono] [--out benchmarks/results]
                                 [--gpu ROWS.json] [--set TABLE.KEY=VALUE ...]
    python -m benchmarks.authors --table ROWS.json[,ROWS.json] [--gpu ROWS.json]

The authors (GitHub ``David-Cha/shape-aware-sieves``, commit 686c1f7) publish one
``results.json`` per example, measured on one NVIDIA A40: ``total_time`` (the optimisation, paper
Table 1's "optimization runtime"), ``winner_declaration_time`` (the verdict) and
``meshes_B_best_losses`` (each B's final β; A wins when none is 0). Their meshes are Thingi10K
downloads that are not reachable here, so every case is rebuilt like for like from bundled meshes:
the same number of A and B shapes, face counts within a factor of about 1.3 (where a count is
recorded), the same role (e.g. a cut-down mesh as A against the whole mesh as B), and their
hyperparameters (``benchmarks/authors/*.toml`` map their keys to ``[solver]``). The one-A-against-
random-B cases are ``benchmarks.stress``'s scene at its own settings (see ``STRESS``).

Every case runs in its own process (``sieve-mi solve SCENE --quiet --json --no-figure
--no-animation``, or ``python -m benchmarks.stress --one N``); its peak RSS comes from ``wait4``
(the process and the workers it waited for). A case that runs past ``--timeout`` is stopped and
reported as time-limited; ``--reduced`` runs the named cases at reduced settings (``REDUCED``),
which the table says; ``--set TABLE.KEY=VALUE`` changes a key of every scene case (e.g.
``verdict.certify=false``, as on a GPU lent for minutes, since certificates do not count here). The table is printed and written to ``<out>/authors-<variant>.md`` and
``.json``; generated meshes are made first (``benchmarks/authors/make_meshes.py``). ``--table``
prints the table of saved rows without running anything; ``--gpu`` fills the GPU column from
rows saved by a ``--variant cuda_ad_mono`` run (otherwise it says that none was measured).

Columns: the authors' search + verdict seconds against ours (``timings`` of report.json), their
ratio, our whole solve (``total_s``: with the certificates and the written outputs, no figure or
GIF), the solve's CPU seconds (user + system; on a machine shared with other jobs, a measure of
the work that load does not inflate as much as wall time), the 1-minute load average before and
after the case, and the peak RSS.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
import tomllib

from benchmarks.run import parse_override

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENES = os.path.join(HERE, "authors")
#: The command line, through the interpreter (a machine with sieve-mi on PYTHONPATH has no script).
SIEVE_MI = [sys.executable, "-m", "sieve_mi"]
REPO = "David-Cha/shape-aware-sieves@686c1f7"

#: name -> the authors' run: results folder, paper figure, A40 seconds (search = results.json's
#: total_time, verdict = winner_declaration_time), faces (paper's mesh table; None: not recorded),
#: B losses (meshes_B_best_losses) and their settings where they differ from the paper's.
AUTHORS = {
    "arch-vs-rect-prism": dict(
        folder="arch_vs_rect_prism",
        figure="Fig. 12 bottom",
        search=23.35779595375061,
        verdict=10.280737161636353,
        faces_a=[52],
        faces_b=[12],
        losses=[0.02083333395421505],
    ),
    "bowtie-vs-sphere": dict(
        folder="bowtie_vs_sphere",
        figure="Fig. 3 right",
        search=29.817814588546753,
        verdict=11.528778314590454,
        faces_a=[28],
        faces_b=[96],
        losses=[0.19281046092510223],
    ),
    "fig2-beetle-vs-beetle-front": dict(
        folder="67223_vs_591211",
        figure="Fig. 2",
        search=63.55784225463867,
        verdict=27.716338396072388,
        faces_a=[2064],
        faces_b=[1380],
        losses=[0.016544118523597717],
    ),
    "fandisk-cut-vs-fandisk": dict(
        folder="62526_cut_vs_62526",
        figure="Fig. 11 bottom",
        search=352.06060671806335,
        verdict=149.34932565689087,
        faces_a=[12560],
        faces_b=[13152],
        losses=[0.030325720086693764],
    ),
    "bunny-multi-b": dict(
        folder="37111_multi_B",
        figure="Fig. 8 top",
        search=901.9684596061707,
        verdict=415.88890981674194,
        faces_a=[88106],
        faces_b=[23909, 13340],
        losses=[0.16794081032276154, 0.07695690542459488],
    ),
    "mechanical-parts": dict(
        folder="mechanical_parts_multi_A_multi_B",
        figure="Fig. 15 fourth",
        search=2037.720073223114,
        verdict=271.4892053604126,
        faces_a=[3204, 2064],
        faces_b=[22450, 1380],
        losses=[0.0317460335791111, 0.03654485195875168],
    ),
    "bunny-poses-multi-b": dict(
        folder="cat_multi_B",
        figure="Fig. 1",
        search=3956.2269220352173,
        verdict=1778.4780232906342,
        faces_a=[55788],
        faces_b=[55788] * 3,
        losses=[0.011778563261032104, 0.02980472706258297, 0.05329153686761856],
    ),
    "three-a-three-b": dict(
        folder="coseg_chairs_multi_A_multi_B",
        figure="Fig. 15 fifth",
        search=9410.538755655289,
        verdict=878.913019657135,
        faces_a=[31456, 19304, 16100],
        faces_b=[27256, 26926, 20242],
        losses=[0.08130080997943878, 0.04888888821005821, 0.046357616782188416],
    ),
    "random-10": dict(
        folder="32770_vs_10_random_B_meshes",
        figure="Fig. 16",
        search=1778.2427763938904,
        verdict=830.415899515152,
        faces_a=None,
        faces_b=None,
        n_a=1,
        n_b=10,
        unblocked=3,
        settings="128² raster, out-of-bounds weight 1000",
    ),
    "random-50": dict(
        folder="32770_vs_50_random_B_meshes",
        figure="Fig. 16",
        search=6624.535379648209,
        verdict=3145.6988365650177,
        faces_a=None,
        faces_b=None,
        n_a=1,
        n_b=50,
        unblocked=16,
        settings="128² raster, out-of-bounds weight 1000",
    ),
}

#: name -> how our scene corresponds to theirs (the table's column; details in the scene file).
LIKE = {
    "arch-vs-rect-prism": "bundled arch (80 f) vs bundled prism grown 8 % (12 f)",
    "bowtie-vs-sphere": "bundled bowtie (20 f) vs generated 96-face UV sphere, 14.4 mm",
    "fig2-beetle-vs-beetle-front": "beetle (2,053 f) vs its front 58 % grown 15 % (1,430 f)",
    "fandisk-cut-vs-fandisk": "fandisk with 7 % of its thickness cut off (12,564 f) vs fandisk "
    "(12,946 f)",
    "bunny-multi-b": "bunny (69,451 f) vs spot ×4 (23,424 f), fandisk (12,946 f)",
    "mechanical-parts": "cow's front 40 % (3,338 f) + beetle (2,053 f), merged, vs spot ×4 "
    "(23,424 f), beetle front (1,430 f)",
    "bunny-poses-multi-b": "bunny (69,451 f) vs the bunny twisted, bent, stretched, 6 % larger "
    "(69,451 f each)",
    "three-a-three-b": "beetle ×16 (32,848 f) + cow ×4 (23,216 f) + suzanne ×16 (15,488 f), "
    "merged, vs spot ×4 (23,424 f), cow ×4 (23,216 f), fandisk (12,946 f)",
    "random-10": "`benchmarks.stress`: 20 mm ball (1,280 f) vs 10 closed real meshes "
    "(cow 5,804 f / fandisk 12,946 f)",
    "random-50": "`benchmarks.stress`: 20 mm ball vs 50 closed real meshes (as above)",
}

#: Cases played by ``benchmarks.stress`` (one A against n B), by name.
STRESS = {"random-10": 10, "random-50": 50}
#: Settings of ``--reduced`` runs (the rest as in the scene file).
REDUCED = {"solver": {"particles": 6, "iterations": 4}, "verdict": {"starts": 50, "steps": 300}}


def ensure_meshes() -> None:
    """Generate the meshes of the scenes in ``benchmarks/authors/`` that are missing."""
    spec = importlib.util.spec_from_file_location(
        "make_meshes", os.path.join(SCENES, "make_meshes.py")
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with open(os.devnull, "w") as sink:
        stdout, sys.stdout = sys.stdout, sink
        try:
            module.main([])
        finally:
            sys.stdout = stdout


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def reduced_scene(path: str, folder: str, settings: dict | None = None) -> str:
    """Write ``path`` with other settings (and absolute mesh paths) into ``folder``.

    Parameters
    ----------
    path : str
        A scene file of ``benchmarks/authors/``.
    folder : str
        Where to write the changed scene.
    settings : dict, optional
        ``{table: {key: value}}`` to set; default ``REDUCED``.

    Returns
    -------
    str
        The new scene file's path.
    """
    with open(path, "rb") as fh:
        scene = tomllib.load(fh)
    base = os.path.dirname(os.path.abspath(path))
    for shape in scene.get("pass", []) + scene.get("block", []):
        shape["mesh"] = os.path.normpath(os.path.join(base, shape["mesh"]))
    for table, keys in (REDUCED if settings is None else settings).items():
        scene.setdefault(table, {}).update(keys)
    lines = [f"{k} = {_toml_value(v)}" for k, v in scene.items() if not isinstance(v, (dict, list))]
    for key in ("pass", "block"):
        for shape in scene.get(key, []):
            lines += [f"[[{key}]]"] + [f"{k} = {_toml_value(v)}" for k, v in shape.items()]
    for key, table in scene.items():
        if isinstance(table, dict):
            lines += [f"[{key}]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    out = os.path.join(folder, os.path.basename(path))
    with open(out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return out


def run_process(cmd: list[str], timeout: float) -> dict:
    """Run ``cmd`` in its own process group; its stdout, wall time, peak RSS and exit status.

    Parameters
    ----------
    cmd : list of str
        The command.
    timeout : float
        Seconds after which the whole process group is killed.

    Returns
    -------
    dict
        ``stdout``, ``stderr``, ``wall_s``, ``peak_gb`` (``wait4``'s maximum RSS: the process and
        the children it waited for), ``cpu_s`` (their user + system CPU seconds), ``returncode``
        and ``timed_out``.
    """
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, cwd=ROOT, start_new_session=True)
        timed_out = False
        deadline = t0 + timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                timed_out = True
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.2)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        return {
            "stdout": out.read(),
            "stderr": err.read(),
            "wall_s": wall,
            "peak_gb": usage.ru_maxrss / 2**20,
            "cpu_s": usage.ru_utime + usage.ru_stime,
            "returncode": proc.returncode,
            "timed_out": timed_out,
        }


def row_from_report(report: dict) -> dict:
    """Our side of a row from a ``report.json``. A retried search (``[solver] retries``: the
    first hole lost the verdict) counts its searches and verdicts with the search, so "search +
    verdict" is the whole game's time."""
    t = report["timings"]
    blocks = report["block"]
    return {
        "faces_a": [s.get("faces") for s in report["pass"]],
        "faces_b": [s.get("faces") for s in blocks],
        "search_s": t.get("search_s", 0.0) + t.get("retry_s", 0.0),
        "verdict_s": t.get("verdict_s", 0.0),
        "total_s": t.get("total_s"),
        "winner": report["winner"],
        "beta": [b.get("beta") for b in blocks],
        "unblocked": sum(not b.get("blocked") for b in blocks),
        "certified": [b.get("certified") for b in blocks],
    }


def run_case(
    name: str, variant: str, timeout: float, reduced: bool, settings: dict | None = None
) -> dict:
    """Solve one case in a child process and return its row (ours and the authors').

    Parameters
    ----------
    name : str
        A key of ``AUTHORS``.
    variant : str
        Mitsuba variant.
    timeout : float
        Seconds before the case is stopped (then the row says so).
    reduced : bool
        Use ``REDUCED`` settings instead of the scene file's.
    settings : dict, optional
        ``{table: {key: value}}`` set on top (``--set``), e.g. ``{"verdict": {"certify": False}}``.

    Returns
    -------
    dict
        The row: ``name``, ``variant``, ``reduced``, ``wall_s``, ``peak_gb``, our results (see
        ``row_from_report``) or ``error``, and the authors' run under ``authors``.
    """
    row = {"name": name, "variant": variant, "reduced": reduced, "authors": AUTHORS[name]}
    if settings:
        row["settings"] = settings
    with tempfile.TemporaryDirectory() as tmp:
        if name in STRESS:
            cmd = [sys.executable, "-m", "benchmarks.stress", "--one", str(STRESS[name])]
            cmd += ["--variant", variant]
        else:
            scene = os.path.join(SCENES, f"{name}.toml")
            changed = {t: dict(k) for t, k in (REDUCED if reduced else {}).items()}
            for table, keys in (settings or {}).items():
                changed.setdefault(table, {}).update(keys)
            scene = reduced_scene(scene, tmp, changed) if changed else scene
            cmd = [*SIEVE_MI, "solve", scene, "--out", os.path.join(tmp, "out"), "--quiet"]
            cmd += ["--json", "--no-figure", "--no-animation", "--variant", variant]
        done = run_process(cmd, timeout)
    row.update(wall_s=done["wall_s"], peak_gb=done["peak_gb"], cpu_s=done["cpu_s"])
    if done["timed_out"]:
        row["error"] = f"stopped after {timeout:.0f} s (time limit)"
    elif done["returncode"] not in (0, 3):
        tail = (done["stderr"].strip().splitlines() or ["no output"])[-1]
        row["error"] = f"exit {done['returncode']}: {tail}"
    elif name in STRESS:
        r = json.loads(done["stdout"].strip().splitlines()[-1])
        row.update(
            faces_a=[1280],
            faces_b=[r["faces"]],
            search_s=r["search_s"],
            verdict_s=r["verdict_s"],
            total_s=r["total_s"],
            winner=r["winner"],
            unblocked=r["unblocked"],
            beta=None,
            proved=r["proved"],
        )
    else:
        row.update(row_from_report(json.loads(done["stdout"])))
    return row


def _faces(values) -> str:
    if not values or None in values:
        return "not recorded"
    return " + ".join(f"{v:,}" for v in values)


def _load(row: dict) -> str:
    if "load" not in row:
        return "–"
    return "{:.1f}–{:.1f}".format(*sorted(row["load"]))


def _outcome(winner: str, losses, unblocked: int | None) -> str:
    if losses is None:
        return f"{winner}, {unblocked} unblocked"
    return f"{winner}, β " + ", ".join(f"{x:.3f}" for x in losses)


def authors_cells(a: dict) -> list[str]:
    """The authors' cells of a row: figure, shapes, faces, seconds, outcome."""
    n_a = a.get("n_a", len(a["faces_a"] or []))
    n_b = a.get("n_b", len(a["faces_b"] or []))
    losses = a.get("losses")
    winner = "B" if losses is None or min(losses) == 0 else "A"
    if losses is None:
        winner = "B" if a["unblocked"] else "A"
    return [
        f"`{a['folder']}` ({a['figure']})",
        f"{n_a} / {n_b}",
        f"{_faces(a['faces_a'])} / {_faces(a['faces_b'])}",
        f"{a['search']:,.0f} + {a['verdict']:,.0f} = {a['search'] + a['verdict']:,.0f}",
        _outcome(winner, losses, a.get("unblocked")),
    ]


def our_cells(row: dict) -> list[str]:
    """Our cells of a row: seconds, ratio, whole solve, CPU seconds, peak, outcome."""
    if "error" in row:
        cpu = f"{row['cpu_s']:,.0f}" if "cpu_s" in row else "–"
        a = row["authors"]
        limited = row["error"].startswith("stopped after")
        bound = f"< {(a['search'] + a['verdict']) / row['wall_s']:.1f}×" if limited else "–"
        reduced = " (reduced settings)" if row["reduced"] else ""
        return [
            row["error"] + reduced,
            bound,
            f"{row['wall_s']:,.0f} (wall)",
            cpu,
            _load(row),
            f"{row['peak_gb']:.2f}",
            "–",
        ]
    a = row["authors"]
    ours = row["search_s"] + row["verdict_s"]
    ratio = (a["search"] + a["verdict"]) / ours if ours > 0 else float("inf")
    seconds = f"{row['search_s']:,.1f} + {row['verdict_s']:,.1f} = {ours:,.1f}"
    if row["reduced"]:
        seconds += " (reduced settings)"
    return [
        seconds,
        f"{ratio:.1f}×" if ratio < 10 else f"{ratio:,.0f}×",
        f"{row['total_s']:,.1f}",
        f"{row['cpu_s']:,.0f}" if "cpu_s" in row else "–",
        _load(row),
        f"{row['peak_gb']:.2f}",
        _outcome(row["winner"], row["beta"], row.get("unblocked")),
    ]


def gpu_cell(row: dict | None, lent: bool = False) -> str:
    """The GPU column: search + verdict seconds of a ``cuda_ad_mono`` row, or why there is none.

    ``lent``: a GPU run was given (``--gpu``), so a missing row was not run on it.
    """
    if row is None:
        return "not run on the GPU" if lent else "not measured (no GPU lent)"
    if "error" in row:
        return row["error"]
    a = row["authors"]
    ours = row["search_s"] + row["verdict_s"]
    ratio = (a["search"] + a["verdict"]) / ours if ours > 0 else float("inf")
    outcome = _outcome(row["winner"], row.get("beta"), row.get("unblocked"))
    return (
        f"{row['search_s']:,.1f} + {row['verdict_s']:,.1f} = {ours:,.1f} ({ratio:,.0f}×), {outcome}"
    )


def markdown(rows: list[dict], header: str, gpu_rows: list[dict] | None = None) -> str:
    """The side-by-side table.

    Parameters
    ----------
    rows : list of dict
        Rows from ``run_case`` on the CPU (``llvm_ad_mono``).
    header : str
        A line above the table (machine, date, variant).
    gpu_rows : list of dict, optional
        Rows of the same cases run with ``cuda_ad_mono`` (``--gpu FILE``), for the GPU column.

    Returns
    -------
    str
        Markdown text.
    """
    gpu = {r["name"]: r for r in gpu_rows or []}
    head = [
        "case (their results folder)",
        "A / B",
        "their faces A / B",
        "A40 search + verdict s",
        "their winner",
        "like for like (ours)",
        "ours, 2 CPU cores: search + verdict s",
        "A40 / ours",
        "ours: whole solve s",
        "CPU s",
        "load",
        "peak GB",
        "our winner",
        "ours, GPU: search + verdict s",
    ]
    out = [header, "", "| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in rows:
        a = authors_cells(row["authors"])
        cells = (
            a + [LIKE[row["name"]]] + our_cells(row) + [gpu_cell(gpu.get(row["name"]), bool(gpu))]
        )
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def machine() -> str:
    """CPU model (``/proc/cpuinfo``), core count and load average."""
    cpu = platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return f"{cpu}, {os.cpu_count()} cores, load average {load}"


def _rows(path: str | None) -> list[dict] | None:
    if not path:
        return None
    with open(path) as fh:
        return json.load(fh)


def main(argv=None) -> int:
    """Run the cases, print the table and write it (markdown and JSON) under ``--out``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", help="comma-separated case names: " + ", ".join(AUTHORS))
    p.add_argument("--reduced", default="", help="cases to run at reduced settings")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per case (default 900)")
    p.add_argument("--variant", default="llvm_ad_mono")
    p.add_argument("--out", default=os.path.join(HERE, "results"))
    p.add_argument(
        "--table", help="only print the table of saved rows (JSON files, comma-separated)"
    )
    p.add_argument("--gpu", help="a JSON file of rows run with cuda_ad_mono, for the GPU column")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="change a scene key of every case (TOML value), e.g. verdict.certify=false",
    )
    args = p.parse_args(argv)
    settings = {}
    for text in args.set:
        try:
            table, key, value = parse_override(text)
            settings.setdefault(table, {})[key] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError as exc:
            p.error(f"--set {text!r}: the value is not TOML ({exc})")
        except ValueError as exc:
            p.error(str(exc))
    if args.table:
        rows = []
        for path in args.table.split(","):
            with open(path) as fh:
                rows += json.load(fh)
        print(markdown(rows, f"{len(rows)} rows from {args.table}", _rows(args.gpu)))
        return 0
    names = args.only.split(",") if args.only else list(AUTHORS)
    unknown = [n for n in names if n not in AUTHORS]
    if unknown:
        p.error(f"unknown case {unknown[0]!r}; known: {', '.join(AUTHORS)}")
    reduced = set(filter(None, args.reduced.split(",")))
    ensure_meshes()
    os.makedirs(args.out, exist_ok=True)
    stem = os.path.join(args.out, f"authors-{args.variant}")
    rows = []
    for name in names:
        before, load = machine(), os.getloadavg()[0]
        rows.append(run_case(name, args.variant, args.timeout, name in reduced, settings))
        rows[-1].update(machine=before, load=[load, os.getloadavg()[0]])
        rows[-1]["date"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="minutes")
        print(markdown(rows[-1:], f"{name}: {before}").splitlines()[-1], flush=True)
        with open(stem + ".json", "w") as fh:  # after every case: a stopped run keeps its rows
            json.dump(rows, fh, indent=1)
    header = f"{machine()}; {args.variant}; {datetime.date.today().isoformat()}; {REPO}"
    text = markdown(rows, header, _rows(args.gpu))
    print(text)
    with open(stem + ".md", "w") as fh:
        fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
