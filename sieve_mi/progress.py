"""Progress on stderr: one bar for every long step of sieve-mi (solve, shake, sort and sweep).

One idea: how a command shows that it is working, decided once.

* On a terminal: a tqdm bar (``\\r`` frames), with the current stage and numbers after it.
* Elsewhere (stderr is a log file or a pipe): no ``\\r`` frames; plain lines instead, one when
  the stage changes (``search: cube: nlopt``), the lines the caller writes, and with
  ``done_line`` one at the end (``verdict: done in 12.3 s``).
* Quiet (not ``enabled``): nothing at all.

Callers: :mod:`sieve_mi.game.solver` (search and verdict), :mod:`sieve_mi.shake.run` (a bar
over trials, a line per shape in a log) and :mod:`sieve_mi.cascade.games` (a bar over games
whose total grows, a line per finished game).
"""

from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


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
    ):
        self.enabled, self.desc, self.grow_by, self.done_line = enabled, desc, grow_by, done_line
        self.bar, self.plain = None, enabled and not sys.stderr.isatty()
        self.stage, self.t0 = None, time.perf_counter()
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
        if self.bar is not None:
            if self.bar.total is not None and self.grow_by and self.bar.n + n > self.bar.total:
                self.bar.total += self.grow_by
            if postfix:
                self.bar.set_postfix(postfix, refresh=False)
            self.bar.update(n)
            if n == 0:
                self.bar.refresh()

    def grow(self, n: int) -> None:
        """``n`` more steps to do (work found on the way)."""
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
