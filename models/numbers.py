"""Numbers as text, one rule for every layer: four significant digits, then the unit.

Fixed point from 1e-3 to 1e6 with trailing zeros dropped (``2.329``), ``1.3e-9`` outside,
integers with thousands separators (``40,000``), a missing value ``-`` and a NaN said in words.
The terminal (:func:`tippetop.compare.presentation.terminal.fmt`), the analysis layer's
sentences and MuJoCo's run message all print numbers through it. Standard library only.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

#: Text of a missing number.
MISSING = "-"
#: Text of a NaN: an undefined number is said, never shown as ``nan``.
NAN_TEXT = "undefined (NaN)"


def float_text(x: float, digits: int = 4) -> str:
    """A float in ``digits`` significant digits, scientific below 1e-3 and from 1e6 on.

    Returns:
        ``2.329``, ``0.0038``, ``2e-5``, ``1.2e6``, ``0``, ``inf`` or :data:`NAN_TEXT`.
    """
    x = float(x)
    if math.isnan(x):
        return NAN_TEXT
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e6:
        decimals = max(0, digits - 1 - math.floor(math.log10(abs(x))))
        text = f"{x:.{decimals}f}"
        return text.rstrip("0").rstrip(".") if "." in text else text
    mant, _, exp = f"{x:.{max(0, digits - 1)}e}".partition("e")
    if "." in mant:
        mant = mant.rstrip("0").rstrip(".")
    return f"{mant}e{int(exp)}"


def number_text(value: float | int | None, unit: str = "", digits: int = 4) -> str:
    """A number with its unit: ``5.774 mm/s``, ``40,000``, ``2e-5 s``.

    Args:
        value: The number (numpy scalars too); None reads :data:`MISSING`.
        unit: Appended after the number, or ``"relative"``: two significant digits and no
            unit (the sentence says what it is relative to).
        digits: Significant digits of a float.
    """
    if value is None:
        return MISSING
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        text = f"{int(value):,}"
        return f"{text} {unit}" if unit and unit != "relative" else text
    if unit == "relative":
        digits, unit = 2, ""
    text = float_text(float(value), digits)
    return f"{text} {unit}" if unit and math.isfinite(float(value)) else text


def signed_text(value: float, unit: str = "") -> str:
    """A signed difference with its unit: ``-3.109 rad``, ``+0.0012 rad/s`` (``+`` for 0)."""
    return f"{'-' if value < 0 else '+'}{number_text(abs(value), unit)}"


#: The unit of each number of MuJoCo's solref (timeconst, dampratio) and solimp (d0, dwidth,
#: width, midpoint, power). A solref with a negative first number is MuJoCo's direct stiffness
#: and damping instead, said without units.
SOLVER_UNITS = {"solref": ("s", ""), "solimp": ("", "", "m", "", "")}


def solver_text(key: str, values: Sequence[float]) -> str:
    """MuJoCo's solver settings as text, each number with its unit (:data:`SOLVER_UNITS`).

    Returns:
        ``0.002 s, 1`` for a solref, ``0.05, 0.95, 0.001 m, 0.5, 2`` for a solimp (brackets are
        the caller's); another key's numbers, or a direct (negative) solref, without units.
    """
    units = SOLVER_UNITS.get(key, ())
    if key == "solref" and values and values[0] <= 0:
        units = ()
    return ", ".join(number_text(x, units[i] if i < len(units) else "")
                     for i, x in enumerate(values))


__all__ = ["MISSING", "NAN_TEXT", "SOLVER_UNITS", "float_text", "number_text", "signed_text",
           "solver_text"]
