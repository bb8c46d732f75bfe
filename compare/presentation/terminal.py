"""What a person reads in the terminal: values with units, and tables.

:func:`fmt` and :func:`fmt_value` turn a value into text with the unit its key implies,
:func:`table` lines up columns, :func:`cache_line` says where a command's runs went. This
module imports only the standard library (and, for the cache's folder,
:mod:`tippetop.models.resources`).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Iterable, Sequence
from typing import Any

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
    if key == "friction_realised" and isinstance(value, dict):
        from tippetop.compare.analysis.friction_realised import realised_sentence

        return realised_sentence("the run", value)
    if key == "solref" and isinstance(value, (list, tuple)) and len(value) == 2:
        return f"{fmt(value[0])} s, {fmt(value[1])}"
    return fmt(value, unit_of(key))


#: The keys of what ran (a summary's settings read back from the engine, or a plan's), in the
#: order they are listed.
RAN_KEYS = ("mode", "friction_law", "formulation", "rtol", "atol", "law_mu", "timestep_s",
            "integrator", "cone", "impratio", "noslip_iterations", "condim", "mu", "torsional",
            "rolling", "solref", "solimp", "gravity_mps2", "sample_dt_s", "keyframe")


def ran_lines(values: dict[str, Any], width: int) -> list[str]:
    """What ran (or will run): an indented ``key  value unit`` line per key present.

    In :data:`RAN_KEYS` order, the values starting at column ``width + 2``.
    """
    return [f"  {k:<{width - 2}}  {fmt_value(k, values[k])}" for k in RAN_KEYS if k in values]


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


def cache_line(computed: int | None, cached: int | None, use_cache: bool) -> str:
    """Where the runs went: ``runs: 6 computed, 2 from the cache in /root/.cache/tippetop``."""
    from tippetop.models.resources import user_cache_dir

    counts = f"{computed} computed, {cached} from the cache" if computed is not None else ""
    if not use_cache:
        return f"runs: {counts or 'computed'}; the cache was not used (--no-cache)"
    where = f"{user_cache_dir()} ($TIPPETOP_CACHE)"
    return f"runs: {counts} in {where}" if counts else f"runs: cached in {where}"


__all__ = ["MISSING", "NAN_TEXT", "RAN_KEYS", "cache_line", "fmt", "fmt_duration", "fmt_float",
           "fmt_percent", "fmt_value", "key_values", "labelled", "ran_lines", "table",
           "text_width", "unit_of"]
