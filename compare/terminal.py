"""What a person reads in the terminal: values with units, tables, and a progress bar.

* :func:`fmt` turns one value into text: ``None`` is ``-``, NaN is ``undefined (NaN)``, a float
  has four significant digits (a relative drift two, in scientific notation), an integer has
  thousands separators, a boolean is ``yes`` or ``no``; :func:`fmt_value` adds the unit that a
  key's name implies (``t_invert`` -> s, ``theta_*`` -> rad, ``*_J`` -> J, ``rel_diff`` -> %).
* :func:`table` lines up rows of text in columns, numbers right-aligned.
* :class:`WorkProgress` is the bar of a batch of runs: each run weighs its expected cost
  (:func:`expected_cost_s`: MuJoCo steps times a per-step cost, ODE runs much cheaper), runs
  still going report how far they got, and the ETA is the remaining work scheduled on the
  workers at the speed measured so far. It is drawn on stderr only when stderr is a terminal.

This module imports only the standard library (a run plan is read, never imported).
"""

from __future__ import annotations

import heapq
import math
import shutil
import sys
import time
from collections.abc import Iterable, Sequence
from typing import Any, TextIO

# ---------------------------------------------------------------- values
#: Text of a missing value (a quantity that does not exist, or was not measured).
MISSING = "-"
#: Text of a NaN: an undefined number is said, never shown as ``nan``.
NAN_TEXT = "undefined (NaN)"

#: Units of keys whose names do not carry one.
_KEY_UNITS: dict[str, str] = {
    "n0": "rad/s", "n1": "rad/s", "n2": "rad/s", "n3": "rad/s", "n4": "rad/s", "nc": "rad/s",
    "measured": "rad/s", "theory": "rad/s", "t_invert": "s", "t_stem": "s",
    "theta_rms": "rad", "A": "kg m^2", "C": "kg m^2", "mu": "", "law_mu": "",
}
#: Name endings that carry a unit, longest first.
_SUFFIX_UNITS: tuple[tuple[str, str], ...] = (
    ("_rad_s", "rad/s"), ("_mps2", "m/s^2"), ("_kgm2", "kg m^2"), ("_mps", "m/s"),
    ("_kg", "kg"), ("_J", "J"), ("_m", "m"), ("_s", "s"),
)
#: Keys that are relative quantities (dimensionless, usually tiny): scientific notation.
_RELATIVE = ("J_rel_drift", "energy_rise_rel", "rel_drift")
#: Keys that are a relative difference shown as a signed percentage.
_PERCENT = ("rel_diff",)


def unit_of(key: str) -> str:
    """The unit a key's name implies: ``"s"``, ``"rad"``, ``"rad/s"``, ``"%"`` ... or ``""``.

    Args:
        key: A summary or result key such as ``t_invert``, ``theta_asymp`` or ``wall_s``.

    Returns:
        The unit, ``"relative"`` for relative drifts, ``"%"`` for relative differences, or
        ``""`` when the key is dimensionless or unknown.
    """
    if key in _KEY_UNITS:
        return _KEY_UNITS[key]
    if key in _PERCENT:
        return "%"
    if key in _RELATIVE or key.endswith("_rel") or "_rel_" in key:
        return "relative"
    if key.startswith(("theta", "d_theta")):
        return "rad/s" if key.endswith("_rad_s") else "rad"
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return ""


def _exp(text: str) -> str:
    """``1.3e-09`` -> ``1.3e-9``, ``1.2e+05`` -> ``1.2e5``."""
    if "e" not in text:
        return text
    mant, exp = text.split("e")
    sign = "-" if exp.startswith("-") else ""
    return f"{mant}e{sign}{exp.lstrip('+-').lstrip('0') or '0'}"


def fmt_float(x: float, digits: int = 4) -> str:
    """A float in ``digits`` significant digits, scientific below 1e-3 and from 1e6 on."""
    if math.isnan(x):
        return NAN_TEXT
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e6:
        mag = math.floor(math.log10(abs(x)))
        decimals = max(0, digits - 1 - mag)
        text = f"{x:.{decimals}f}"
        return text.rstrip("0").rstrip(".") if "." in text else text
    mant, _, exp = f"{x:.{max(0, digits - 1)}e}".partition("e")
    if "." in mant:
        mant = mant.rstrip("0").rstrip(".")
    return _exp(f"{mant}e{exp}")


def fmt_percent(x: float | None, digits: int = 3) -> str:
    """A relative difference (0.0083) as a signed percentage (``+0.83 %``)."""
    if x is None:
        return MISSING
    if not math.isfinite(x):
        return fmt_float(x)
    p = 100.0 * x
    text = f"{p:+.{digits}g}" if abs(p) >= 1e-3 else f"{p:+.1e}"
    return f"{_exp(text)} %"


def fmt_duration(seconds: float | None) -> str:
    """Wall time for a person: ``0.025 s``, ``18.1 s``, ``2 min 05 s``, ``1 h 02 min``."""
    if seconds is None:
        return MISSING
    if not math.isfinite(seconds):
        return fmt_float(seconds)
    if seconds < 60:
        return f"{fmt_float(seconds, 3)} s"
    s = int(round(seconds))
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def fmt(value: Any, unit: str = "", digits: int = 4) -> str:
    """One value as text, with its unit.

    Args:
        value: None, a bool, int, float, string, list or dict (numpy scalars too).
        unit: Appended after a number (``"rad"``, ``"s"``); ``"relative"`` gives two
            significant digits in scientific notation, ``"%"`` a signed percentage of a
            relative value.
        digits: Significant digits of a float.

    Returns:
        ``-`` for None, ``undefined (NaN)`` for NaN, ``yes``/``no`` for a bool, ``400,000``
        for an integer, ``2.329 s`` for a float with a unit, items joined by commas for a list.
    """
    if hasattr(value, "item") and not isinstance(value, (list, tuple, dict, str)):
        value = value.item()  # numpy scalar
    if value is None:
        return MISSING
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        text = f"{value:,}"
        return f"{text} {unit}" if unit and unit not in ("relative", "%") else text
    if isinstance(value, float):
        if unit == "%":
            return fmt_percent(value)
        if not math.isfinite(value):
            return fmt_float(value)
        if unit == "relative":
            return fmt_float(value, 2) if value != 0 else "0"
        text = fmt_float(value, digits)
        return f"{text} {unit}" if unit else text
    if isinstance(value, dict):
        return ", ".join(f"{k} {fmt(v)}" for k, v in value.items()) or MISSING
    if isinstance(value, (list, tuple)):
        if not value:
            return "none"
        return ", ".join(fmt(v, unit, digits) for v in value)
    return str(value)


def _phases(value: Any) -> str | None:
    """``[{contact, t_start, t_end}, ...]`` -> ``ball 0-2.5 s, stem 2.5-8 s``, else None."""
    if not (isinstance(value, list) and value and all(
            isinstance(p, dict) and {"contact", "t_start", "t_end"} <= set(p) for p in value)):
        return None
    return ", ".join(f"{p['contact']} {fmt(p['t_start'])}-{fmt(p['t_end'])} s" for p in value)


#: What None means for keys where "-" would hide it.
_NONE_MEANS = {"t_invert": "never (does not turn over)", "t_stem": "never (no stem contact)"}


def fmt_value(key: str, value: Any) -> str:
    """A value as text with the unit its key implies (:func:`unit_of`).

    ``t_invert`` None reads ``never (does not turn over)``; ``wall_s`` is a duration; a
    ``phases`` list reads ``ball 0-2.5 s, stem 2.5-8 s``; an empty ``unused`` list ``none``.
    """
    if value is None and key in _NONE_MEANS:
        return _NONE_MEANS[key]
    if key == "wall_s" and isinstance(value, (int, float)) and not isinstance(value, bool):
        return fmt_duration(float(value))
    if key == "phases":
        text = _phases(value)
        if text is not None:
            return text
    if key == "solref" and isinstance(value, (list, tuple)) and len(value) == 2:
        return f"{fmt(value[0])} s, {fmt(value[1])}"
    return fmt(value, unit_of(key))


def key_values(items: Iterable[tuple[str, Any]] | dict[str, Any], indent: str = "") -> str:
    """``key  value unit`` lines, the values lined up."""
    pairs = list(items.items() if isinstance(items, dict) else items)
    if not pairs:
        return ""
    width = max(len(k) for k, _ in pairs)
    return "\n".join(f"{indent}{k:<{width}}  {fmt_value(k, v)}" for k, v in pairs)


def text_width() -> int:
    """Columns to wrap prose at: the terminal's (at most 120), or 100 off a terminal."""
    return max(40, min(120, shutil.get_terminal_size((101, 24)).columns) - 1)


def labelled(label: str, text: str, label_width: int, indent: str = "  ") -> str:
    """``label  text``, the text wrapped to :func:`text_width` under itself."""
    import textwrap

    head = f"{indent}{label:<{label_width}}  "
    return textwrap.fill(text, width=text_width(), initial_indent=head,
                         subsequent_indent=" " * len(head), break_on_hyphens=False,
                         break_long_words=False)


# ---------------------------------------------------------------- tables
def _numeric(text: str) -> bool:
    head = text.split(" ")[0].lstrip("+-")
    return bool(head) and (head[0].isdigit() or head in ("inf",)) and text != MISSING


def table(columns: Sequence[str], rows: Sequence[Sequence[str]], indent: str = "",
          header: bool = True) -> str:
    """Rows of text in columns two spaces apart; a column of numbers is right-aligned.

    Args:
        columns: Column titles (they set the number of columns).
        rows: One sequence of already formatted cells per row.
        indent: Prefix of every line.
        header: Print the titles as the first line.

    Returns:
        The header, then the rows (no trailing newline).
    """
    cols = len(columns)
    cells = [list(columns)] + [[str(c) for c in r] + [""] * (cols - len(r)) for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(cols)]
    right = [all(_numeric(r[i]) or r[i] in (MISSING, "") for r in cells[1:]) and
             any(_numeric(r[i]) for r in cells[1:]) for i in range(cols)]
    lines = []
    for r in cells if header else cells[1:]:
        parts = [r[i].rjust(widths[i]) if right[i] else r[i].ljust(widths[i])
                 for i in range(cols)]
        lines.append(indent + "  ".join(parts).rstrip())
    return "\n".join(lines)


# ---------------------------------------------------------------- cost of a run
#: Expected wall time of one MuJoCo step, any integrator and mode (s). Measured on a 2-core
#: machine: 21-90 us a step over the cached paper- and native-mode runs (median about 65 us;
#: recording the observables costs as much as the physics). The bar measures the real speed.
MUJOCO_STEP_S = 65e-6
#: MuJoCo's own timestep, for a loaded file whose plan leaves it to the file (s).
MUJOCO_DEFAULT_TIMESTEP_S = 2e-3
#: Fixed cost of a run in a worker: building the model or problem, the table, the cache (s).
TASK_OVERHEAD_S = 0.3
#: Expected wall time of the compiled reference ODE per simulated second (s): median 5 ms,
#: at most 15 ms over the cached reference runs, so far below MuJoCo's (about 26 s at 2.5 us).
ODE_PER_SIM_S = 0.01


def expected_cost_s(plan: Any) -> float:
    """The expected wall time of one run on one core (s), from its plan.

    MuJoCo: ``t_end / timestep`` steps times :data:`MUJOCO_STEP_S`; the reference ODE:
    :data:`ODE_PER_SIM_S` per simulated second; both plus :data:`TASK_OVERHEAD_S`. Only the
    ratios matter to the bar; its ETA uses the speed measured while it runs.

    Args:
        plan: A :class:`tippetop.models.plan.RunPlan` (read by attribute).
    """
    mj = getattr(plan, "mujoco", None)
    t_end = float(getattr(plan, "t_end_s", 0.0) or 0.0)
    if getattr(plan, "engine", "ode") != "ode" and mj is not None:
        dt = getattr(mj, "timestep_s", None) or MUJOCO_DEFAULT_TIMESTEP_S
        t_end = float(getattr(mj, "t_end_s", t_end) or t_end)
        return TASK_OVERHEAD_S + t_end / dt * MUJOCO_STEP_S
    ode = getattr(plan, "ode", None)
    if ode is not None:
        t_end = float(getattr(ode, "t_end_s", t_end) or t_end)
    return TASK_OVERHEAD_S + t_end * ODE_PER_SIM_S


# ---------------------------------------------------------------- progress
def schedule_s(running: Sequence[float], pending: Sequence[float], slots: int) -> float:
    """Time until all work is done on ``slots`` workers.

    The running remainders go first, then the pending runs in order, each on the first
    worker to come free (a pool's first-in first-out queue).

    Args:
        running: Remaining time of each run going now.
        pending: Time of each run not started, in the order they start.
        slots: Workers.

    Returns:
        The makespan (same units as the inputs).
    """
    slots = max(1, slots)
    free = sorted(list(running)[:slots] + [0.0] * max(0, slots - len(running)))
    extra = list(running)[slots:]  # more running than slots: treat as queued first
    heapq.heapify(free)
    for c in [*extra, *pending]:
        heapq.heappush(free, heapq.heappop(free) + c)
    return max(free) if free else 0.0


class WorkProgress:
    """Progress of a batch of runs weighted by their expected cost, with an honest ETA.

    Each run has a weight, its expected cost (:func:`expected_cost_s`). The fraction done is
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
    """

    #: Weight of the prior speed (1 expected second per second), in seconds of busy worker.
    PRIOR_S = 2.0
    #: The speed is measured over about this much recent time (s; older work fades out), so a
    #: slow start (workers importing their engines) does not weigh on the ETA for long.
    MEMORY_S = 30.0

    def __init__(self, label: str, costs: Sequence[float], *, slots: int = 1,
                 stream: TextIO | None = None, enabled: bool | None = None,
                 clock: Any = time.monotonic, note: str = "",
                 min_interval_s: float = 0.2) -> None:
        self.label = label
        self.costs = [max(float(c), 1e-6) for c in costs]
        self.slots = max(1, int(slots))
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = enabled and bool(self.costs)
        self.clock = clock
        self.note = note
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
        if n < total and not self._measuring and elapsed >= 1.0:
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


__all__ = ["MISSING", "NAN_TEXT", "WorkProgress", "expected_cost_s", "fmt", "fmt_duration",
           "fmt_float", "fmt_percent", "fmt_value", "key_values", "labelled", "schedule_s",
           "table", "text_width", "unit_of"]
