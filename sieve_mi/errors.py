"""User-facing errors, and the one home of interrupts.

Every problem a user can fix (a missing file, a bad key, an unreadable mesh) is raised as
:class:`SieveError`; the command line prints its message as one line and exits with code 2.
Signals: the command line's handlers note each one (:func:`note_signal`), code that a library
may have run on through a swallowed interrupt checks (:func:`raise_if_signalled`,
:func:`interruption`), and short critical sections hold them back (:func:`deferred_signals`).
"""

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_NO",
    "EXIT_OK",
    "EXIT_UNDECIDED",
    "SieveError",
    "clear_signals",
    "deferred_signals",
    "interruption",
    "note_signal",
    "raise_if_signalled",
    "signals_received",
]

#: Exit codes of the command line (docs/cli.md). 0: the answer is yes (A wins, the part passes,
#: the shape is proved blocked, the certificate holds, every shape has its own tray).
EXIT_OK = 0
#: Bad input or usage: one line on stderr, nothing written (argparse uses 2 as well).
EXIT_BAD_INPUT = 2
#: The run worked and the answer is no: some B gets through, the part is blocked, a passage was
#: found, the certificate is invalid, some shapes share a tray, no sweep run won. Outputs are written.
EXIT_NO = 3
#: ``certify`` ran out of budget with cells left open: neither proved nor refuted.
EXIT_UNDECIDED = 4


class SieveError(Exception):
    """An error in the user's input or environment, with a one-line message saying what to do."""


#: Signals (SIGINT, SIGTERM, SIGHUP numbers) whose handler ran in this run, oldest first.
_SIGNALS: list[int] = []


def note_signal(signum: int) -> None:
    """Record that the command line's handler of ``signum`` ran (before it raises).

    A library may catch the exception the handler raises and report it as its own error, with
    the interrupt only as text (Mitsuba's plugin loader, Dr.Jit's frozen functions): code that
    catches such errors asks :func:`signals_received` whether it was really a signal.
    """
    _SIGNALS.append(int(signum))


def signals_received() -> list[int]:
    """The signals noted by :func:`note_signal` since :func:`clear_signals`, oldest first."""
    return list(_SIGNALS)


def clear_signals() -> None:
    """Forget the noted signals (at the start and the end of a command)."""
    _SIGNALS.clear()


def raise_if_signalled() -> None:
    """Raise KeyboardInterrupt if a signal was noted (:func:`note_signal`) since the command
    started: a checkpoint after work that a library may have run on through an interrupt it
    swallowed (Mitsuba's render, trimesh's imports), and before anything is committed to disk.

    Examples
    --------
    >>> clear_signals(); raise_if_signalled()  # nothing noted: returns
    """
    if _SIGNALS:
        raise KeyboardInterrupt


def interruption(exc: BaseException) -> BaseException | None:
    """The interrupt behind ``exc``, if any: the one rule for "was this error really a signal?".

    The first exception of ``exc``'s cause/context chain that is not an :class:`Exception`
    (a KeyboardInterrupt, which the command line's termination signals raise as well, or a
    SystemExit); else, where the command line's handler ran (:func:`signals_received`), a new
    KeyboardInterrupt standing for the signal; else None. Libraries re-raise what they caught
    as their own errors: Dr.Jit a frozen function's interrupt as a RuntimeError whose cause is
    the original or that holds it only as text, Mitsuba a render's interrupt likewise.

    Parameters
    ----------
    exc : BaseException
        The exception caught.

    Returns
    -------
    BaseException or None
        The interrupt to raise instead of ``exc``; None when ``exc`` is a real error.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if not isinstance(exc, Exception):
            return exc
        exc = exc.__cause__ or exc.__context__
    return KeyboardInterrupt() if signals_received() else None


#: The signals :func:`deferred_signals` holds back.
_HELD = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)

#: Whether this platform has per-thread signal masks.
_MASKS = hasattr(signal, "pthread_sigmask")


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back until the block ends (they arrive afterwards).

    In the main thread the signals' Python handlers are swapped for one that only records them,
    and the recorded signals are raised again once the old handlers are back. (Blocking them with
    ``pthread_sigmask`` would not do: it blocks one thread only, and the kernel hands a signal
    sent to the process to any thread that does not block it, such as Dr.Jit's workers, after
    which Python runs the handler in the main thread anyway.) Elsewhere, where Python allows no
    handlers, the calling thread's signal mask is used.
    """
    if threading.current_thread() is not threading.main_thread():
        if not hasattr(signal, "pthread_sigmask"):
            yield
            return
        old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        return
    pending: list[int] = []

    def hold(signum, frame):
        pending.append(signum)

    old = {}
    for sig in _HELD:
        if signal.getsignal(sig) is not None:  # None: a handler not installed from Python
            old[sig] = signal.signal(sig, hold)
    # A thread mask that blocks them (inherited, e.g. from a process launched with SIGINT
    # blocked) would keep them pending past the block: unblock them while it lasts.
    old_mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD) if _MASKS else None
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        try:
            for sig in dict.fromkeys(pending):
                signal.raise_signal(sig)
        finally:
            if old_mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
