"""Command line: ``sieve-mi solve SCENE``."""

from __future__ import annotations

import argparse
import os
import sys

from sieve_mi.errors import SieveError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="sieve-mi", description="Design shape-aware sieves (Mitsuba 3 + Dr.Jit).")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("solve", help="design a hole that passes the [[pass]] shapes and blocks the [[block]] shapes")
    s.add_argument("scene", help="scene file (TOML)")
    s.add_argument("--out", help="output folder (default: out/<name>/ beside the current directory)")
    s.add_argument("--variant", default="llvm_ad_mono", help="Mitsuba variant: llvm_ad_mono (CPU, default) or cuda_ad_mono (GPU)")
    s.add_argument("--seed", type=int, help="random seed (overrides [solver] seed)")
    s.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def cmd_solve(args) -> int:
    from sieve_mi.report import summary_table, write_outputs
    from sieve_mi.scene import load_scene
    from sieve_mi.solve import solve

    scene = load_scene(args.scene)
    out_dir = args.out or os.path.join("out", scene.name)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise SieveError(f"{out_dir}: --out exists and is not a folder; choose another path")
    if args.seed is not None and args.seed < 0:
        raise SieveError(f"--seed {args.seed}: must be >= 0")
    result = solve(scene, variant=args.variant, seed=args.seed, progress=not args.quiet)
    report = write_outputs(result, out_dir)
    print(summary_table(report))
    print(f"outputs: {out_dir}/")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "solve":
            return cmd_solve(args)
    except SieveError as exc:
        print(f"sieve-mi: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sieve-mi: interrupted", file=sys.stderr)
        return 130
    return 1


if __name__ == "__main__":
    sys.exit(main())
