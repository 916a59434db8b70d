"""A run's record of itself: the seconds each stage took and, where watched, its peak memory.

One :class:`Run` owns a run's telemetry, so no stage threads ``time.perf_counter()`` and a
``timings`` dict by hand: ``with run.stage("search"):`` records the block's seconds as
``timings["search_s"]`` and ends the memory watch's stage ``"search"``
(:class:`sieve_mi.backend.MemoryWatch`). A solve's ``report.json`` ``timings`` and ``memory``
come from its record. The command line makes the record before the solve with
:meth:`Run.from_process_start`, so that its times count from the process's start (Python, the
imports and reading the scene are the stage ``startup``); a solve from Python counts from its
own start.
"""

from __future__ import annotations

import contextlib
import time

from sieve_mi.backend import MemoryWatch, process_age

__all__ = ["Run"]


class Run:
    """The telemetry of one run: seconds per stage, in the order the stages ended, and the peak
    resident memory of each stage where :meth:`start` was asked to watch it.

    Parameters
    ----------
    startup : float, optional
        Seconds the process ran before this record was made (:func:`~sieve_mi.backend.process_age`):
        the run's time then counts from the process's start and :meth:`start` records the
        seconds up to it as the stage ``startup``. None: the time counts from :meth:`start`.

    Attributes
    ----------
    timings : dict of str to float
        ``<stage>_s`` -> seconds, in the order the stages ended (``startup_s`` first where counted).
    started : float or None
        ``time.perf_counter()`` from which the run's time counts (``report.json``'s ``total_s``);
        None until :meth:`start` unless counted from the process's start.
    memory : sieve_mi.backend.MemoryWatch or None
        Each stage's peak resident memory, from :meth:`start` with ``memory=True``; else None.

    Examples
    --------
    >>> run = Run().start()
    >>> with run.stage("load"):
    ...     data = list(range(1000))
    >>> list(run.timings), run.timings["load_s"] >= 0.0, run.elapsed() >= run.timings["load_s"]
    (['load_s'], True, True)
    """

    def __init__(self, startup: float | None = None):
        self.timings: dict[str, float] = {}
        self.memory: MemoryWatch | None = None
        self._startup = startup is not None
        self._after: dict[str, list] = {}
        self.started = None if startup is None else time.perf_counter() - float(startup)

    @classmethod
    def from_process_start(cls) -> Run:
        """A record whose time counts from this process's start, where the system says when that
        was (:func:`~sieve_mi.backend.process_age`, Linux); elsewhere from :meth:`start`."""
        return cls(startup=process_age())

    def start(self, *, memory: bool = False) -> Run:
        """The run's work begins here: returns the record itself.

        Counted from the process's start, the seconds up to here become ``timings["startup_s"]``;
        otherwise the run's time counts from here. With ``memory``, a
        :class:`~sieve_mi.backend.MemoryWatch` starts watching the first stage.
        """
        now = time.perf_counter()
        if self._startup:
            self.timings["startup_s"] = now - self.started
        else:
            self.started = now
        if memory:
            self.memory = MemoryWatch()
        return self

    @contextlib.contextmanager
    def stage(self, name: str, *, mark: bool = True):
        """Time the ``with`` block as the stage ``name``: ``timings[name + "_s"]``, seconds (not
        recorded when the block raises); then, with ``mark``, end the memory watch's stage
        ``name`` (``mark=False``: the caller ends it later with :meth:`mark`)."""
        t0 = time.perf_counter()
        yield
        self.timings[f"{name}_s"] = time.perf_counter() - t0
        if mark:
            self.mark(name)
        for fn in self._after.pop(name, ()):
            fn()

    def after(self, name: str, fn) -> None:
        """Call ``fn()`` (no arguments) once, when the stage ``name`` next ends (after its time
        is recorded): e.g. the pictures' worker is forked after ``screen`` where the command
        line did not fork it first."""
        self._after.setdefault(name, []).append(fn)

    def mark(self, name: str) -> None:
        """End the memory watch's stage ``name`` here (nothing without a watch)."""
        if self.memory is not None:
            self.memory.mark(name)

    def elapsed(self) -> float:
        """Seconds since the run's time began (:attr:`started`)."""
        return time.perf_counter() - self.started

    def stop(self) -> None:
        """Stop the memory watch's sampling (:meth:`MemoryWatch.start` resumes it); the record
        stays readable."""
        if self.memory is not None:
            self.memory.stop()
