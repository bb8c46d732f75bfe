"""The progress bar of a batch of runs, weighted by their expected cost, with an honest ETA.

This module imports only the standard library.
"""

from __future__ import annotations

import math
import shutil
import sys
import time
from collections.abc import Sequence
from typing import Any, TextIO

from tippetop.compare.running.cost import schedule_s


class WorkProgress:
    """Progress of a batch of runs weighted by their expected cost, with an honest ETA.

    Each run has a weight, its expected cost
    (:func:`~tippetop.compare.running.cost.expected_cost_s`). The fraction done is
    the weight of the finished runs plus, for a run still going that reports its simulated
    time, the part of its weight it has covered. The speed is measured (expected seconds done
    per second of one busy worker, starting from 1) and the ETA is the remaining work, run by
    run, scheduled on the workers (:func:`schedule_s`) at that speed: a batch whose cheap ODE
    runs are done shows the MuJoCo runs' share still to go, not "half done".

    The bar is one line on ``stream``, redrawn at most every ``min_interval_s`` and erased at
    the end; ``enabled`` False (the default when ``stream`` is not a terminal) draws nothing
    but still keeps the numbers (for tests and the caller).

    Args:
        label: Shown before the bar (``sweep``, ``compare`` ...).
        costs: Expected cost of each run (s), in the order they will start.
        slots: Workers running at once.
        stream: Where the bar goes (default stderr).
        enabled: Draw the bar (default: when ``stream`` is a terminal).
        clock: Time source (for tests).
        note: Shown after the run count (e.g. ``4 from the cache``).
        compile_s: About how long the workers compile before any run moves (s; 0: nothing
            to compile), said in place of the ETA until then.
    """

    #: Weight of the prior speed (1 expected second per second), in seconds of busy worker.
    PRIOR_S = 2.0
    #: The speed is measured over about this much recent time (s; older work fades out), so a
    #: slow start (workers importing their engines) does not weigh on the ETA for long.
    MEMORY_S = 30.0

    def __init__(self, label: str, costs: Sequence[float], *, slots: int = 1,
                 stream: TextIO | None = None, enabled: bool | None = None,
                 clock: Any = time.monotonic, note: str = "",
                 min_interval_s: float = 0.2, compile_s: float = 0.0) -> None:
        self.label = label
        self.costs = [max(float(c), 1e-6) for c in costs]
        self.slots = max(1, int(slots))
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = enabled and bool(self.costs)
        self.clock = clock
        self.note = note
        self.compile_s = max(0.0, float(compile_s))
        self.min_interval_s = min_interval_s
        self.t0 = clock()
        self._last_t = self.t0
        self._busy_s = 0.0  # recent busy worker time (fading, see MEMORY_S)
        self._work_s = 0.0  # recent work done (fading the same way)
        self._work_seen = 0.0
        self._measuring = False
        self._done: set[int] = set()
        self._frac: dict[int, float] = {}
        self._drawn = 0.0
        self._width = 0

    # ------------------------------------------------------------ state
    @property
    def total(self) -> float:
        """Expected cost of the whole batch (s)."""
        return sum(self.costs)

    def _running(self) -> list[int]:
        """The runs taken to be going now: the first ``slots`` unfinished, in start order."""
        return [i for i in range(len(self.costs)) if i not in self._done][: self.slots]

    def _busy_now(self) -> int:
        return min(self.slots, len(self.costs) - len(self._done))

    def _advance_clock(self, busy: int | None = None) -> float:
        """Account for the time since the last event: busy workers and the work they did."""
        now = self.clock()
        dt = max(0.0, now - self._last_t)
        if busy is None:
            busy = self._busy_now()
        work = self.work_done()
        if not self._measuring:
            # workers starting (spawning, importing the engines) before any work shows: that
            # time says nothing about the speed of the runs
            self._measuring = work > 0
            self._work_seen = work
            self._last_t = now
            return now
        fade = math.exp(-dt / self.MEMORY_S)
        self._busy_s = self._busy_s * fade + dt * busy
        self._work_s = self._work_s * fade + (work - self._work_seen)
        self._work_seen = work
        self._last_t = now
        return now

    def work_done(self) -> float:
        """Expected seconds of work done: finished runs, and the reported part of the others."""
        done = sum(self.costs[i] for i in self._done)
        return done + sum(self.costs[i] * f for i, f in self._frac.items() if i not in self._done)

    def fraction(self) -> float:
        """Fraction of the batch's expected cost done, in [0, 1]."""
        return min(1.0, self.work_done() / self.total) if self.costs else 1.0

    def speed(self) -> float:
        """Expected seconds of work done per second of a busy worker.

        Measured over the last :data:`MEMORY_S` or so, starting from 1 (the cost model's).
        """
        return (self._work_s + self.PRIOR_S) / (self._busy_s + self.PRIOR_S)

    def eta_s(self) -> float:
        """Seconds until the batch is done, at the measured speed."""
        run = self._running()
        running = [self.costs[i] * (1.0 - self._frac.get(i, 0.0)) for i in run]
        pending = [self.costs[i] for i in range(len(self.costs))
                   if i not in self._done and i not in run]
        return schedule_s(running, pending, self.slots) / max(self.speed(), 1e-9)

    # ------------------------------------------------------------ events
    def reached(self, index: int, fraction: float) -> None:
        """Run ``index`` reports how far it got (0..1 of its simulated time)."""
        busy = self._busy_now()
        if index not in self._done and 0.0 <= fraction:
            self._frac[index] = min(max(self._frac.get(index, 0.0), fraction), 0.999)
        self._advance_clock(busy)
        self.draw()

    def finished(self, index: int) -> None:
        """Run ``index`` is done."""
        busy = self._busy_now()
        self._done.add(index)
        self._advance_clock(busy)
        self.draw()

    def tick(self) -> None:
        """Time passed (redraw the elapsed time and ETA)."""
        self._advance_clock()
        self.draw()

    # ------------------------------------------------------------ drawing
    def line(self, width: int = 100) -> str:
        """The bar's text: label, bar, percent of the work, runs, elapsed, ETA."""
        n, total = len(self._done), len(self.costs)
        pct = 100.0 * self.fraction()
        elapsed = self._last_t - self.t0
        eta = "done" if n == total else f"about {_clock_text(self.eta_s())} left"
        if n < total and not self._measuring and self.compile_s > 0:
            left = self.compile_s - elapsed  # the workers compile before any run moves
            doing = (f"compiling, about {_clock_text(left)} more" if left >= 1.0
                     else "compiling")
            eta = f"{doing}, then about {_clock_text(self.eta_s())}"
        elif n < total and not self._measuring and elapsed >= 1.0:
            eta = f"starting, then about {_clock_text(self.eta_s())}"  # workers importing
        note = f" ({self.note})" if self.note else ""
        tail = f" {pct:3.0f}%  {n}/{total} runs{note}  {_clock_text(elapsed)} elapsed, {eta}"
        room = width - len(self.label) - len(tail) - 3
        bar = ""
        if room >= 10:
            room = min(room, 40)
            full = int(round(room * self.fraction()))
            fill, empty = ("█", "░") if self._unicode() else ("#", "-")
            bar = " |" + fill * full + empty * (room - full) + "|"
        return f"{self.label}{bar}{tail}"[:width]

    def _unicode(self) -> bool:
        return "utf" in str(getattr(self.stream, "encoding", "") or "").lower()

    def draw(self, force: bool = False) -> None:
        """Redraw the bar (at most every ``min_interval_s`` unless ``force``)."""
        if not self.enabled:
            return
        now = self._last_t
        if not force and now - self._drawn < self.min_interval_s:
            return
        self._drawn = now
        width = max(20, shutil.get_terminal_size((100, 20)).columns - 1)
        text = self.line(width)
        pad = " " * max(0, self._width - len(text))
        self._width = len(text)
        self.stream.write(f"\r{text}{pad}")
        self.stream.flush()

    def close(self) -> None:
        """Erase the bar (the results are printed after it)."""
        if self.enabled and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()
            self._width = 0


def _clock_text(seconds: float) -> str:
    """``0:42``, ``12:05``, ``1:02:03``."""
    if not math.isfinite(seconds):
        return "?"
    s = int(round(max(0.0, seconds)))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


__all__ = ["WorkProgress"]
