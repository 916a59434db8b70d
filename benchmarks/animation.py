"""The cost of passage.gif and report.html, in one run.

Usage: ``python -m benchmarks.animation [--variant V] [--scene default|letters] [--repeat R]``

Solves the scene with small solver settings (the outputs' cost does not depend on how long the
search ran), then times: the passage scene (:func:`sieve_mi.outputs.passage.build`), the GIF's frames in
one batched ``mi.render`` (first call, with kernel compilation, then the median of R more), the
same frames rendered one ``mi.render`` per frame (the alternative the batch replaces), the GIF
file, and the page (:func:`sieve_mi.outputs.viewer.render_page`, with its size).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from sieve_mi.testing.settings import TINY_SOLVER, TINY_VERDICT, settings_toml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMALL = settings_toml(solver=TINY_SOLVER, verdict={**TINY_VERDICT, "resolution": 128})


def _timed(fn, repeat: int = 1) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--variant", default=None)
    p.add_argument("--scene", default="default", choices=("default", "letters"))
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()

    from sieve_mi.api import solve
    from sieve_mi.outputs import animation, viewer
    from sieve_mi.outputs.passage import build
    from sieve_mi.outputs.report import report_dict
    from sieve_mi.scene import load_scene

    body = open(os.path.join(ROOT, "scenes", f"{args.scene}.toml")).read()
    body = body.split("[solver]")[0].split("[verdict]")[0]  # the scene's own solver settings go
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "scene.toml")
        with open(path, "w") as fh:
            fh.write(body.replace('mesh = "meshes/', f'mesh = "{ROOT}/scenes/meshes/') + SMALL)
        result = solve(load_scene(path), variant=args.variant, progress=False)
        t_build, passage = _timed(lambda: build(result))
        n = animation.frame_count(passage)
        faces = len(passage.plate_faces) + sum(len(x.faces) for x in passage.pieces)
        t_first, _ = _timed(lambda: animation.render_frames(passage))
        t_batch, _ = _timed(lambda: animation.render_frames(passage), args.repeat)
        s = animation.phases(n)
        box = passage.bounds()

        def one_by_one():
            return [animation.render_frames(passage, phases=[x], box=box) for x in s]

        one_by_one()  # compile
        t_single, _ = _timed(one_by_one, args.repeat)
        t_gif, info = _timed(lambda: animation.write_gif(os.path.join(tmp, "p.gif"), passage))
        size_gif = os.path.getsize(os.path.join(tmp, "p.gif"))
        report = report_dict(result)
        t_page, page = _timed(lambda: viewer.render_page(result, report, passage, []))
    print(f"scene {args.scene}: {n} frames of {animation.WIDTH}x{animation.HEIGHT}, "
          f"{animation.SPP} spp, {faces:,} faces per frame, variant {result.variant}")  # fmt: skip
    print(f"passage scene (plate, rest heights)  {t_build:.3f} s")
    print(f"frames, one batch, first call        {t_first:.3f} s")
    print(f"frames, one batch (median of {args.repeat})      {t_batch:.3f} s")
    print(f"frames, one render per frame         {t_single:.3f} s")
    print(f"passage.gif written                  {t_gif:.3f} s, {size_gif / 1024:.0f} KiB")
    print(f"report.html rendered                 {t_page:.3f} s, {len(page) / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
