"""Worker processes and threads: one bound on threads, and workers that stop with their run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
from helpers import REPO

from sieve_mi import cli
from sieve_mi.backend import max_threads, set_threads
from sieve_mi.errors import SieveError
from sieve_mi.workers import worker_pool


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _pid_then_sleep(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def _crash() -> None:
    import faulthandler

    faulthandler.disable()  # pytest's dump of the worker's stack is not what is tested
    os.kill(os.getpid(), signal.SIGSEGV)


@pytest.mark.parametrize("count", [0, -1, 4 * (os.cpu_count() or 1) + 1, 10**9, 2.5, "8", True])
def test_thread_counts_outside_one_to_four_per_core_are_refused(count):
    with pytest.raises(SieveError, match=r"must be a whole number from 1 to \d+") as err:
        set_threads(count)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("given", [["--threads", "1000000000"], []])
def test_the_cli_refuses_a_runaway_thread_count_in_one_line(given, monkeypatch, capsys, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text("name = 'x'\n")
    before = scene.read_bytes()
    if not given:
        monkeypatch.setenv("SIEVE_MI_THREADS", "1000000000")
    assert cli.main(["solve", str(scene), "--out", str(tmp_path / "out"), *given]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"from 1 to {max_threads()}" in err[0], err
    assert scene.read_bytes() == before and not (tmp_path / "out").exists()


def test_an_interrupt_kills_the_pools_workers_at_once():
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt), worker_pool(2, what="test") as pool:
        jobs = [pool.submit(_pid_then_sleep, 600.0) for _ in range(4)]
        pids = list(pool._processes)
        raise KeyboardInterrupt
    assert time.monotonic() - t0 < 30  # the jobs would take 20 minutes
    assert pids and not any(_alive(p) for p in pids)
    assert all(j.cancelled() or j.done() for j in jobs)


def test_a_worker_that_dies_is_one_line_naming_its_signal():
    with pytest.raises(SieveError, match="a test worker process died") as err:
        with worker_pool(1, what="test") as pool:
            pool.submit(_crash).result()
    assert "\n" not in str(err.value)


def test_the_pool_gives_results_as_a_plain_pool_does():
    with worker_pool(2, what="test") as pool:
        pids = set(pool.map(_pid_then_sleep, [0.0] * 6))
    assert os.getpid() not in pids and 1 <= len(pids) <= 2


_SCRIPT = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {tests!r})
    from test_workers import _pid_then_sleep
    from sieve_mi import cli
    from sieve_mi.workers import worker_pool

    def run(args):  # stands in for a command that proves or searches on workers
        with worker_pool(2, method={method!r}, what="test") as pool:
            jobs = [pool.submit(_pid_then_sleep, 600.0) for _ in range(2)]
            time.sleep(1.0)
            print(*pool._processes, flush=True)
            jobs[0].result()
        return 0

    if __name__ == "__main__":  # the forkserver imports this file too
        cli._dispatch = run
        sys.exit(cli.main(["view", "unused"]))
    """
)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["fork", "forkserver"])
def test_sigterm_ends_a_run_and_its_workers_within_seconds(method, tmp_path):
    script = tmp_path / "run.py"
    script.write_text(_SCRIPT.format(tests=os.path.join(REPO, "tests"), method=method))
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [REPO, os.environ.get("PYTHONPATH")])),
    }
    proc = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=env,
    )  # fmt: skip
    pids = [int(p) for p in proc.stdout.readline().split()]
    assert len(pids) == 2 and all(_alive(p) for p in pids)
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)  # the run only, as `kill PID` does
    _, err = proc.communicate(timeout=60)
    assert time.monotonic() - t0 < 30  # the jobs would take 10 minutes
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines() == ["sieve-mi: terminated"], err
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in pids)


def test_a_signal_a_library_swallowed_still_stops_an_addition(tmp_path):
    from sieve_mi.errors import clear_signals, note_signal
    from sieve_mi.outputs import outdir

    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "report.json").write_text("{}")
    (folder / "shake.json").write_text('{"seed": 0}')
    outdir.write_marker(str(folder), "solve")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    note_signal(signal.SIGTERM)  # the handler ran, but a library caught what it raised
    try:
        with pytest.raises(KeyboardInterrupt):
            outdir.add_files(str(folder), {"shake.json": b'{"seed": 7}'})
    finally:
        clear_signals()
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_shake_workers_start_no_opengl_probe_subprocesses():
    # MuJoCo's import probes GLFW with a Python subprocess per library unless MUJOCO_GL says
    # otherwise; a run stopped meanwhile printed those subprocesses' tracebacks.
    code = "import sieve_mi.shake, mujoco, sys, os; print('glfw' in sys.modules, os.environ['MUJOCO_GL'])"
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.split() == ["False", "disable"], out.stderr
