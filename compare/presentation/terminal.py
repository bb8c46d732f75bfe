"""What a person reads in the terminal: values with units, and tables.

:func:`fmt` and :func:`fmt_value` turn a value into text with the unit its key implies,
:func:`check_text` a verdict check's value; :func:`table` lines up columns,
:func:`cache_line` says where a command's runs went. This module imports only the standard
library (and, when asked, for the cache's folder :mod:`tippetop.models.resources`, for the
realised law's sentence :mod:`tippetop.compare.measures.friction_realised`).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Iterable, Sequence
from typing import Any

from tippetop.models.modes import REFERENCE_RUN
from tippetop.models.numbers import MISSING, NAN_TEXT, float_text, solver_text

# ---------------------------------------------------------------- values
#: Units of keys that are neither a declared metric nor a setting of what ran, and whose names
#: do not carry one (a metric's unit is its declaration's: :func:`_declared_unit`).
_KEY_UNITS: dict[str, str] = {
    "n0": "rad/s", "n1": "rad/s", "n2": "rad/s", "n3": "rad/s", "n4": "rad/s", "nc": "rad/s",
    "theory": "rad/s", "A": "kg m^2", "C": "kg m^2", "mu": "", "law_mu": "",
    # MuJoCo's solver tolerance (a relative improvement of its cost), the ODE's rtol
    "tolerance": "relative", "rtol": "relative",
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
    declared = _declared_unit(key)
    if declared is not None:
        return declared
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


def _declared_unit(key: str) -> str | None:
    """The unit a metric or a setting of what ran is declared with (None: not declared)."""
    from tippetop.compare.measures.metrics import METRICS
    from tippetop.compare.measures.summary import RAN_FIELDS

    if key in METRICS:
        unit = METRICS[key].unit
        return "" if unit == "fraction" else unit
    if key in RAN_FIELDS:
        return RAN_FIELDS[key].unit
    return None


def _exp(text: str) -> str:
    """``1.3e-09`` -> ``1.3e-9``, ``1.2e+05`` -> ``1.2e5``."""
    if "e" not in text:
        return text
    mant, exp = text.split("e")
    sign = "-" if exp.startswith("-") else ""
    return f"{mant}e{sign}{exp.lstrip('+-').lstrip('0') or '0'}"


def fmt_float(x: float, digits: int = 4) -> str:
    """A float in ``digits`` significant digits (:func:`tippetop.models.numbers.float_text`)."""
    return float_text(x, digits)


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
    """Wall time for a person: ``24.78 ms``, ``18.06 s``, ``2 min 05 s``, ``1 h 02 min``.

    Four significant digits below a minute, as every other number (in ms below a second).
    """
    if seconds is None:
        return MISSING
    if not math.isfinite(seconds):
        return fmt_float(seconds)
    if 0 < seconds < 1:
        return f"{fmt_float(1e3 * seconds)} ms"
    if seconds < 60:
        return f"{fmt_float(seconds)} s"
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


#: The most contact phases a line lists; the rest are counted.
MAX_PHASES_SHOWN = 8


def _phases(value: Any) -> str | None:
    """``[{contact, t_start, t_end}, ...]`` -> ``ball 0-2.5 s, stem 2.5-8 s``, else None.

    A phase without contact shorter than :data:`~tippetop.compare.measures.series.HOP_MIN_S`
    (the soft contact chattering) is folded into the phases around it; past
    :data:`MAX_PHASES_SHOWN` phases the middle ones are counted, not listed.
    """
    if not (isinstance(value, list) and value and all(
            isinstance(p, dict) and {"contact", "t_start", "t_end"} <= set(p) for p in value)):
        return None
    from tippetop.compare.measures.series import HOP_MIN_S

    # a phase runs from its first sample to its last: the next starts one sample later
    gaps = [b["t_start"] - a["t_end"] for a, b in zip(value, value[1:], strict=False)]
    dt = min((g for g in gaps if g > 0), default=0.0)
    merged: list[dict[str, Any]] = []
    folded = 0
    for p in value:
        short = p["t_end"] - p["t_start"] + dt < HOP_MIN_S * (1 - 1e-9)
        if p["contact"] == "none" and merged and short:
            folded += 1
            merged[-1] = {**merged[-1], "t_end": p["t_end"]}
        elif merged and merged[-1]["contact"] == p["contact"]:
            merged[-1] = {**merged[-1], "t_end": p["t_end"]}
        else:
            merged.append(dict(p))
    parts = [f"{p['contact']} {fmt(p['t_start'])}-{fmt(p['t_end'])} s" for p in merged]
    if len(parts) > MAX_PHASES_SHOWN:
        head, tail = MAX_PHASES_SHOWN // 2, MAX_PHASES_SHOWN // 4
        parts = [*parts[:head], f"... {len(parts) - head - tail:,} more ...", *parts[-tail:]]
    text = ", ".join(parts)
    if folded:  # how many depends on the sample spacing: the flights line counts them
        text += (f" (samples without contact for under {fmt(1e3 * HOP_MIN_S, 'ms')} folded in: "
                 "see flights)")
    return text


def none_means(key: str) -> str | None:
    """What None means for a metric of a run that finished, where ``-`` would hide it.

    The metric's declaration says it (``t_invert``: ``never (does not turn over)``); None
    for a key whose None is ``-``.
    """
    from tippetop.compare.measures.metrics import METRICS

    m = METRICS.get(key)
    return m.none_means or None if m is not None else None


#: What None means among the settings that ran (:func:`ran_lines`): a coefficient MuJoCo's
#: contact has no row for, or a start that is not a keyframe.
_RAN_NONE_MEANS = {
    "mu": "none (condim 1: MuJoCo's contact has no friction of its own)",
    "torsional": "none (condim below 4: no torsional friction)",
    "rolling": "none (condim below 6: no rolling friction)",
    "law_mu": "none (no friction law of the harness's)",
    "keyframe": "none (the scene's own start, not a keyframe)",
    "solreffriction": "none (the friction rows use solref; only a contact pair sets it)",
}
#: ``stiff`` of a reference run (what ran for stiff friction) as a person reads it.
_STIFF_MEANS = {"rolling": "rolling phases where the law turns stiff",
                "off": "off (the law throughout, as asked)"}


def fmt_flights(fl: dict[str, Any]) -> str:
    """A MuJoCo run's stretches without contact, measured at every step, in words.

    Example: ``1,166 from 0.637 s, up to 3.2 ms and 0.81 um high, 0.411 s in all; no flight
    (10 ms or more, risen 10 um or more: the contact chattering, not the ball leaving the
    table)``.
    """
    from tippetop.compare.measures.series import FLIGHT_RISE_M, HOP_MIN_S

    n, hops = int(fl.get("count") or 0), int(fl.get("hops") or 0)
    high = fl.get("height_m")
    head = (f"{n:,} from {fmt(fl.get('t_first'), 's')}, up to "
            f"{fmt(1e3 * float(fl.get('longest_s') or 0.0), 'ms')}"
            + (f" and {fmt(1e6 * float(high), 'um')} high" if high is not None else "")
            + f", {fmt(fl.get('airborne_s'), 's')} in all")
    rule = (f"{fmt(1e3 * float(fl.get('hop_min_s') or HOP_MIN_S), 'ms')} or more, risen "
            f"{fmt(1e6 * float(fl.get('rise_min_m') or FLIGHT_RISE_M), 'um')} or more")
    if hops:
        longest, top = fl.get("longest_hop_s"), fl.get("hop_height_m")
        size = (f", up to {fmt(1e3 * float(longest), 'ms')} and "
                f"{fmt(1e3 * float(top), 'mm')} high" if longest is not None
                and top is not None else "")
        return (f"{head}; {hops:,} flight{'s' if hops != 1 else ''} ({rule}) from "
                f"{fmt(fl.get('t_first_hop'), 's')}{size}: the ball leaving the table")
    return f"{head}; no flight ({rule}: the contact chattering, not the ball leaving the table)"


def fmt_rolling(rolling: Any) -> str:
    """The reference's rolling phases (``{"phases", "t_s"}``) as a person reads them."""
    if not (isinstance(rolling, dict) and "phases" in rolling):
        return fmt(rolling)
    n = rolling["phases"]
    if not n:
        return "no rolling phase entered"
    return (f"{fmt(n)} rolling {'phase' if n == 1 else 'phases'}, "
            f"{fmt(rolling.get('t_s'), 's')} in all")


def fmt_stiff(stiff: Any, rolling: Any = None) -> str:
    """What ran for stiff friction, coherent with the rolling phases the run entered.

    ``rolling`` (rolling phases were available where the law turns stiff) says whether the run
    entered any: ``rolling phases where the law turns stiff: available, never entered``.
    """
    text = _STIFF_MEANS.get(stiff, fmt(stiff))
    if stiff == "rolling" and isinstance(rolling, dict) and "phases" in rolling:
        n = rolling["phases"]
        text += (": available, never entered" if not n else
                 f": available, entered {fmt(n)} {'time' if n == 1 else 'times'} "
                 f"({fmt(rolling.get('t_s'), 's')} in all)")
    return text


# ---------------------------------------------------------------- a verdict's checks
#: The events of the event checks (:mod:`tippetop.compare.measures.verdict`): what a run does,
#: what it does not.
_EVENTS = {"t_invert": ("turns over", "does not turn over"),
           "t_stem": ("touches its stem", "does not touch its stem")}


def within_run(t_end_s: float | None) -> str:
    """What "never" means for an event: ``within the run's 8 s`` (``within the run`` unknown)."""
    return f"within the run's {fmt(float(t_end_s), 's')}" if t_end_s is not None else \
        "within the run"


def _event_text(check: dict[str, Any], t_end_s: float | None,
                times: tuple[float | None, float | None] | None) -> str:
    """An event check's value: how far from the reference's, or which run never has it."""
    does, never = _EVENTS[check["check"]]
    d = check["value"]
    if d is not None:
        if d == 0:
            return "0 s from the reference's"
        return f"{fmt(abs(float(d)), 's')} {'later' if d > 0 else 'earlier'} than the reference"
    within = within_run(t_end_s)
    mine, ref = times if times is not None else (None, None)
    note = str(check.get("note", ""))
    if check["passed"] or note.startswith("neither"):
        verb = never.removeprefix("does not ")
        return f"neither this run nor the reference {verb} {within}"
    if note.endswith("this run only"):  # the reference never has it
        at = f" at {fmt(float(mine), 's')}" if mine is not None else ""
        return f"{does}{at}; the reference {never} {within}"
    at = f" at {fmt(float(ref), 's')}" if ref is not None else ""
    return f"{never} {within}; the reference {does}{at}"


def check_text(check: dict[str, Any], t_end_s: float | None = None,
               runs: dict[str, dict[str, Any]] | None = None) -> str:
    """A check's value as a person reads it: with its unit, or why there is none.

    ``t_invert`` and ``t_stem`` are the run's time less the reference's (``1.29 s later than
    the reference``), or which of the two never has the event within the run's ``t_end_s``;
    Jellett's drift is relative, the energy's rise a fraction of E0; a string is itself. Never
    a bare ``None``: the JSON keeps ``value`` as it is (null), this is the text beside it.

    Args:
        check: One check of :func:`tippetop.compare.measures.verdict.verdict`.
        t_end_s: The runs' simulated time (s), to say what "never" means.
        runs: The runs by name (``ode/paper`` the reference), for the event times.
    """
    name, v = check["check"], check["value"]
    if name in _EVENTS:
        times = None
        if runs is not None:
            times = ((runs.get(check["run"]) or {}).get(name),
                     (runs.get(REFERENCE_RUN) or {}).get(name))
        return _event_text(check, t_end_s, times)
    if name == "stays_on_table":
        return ("stays on the table" if v is None else
                f"leaves the table at {fmt(float(v), 's')}")
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        if not math.isfinite(v):
            return fmt(float(v))
        if name == "jellett_before_stem":
            return f"{fmt(float(v), 'relative')} (relative)"
        if name == "energy_never_rises":
            return f"{fmt(float(v), 'relative')} of E0"
        return fmt(v)
    if v is None:
        why = {"jellett_before_stem": "not measured: the ball alone never touched before the "
                                      "stem",
               "energy_never_rises": "not measured: the run has no energy record",
               "outcome": "no outcome: the run did not finish"}
        return why.get(name, f"none ({check.get('note') or 'not measured'})")
    return str(v)


def check_note(check: dict[str, Any]) -> str:
    """The note to show beside :func:`check_text`'s value, or "" when that text already says it.

    An event check (``t_invert``, ``t_stem``) with no number says which run never has the
    event, which is what its note says too.
    """
    if check["value"] is None and check["check"] in _EVENTS:
        return ""
    return str(check.get("note") or "")


def fmt_value(key: str, value: Any) -> str:
    """A value as text with the unit its key implies (:func:`unit_of`).

    ``t_invert`` None reads ``never (does not turn over)``; ``wall_s`` is a duration; a
    ``phases`` list reads ``ball 0-2.5 s, stem 2.5-8 s``; an empty ``unused`` list ``none``;
    a relative quantity says so (``1.3e-9 (relative)``, an energy's ``0 of E0``).
    """
    if value is None and (meaning := none_means(key)) is not None:
        return meaning
    if key == "wall_s" and isinstance(value, (int, float)) and not isinstance(value, bool):
        return fmt_duration(float(value))
    if key == "phases":
        text = _phases(value)
        if text is not None:
            return text
    if key == "friction_realised" and isinstance(value, dict):
        # the one sentence every command and report says it in (it brings numpy and pandas)
        from tippetop.compare.measures.friction_realised import realised_sentence

        return realised_sentence("the run", value)
    if key == "stiff":
        return fmt_stiff(value)
    if key == "flights" and isinstance(value, dict):
        return fmt_flights(value)
    if key == "rolling_phases" and isinstance(value, dict):
        return fmt_rolling(value)
    if key in ("solref", "solimp", "solreffriction") and isinstance(value, (list, tuple)):
        return solver_text(key, value)
    if key == "atol" and isinstance(value, float):
        return f"{fmt(value)} (absolute, in each state variable's own unit)"
    unit = unit_of(key)
    text = fmt(value, unit)
    if unit == "relative" and isinstance(value, (int, float)) and not isinstance(value, bool) \
            and math.isfinite(value):
        return f"{text} of E0" if key.startswith("energy") else f"{text} (relative)"
    return text


#: The keys of what ran (a summary's settings read back from the engine, or a plan's), in the
#: order they are listed.
RAN_KEYS = ("friction_law", "formulation", "method", "rtol", "atol", "law_mu", "timestep_s",
            "integrator", "cone", "impratio", "noslip_iterations", "condim", "mu", "torsional",
            "rolling", "solref", "solreffriction", "solimp", "gravity_mps2", "sample_dt_s",
            "keyframe")


def ran_lines(values: dict[str, Any], width: int) -> list[str]:
    """What ran (or will run): an indented ``key  value unit`` line per key present.

    In :data:`RAN_KEYS` order, the values starting at column ``width + 2``; a setting that
    is None says why (``mu  none (condim 1: ...)``).
    """
    def said(k: str) -> str:
        v = values[k]
        return _RAN_NONE_MEANS[k] if v is None and k in _RAN_NONE_MEANS else fmt_value(k, v)

    return [f"  {k:<{width - 2}}  {said(k)}" for k in RAN_KEYS if k in values]


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


def wrapped(text: str, indent: str = "", width: int | None = None) -> str:
    """``text`` wrapped to the terminal's width (at most 100 columns), each line indented."""
    import shutil
    import textwrap

    width = width or max(60, min(100, shutil.get_terminal_size((100, 24)).columns))
    return textwrap.fill(text, width, initial_indent=indent, subsequent_indent=indent)


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


def cache_line(computed: int | None, cached: int | None, use_cache: bool) -> str:
    """Where the runs went: ``runs: 6 computed, 2 from the cache in /root/.cache/tippetop``."""
    from tippetop.models.resources import user_cache_dir

    counts = f"{computed} computed, {cached} from the cache" if computed is not None else ""
    if not use_cache:
        return f"runs: {counts or 'computed'}; the cache was not used (--no-cache)"
    where = f"{user_cache_dir()} ($TIPPETOP_CACHE)"
    return f"runs: {counts} in {where}" if counts else f"runs: cached in {where}"


__all__ = ["MISSING", "NAN_TEXT", "RAN_KEYS", "cache_line", "check_note", "check_text", "fmt",
           "fmt_duration", "fmt_float", "fmt_percent", "fmt_rolling", "fmt_stiff", "fmt_value",
           "key_values", "labelled", "ran_lines", "table", "text_width",
           "unit_of", "within_run"]
