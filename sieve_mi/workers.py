"""Worker processes: every process pool of sieve-mi, and how its workers stop with their run.

A pool's workers compute only (certify's proofs, thin-plate searches, shake trials); they write
no file. So an interrupt or an error in the parent kills them at once instead of waiting for
their jobs, a worker that dies becomes one line, workers ignore Ctrl-C (the parent handles it)
and die with their parent, and workers are started with signals held so none is left
half-started.
"""

from __future__ import annotations

import contextlib
import sys
from concurrent.futures import ProcessPoolExecutor

from sieve_mi.errors import SieveError, deferred_signals

__all__ = ["stop_workers", "worker_pool"]


#: Linux ``prctl`` option: the signal a process gets when its parent dies.
_PR_SET_PDEATHSIG = 1


def _start_worker(initializer, initargs) -> None:
    """First thing a pool's worker process runs: its signals, then ``initializer(*initargs)``.

    The parent stops its workers itself (:func:`worker_pool`), so a worker ignores Ctrl-C (sent
    to the whole terminal's process group), dies quietly on SIGTERM or SIGHUP (no traceback of
    the handler it inherited by fork), and on Linux is killed when its parent dies, even by
    SIGKILL (``PR_SET_PDEATHSIG``): no orphan keeps computing after its run has ended.
    """
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL))
    if initializer is not None:
        initializer(*initargs)


def stop_workers(pool, others=()) -> None:
    """Kill a :class:`~concurrent.futures.ProcessPoolExecutor`'s workers now; wait for none.

    ``shutdown(wait=True)`` (what leaving a ``with`` block does) waits for every submitted job,
    which after an interrupt may be many minutes of proofs or searches. The workers compute
    only (they write no file), so they are killed, pending jobs are cancelled, the dead
    processes are reaped (at most a second each) and the pool's manager thread is given up to
    5 s to mark the jobs that were running failed: on return every job is done or cancelled.

    Parameters
    ----------
    pool : concurrent.futures.ProcessPoolExecutor
    others : iterable of multiprocessing.Process
        Processes started for the pool that it may not list yet (one interrupted while it was
        being started: left alive, it would print a traceback once its parent is gone).
    """
    processes = list((getattr(pool, "_processes", None) or {}).values())
    processes += [p for p in others if p not in processes]
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.kill()
    manager = getattr(pool, "_executor_manager_thread", None)  # shutdown forgets it
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.join(timeout=1.0)
    if manager is not None:  # it marks the killed workers' running jobs failed, then ends
        manager.join(timeout=5.0)


class _Pool(ProcessPoolExecutor):
    """:class:`~concurrent.futures.ProcessPoolExecutor` whose ``submit`` (where it starts its
    worker processes) holds SIGINT, SIGTERM and SIGHUP back: a worker interrupted half-started is
    unknown to the pool, outlives its parent and prints a traceback
    (``SemLock._rebuild ... FileNotFoundError``) once the parent is gone."""

    def submit(self, fn, /, *args, **kwargs):
        with deferred_signals():
            return super().submit(fn, *args, **kwargs)


@contextlib.contextmanager
def worker_pool(workers: int, *, method: str = "fork", initializer=None, initargs=(), what: str):
    """A process pool whose workers stop at once when the block is left by an exception.

    Every process pool of sieve-mi is made here, so an interrupt (Ctrl-C, SIGTERM, SIGHUP) or an
    error ends the workers within seconds instead of waiting for their jobs, and a worker that
    dies (a crash in a native library) becomes one line instead of ``BrokenProcessPool``.

    Parameters
    ----------
    workers : int
        Number of worker processes (at least 1).
    method : str
        :mod:`multiprocessing` start method: ``"fork"`` (cheap; the parent's modules are
        there) or ``"forkserver"`` (a clean process, for libraries that do not survive a fork
        of a process with threads).
    initializer, initargs
        Run once in each worker, after its signals are set (:func:`_start_worker`).
    what : str
        What the workers do, for the message when one dies ("thin-plate search").

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor

    Raises
    ------
    SieveError
        A worker process died (its exit signal named).
    """
    import multiprocessing
    from concurrent.futures.process import BrokenProcessPool

    before = set(multiprocessing.active_children())
    pool = _Pool(
        max(1, int(workers)),
        mp_context=multiprocessing.get_context(method),
        initializer=_start_worker,
        initargs=(initializer, tuple(initargs)),
    )
    try:
        yield pool
    except BrokenProcessPool:
        codes = [p.exitcode for p in (getattr(pool, "_processes", None) or {}).values()]
        stop_workers(pool, set(multiprocessing.active_children()) - before)
        raise SieveError(
            f"a {what} worker process died ({_exit_words(codes)}); this is a bug in sieve-mi or "
            "a library it uses: please report it with the input files"
        ) from None
    except BaseException:
        stop_workers(pool, set(multiprocessing.active_children()) - before)
        raise
    pool.shutdown(wait=True)


def _exit_words(codes) -> str:
    """How worker processes ended, in words: ``"signal SIGSEGV"`` or ``"exit code 1"``."""
    import signal

    for code in codes:
        if code is not None and code < 0:
            with contextlib.suppress(ValueError):
                return f"signal {signal.Signals(-code).name}"
        if code:
            return f"exit code {code}"
    return "no exit status"
