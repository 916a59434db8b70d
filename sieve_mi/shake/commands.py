"""The ``shake`` subcommand: ``sieve-mi shake DIR`` and ``sieve-mi shake --sieve PLATE PART...``."""

from __future__ import annotations

import os
import sys
from dataclasses import fields, replace

from sieve_mi.errors import SieveError
from sieve_mi.shake.settings import ShakeSettings, check_workers, metres_per_unit

__all__ = [
    "add_parser",
    "after_solve",
    "cmd_shake",
    "need_engine",
    "settings_from_args",
    "shake_after_solve",
    "shake_folder",
    "solve_shake_settings",
    "solve_shaken",
    "trials_option",
]


#: The optional extra that holds the physics engine and the convex decomposition.
ENGINE_MODULES = ("mujoco", "coacd")


def need_engine(command: str = "sieve-mi shake") -> None:
    """Refuse, in one line and before any work, a ``command`` that shakes where MuJoCo or CoACD
    is not installed (they are the optional extra ``sieve-mi[shake]``).

    Raises
    ------
    SieveError
        ``"sieve-mi shake needs MuJoCo and CoACD: pip install 'sieve-mi[shake]'"``.
    """
    import importlib

    for name in ENGINE_MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:  # the module is there but something it needs is not
                raise
            raise SieveError(
                f"{command} needs MuJoCo and CoACD: pip install 'sieve-mi[shake]'"
            ) from None


def add_parser(sub) -> None:
    """Add ``shake`` to the subcommand parsers ``sub``."""
    from sieve_mi.options import add_options

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
    p.add_argument(
        "--only",
        metavar="NAMES",
        help="shake only these shapes: their names separated by commas (as report.json names "
        "them; with --sieve, the part files' stems), e.g. --only S,G",
    )
    add_options(p, ShakeSettings)
    p.add_argument(
        "--no-clip", action="store_true", help="skip shake.gif (one rendered trial per shape)"
    )
    p.add_argument("--json", action="store_true", help="print shake.json on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")


def settings_from_args(args) -> ShakeSettings:
    """The options as :class:`ShakeSettings`; a bad value is one SieveError line naming the
    option (``shake: --trials: must be >= 1, got 0``), as a bad scene key's.

    Parameters
    ----------
    args : argparse.Namespace
        With an attribute per field (text or a value; None or absent: the default), as
        :func:`sieve_mi.options.add_options` makes them.
    """
    from sieve_mi.options import read_option

    values = {}
    for f in fields(ShakeSettings):
        value = getattr(args, f.name, None)
        if value is not None:
            values[f.name] = read_option(ShakeSettings, f.name, value, "shake")
    check_workers(values.get("workers", 0), "shake: --workers")  # as --threads is bounded
    return ShakeSettings(**values)


def shake_folder(
    folder: str, settings: ShakeSettings, progress=True, clip=True, only: list[str] | None = None
) -> dict:
    """Shake a solve's output folder; add ``shake.json``, ``shake.png``, ``shake.gif`` to it.

    ``only``: the names of the shapes to shake (default every one); ``shake.json`` then lists
    those alone. Every input and the folder itself are checked before the trials
    (:func:`~sieve_mi.shake.outputs.check_folder`: a folder without sieve-mi's marker, or with a
    file in it that the marker does not list, is refused); a folder without a ``report.html``
    gets the files and a one-line warning that no page got the card."""
    import tempfile

    from sieve_mi.shake.inputs import from_folder, select
    from sieve_mi.shake.outputs import add_to_folder, check_folder
    from sieve_mi.shake.run import shake

    inp = select(from_folder(folder, only), only)
    check_folder(folder)
    with tempfile.TemporaryDirectory(prefix="sieve-mi-shake-") as tmp:
        gif = os.path.join(tmp, "shake.gif") if clip else None
        report = shake(inp, settings, progress=progress, clip=gif)
        note = add_to_folder(report, folder, gif)
    if note is not None:
        print(f"sieve-mi: warning: {note}", file=sys.stderr)
    return report


def _shake_files(args, settings: ShakeSettings, inputs: list[str]) -> dict:
    """``shake --sieve PLATE PART... [--out DIR]``."""
    import tempfile

    from sieve_mi.shake.inputs import from_files, only_names, select
    from sieve_mi.shake.outputs import write_new_folder
    from sieve_mi.shake.run import shake

    metres_per_unit(args.units or "mm")  # an unknown unit refused before any mesh is read
    inp = select(from_files(args.sieve, args.paths, args.units or "mm"), only_names(args.only))
    if args.out is None:
        return shake(inp, settings, not args.quiet)
    with tempfile.TemporaryDirectory() as tmp:
        clip = None if args.no_clip else os.path.join(tmp, "shake.gif")
        report = shake(inp, settings, not args.quiet, clip=clip)
        write_new_folder(report, args.out, inputs, clip)
    return report


def cmd_shake(args) -> int:
    """Run ``sieve-mi shake``; prints the summary table (or shake.json with ``--json``)."""
    from sieve_mi.shake.inputs import only_names
    from sieve_mi.shake.outputs import summary, to_json

    need_engine()
    settings = settings_from_args(args)
    only = only_names(args.only)
    if args.sieve is None:
        if len(args.paths) != 1:
            raise SieveError("shake needs one solve output folder DIR, or --sieve PLATE PART...")
        if args.out is not None or args.units is not None:
            raise SieveError(
                "shake DIR writes into DIR and reads its units from report.json; "
                "--out and --units go with --sieve PLATE PART..."
            )
        report = shake_folder(args.paths[0], settings, not args.quiet, not args.no_clip, only)
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


def trials_option(
    text: str | None, command: str, flag: str = "--shake", base: ShakeSettings | None = None
) -> ShakeSettings | None:
    """``solve --shake N`` and ``sort --shake N``: ``base`` (default: the declared settings)
    with N trials, checked before any work starts as ``--trials`` is; None without the option.

    Raises
    ------
    SieveError
        ``"{command}: --shake: expected a whole number, got 'lots'"`` and the like.
    """
    if text is None:
        return None
    from sieve_mi.options import read_option

    trials = read_option(ShakeSettings, "trials", text, command, flag)
    return replace(base or ShakeSettings(), trials=trials)


def solve_shake_settings(text: str | None, scene=None) -> ShakeSettings | None:
    """``solve``'s shake settings, checked before the solve starts (as is the engine:
    :func:`need_engine`): the scene's ``[shake]`` table (its ``duration`` and ``seed``; its
    ``trials``, 200 where it gives a target alone) with ``--shake N`` trials; None where neither
    asks for trials."""
    table = None if scene is None else scene.shake
    base = None
    if table is not None and (text is not None or table.trials or table.target):
        base = ShakeSettings(trials=table.trials or ShakeSettings.trials,
                             duration=table.duration, seed=table.seed)  # fmt: skip
    settings = trials_option(text, "solve", base=base) if text is not None else base
    if settings is not None:
        need_engine("sieve-mi solve --shake" if text is not None else "a scene's [shake] table")
    return settings


def after_solve(scene, result, out_dir: str, settings: ShakeSettings, args) -> None:
    """Shake a fresh solve's folder (``solve --shake N`` or the scene's ``[shake]`` table), or
    reach the scene's ``[shake] target`` (:func:`sieve_mi.shake.target.reach_target`); then put
    the ``shake`` entry into report.json and print one line per shape (stdout; stderr when
    solve prints JSON). A solve that wrote no plate says so in one warning line."""
    from sieve_mi.shake.inputs import read_report
    from sieve_mi.shake.outputs import record, report_entry, shape_lines, target_card

    if not os.path.isfile(os.path.join(out_dir, "sieve.stl")):
        print("sieve-mi: warning: no sieve.stl to shake (no hole was found)", file=sys.stderr)
        return
    out = sys.stderr if args.json else sys.stdout
    card = None
    if scene.shake.target is None:
        run = shake_after_solve(out_dir, settings, args.quiet, args.json)
        entry = report_entry(run, read_report(out_dir)[1])
    else:
        from sieve_mi.shake.target import reach_target

        flags = {"variant": args.variant, "seed": args.seed, "quiet": args.quiet,
                 "to_stderr": args.json, "figure": not args.no_figure,
                 "animation": not args.no_animation}  # fmt: skip
        got = reach_target(scene, result, out_dir, settings, flags)
        entry = report_entry(got["run"], got["report"])
        entry["target"] = {"fraction": scene.shake.target, "met": got["met"],
                           "chosen": got["chosen"], "tries": got["tries"]}  # fmt: skip
        card = target_card(entry["target"], scene.units)
        word = "met" if got["met"] else "not met; the folder holds the best try"
        print(f"target {100 * scene.shake.target:g} %: {word} (try {got['chosen']})", file=out)
    record(out_dir, entry, card)
    for line in shape_lines(entry):
        print(line, file=out)


def shake_after_solve(out_dir: str, settings: ShakeSettings, quiet: bool, to_stderr: bool) -> dict:
    """Shake a fresh solve's folder; the table goes to stdout (stderr when solve prints JSON);
    returns the run (:func:`~sieve_mi.shake.run.shake`)."""
    from sieve_mi.shake.outputs import summary

    report = shake_folder(out_dir, settings, progress=not quiet)
    print(summary(report), file=sys.stderr if to_stderr else sys.stdout)
    return report


def solve_shaken(
    scene, out_dir: str, *, variant=None, seed=None, progress=True, figure=True, animation=True
) -> dict:
    """``sieve-mi solve SCENE --out DIR`` in Python, the scene's ``[shake]`` table honoured:
    solve (:func:`sieve_mi.solve`), save into ``out_dir``, then the table's trials or its
    target loop (:func:`after_solve`), as the command line does. ``sieve_mi.solve`` plays the
    game alone: the trials need the engine (an optional extra) and the plate in a folder, and sit
    above the API in the floor plan (docs/api.md).

    Parameters
    ----------
    scene : sieve_mi.Scene
    out_dir : str
        The output folder (a folder sieve-mi did not write is refused, as ``Result.save`` does).
    variant, seed, progress
        As for :func:`sieve_mi.solve`; the per-shape lines and the target's lines go to stderr.
    figure, animation
        figure.png and passage.gif (of every try the target loop saves).

    Returns
    -------
    dict
        The folder's report.json after the trials: with a ``shake`` entry where the table asks
        for trials (``shake.target`` with a target).

    Raises
    ------
    SieveError
        As ``sieve-mi solve``: bad arguments, or trials asked for without MuJoCo and CoACD.
    """
    import json
    from types import SimpleNamespace

    from sieve_mi import api
    from sieve_mi.outputs.outdir import validate
    from sieve_mi.outputs.report import input_paths

    validate(out_dir, inputs=input_paths(scene))  # refused before the solve, as solve does
    settings = solve_shake_settings(None, scene)  # the engine checked before the solve too
    result = api.solve(scene, variant=variant, seed=seed, progress=progress)
    result.save(out_dir, figure=figure, animation=animation)
    if settings is not None:
        args = SimpleNamespace(variant=variant, seed=seed, quiet=not progress, json=True,
                               no_figure=not figure, no_animation=not animation)  # fmt: skip
        after_solve(scene, result, out_dir, settings, args)
    with open(os.path.join(out_dir, "report.json"), encoding="utf-8") as f:
        return json.load(f)
