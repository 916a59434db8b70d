"""Command line: ``sieve-mi solve SCENE [--out DIR]``, ``sieve-mi check SHAPE (--sieve PLATE | --hole IMAGE --pixel-size MM) [--out DIR]``, ``sieve-mi certify ...`` and ``sieve-mi view DIR``."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading

from sieve_mi.errors import (
    EXIT_BAD_INPUT,
    EXIT_NO,
    EXIT_OK,
    EXIT_UNDECIDED,
    SieveError,
    clear_signals,
    interruption,
    note_signal,
    signals_received,
)

__all__ = [
    "COMMANDS",
    "Terminated",
    "cmd_certify",
    "cmd_check",
    "cmd_solve",
    "cmd_view",
    "main",
    "run",
]


def _parser() -> argparse.ArgumentParser:
    from sieve_mi.game.check_settings import CheckInputs, CheckSettings
    from sieve_mi.options import add_options

    p = argparse.ArgumentParser(
        prog="sieve-mi", description="Design shape-aware sieves (Mitsuba 3 + Dr.Jit)."
    )
    from sieve_mi._version import VERSION

    p.add_argument("--version", action="version", version=f"sieve-mi {VERSION}")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser(
        "solve",
        help="design a hole that passes the [[pass]] shapes and blocks the [[block]] shapes",
    )
    s.add_argument(
        "scene", help="scene file (TOML), or a configuration of the paper authors' code (JSON)"
    )
    s.add_argument(
        "--out",
        help="output folder (default: out/<name>/ in the current directory); an existing folder "
        "is replaced only if it is an earlier sieve-mi output",
    )
    s.add_argument(
        "--variant",
        help="Mitsuba variant: llvm_ad_mono (CPU) or cuda_ad_mono (GPU); default $SIEVE_MI_VARIANT or llvm_ad_mono",
    )
    s.add_argument("--seed", type=int, help="random seed (overrides [solver] seed)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.add_argument(
        "--json", action="store_true", help="print report.json on stdout instead of the table"
    )
    _skip_flags(s)
    s.add_argument(
        "--shake",
        metavar="N",
        help="then shake each shape N times on the plate (MuJoCo; as sieve-mi shake OUT --trials N)",
    )
    c = sub.add_parser(
        "check",
        help="test a shape against a sieve (plate mesh or hole image): passes or blocked, and the fit scale",
    )
    c.add_argument("shape", help="mesh of the shape to test (STL, OBJ, PLY, ...)")
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("--sieve", help="sieve plate mesh; its through-holes along --axis are used")
    src.add_argument(
        "--hole",
        help="hole image (white = hole, black = material); its pixel size comes from the PNG's "
        "pHYs (solve's hole.png has it) unless --pixel-size is given",
    )
    add_options(c, CheckInputs, "pixel_size", "axis", "scale")
    add_options(c, CheckSettings)
    add_options(c, CheckInputs, "units")
    c.add_argument(
        "--variant",
        help="Mitsuba variant: llvm_ad_mono (CPU) or cuda_ad_mono (GPU); default $SIEVE_MI_VARIANT or llvm_ad_mono",
    )
    c.add_argument("--json", action="store_true", help="print the result as JSON")
    c.add_argument("--quiet", action="store_true", help="no progress on stderr")
    c.add_argument(
        "--out",
        help="also write the result as DIR/report.json (same rules as solve --out: only a new, "
        "empty or earlier sieve-mi output folder is used)",
    )
    _certify_parser(sub)
    from sieve_mi.cascade.commands import add_parsers

    add_parsers(sub)
    from sieve_mi.shake.commands import add_parser as add_shake_parser

    add_shake_parser(sub)
    _view_parser(sub)
    for command in sub.choices.values():
        _threads_option(command)
    return p


def _threads_option(parser) -> None:
    """``--threads N`` (every subcommand): Dr.Jit's CPU threads, as Mitsuba's ``-t``."""
    with contextlib.suppress(argparse.ArgumentError):  # a subcommand with its own --threads
        parser.add_argument(
            "--threads",
            type=int,
            metavar="N",
            help="Dr.Jit CPU threads for the kernels (default: one per core; sort and sweep pass "
            "it to every worker)",
        )


def _skip_flags(s) -> None:
    """``solve``'s flags that skip an optional output."""
    s.add_argument("--no-figure", action="store_true", help="skip the Mitsuba rendering figure.png")
    s.add_argument(
        "--no-animation", action="store_true", help="skip the Mitsuba animation passage.gif"
    )


def _view_parser(sub) -> None:
    """``sieve-mi view FOLDER``."""
    v = sub.add_parser("view", help="open an output folder's report.html in the default browser")
    v.add_argument("folder", help="output folder of solve or check (e.g. out/<name>)")


def _certify_parser(sub) -> None:
    """``sieve-mi certify SHAPE (--sieve PLATE | --hole SVG)`` and ``sieve-mi certify --replay CERT``."""
    from sieve_mi.game.check_settings import CheckInputs
    from sieve_mi.options import add_options
    from sieve_mi.scene import Verdict

    k = sub.add_parser(
        "certify",
        help="prove that a shape cannot pass a sieve in any pose (or find a pose that passes)",
    )
    k.add_argument("shape", nargs="?", help="mesh of the shape (STL, OBJ, PLY, ...)")
    src = k.add_mutually_exclusive_group()
    src.add_argument("--sieve", help="sieve plate mesh; its through-holes along --axis are used")
    src.add_argument("--hole", help="hole outline as SVG (the hole.svg that solve writes)")
    src.add_argument("--replay", help="re-check a certificate file independently")
    add_options(k, CheckInputs, "axis", "scale")
    add_options(k, Verdict, "certify_budget", flags={"certify_budget": "--budget"})
    k.add_argument("--certificate", help="write the certificate (JSON) to this file")
    k.add_argument("--json", action="store_true", help="print the result as JSON")
    k.add_argument("--quiet", action="store_true", help="no progress on stderr")


def cmd_solve(args) -> int:
    from contextlib import nullcontext

    from sieve_mi import api as sm
    from sieve_mi.game.solver import solve as play
    from sieve_mi.outputs import pictures
    from sieve_mi.outputs.console import summary_table
    from sieve_mi.outputs.outdir import validate
    from sieve_mi.outputs.report import input_paths
    from sieve_mi.telemetry import Run

    scene = sm.load_scene(args.scene)
    out_dir = args.out or os.path.join("out", scene.name)
    validate(out_dir, inputs=input_paths(scene))  # again just before the swap
    sm.check_seed(args.seed, "--seed")
    from sieve_mi.shake.commands import after_solve, solve_shake_settings

    shake = solve_shake_settings(args.shake, scene)
    # sm.solve's game, with a record whose times count from the process's start (Python, the
    # imports and reading the scene are "startup"); sm.solve's checks of the arguments ran above.
    run = Run.from_process_start()
    figure, gif = not args.no_figure, not args.no_animation
    # the pictures' worker is forked once the scene and --out are accepted (a refused run has
    # imported no Dr.Jit: nothing of it, such as its kernel cache, is made) and before Dr.Jit is
    # imported, so its imports run beside this process's one-thread start
    first = pictures.first(args.variant, args.threads) if figure or gif else nullcontext()
    with first, pictures.ahead(run) if figure or gif else nullcontext() as early:
        start = early and (lambda r: early.prerender(r, figure, gif))  # before the margins
        result = sm.Result.of(
            play(
                scene,
                variant=args.variant,
                seed=args.seed,
                progress=not args.quiet,
                run=run,
                early=start,
            )  # fmt: skip
        )
        report = result.save(out_dir, figure=figure, animation=gif)
    if not args.json:
        print(summary_table(report))
    for w in report["warnings"] + report.get("fabrication", {}).get("warnings", []):
        print(f"sieve-mi: warning: {w}", file=sys.stderr)
    print(f"outputs: {out_dir}/", file=sys.stderr if args.json else sys.stdout)
    if shake is not None:
        try:
            after_solve(scene, result, out_dir, shake, args)
        except KeyboardInterrupt:
            print(f"sieve-mi: the solve's outputs in {out_dir}/ are complete; stopped during "
                  "the shake trials: shake.json, shake.png and shake.gif were not made",
                  file=sys.stderr)  # fmt: skip
            raise
        report = _folder_report(out_dir)  # with its shake entry (and a target's chosen try)
    if args.json:  # report.json's content, for scripts (jq); everything else on stderr
        import json

        print(json.dumps(report, indent=2))
    return EXIT_OK if report["winner"] == "A" else EXIT_NO


def _folder_report(out_dir: str) -> dict:
    """The report.json a solve's folder holds now (after its shake trials)."""
    import json

    with open(os.path.join(out_dir, "report.json"), encoding="utf-8") as f:
        return json.load(f)


def _say_fit(v) -> None:
    """One stderr line per scale that ``check`` tried (it runs a whole attack each time)."""
    what = "passes" if v.passes else f"blocked (beta {v.beta:.4f}, sticks out {v.protrusion:.3f})"
    print(f"check: scale {v.scale:.4f}: {what}", file=sys.stderr, flush=True)


def _recorded_pixel_size(image: str, units: str) -> float:
    """The pixel size a hole image records (PNG ``pHYs``, as solve's hole.png has), in ``units``."""
    from sieve_mi.geometry.hole_image import image_size
    from sieve_mi.geometry.pixels import image_pixel_size

    image_size(image)  # a missing, unreadable or oversized image: one line
    size = image_pixel_size(image, units)
    if size is None:
        raise SieveError(
            f"--hole {image}: the image records no pixel size (PNG pHYs); give --pixel-size "
            "(the image's pixel size in scene units)"
        )
    return size


def cmd_check(args) -> int:
    import json
    from dataclasses import fields

    from sieve_mi.backend import use_variant
    from sieve_mi.game.check import CheckSettings, check
    from sieve_mi.geometry.meshes import load_shape
    from sieve_mi.outputs import outdir
    from sieve_mi.outputs.console import check_summary

    if args.hole is not None and args.pixel_size is None:
        args.pixel_size = _recorded_pixel_size(args.hole, args.units)
    inputs = [p for p in (args.shape, args.sieve, args.hole) if p]
    if args.out is not None:
        outdir.validate(args.out, inputs=inputs)  # again just before the swap
    use_variant(args.variant)
    shape = load_shape(args.shape, scale=args.scale)
    settings = CheckSettings(**{f.name: getattr(args, f.name) for f in fields(CheckSettings)})
    rep = check(
        shape,
        sieve=args.sieve,
        axis=args.axis,
        image=args.hole,
        pixel_size=args.pixel_size,
        units=args.units,
        settings=settings,
        progress=None if args.quiet else _say_fit,
    )
    text = json.dumps(rep.to_dict(), indent=2, default=lambda x: None if x != x else str(x))
    if args.out is not None:
        from sieve_mi.outputs.viewer import check_holes, render_check_page

        with outdir.writing(args.out, command="check", inputs=inputs) as tmp:
            with open(os.path.join(tmp, "report.json"), "w") as fh:
                fh.write(text + "\n")
            holes = check_holes(rep.sieve_holes)
            with open(os.path.join(tmp, "report.html"), "w", encoding="utf-8") as fh:
                fh.write(render_check_page(json.loads(text), shape, holes))
    print(text if args.json else check_summary(rep))
    if args.out is not None:
        print(f"outputs: {args.out}/", file=sys.stderr if args.json else sys.stdout)
    return EXIT_OK if rep.passes else EXIT_NO


def cmd_view(args) -> int:
    """Open ``FOLDER/report.html`` in the default browser (Python's :mod:`webbrowser`)."""
    import pathlib
    import webbrowser

    folder = args.folder
    if not os.path.isdir(folder):
        raise SieveError(f"{folder}: no such output folder")
    page = os.path.join(folder, "report.html")
    if not os.path.isfile(page):
        raise SieveError(
            f"{folder}: has no report.html (write it with sieve-mi solve or check --out)"
        )
    from sieve_mi.outputs.outdir import read_marker

    marker = read_marker(folder)
    if marker is None or "report.html" not in marker.get("files", []):
        raise SieveError(
            f"{folder}: its report.html was not written by sieve-mi (no .sieve-mi marker lists "
            "it); open it with a browser yourself if you trust it"
        )
    url = pathlib.Path(os.path.abspath(page)).as_uri()
    if not webbrowser.open(url):
        raise SieveError(f"{page}: no browser could be started; open {url} by hand")
    print(url)
    return 0


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM and SIGHUP handlers, so a kill cleans up as Ctrl-C does."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum, frame):
    note_signal(signum)  # a library may wrap the exception raised here, even as text only
    raise Terminated(signum)


def _raise_interrupt(signum, frame):
    note_signal(signum)
    raise KeyboardInterrupt


@contextlib.contextmanager
def _termination_as_interrupt():
    """Turn SIGTERM and SIGHUP into :class:`Terminated` inside the block (main thread only).

    SIGINT, SIGTERM and SIGHUP are unblocked in the main thread first: a process started with
    them blocked (a launcher's inherited signal mask) could otherwise not be interrupted.
    """
    names = ("SIGTERM", "SIGHUP")
    sigs = [getattr(signal, n) for n in names if hasattr(signal, n)]
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT, *sigs])
    old = {s: signal.signal(s, _raise_terminated) for s in sigs}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not when ignored
        old[signal.SIGINT] = signal.signal(signal.SIGINT, _raise_interrupt)
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


def cmd_certify(args) -> int:
    import json

    from sieve_mi.certify import certify, read_svg_hole, replay
    from sieve_mi.certify.certificate import writable_certificate

    if args.replay is not None:
        if args.shape or args.certificate is not None:
            raise SieveError(
                "--replay takes only the certificate file (no SHAPE, no --certificate)"
            )
        rep = replay(args.replay)
        if args.json:
            print(json.dumps(rep, indent=2))
        else:
            verdict = "valid" if rep["valid"] else "INVALID"
            print(
                f"certificate {verdict}: claims {rep['status']}{_replay_scope(rep)}, "
                f"{rep['leaves']} leaves re-proved, {rep['open']} open, {rep['seconds']:.2f} s"
            )
            for e in rep["errors"]:
                print(f"  {e}")
        return EXIT_OK if rep["valid"] else EXIT_NO
    if not args.shape or (args.sieve is None and args.hole is None):
        raise SieveError("certify needs SHAPE and --sieve PLATE or --hole SVG (or --replay CERT)")
    inputs = (args.shape, args.sieve, args.hole)
    if args.certificate is not None:
        writable_certificate(args.certificate, inputs)  # before any work, and again when written
    from sieve_mi.geometry.meshes import load_shape

    shape = load_shape(args.shape, scale=args.scale)
    if args.sieve:
        holes, thickness, note = _certify_plate(args.sieve, args.axis)
    else:
        holes, thickness, note = [read_svg_hole(args.hole)], None, ""
    # the answer on this plate: a thin one needs more than a straight proof (a section proof)
    result = certify(shape, holes, budget_s=args.certify_budget, scale=args.scale,
                     thickness=thickness)  # fmt: skip
    if args.sieve and thickness is None:
        result = result.on_plate(thickness, note)
    if args.certificate is not None:
        result.write_certificate(args.certificate, inputs)
    if args.json:
        scope = result.scope_line()
        print(json.dumps({**result.to_dict(), **({"scope": scope} if scope else {})}, indent=2))
    else:
        print(_certify_summary(shape.name, result))
    return {"proved": EXIT_OK, "passage": EXIT_NO}.get(result.status, EXIT_UNDECIDED)


def _certify_plate(path: str, axis: str) -> tuple[list, float | None, str]:
    """A plate's holes, its thickness where they are (None when it cannot be measured: an open
    or tilted mesh) and why not (``geometry.sieve.read_plate``)."""
    from sieve_mi.geometry.sieve import plate_holes, read_plate

    try:
        plate = read_plate(path, axis)
    except SieveError as exc:
        holes = plate_holes(path, axis)  # an unreadable mesh, or no hole: its own one line
        return holes, None, str(exc).removeprefix(f"{path}: ").split(";")[0]
    return plate.holes, plate.thickness, ""


def _replay_scope(rep: dict) -> str:
    """`` (holds for ...)`` of a replayed certificate's claim, empty when it claims nothing."""
    if not rep.get("holds_for"):
        return ""
    text = f" (holds for {rep['holds_for']}"
    if rep.get("section_thickness") is not None:  # a slab-section proof: its thickness
        text += f": {rep['section_thickness']:.4g} mm"
    elif rep["holds_for"] != "any plate" and rep.get("diameter") is not None:
        text += f": {rep['diameter']:.4g} mm"
    if rep.get("thickness") is not None:
        covered = "covered" if rep.get("covers_plate") else "NOT covered"
        text += f"; the recorded plate, {rep['thickness']:.4g} mm, is {covered}"
    return text + ")"


def _certify_summary(name: str, r) -> str:
    scope = r.scope_line()
    if r.straight == "proved" and r.status == "undecided":  # a straight proof, a thinner plate
        return f"{name}: undecided ({r.method}) in {r.seconds:.2f} s: {scope}"
    how = "section" if r.by_section else r.method  # the slab section alone: cells left open
    line = (
        f"{name}: {r.status} ({how}) in {r.seconds:.2f} s; cells {r.cells_examined} examined, "
        f"{r.cells_excluded} excluded, {r.cells_open} open; excluded {r.excluded_percent()} %"
    )
    if scope:
        line += "\n" + scope
    elif r.section is not None and r.section["status"] != "proved":
        line += f"\nno slab-section proof at {r.section['thickness']:.4g} mm within the budget"
    if r.passage:
        q, t = r.passage["quaternion"], r.passage["translation"]
        line += "\npassage: rotation (w,x,y,z) " + ", ".join(f"{v:.6f}" for v in q)
        line += ", translation " + ", ".join(f"{v:.6f}" for v in t)
    return line


#: Each subcommand -> the module and function that run it (looked up, and imported, on use).
COMMANDS = {
    "solve": (__name__, "cmd_solve"),
    "check": (__name__, "cmd_check"),
    "certify": (__name__, "cmd_certify"),
    "sort": ("sieve_mi.cascade.commands", "cmd_sort"),
    "sweep": ("sieve_mi.cascade.commands", "cmd_sweep"),
    "shake": ("sieve_mi.shake.commands", "cmd_shake"),
    "view": (__name__, "cmd_view"),
}


def _dispatch(args) -> int:
    """Apply the shared options, then run ``args.command``; its exit code."""
    from sieve_mi.backend import apply_threads, set_threads
    from sieve_mi.options import check_options

    check_options(args)
    if args.threads is not None:
        set_threads(args.threads)
    else:
        apply_threads()  # $SIEVE_MI_THREADS, checked as --threads is
    module, function = COMMANDS[args.command]
    return getattr(importlib.import_module(module), function)(args)


def _import_swallowers() -> None:
    """Import, before the signal handlers are set, the libraries that would swallow them.

    trimesh imports its optional dependencies inside ``except BaseException``, so a Ctrl-C or a
    SIGTERM turned into an exception during that import was lost and the run went on to the
    end. Imported here, a signal kills the process outright (nothing is written yet).
    """
    import trimesh  # noqa: F401


def _command(args) -> int:
    """Run the subcommand; a signal that some library swallowed still ends it as one."""
    code = _dispatch(args)
    received = signals_received()
    if received:
        raise Terminated(received[-1]) if received[-1] != signal.SIGINT else KeyboardInterrupt
    return code


def main(argv: list[str] | None = None) -> int:
    clear_signals()
    args = _parser().parse_args(argv)
    _import_swallowers()
    try:
        with _termination_as_interrupt():
            return _command(args)
    except SieveError as exc:
        print(f"sieve-mi: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Terminated as exc:
        print("sieve-mi: terminated", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:  # Ctrl-C, or a SIGTERM that a library's error stood in for
        signum = (signals_received() or [signal.SIGINT])[-1]
        print(f"sieve-mi: {'interrupted' if signum == signal.SIGINT else 'terminated'}",
              file=sys.stderr)  # fmt: skip
        return 128 + int(signum)
    except Exception as exc:  # a library (Mitsuba's render) may wrap the signal's exception
        cause = interruption(exc)  # the interrupt in its chain, or one a noted signal stands for
        if cause is None:
            raise
        received = signals_received()
        signum = cause.signum if isinstance(cause, Terminated) else None
        signum = signum or (received[-1] if received else signal.SIGINT)
        word = "interrupted" if signum == signal.SIGINT else "terminated"
        print(f"sieve-mi: {word}", file=sys.stderr)
        return 128 + int(signum)
    finally:
        clear_signals()  # a caller that runs main() in-process starts its next work afresh


def run() -> None:
    """The ``sieve-mi`` command: :func:`main`, then a quick exit with its status.

    When :func:`main` returns, every output is written, closed and in place. What the
    interpreter's teardown did after that (freeing Dr.Jit's, LLVM's and every module's objects,
    one by one) took 0.21-0.25 s of the default solve's 6 s (2026-12-07, the 2-core VM), so the
    exit handlers run (logging, multiprocessing, Ray, temporary folders), Python's and C's
    buffered output is flushed, and the process ends there. In-process callers use
    :func:`main`, which returns.
    """
    import atexit
    import ctypes

    code = main()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)  # a library's own printf buffer
    os._exit(int(code or 0))


if __name__ == "__main__":
    run()
