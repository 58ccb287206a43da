"""Progress of a command's long work on stderr: a bar on a terminal, a line every few seconds
with the rate and the time left in a log file (a batch job's output)."""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence


class Progress:
    """Progress on stderr once work has taken ``after_s`` seconds: on a terminal a bar redrawn
    every second; off one (a log file, a batch job's output) a plain line every
    :attr:`FILE_INTERVAL_S` seconds, each with the rate and the time left once a unit has
    finished, and a closing line with the total time when any line was printed.

    With ``weights`` (the estimated seconds of each unit, in order: :mod:`chiptwin.config.cost`)
    the time left is the estimate of the units left scaled by measured / estimated so far, which
    holds steady when units differ in cost (a ladder's levels); without, the measured rate. No rate
    is shown before a unit has finished.

    With ``at_most`` (a study that stops early, a bisection) ``total`` is an upper bound: the
    work may end before it, so a line says "rows 40 of at most 120", without a percentage, a
    bar's fill or a time left, and :meth:`finish` prints the closing line when the work ends
    short of it. A total that grows between calls (a search that asks for rows as it goes) is
    taken as such a bound from then on: the done-equals-total of each of its looks is never
    shown as 100 %.
    """

    PRIOR_UNITS = 4
    TTY_INTERVAL_S, FILE_INTERVAL_S = 1.0, 5.0

    def __init__(self, unit: str = "frames", after_s: float = 1.0,
                 weights: Sequence[float] | None = None, at_most: bool = False) -> None:
        self.unit = unit
        self.t0 = time.perf_counter()
        self.after_s = after_s
        self.last: float | None = None  # when a line was last printed
        self.weights = list(weights) if weights else None
        self.per_unit_s: float | None = None  # one estimate for every unit (a study's rows)
        self.start: int | None = None  # units already done when the first call came (resumed)
        self.tty = sys.stderr.isatty()
        self.at_most = at_most
        self.seen: tuple[int, int] | None = None  # the last (done, total) reported
        self.closed = False

    def __call__(self, done: int, total: int) -> None:
        now = time.perf_counter()
        if self.start is None:  # measured from the first unit on (not the start-up before it)
            self.start, self.t0 = done, now
        if self.seen is not None and total != self.seen[1]:
            self.at_most, self.closed = True, False  # a total that moves was never the whole
        self.seen = (done, total)
        if self.at_most:
            self._bounded(done, total, now)
            return
        if done >= total:
            self.closed = True
            if self.last is not None or now - self.t0 > 2.0:
                self._print(f"{self.unit} {done}/{total} (100 %) in {now - self.t0:.1f} s",
                            done, total)
            return
        interval = self.TTY_INTERVAL_S if self.tty else self.FILE_INTERVAL_S
        since = now - self.t0 if self.last is None else now - self.last
        if since < (self.after_s if self.last is None else interval):
            return
        eta = self._rate_eta(done, total, now)
        if not self.tty and not eta:  # a log line says how fast, or waits until it can
            return
        self._print(f"{self.unit} {done}/{total} ({100 * done / max(total, 1):.0f} %{eta})",
                    done, total)
        self.last = now

    def _bounded(self, done: int, total: int, now: float) -> None:
        """A line for an upper-bound total: the count and the rate, never a percentage."""
        interval = self.TTY_INTERVAL_S if self.tty else self.FILE_INTERVAL_S
        since = now - self.t0 if self.last is None else now - self.last
        if since < (self.after_s if self.last is None else interval):
            return
        n, elapsed = done - (self.start or 0), now - self.t0
        rate = f", {n / elapsed:.3g} {self.unit}/s" if n > 0 and elapsed > 0 else ""
        self._print(f"{self.unit} {done} of at most {total}{rate}", 0, 1, bar=False)
        self.last = now

    def finish(self) -> None:
        """The closing line when the work ended before its total (a study that stopped early),
        if any line was printed or the work took over 2 s; nothing after a completed total."""
        if self.closed or self.seen is None:
            return
        self.closed = True
        done, total = self.seen
        now = time.perf_counter()
        if self.last is None and now - self.t0 <= 2.0:
            return
        text = f"{self.unit} {done} in {now - self.t0:.1f} s"
        if done < total:
            text += f" (stopped early: {done} of at most {total})"
        self._print(text, 1, 1, bar=False)

    def _print(self, text: str, done: int, total: int, bar: bool = True) -> None:
        if self.tty:
            filled = int(30 * done / max(total, 1))
            fill = "[" + "#" * filled + "." * (30 - filled) + "] " if bar else ""
            print(f"\r\033[K  {fill}{text}", end="" if done < total else "\n", file=sys.stderr,
                  flush=True)
        else:
            print(f"  {text}", file=sys.stderr, flush=True)

    def _rate_eta(self, done: int, total: int, now: float) -> str:
        elapsed = now - self.t0
        n = done - (self.start or 0)
        weights = self.weights if self.weights and len(self.weights) >= total else None
        if weights:
            est_done = sum(weights[self.start or 0:done])
            scale = elapsed / est_done if n > 0 and est_done > 0 and elapsed > 0 else 1.0
            return f", ETA {_eta(scale * sum(weights[done:total]))}"
        prior = self.per_unit_s * (total - done) if self.per_unit_s else None
        if n <= 0 or elapsed <= 0:  # nothing measured yet: the estimate, or nothing
            return "" if prior is None else f", ETA {_eta(prior)} (estimated)"
        rate = n / elapsed
        eta = (total - done) / rate
        if prior is not None:  # the estimate counts as PRIOR_UNITS units, measured ones win
            eta = (self.PRIOR_UNITS * prior + n * eta) / (self.PRIOR_UNITS + n)
        return f", {rate:.3g} {self.unit}/s, ETA {_eta(eta)}"


def _eta(seconds: float) -> str:
    from chiptwin.config.cost import format_seconds

    return format_seconds(round(seconds))
