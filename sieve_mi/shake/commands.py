"""The ``shake`` subcommand: ``sieve-mi shake DIR`` and ``sieve-mi shake --sieve PLATE PART...``."""

from __future__ import annotations

import os
import sys
from dataclasses import fields

from sieve_mi.errors import SieveError
from sieve_mi.shake.settings import ShakeSettings

__all__ = [
    "add_parser",
    "cmd_shake",
    "settings_from_args",
    "shake_after_solve",
    "shake_folder",
    "solve_shake_settings",
]

_HELP = {
    "trials": "independent trials per shape",
    "duration": "shaking time per trial, s",
    "amplitude": "peak vertical displacement of the plate, mm (Retsch AS 200: up to 3 mm)",
    "frequency": "shaker frequency, Hz (mains: 50 or 60)",
    "twist": "peak rotation of the plate about the vertical, degrees",
    "wall": "height of the frame wall above the plate, mm",
    "drop": "gap between the plate and the part's bounding sphere at release, mm",
    "density": "density of every part, kg/m^3 (PLA 1240)",
    "friction": "friction coefficient part-plate",
    "timestep": "integration step, ms",
    "seed": "seed of the random drops (same seed, same numbers)",
    "coacd_threshold": "CoACD concavity threshold for non-convex parts",
    "workers": "worker processes (0: every CPU core); results do not depend on it",
}


def add_parser(sub) -> None:
    """Add ``shake`` to the subcommand parsers ``sub``."""
    p = sub.add_parser(
        "shake",
        help="shake each shape on its sieve many times (MuJoCo) and count how often it falls through",
    )
    p.add_argument(
        "paths",
        nargs="*",
        metavar="DIR | PART",
        help="a solve's output folder; or, with --sieve, the part meshes to shake",
    )
    p.add_argument("--sieve", help="a plate mesh (holes along z) to shake the PART meshes on")
    p.add_argument("--units", help="length unit of --sieve's meshes (default mm)")
    p.add_argument("--out", help="with --sieve: also write DIR/shake.json, shake.png")
    defaults = ShakeSettings()
    for f in fields(ShakeSettings):
        p.add_argument(
            "--" + f.name.replace("_", "-"),
            dest=f.name,
            default=None,
            metavar="N",
            help=f"{_HELP[f.name]} (default {getattr(defaults, f.name)})",
        )
    p.add_argument(
        "--no-clip", action="store_true", help="skip shake.gif (one rendered trial per shape)"
    )
    p.add_argument("--json", action="store_true", help="print shake.json on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")


def settings_from_args(args, **overrides) -> ShakeSettings:
    """The options as :class:`ShakeSettings`; a bad value is one SieveError line."""
    values = {}
    for f in fields(ShakeSettings):
        text = getattr(args, f.name, None)
        if text is None:
            continue
        kind = int if f.type in ("int", int) else float
        try:
            values[f.name] = kind(text)
        except (TypeError, ValueError):
            what = "a whole number" if kind is int else "a number"
            raise SieveError(
                f"shake --{f.name.replace('_', '-')} {text}: expected {what}"
            ) from None
    values.update(overrides)
    return ShakeSettings(**values)


def _clip_path(folder: str) -> str:
    """A temporary GIF path in ``folder`` (the clip is moved in as ``shake.gif`` at the end)."""
    return os.path.join(folder, f".shake.tmp-{os.getpid()}.gif")


def shake_folder(folder: str, settings: ShakeSettings, progress=True, clip=True) -> dict:
    """Shake a solve's output folder; add ``shake.json``, ``shake.png``, ``shake.gif`` to it."""
    from sieve_mi.shake.inputs import from_folder
    from sieve_mi.shake.outputs import add_to_folder
    from sieve_mi.shake.run import shake

    inp = from_folder(folder)
    tmp = _clip_path(folder) if clip else None
    try:
        report = shake(inp, settings, progress=progress, clip=tmp)
        add_to_folder(report, folder, tmp)
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.remove(tmp)
    return report


def _shake_files(args, settings: ShakeSettings, inputs: list[str]) -> dict:
    """``shake --sieve PLATE PART... [--out DIR]``."""
    import tempfile

    from sieve_mi.shake.inputs import from_files
    from sieve_mi.shake.outputs import write_new_folder
    from sieve_mi.shake.run import shake

    inp = from_files(args.sieve, args.paths, args.units or "mm")
    if args.out is None:
        return shake(inp, settings, not args.quiet)
    with tempfile.TemporaryDirectory() as tmp:
        clip = None if args.no_clip else os.path.join(tmp, "shake.gif")
        report = shake(inp, settings, not args.quiet, clip=clip)
        write_new_folder(report, args.out, inputs, clip)
    return report


def cmd_shake(args) -> int:
    """Run ``sieve-mi shake``; prints the summary table (or shake.json with ``--json``)."""
    from sieve_mi.shake.outputs import summary, to_json

    settings = settings_from_args(args)
    if args.sieve is None:
        if len(args.paths) != 1:
            raise SieveError("shake needs one solve output folder DIR, or --sieve PLATE PART...")
        if args.out is not None or args.units is not None:
            raise SieveError(
                "shake DIR writes into DIR and reads its units from report.json; "
                "--out and --units go with --sieve PLATE PART..."
            )
        report = shake_folder(args.paths[0], settings, not args.quiet, not args.no_clip)
        where = args.paths[0]
    else:
        inputs = [args.sieve, *args.paths]
        if args.out is not None:
            from sieve_mi.outputs.outdir import validate

            validate(args.out, inputs=inputs)  # before the work; again before the swap
        report = _shake_files(args, settings, inputs)
        where = args.out
    print(to_json(report) if args.json else summary(report), end="" if args.json else "\n")
    if where is not None:
        print(f"outputs: {os.path.join(where, 'shake.json')}", file=sys.stderr)
    return 0


def solve_shake_settings(text: str | None) -> ShakeSettings | None:
    """``solve --shake N``'s settings (checked before the solve starts), None without it."""
    if text is None:
        return None
    try:
        trials = int(text)
    except ValueError:
        raise SieveError(f"solve --shake {text}: expected a whole number of trials") from None
    if trials < 1:
        raise SieveError(f"solve --shake {text}: expected at least 1 trial")
    return ShakeSettings(trials=trials)


def shake_after_solve(out_dir: str, settings: ShakeSettings, quiet: bool, to_stderr: bool) -> None:
    """Shake a fresh solve's folder; the table goes to stdout (stderr when solve prints JSON).

    A solve that found no hole wrote no plate: then it says so in one warning line."""
    from sieve_mi.shake.outputs import summary

    if not os.path.isfile(os.path.join(out_dir, "sieve.stl")):
        print("sieve-mi: warning: no sieve.stl to shake (no hole was found)", file=sys.stderr)
        return
    report = shake_folder(out_dir, settings, progress=not quiet)
    print(summary(report), file=sys.stderr if to_stderr else sys.stdout)
