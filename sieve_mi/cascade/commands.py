"""The ``sort`` and ``sweep`` subcommands of the command line (see :mod:`sieve_mi.cli`)."""

from __future__ import annotations

import json
import os
import sys

from sieve_mi.errors import EXIT_NO, EXIT_OK, SieveError

__all__ = [
    "COMMANDS",
    "MAX_SEEDS",
    "MAX_TOLERANCES",
    "VARIANT_HELP",
    "add_parsers",
    "cmd_sort",
    "cmd_sweep",
    "parse_seeds",
    "parse_tolerances",
    "tray_table",
]

VARIANT_HELP = "Mitsuba variant: llvm_ad_mono (CPU) or cuda_ad_mono (GPU); default $SIEVE_MI_VARIANT or llvm_ad_mono"


def _engine_options(p, default_out: str, what: str) -> None:
    """Options shared by ``sort`` and ``sweep``: where the games run and the output folder."""
    p.add_argument("--out", help=f"output folder (default: {default_out})")
    p.add_argument("--variant", help=VARIANT_HELP)
    p.add_argument(
        "--address",
        help="run the games on an existing Ray cluster (host:port of its head); default: a "
        "local Ray on this machine",
    )
    p.add_argument("--workers", type=int, help="local Ray: CPUs to use (default: all)")
    p.add_argument(
        "--serial", action="store_true", help="play the games one after another, without Ray"
    )
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument(
        "--json", action="store_true", help=f"print {what} on stdout instead of the table"
    )


def add_parsers(sub) -> None:
    """Add ``sort`` and ``sweep`` to the subcommand parsers ``sub``."""
    s = sub.add_parser(
        "sort", help="design a cascade of sieves that sorts a mixture of [[shape]]s into trays"
    )
    s.add_argument("mixture", help="mixture file (TOML with [[shape]] tables)")
    s.add_argument("--seed", type=int, help="random seed of every game (overrides [solver] seed)")
    s.add_argument(
        "--shake",
        metavar="N",
        help="then shake each sieve with the parts that reach it, N parts of each shape (MuJoCo; "
        "the mixture's [shake] table sets the shaker), and report in which tray each shape ends",
    )
    _engine_options(s, "out/<name>/", "cascade.json")
    w = sub.add_parser(
        "sweep",
        help="solve one scene over several seeds (and tolerances) and keep the largest margin",
    )
    w.add_argument("scene", help="scene file (TOML) or a paper authors' configuration (JSON)")
    w.add_argument(
        "--seeds",
        "--seed",
        dest="seeds",
        help="seeds to play: one seed 7, a range 0-9 or a list 0,3,7 (default 0-4); "
        "--seed is the same option",
    )
    w.add_argument("--tolerance", help="tolerances to try, comma-separated (default: the scene's)")
    _engine_options(w, "out/<name>-sweep/", "sweep.json")


#: Most seeds one sweep plays (each is a whole solve: 1,000 default solves take about an hour).
MAX_SEEDS = 1000


def parse_seeds(text: str) -> list[int]:
    """``"0-9"`` -> [0, ..., 9]; ``"0,3,7"`` -> [0, 3, 7]; a one-line SieveError otherwise.

    At most :data:`MAX_SEEDS` seeds, each from 0 to 2**64 - 1 (counted before any list is built).
    """
    from sieve_mi.settings import SEED_MAX

    ranges = []
    try:
        for part in text.split(","):
            lo, dash, hi = part.strip().partition("-")
            ranges.append((int(lo), int(hi) if dash else int(lo)))
    except ValueError:
        raise SieveError(
            f"--seeds {text}: expected a range like 0-9 or a list like 0,3,7"
        ) from None
    if not ranges or any(lo < 0 or hi < lo or hi > SEED_MAX for lo, hi in ranges):
        raise SieveError(
            f"--seeds {text}: give at least one seed, all from 0 to 2**64 - 1, ranges low-high"
        )
    if sum(hi - lo + 1 for lo, hi in ranges) > MAX_SEEDS:
        raise SieveError(f"--seeds {text}: more than {MAX_SEEDS} seeds; sweep fewer at a time")
    return sorted({s for lo, hi in ranges for s in range(lo, hi + 1)})


#: Most tolerances one sweep tries (each is a solve per seed).
MAX_TOLERANCES = 100


def parse_tolerances(text: str | None) -> list[float] | None:
    """``"0.5,1.0"`` -> [0.5, 1.0]; None stays None (the scene's own tolerance)."""
    if text is None:
        return None
    from sieve_mi.scene import Fabrication
    from sieve_mi.settings import read_value

    parts = text.split(",")
    if len(parts) > MAX_TOLERANCES:
        raise SieveError(f"--tolerance {text[:60]}: more than {MAX_TOLERANCES} tolerances")
    try:
        values = [float(x) for x in parts]
    except ValueError:
        raise SieveError(f"--tolerance {text[:60]}: expected numbers like 0.5,1.0") from None
    return [read_value(Fabrication, "tolerance", v, "sweep", "--tolerance") for v in values]


def _engine(args):
    """The :class:`~sieve_mi.cascade.games.EngineSettings` of ``--variant``, ``--address``,
    ``--workers``, ``--serial`` and ``--quiet`` (checked)."""
    from sieve_mi.cascade.games import EngineSettings, check_address, ray_module

    if args.workers is not None and args.workers < 1:
        raise SieveError(f"--workers {args.workers}: must be at least 1")
    if args.serial and args.address:
        raise SieveError("--serial and --address exclude each other")
    use_ray = not args.serial
    if use_ray and ray_module() is None:
        if args.address:
            raise SieveError(
                f"--address {args.address}: Ray is not installed; pip install 'sieve-mi[cluster]'"
            )
        print(
            "sieve-mi: Ray is not installed; playing the games one after another", file=sys.stderr
        )
        use_ray = False
    if args.address:
        check_address(args.address)
    return EngineSettings(
        use_ray=use_ray,
        address=args.address,
        workers=args.workers,
        variant=args.variant,
        progress=not args.quiet,
    )


def cmd_sort(args) -> int:
    from sieve_mi.api import check_seed
    from sieve_mi.cascade.mixture import load_mixture
    from sieve_mi.cascade.sort import sort_mixture
    from sieve_mi.shake.commands import need_engine, trials_option

    mixture = load_mixture(args.mixture)
    shake = trials_option(args.shake, "sort", base=mixture.shake)
    if shake is not None:
        need_engine("sieve-mi sort --shake")
    check_seed(args.seed, "--seed")
    engine = _engine(args)
    out = args.out or os.path.join("out", mixture.name)
    report = sort_mixture(mixture, out, engine=engine, seed=args.seed, shake=shake)
    text = tray_table(report)
    if "shake" in report:
        from sieve_mi.cascade.purity import purity_table

        text += "\n" + purity_table(report["shake"])
    print(json.dumps(report, indent=2) if args.json else text)
    for w in report["warnings"]:
        print(f"sieve-mi: warning: {w}", file=sys.stderr)
    print(f"outputs: {out}/", file=sys.stderr if args.json else sys.stdout)
    return EXIT_NO if report["inseparable"] else EXIT_OK


def tray_table(report: dict) -> str:
    """The cascade as text: one line per sieve and tray, then the inseparable pairs."""
    lines = [f"{'sieve':<6}{'holds':<24}{'passes':<36}{'beta':>8}{'protrusion':>12}  certified"]
    for s in report["sieves"]:
        lines.append(
            f"{s['index'] + 1:<6}{'+'.join(s['holds']):<24}{', '.join(s['passes']):<36}"
            f"{s['margins']['beta']:>8.4f}{s['margins']['protrusion']:>12.3f}  "
            + _proofs_cell(s["blocks"])
        )
    lines.append("trays (top to bottom): " + " | ".join("+".join(t) for t in report["trays"]))
    for pair in report["inseparable"]:
        lines.append(f"cannot split {pair['pair'][0]} and {pair['pair'][1]}: {pair['reason']}")
    run = report["runner"]
    lines.append(f"games: {run['played']} played, {run['reused']} reused ({run['mode']})")
    return "\n".join(lines)


def _proofs_cell(blocks: list) -> str:
    """The tray table's 'certified' cell: "proved" when every held shape is, else per shape."""
    status = [b.get("certified", "-") for b in blocks]
    if status and all(x == "proved" for x in status):
        return "proved"
    return ", ".join(f"{b['name']} {x}" for b, x in zip(blocks, status))


def cmd_sweep(args) -> int:
    from sieve_mi.api import load_scene
    from sieve_mi.cascade.sweep import sweep_scene, sweep_table

    seeds = parse_seeds(args.seeds or "0-4")
    tolerances = parse_tolerances(args.tolerance)
    scene = load_scene(args.scene)
    engine = _engine(args)
    out = args.out or os.path.join("out", scene.name + "-sweep")
    report = sweep_scene(scene, out, seeds=seeds, tolerances=tolerances, engine=engine)
    print(json.dumps(report, indent=2) if args.json else sweep_table(report))
    print(f"outputs: {out}/", file=sys.stderr if args.json else sys.stdout)
    return EXIT_OK if report["best"]["winner"] == "A" else EXIT_NO


COMMANDS = {"sort": cmd_sort, "sweep": cmd_sweep}
