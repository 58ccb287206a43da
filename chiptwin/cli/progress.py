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
    """

    PRIOR_UNITS = 4
    TTY_INTERVAL_S, FILE_INTERVAL_S = 1.0, 5.0

    def __init__(self, unit: str = "frames", after_s: float = 1.0,
                 weights: Sequence[float] | None = None) -> None:
        self.unit = unit
        self.t0 = time.perf_counter()
        self.after_s = after_s
        self.last: float | None = None  # when a line was last printed
        self.weights = list(weights) if weights else None
        self.per_unit_s: float | None = None  # one estimate for every unit (a study's rows)
        self.start: int | None = None  # units already done when the first call came (resumed)
        self.tty = sys.stderr.isatty()

    def __call__(self, done: int, total: int) -> None:
        now = time.perf_counter()
        if self.start is None:  # measured from the first unit on (not the start-up before it)
            self.start, self.t0 = done, now
        if done >= total:
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

    def _print(self, text: str, done: int, total: int) -> None:
        if self.tty:
            filled = int(30 * done / max(total, 1))
            bar = "[" + "#" * filled + "." * (30 - filled) + "] "
            print(f"\r\033[K  {bar}{text}", end="" if done < total else "\n", file=sys.stderr,
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
