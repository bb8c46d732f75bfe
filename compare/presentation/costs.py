"""The costs the README, the guides and the help quote: one stored benchmark result, one text.

``docs/data/costs.json`` (format :data:`FORMAT`) holds what each quoted cost measured, how and
when: ``benchmarks/bench_costs.py`` writes it. A page quotes a cost as :func:`cost_text` words
it: the docs through the ``{{ cost KEY }}`` marker (docs/hooks/costs.py fills it in when the site
is built), the README in its own words, which tests/test_costs.py checks against the same
text; so each claim has one number, and a new measurement that moves it fails the check until
the page says the new figure.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: The stored result's format.
FORMAT = "tippetop-costs/1"
#: Where it is, in the repository.
DEFAULT_PATH = Path(__file__).resolve().parents[2] / "docs" / "data" / "costs.json"
#: A page's marker for a cost: ``{{ cost KEY }}``.
MARKER = re.compile(r"\{\{\s*cost\s+(?P<key>[a-z0-9_]+)\s*\}\}")


@dataclass(frozen=True)
class Cost:
    """One measured cost.

    Attributes:
        key: Its name (``nightly_quick_s``).
        value: The measured value, in ``unit`` (of a range: its low end).
        unit: ``s`` (wall-clock seconds), ``ms`` (milliseconds), ``MB`` (megabytes, 2^20
            bytes) or ``x`` (a ratio of two times).
        what: What was measured, in words.
        command: How (the command or the benchmark that measured it, or the stored result it
            was read from).
        high: The high end of a range (several measurements of one kind: two releases' managed
            environments), or None for one value.
    """

    key: str
    value: float
    unit: str
    what: str
    command: str
    high: float | None = None


#: The units a cost may be stored in.
UNITS = ("s", "ms", "MB", "x")


def load(path: Path | None = None) -> tuple[dict[str, Cost], dict[str, Any]]:
    """The stored costs by key, and the file's other fields (when, the machine)."""
    data = json.loads((path or DEFAULT_PATH).read_text())
    if data.get("format") != FORMAT:
        raise ValueError(f"{path or DEFAULT_PATH}: expected format {FORMAT}, got "
                         f"{data.get('format')!r}")
    costs = {k: Cost(k, float(v["value"]), v["unit"], v["what"], v["command"],
                     None if v.get("high") is None else float(v["high"]))
             for k, v in data["costs"].items()}
    return costs, {k: v for k, v in data.items() if k != "costs"}


def _seconds(v: float) -> tuple[str, str]:
    if v < 20:
        return str(max(1, round(v))), "s"
    if v < 100:
        return str(5 * round(v / 5)), "s"
    return str(round(v / 60)), "min"


def _figure(v: float) -> str:
    """Two figures at most: 0.3, 2.6, 16, 140, 990, 1500."""
    if v >= 100:
        return str(int(float(f"{v:.2g}")))
    if v >= 10:
        return str(round(v))
    if v >= 1:
        return f"{v:.1f}"
    return f"{v:.1g}"


def cost_text(cost: Cost) -> str:
    """The words a page quotes ``cost`` in: ``about 15 s``, ``about 11 min``, ``about 2.0x``.

    Seconds under 20 to the second, under 100 to 5 s, longer to the minute; milliseconds,
    megabytes and ratios to two figures (a ratio under 10 to one decimal: ``about 2.0x``,
    ``about 110x``). A range is worded ``about 3-5 s`` (``about 7 s to 7 min`` where its ends
    take different units).
    """
    if cost.unit not in UNITS:
        raise ValueError(f"cost {cost.key}: expected unit {', '.join(UNITS)}, got "
                         f"{cost.unit!r}")
    ends = [cost.value] if cost.high is None else [cost.value, cost.high]
    if cost.unit == "s":
        worded = [_seconds(v) for v in ends]
    else:
        worded = [(_figure(v), cost.unit) for v in ends]
    sep = "" if cost.unit == "x" else " "
    (lo, unit), (hi, high_unit) = worded[0], worded[-1]
    if len(worded) == 1 or (lo, unit) == (hi, high_unit):
        return f"about {lo}{sep}{unit}"
    if unit == high_unit:
        return f"about {lo}-{hi}{sep}{unit}"
    return f"about {lo}{sep}{unit} to {hi}{sep}{high_unit}"


def expand(text: str, costs: dict[str, Cost]) -> str:
    """``text`` with every ``{{ cost KEY }}`` marker replaced by :func:`cost_text`.

    Raises:
        KeyError: A marker names a cost the stored result does not hold.
    """
    def fill(m: re.Match[str]) -> str:
        key = m.group("key")
        if key not in costs:
            raise KeyError(f"{{{{ cost {key} }}}}: no such cost in {DEFAULT_PATH.name} "
                           f"(it has {', '.join(sorted(costs))})")
        return cost_text(costs[key])

    return MARKER.sub(fill, text)


__all__ = ["DEFAULT_PATH", "FORMAT", "MARKER", "UNITS", "Cost", "cost_text", "expand", "load"]
