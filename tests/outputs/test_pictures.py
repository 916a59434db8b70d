"""The pictures' worker (sieve_mi.outputs.pictures): a forked process renders on the parent's threads."""

from __future__ import annotations

import os
import sys
import types

import numpy as np
import pytest
import trimesh

from sieve_mi.outputs import pictures
from sieve_mi.workers import worker_pool

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux only")


def _threads_in_worker() -> tuple[int, int, str]:
    """Dr.Jit's thread count, the threads running beside this one, and the variant."""
    import drjit as dr
    import mitsuba as mi

    return dr.thread_count(), len(os.listdir("/proc/self/task")) - 1, mi.variant()


def test_the_worker_renders_on_as_many_threads_as_its_parent(mi):
    # A fork keeps only the forking thread: without _rgb_once's restart the worker's Dr.Jit
    # pool counts the parent's workers but none runs (every kernel on one thread).
    import drjit as dr

    before = mi.variant()
    if before.startswith("cuda"):
        pytest.skip("the pictures render in-process with a CUDA variant")
    threads = dr.thread_count()
    dr.set_thread_count(2)
    try:
        assert np.asarray(dr.sum(mi.Float(np.arange(1000.0)))).item() == 499500.0  # pool busy
        with worker_pool(1, initializer=pictures._rgb_once, what="test") as pool:
            count, running, variant = pool.submit(_threads_in_worker).result()
    finally:
        dr.set_thread_count(threads)
    assert running >= 2 and count >= 2
    if "llvm_ad_rgb" in mi.variants():
        assert variant == "llvm_ad_rgb"  # switched once, in the worker only
    assert mi.variant() == before


def test_the_worker_forked_ahead_renders_the_save_and_stops_with_an_error(mi, tmp_path):
    # pictures.ahead forks the worker when the stage ends; start() hands the pictures to that
    # process (already in an RGB variant); an exception in the save ends it at once.
    from sieve_mi.telemetry import Run

    if mi.variant().startswith("cuda"):
        pytest.skip("the pictures render in-process with a CUDA variant")
    run = Run().start()
    with pytest.raises(KeyboardInterrupt), pictures.ahead(run) as early:
        assert early.take() is None  # not before the stage ends
        with run.stage("screen"):
            pass
        pool = early.take()
        (pid,) = list(pool._processes)
        assert pid != os.getpid()
        _, _, variant = pool.submit(_threads_in_worker).result()
        if "llvm_ad_rgb" in mi.variants():
            assert variant == "llvm_ad_rgb"
        plate = trimesh.creation.box((60.0, 60.0, 2.0))
        cube, ball = trimesh.creation.box((10.0, 10.0, 10.0)), trimesh.creation.icosphere(2, 6.0)
        job = (plate, [cube], [ball], [True], "ahead")
        with pictures.start(str(tmp_path), job, None, mi.variant()) as pics:
            assert pics._future is not None  # the job went to the forked worker
            raise KeyboardInterrupt
    assert pictures._AHEAD is None
    with pytest.raises(ProcessLookupError):  # killed and reaped
        os.kill(pid, 0)


def _fake_render(folder: str, figure_args, passage) -> dict:
    """A stand-in for pictures.render: each picture's file holds its job and the process."""
    for name, what in (("figure.png", figure_args), ("passage.gif", passage)):
        if what is not None:
            with open(os.path.join(folder, name), "w") as fh:
                fh.write(f"{what} {os.getpid()}")
    return {"figure_end": None, "figure_s": 0.0, "animation_s": 0.0, "animation": None,
            "peak_gb": 0.0}  # fmt: skip


def test_pictures_started_before_the_margins_become_the_saves(mi, tmp_path, monkeypatch):
    # The solver hands its result to prerender before the margins stage; the save takes those
    # pictures over (moved into its folder: rendered once, by the worker) and the plate built
    # for them; the worker's own folder is gone when the block ends.
    from sieve_mi.outputs import fabrication, passage
    from sieve_mi.telemetry import Run

    if mi.variant().startswith("cuda"):
        pytest.skip("the pictures render in-process with a CUDA variant")
    monkeypatch.setattr(pictures, "render", _fake_render)
    built = ("sieve", None, 1.0, ("plate",))
    monkeypatch.setattr(fabrication, "plate_meshes", lambda result: built)
    monkeypatch.setattr(fabrication, "figure_args", lambda result, meshes: "figure-job")
    monkeypatch.setattr(passage, "build", lambda result, plate: f"gif-job-{plate}")
    run = Run().start()
    save = tmp_path / "save"
    save.mkdir()
    with pictures.ahead(run) as early:
        with run.stage("screen"):
            pass
        game = types.SimpleNamespace(outline=object(), sheet=None)
        early.prerender(game, True, True)
        folder, future = early.prerendered((True, True))
        assert future is not None and early.prerendered((True, False)) == (None, None)
        # the save writes the plate built for the pictures: its result has the same hole
        assert pictures.built(types.SimpleNamespace(outline=game.outline, sheet=None)) is built
        assert pictures.built(types.SimpleNamespace(outline=object(), sheet=None)) is None
        with pictures.start(str(save), "figure-job", "gif-job-plate", mi.variant()) as pics:
            pics.wait()
        figure, gif = (save / "figure.png").read_text(), (save / "passage.gif").read_text()
        assert figure.startswith("figure-job ") and gif.startswith("gif-job-plate ")
        assert figure.split()[1] != str(os.getpid())  # the worker rendered them
    assert not os.path.exists(folder)


_FIRST = """
import os, sys
from sieve_mi.outputs import pictures
from sieve_mi.telemetry import Run

def worker():
    import drjit as dr
    import mitsuba as mi
    return dr.thread_count(), len(os.listdir("/proc/self/task")) - 1, mi.variant(), os.getpid()

with pictures.first("llvm_ad_mono", 3) as early:
    pool = early.take()
    with pictures.ahead(Run().start()) as again:  # the solve's: the worker forked first
        assert again is early and again.take() is pool
        got = pool.submit(worker).result()
    print(*got, "drjit" in sys.modules, os.getpid())
    try:
        os.kill(got[-1], 0)
    except ProcessLookupError:  # the solve's block ended it (it rendered nothing: at once)
        print("ended")
print(pictures._AHEAD is None)
"""


def test_a_solve_forks_its_pictures_worker_first_with_its_own_dr_jit(mi):
    # The command line forks the worker before anything imports Dr.Jit: the worker imports it
    # itself (every pool thread runs) on the command's --threads, in an RGB variant, while this
    # process has not imported Dr.Jit; ahead() then hands the same worker to the solve.
    import subprocess

    if mi.variant().startswith("cuda") or "llvm_ad_rgb" not in mi.variants():
        pytest.skip("the early worker renders with llvm_ad_rgb")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = {**os.environ, "PYTHONPATH": root}
    done = subprocess.run([sys.executable, "-c", _FIRST], env=env, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    first, ended, last = done.stdout.split("\n")[:3]
    count, running, variant, pid, parent_drjit, parent = first.split()
    assert (int(count), variant, parent_drjit) == (3, "llvm_ad_rgb", "False")
    assert int(running) >= 3 and pid != parent
    assert (ended, last) == ("ended", "True")
    with pictures.first("llvm_ad_mono") as early:  # Dr.Jit imported here: ahead() forks later
        assert early is None and pictures._AHEAD is None
