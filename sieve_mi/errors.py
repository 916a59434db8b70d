"""User-facing errors.

Every problem a user can fix (a missing file, a bad key, an unreadable mesh) is raised as
:class:`SieveError`; the command line prints its message as one line and exits with code 2.
"""

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_NO",
    "EXIT_OK",
    "EXIT_UNDECIDED",
    "SieveError",
    "clear_signals",
    "interruption",
    "note_signal",
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
    """Forget the noted signals (at the start of a command)."""
    _SIGNALS.clear()


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
