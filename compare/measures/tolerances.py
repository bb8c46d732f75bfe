"""How far a metric may move from its baseline, and the comparison of a value with it."""

from __future__ import annotations

import math
from typing import Any

from tippetop.compare.measures.metrics import GROWTH_MEASURED, TOLERANCES, Tolerance

#: The per-metric tolerances, as :mod:`.metrics` declares them (the one place they are set).
#: ``measured`` is widened to the case's own bisection ``rel_tol`` when that is coarser
#: (:func:`tippetop.compare.nightly.checks.tolerance_for`).
__all__ = ["GROWTH_MEASURED", "TOLERANCES", "Tolerance", "compare_value", "format_value"]


def _is_missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and not math.isfinite(v))


def format_value(v: Any, unit: str = "") -> str:
    """A metric value for a message (``none`` when missing)."""
    if _is_missing(v):
        return "none"
    if isinstance(v, float):
        return f"{v:.6g}{' ' + unit if unit else ''}"
    return str(v)


def compare_value(value: Any, baseline: Any, tol: Tolerance) -> tuple[bool, str]:
    """Whether ``value`` is within ``tol`` of ``baseline``, and a message that shows both.

    Dictionaries (sweeps: n0 -> value) are compared point by point on the n0 values both
    have; the message names the worst point.
    """
    if isinstance(baseline, dict) or isinstance(value, dict):
        if not (isinstance(baseline, dict) and isinstance(value, dict)):
            return False, f"{format_value(value)} vs baseline {format_value(baseline)}"
        common = [k for k in value if k in baseline]
        bad = []
        for k in common:
            ok, msg = compare_value(value[k], baseline[k], tol)
            if not ok:
                bad.append(f"{k}: {msg}" if "=" in k else f"n0 = {k}: {msg}")
        extra = len(value) - len(common)
        note = f"; {extra} point(s) without baseline" if extra else ""
        if bad:
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            return False, f"{bad[0]}{more}{note}"
        return True, f"{len(common)} points within {tol.describe()}{note}"
    u = tol.unit
    shown = (f"{format_value(value, u)} vs baseline {format_value(baseline, u)} "
             f"(tolerance {tol.describe()})")
    if _is_missing(value) or _is_missing(baseline):
        return _is_missing(value) and _is_missing(baseline), shown
    if tol.kind == "exact":
        return value == baseline, shown
    v, b = float(value), float(baseline)
    if tol.kind == "abs":
        return abs(v - b) <= tol.value, shown
    if tol.kind == "rel":
        return abs(v - b) <= max(tol.value * abs(b), tol.floor), shown
    if tol.kind == "max":
        return v <= tol.value, shown
    return v <= max(tol.value * b, tol.floor), shown
