"""Progress on stderr: one bar for every long step of sieve-mi (solve, shake, sort and sweep).

One idea: how a command shows that it is working, decided once.

* On a terminal: a tqdm bar (``\\r`` frames), with the current stage and numbers after it, and
  tqdm's estimate of the time left.
* Elsewhere (stderr is a log file or a pipe): no ``\\r`` frames; plain lines instead, one when
  the stage changes (``search: cube: nlopt``), the lines the caller writes, at most one every
  :data:`PLAIN_EVERY` seconds with the share done and the time left
  (``verdict: 40 % (24/60 it), about 3 s left``), and with ``done_line`` one at the end
  (``verdict: done in 12.3 s``).
* Quiet (not ``enabled``): nothing at all.

:meth:`Progress.left` gives the estimate of the time left for the caller's own lines (certify's
and the thin-plate searches' line per B, shake's line per shape).

Callers: :mod:`sieve_mi.game.solver` (search and verdict), :mod:`sieve_mi.shake.run` (a bar
over trials, a line per shape in a log) and :mod:`sieve_mi.cascade.games` (a bar over games
whose total grows, a line per finished game).
"""

from __future__ import annotations

import sys
import time

__all__ = ["PLAIN_EVERY", "Progress"]

#: In a log, the least number of seconds between two lines of the share done and the time left.
PLAIN_EVERY = 10.0


class Progress:
    """A progress bar on stderr, or plain lines where stderr is not a terminal, or nothing.

    Parameters
    ----------
    enabled : bool
        Show progress (False: quiet, every method does nothing).
    total : int
        Steps of the whole work (the bar's 100 %); may grow (``grow_by``, :meth:`grow`).
    desc : str
        The bar's name, and the prefix of its plain lines.
    unit : str
        What a step is (``"it"``, ``"trial"``, ``"game"``), for the bar's rate.
    grow_by : int
        When an update would run past ``total``, ``total`` grows by this many steps (an extra
        round of work nobody could foresee); 0: never.
    done_line : bool
        In plain mode, end with ``<desc>: done in <seconds> s``.
    every : float, optional
        In plain mode, the least seconds between two lines of the time left (default
        :data:`PLAIN_EVERY`; 0: a line at every update).

    Attributes
    ----------
    plain : bool
        Enabled, and stderr is not a terminal: plain lines, no bar.
    bar : tqdm.tqdm or None
        The bar (enabled, on a terminal).
    """

    def __init__(
        self,
        enabled: bool,
        total: int,
        desc: str,
        *,
        unit: str = "it",
        grow_by: int = 0,
        done_line: bool = True,
        every: float | None = None,
    ):
        self.enabled, self.desc, self.grow_by, self.done_line = enabled, desc, grow_by, done_line
        self.bar, self.plain = None, enabled and not sys.stderr.isatty()
        self.stage, self.t0 = None, time.perf_counter()
        self.done, self.total, self.unit = 0, int(total), unit
        self.every = PLAIN_EVERY if every is None else float(every)
        self.said = self.t0  # when the last line of the time left was printed
        if enabled and not self.plain:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit=unit, leave=True, dynamic_ncols=True)

    def update(self, n: int = 1, **postfix) -> None:
        """``n`` more steps done (0: only news); ``postfix`` is shown after the bar.

        A ``stage`` in ``postfix`` that differs from the last one is, in plain mode, a line
        ``<desc>: <stage>``.
        """
        if self.plain and postfix.get("stage", self.stage) != self.stage:
            self.stage = postfix["stage"]
            print(f"{self.desc}: {self.stage}", file=sys.stderr, flush=True)
        self._count(n)
        if self.plain and n and time.perf_counter() - self.said >= self.every:
            self.said = time.perf_counter()
            share = f"{100 * self.done / self.total:.0f} % ({self.done}/{self.total} {self.unit})"
            left = self.left()
            print(f"{self.desc}: {share}" + (f", {left}" if left else ""), file=sys.stderr,
                  flush=True)  # fmt: skip
        if self.bar is not None:
            if self.bar.total is not None and self.grow_by and self.bar.n + n > self.bar.total:
                self.bar.total += self.grow_by
            if postfix:
                self.bar.set_postfix(postfix, refresh=False)
            self.bar.update(n)
            if n == 0:
                self.bar.refresh()

    def _count(self, n: int) -> None:
        """``n`` more steps done; past ``total``, it grows by ``grow_by`` (or to the count)."""
        self.done += n
        while self.done > self.total and self.grow_by:
            self.total += self.grow_by
        self.total = max(self.total, self.done)

    def left(self) -> str:
        """``about 12 s left`` (``about 3 min left``): the time the steps still to do take at the
        rate so far; empty when nothing is done yet, all is done, or progress is quiet."""
        if not self.enabled or self.done <= 0 or self.done >= self.total:
            return ""
        rate = (time.perf_counter() - self.t0) / self.done
        return f"about {_duration(rate * (self.total - self.done))} left"

    def grow(self, n: int) -> None:
        """``n`` more steps to do (work found on the way)."""
        self.total += n
        if self.bar is not None:
            self.bar.total += n
            self.bar.refresh()

    def describe(self, what: str) -> None:
        """Name what is being done now on the bar: ``<desc> <what>``."""
        if self.bar is not None:
            self.bar.set_description(f"{self.desc} {what}")

    def write(self, line: str, terminal: bool = True) -> None:
        """One line of news: printed on stderr in plain mode; on a terminal above the bar
        (tqdm's ``write``: on stdout), unless ``terminal`` is False (the bar says it)."""
        if self.plain:
            print(line, file=sys.stderr, flush=True)
        elif self.bar is not None and terminal:
            self.bar.write(line, file=sys.stderr)

    def close(self) -> None:
        """The work is over: the bar stays on the terminal; the ``done in`` line (``done_line``)."""
        if self.plain and self.done_line:
            took = time.perf_counter() - self.t0
            print(f"{self.desc}: done in {took:.1f} s", file=sys.stderr, flush=True)
        if self.bar is not None:
            self.bar.close()


def _duration(seconds: float) -> str:
    """``12 s``, ``3 min`` or ``1.5 h``: a time left, as precise as an estimate deserves.

    Examples
    --------
    >>> _duration(4.2), _duration(75), _duration(5400)
    ('4 s', '1 min', '1.5 h')
    """
    if seconds < 59.5:
        return f"{max(1, round(seconds))} s"
    if seconds < 3570:
        return f"{round(seconds / 60)} min"
    return f"{seconds / 3600:.1f} h"
