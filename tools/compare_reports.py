"""Compare two folders of report.json files written by tools/scene_sweep.sh.

For every scene in both folders: the winner, and per block shape β and protrusion before and
after. A row is flagged when the winner differs, or when β differs by more than ``--beta`` or the
protrusion by more than ``--pixels`` pixels of that scene's verdict raster.

With ``--exact`` every value of every report must be equal instead (timings, ``*_s`` keys and
provenance aside): the check for refactors that must not change a bit.

Usage: python tools/compare_reports.py BEFORE AFTER [--beta 0.01] [--pixels 1] [--exact]
Exit status 1 when any row is flagged.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _load(folder: str) -> dict[str, dict]:
    out = {}
    for name in sorted(os.listdir(folder)):
        if name.endswith(".json"):
            with open(os.path.join(folder, name)) as fh:
                out[name[:-5]] = json.load(fh)
    return out


def _pixel(report: dict) -> float:
    """The hole raster's pixel size, scene units (0 when the report does not say)."""
    return float(report.get("pixel_size", 0.0))


def compare(before: dict, after: dict, beta_tol: float, pixels: float) -> list[str]:
    """One printed row per scene and block shape; rows ending in '<<' are flagged."""
    rows = []
    for name in sorted(set(before) & set(after)):
        b, a = before[name], after[name]
        px = max(_pixel(b), _pixel(a))
        flag = " <<" if b["winner"] != a["winner"] else ""
        rows.append(f"{name}: winner {b['winner']} -> {a['winner']}{flag}")
        for sb, sa in zip(b["block"], a["block"]):
            db = abs(sb["loss"] - sa["loss"])
            dp = abs(sb["protrusion"] - sa["protrusion"])
            bad = db > beta_tol or (px > 0 and dp > pixels * px)
            rows.append(
                f"  {sb['name']}: beta {sb['loss']:.4f} -> {sa['loss']:.4f}, "
                f"protrusion {sb['protrusion']:.4f} -> {sa['protrusion']:.4f}"
                f" (pixel {px:.4f}){' <<' if bad else ''}"
            )
    for name in sorted(set(before) ^ set(after)):
        rows.append(f"{name}: only in {'before' if name in before else 'after'} <<")
    return rows


#: Keys whose values may differ between two runs of the same code (times, commit, machine).
VOLATILE = {"timings", "provenance"}


def differences(a, b, path: str = "") -> list[str]:
    """Every place where two JSON values differ (``VOLATILE`` keys and ``*_s`` keys aside)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k in VOLATILE or k.endswith("_s"):
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only {'after' if k in b else 'before'}")
            else:
                out += differences(a[k], b[k], f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {str(a)[:60]} -> {str(b)[:60]}"]


def compare_exact(before: dict, after: dict) -> list[str]:
    """One row per scene: identical, or its differences (flagged)."""
    rows = []
    for name in sorted(set(before) | set(after)):
        if name not in before or name not in after:
            rows.append(f"{name}: only in {'before' if name in before else 'after'} <<")
            continue
        diff = differences(before[name], after[name], name)
        rows.append(f"{name}: identical" if not diff else f"{name}: {len(diff)} differences <<")
        rows += [f"  {d} <<" for d in diff[:20]]
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before")
    p.add_argument("after")
    p.add_argument("--beta", type=float, default=0.01, help="largest β change not flagged")
    p.add_argument("--pixels", type=float, default=1.0, help="largest protrusion change, pixels")
    p.add_argument("--exact", action="store_true", help="every value equal (timings aside)")
    args = p.parse_args(argv)
    if args.exact:
        rows = compare_exact(_load(args.before), _load(args.after))
    else:
        rows = compare(_load(args.before), _load(args.after), args.beta, args.pixels)
    print("\n".join(rows))
    return 1 if any(r.endswith("<<") for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
