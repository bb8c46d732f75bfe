"""What ``tippetop history`` prints: the runs in a line, then each case and engine's series.

The series' own lines (their levels over time and a line per change) are made in the nightly
room (:func:`tippetop.compare.nightly.history.series_text`), which this room does not import:
the command passes them in.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def print_history(path: Any, runs: Sequence[dict[str, Any]],
                  found: Sequence[tuple[Any, Sequence[Any], Sequence[str]]]) -> None:
    """The history for a person: the runs in a line, then each case and engine's series.

    Args:
        path: The history file.
        runs: The runs read (each with its ``kind`` and ``started``), oldest first.
        found: Each series shown: the series, its changes and its lines
            (:func:`~tippetop.compare.nightly.history.series_text`).
    """
    if not runs:
        print(f"history: {path}: no runs yet (each nightly and matrix appends to it; --import "
              "adds old results.json files)")
        return
    kinds: dict[str, int] = {}
    for r in runs:
        kinds[r["kind"]] = kinds.get(r["kind"], 0) + 1
    days = [runs[0]["started"][:10], runs[-1]["started"][:10]] if runs else []
    span = "" if not days else f", {days[0]}" if days[0] == days[1] else \
        f", {days[0]} to {days[1]}"
    changed = sum(bool(c) for _, c, _ in found)
    print(f"history: {path}: {len(runs)} run{'' if len(runs) == 1 else 's'} ("
          + ", ".join(f"{n} {k}" for k, n in kinds.items()) + f"){span}; {len(found)} series, "
          f"{changed} changed")
    if not found:
        print("  nothing matches")
        return
    head = None
    for s, _, lines in found:
        if (s.kind, s.case, s.engine) != head:
            head = (s.kind, s.case, s.engine)
            versions = list(dict.fromkeys(v.engine_version or "?" for v in s.values))
            print(f"{s.kind} {s.case} on {s.engine} ({', '.join(versions)}):")
        for line in lines:
            print(line)


__all__ = ["print_history"]
