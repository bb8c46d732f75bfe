"""The history's series and their change-points: the pure part of :mod:`.history`.

A :class:`Series` is one case's metric on one engine over the runs; :func:`change_points`
finds its steps and blips (a value beyond the metric's tolerance from its level), and
:func:`describe_change` names what changed on that run (the engine version, else the commit).
The store that reads and writes them is :mod:`tippetop.compare.nightly.history`, which
re-exports every name here.
"""

from __future__ import annotations

import math
import re
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any


def engine_family(spec: str) -> str:
    """``mujoco==3.3.7`` -> ``mujoco``; ``mjx-f32`` stays as it is."""
    return re.split(r"[=@]", spec, maxsplit=1)[0]


@dataclass
class Value:
    """One night's value of a series."""

    run: int
    started: str
    value: Any
    engine_version: str | None
    commit: str | None
    tippetop_version: str | None
    hostname: str | None
    status: str | None = None


@dataclass
class Series:
    """A case's metric on an engine over time (one point of a sweep or an atlas)."""

    kind: str
    case: str
    engine: str
    metric: str
    point: str
    unit: str
    tolerance: dict[str, Any]
    values: list[Value]

    @property
    def label(self) -> str:
        """``paper/fig3[mujoco/paper] t_invert`` (with the point: ``theta_asymp_vs_n0[45]``)."""
        return f"{self.case} {self.metric}" + (f"[{self.point}]" if self.point else "")




def point_key(point: str) -> tuple[Any, ...]:
    """How a series' points sort: numbers (a sweep's n0) as numbers, before text."""
    try:
        return (0, float(point), "")
    except ValueError:
        return (1, 0.0, point)


def text_value(text: str | None) -> Any:
    """A value stored as text, read back: a boolean, a number (nan, inf) or the text."""
    if text is None:
        return None
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)  # nan, inf
    except ValueError:
        return text


# --------------------------------------------------------------------------- change-points
def _number(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def same_level(value: Any, level: Any, tol: Mapping[str, Any]) -> bool:
    """Whether ``value`` is at ``level`` within the metric's tolerance (symmetric).

    ``abs``: within ``value``; ``rel``: within ``max(value * |level|, floor)``; ``growth``:
    the larger at most ``value`` times the smaller (or both under ``floor``); ``exact``, a
    word or a flag: equal; ``max`` (a bound on the value alone): both on the same side.
    Two missing values are the same; a missing and a present one are not.
    """
    a, b = _number(value), _number(level)
    if a is None or b is None:
        if (value is None) != (level is None):
            return False
        return value == level or (a is None and b is None and value is None)
    kind, bound = tol.get("kind"), float(tol.get("value") or 0.0)
    floor = float(tol.get("floor") or 0.0)
    if kind == "abs":
        return abs(a - b) <= bound * (1 + 1e-12)
    if kind == "rel":
        return abs(a - b) <= max(bound * abs(b), floor) * (1 + 1e-12)
    if kind == "growth":
        lo, hi = sorted((abs(a), abs(b)))
        return hi <= max(bound * lo, floor)
    if kind == "max":
        return (a <= bound) == (b <= bound)
    return a == b  # exact: the same number


def _level(values: Sequence[Any]) -> Any:
    nums = [_number(v) for v in values]
    if values and all(n is not None for n in nums):
        return statistics.median(n for n in nums if n is not None)
    return values[-1]


@dataclass
class Change:
    """Where a series moved.

    ``step`` (it stays), ``blip`` (one night, then back) or ``last`` (it moved on the last
    night: a step if it stays).
    """

    type: str
    index: int
    before: Any
    after: Any
    back: Any = None
    level: Any = None


def change_points(values: Sequence[Any], tol: Mapping[str, Any]) -> list[Change]:
    """The nights a series moved beyond its tolerance from the level before.

    The level is the median of the values since the last step (``level``; ``before`` is the
    value of the run before, ``after`` the run's). A value away from the level is a
    ``step`` when the next value is at the new value's level too, or away from both (it did
    not come back); a ``blip`` when the next value is back at the old level; ``last`` when it is
    the last value (not known yet).
    """
    out: list[Change] = []
    if not values:
        return out
    seg = [values[0]]
    i = 1
    while i < len(values):
        v, level = values[i], _level(seg)
        if same_level(v, level, tol):
            seg.append(v)
            i += 1
            continue
        if i == len(values) - 1:
            out.append(Change("last", i, values[i - 1], v, level=level))
            break
        nxt = values[i + 1]
        if same_level(nxt, level, tol):
            out.append(Change("blip", i, values[i - 1], v, back=nxt, level=level))
            seg.append(nxt)
            i += 2
            continue
        out.append(Change("step", i, values[i - 1], v, level=level))
        seg = [v]
        i += 1
    return out


def fmt_value(v: Any, unit: str = "") -> str:
    """A value for a person: four significant digits and its unit; ``none`` when missing."""
    from tippetop.compare.presentation.terminal import fmt_float

    if v is None:
        return "none"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (int, float)):
        text = fmt_float(float(v))
        return f"{text} {unit}" if unit and unit != "relative" else text
    return str(v)


def _date(started: str) -> str:
    return started[:10] if len(started) >= 10 else started


def _when(s: Series, i: int) -> str:
    """Run ``i``'s date, with its time when the series has two runs on that day."""
    day = _date(s.values[i].started)
    if sum(_date(v.started) == day for v in s.values) > 1:
        return s.values[i].started[:16].replace("T", " ")
    return day


def what_changed(a: Value, b: Value, engine: str) -> dict[str, Any]:
    """What differs between two nights of a series: the engine version, else the commit.

    Returns:
        ``engine_version`` ([before, after] or None), ``commit`` (likewise), ``host``
        (likewise) and ``text``, e.g. ``mujoco 3.3.7 -> 3.17.0``.
    """
    out: dict[str, Any] = {"engine_version": None, "commit": None, "host": None}
    fam = engine_family(engine)
    if a.engine_version != b.engine_version:
        out["engine_version"] = [a.engine_version, b.engine_version]
        out["text"] = f"{fam} {a.engine_version or '?'} -> {b.engine_version or '?'}"
    elif (a.commit or a.tippetop_version) != (b.commit or b.tippetop_version):
        out["commit"] = [a.commit or a.tippetop_version, b.commit or b.tippetop_version]

        def name(v: Value) -> str:
            return v.commit[:10] if v.commit else f"tippetop {v.tippetop_version or '?'}"
        out["text"] = (f"{fam} {b.engine_version or '?'} unchanged; commit {name(a)} -> "
                       f"{name(b)}")
    else:
        if a.hostname != b.hostname:
            out["host"] = [a.hostname, b.hostname]
        out["text"] = (f"{fam} {b.engine_version or '?'} and the commit unchanged"
                       + (f"; the machine changed: {a.hostname} -> {b.hostname}"
                          if out["host"] else ": nothing recorded changed"))
    return out


def describe_change(s: Series, c: Change) -> dict[str, Any]:
    """A change as ``--json`` gives it, with its sentence (``text``).

    E.g. ``t_invert 1.206 -> 1.042 s on 2026-11-20 (mujoco 3.3.7 -> 3.17.0)``.
    """
    prev, here = s.values[c.index - 1], s.values[c.index]
    why = what_changed(prev, here, s.engine)
    unit = s.unit
    name = s.metric + (f"[{s.point}]" if s.point else "")
    moved = f"{name} {fmt_value(c.before, '')} -> {fmt_value(c.after, unit)}"
    when = _when(s, c.index)
    if c.type == "step":
        text = f"step: {moved} on {when} ({why['text']})"
    elif c.type == "blip":
        text = (f"blip: {moved} on {when} only, back to {fmt_value(c.back, unit)} the run "
                f"after; not a step ({why['text']})")
    else:
        text = (f"moved: {moved} on {when}, the last run: a step if it stays "
                f"({why['text']})")
    return {"type": c.type, "index": c.index, "run": here.run, "started": here.started,
            "before": c.before, "after": c.after, "back": c.back, "level": c.level,
            "engine_version": why["engine_version"], "commit": why["commit"],
            "host": why["host"], "text": text}


def levels(s: Series, changes: Sequence[Change]) -> list[tuple[int, int]]:
    """The series cut at its changes: (first, last) index of each stretch at one level."""
    cuts = sorted({c.index for c in changes} | {c.index + 1 for c in changes
                                                 if c.type == "blip"})
    bounds = [0, *[k for k in cuts if 0 < k < len(s.values)], len(s.values)]
    return [(a, b - 1) for a, b in zip(bounds, bounds[1:], strict=False) if b > a]


def series_json(s: Series, changes: Sequence[Change] | None = None) -> dict[str, Any]:
    """A series as ``tippetop history --json`` gives it (see docs/guide/catching-a-change.md)."""
    changes = change_points([v.value for v in s.values], s.tolerance) if changes is None \
        else changes
    tol = dict(s.tolerance)
    if tol.get("kind"):
        from tippetop.compare.measures.metrics import Tolerance

        tol["text"] = Tolerance(str(tol["kind"]), float(tol.get("value") or 0.0),
                                float(tol.get("floor") or 0.0), s.unit).describe()
    else:
        tol["text"] = "none"
    return {"kind": s.kind, "case": s.case, "engine": s.engine, "metric": s.metric,
            "point": s.point, "unit": s.unit, "tolerance": tol,
            "values": [{"run": v.run, "started": v.started, "value": v.value,
                        "engine_version": v.engine_version, "commit": v.commit,
                        "status": v.status} for v in s.values],
            "changes": [describe_change(s, c) for c in changes]}


def series_text(s: Series, changes: Sequence[Change]) -> list[str]:
    """A series for a person: its levels over time, then a line per change."""
    parts = []
    for a, b in levels(s, changes):
        vals = [v.value for v in s.values[a:b + 1]]
        nums = [n for n in (_number(v) for v in vals) if n is not None]
        if len(nums) == len(vals) and nums and min(nums) != max(nums):
            shown = f"{fmt_value(min(nums))}-{fmt_value(max(nums), s.unit)}"
        else:
            shown = fmt_value(vals[-1], s.unit)
        d0, d1 = _when(s, a), _when(s, b)
        n = b - a + 1
        parts.append(f"{shown} ({d0}{'' if d0 == d1 else ' to ' + d1}, {n} "
                     f"run{'' if n == 1 else 's'})")
    head = f"  {s.metric}" + (f"[{s.point}]" if s.point else "") + ": " + " -> ".join(parts)
    return [head] + [f"    {describe_change(s, c)['text']}" for c in changes]


# --------------------------------------------------------------------------- the nightly
