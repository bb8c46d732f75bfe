"""What ``tippetop simulate`` prints: a run's summary, what ran and the unused ``--set`` keys."""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.terminal import (
    RAN_KEYS,
    fmt_stiff,
    fmt_value,
    none_means,
    ran_lines,
)


def print_summary(scene: str, summary: dict[str, Any], table_path: Any = None) -> None:
    """A run's summary: the results, then what ran, then the unused ``--set`` keys.

    Every number with its unit, to four significant digits (a relative drift to two, and
    said to be relative); a value that is not there says why.
    """
    ran = [k for k in RAN_KEYS if k in summary]
    # the rolling phases are said beside what ran for stiff friction
    rest = [(k, v) for k, v in summary.items()
            if k not in RAN_KEYS and k not in ("unused", "rolling_phases")]
    pairs = [("scene", scene), *rest]
    width = max(len(k) for k in [*(k for k, _ in pairs), *ran, "unused"])

    finished = summary.get("status") in (None, "ok")

    def said(k: str, v: Any) -> str:
        # what ran for stiff friction, beside the rolling phases the run did (or did not) enter
        if k == "stiff":
            return fmt_stiff(v, summary.get("rolling_phases"))
        if v is None and not finished and none_means(k) is not None:
            # "never" only of a run that finished: this one stopped before it could tell
            return f"- (the run stopped: {summary.get('status')}, see its message)"
        return fmt_value(k, v)

    print("\n".join(f"{k:<{width}}  {said(k, v)}" for k, v in pairs))
    if ran:
        print("what ran:")
        print("\n".join(ran_lines(summary, width)))
    unused = summary.get("unused")
    if unused is not None:
        print(f"{'unused':<{width}}  {', '.join(unused) if unused else 'none'} (--set keys "
              "the engine did not read)")
    if table_path is not None:
        print(f"wrote {table_path}")


__all__ = ["print_summary"]
