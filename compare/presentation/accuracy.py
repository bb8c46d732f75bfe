"""What ``tippetop bench accuracy`` prints: the files written, the cheapest point per accuracy."""

from __future__ import annotations

from typing import Any

from tippetop.compare.results.accuracy import AccuracyResult


def print_accuracy(res: AccuracyResult) -> None:
    """The study's report: a line per file written, and one per Pareto entry."""
    print(res.report)


def accuracy_json(res: AccuracyResult) -> dict[str, Any]:
    """What ``tippetop bench accuracy --json`` prints: the study's JSON without its report."""
    return {k: v for k, v in res.to_json().items() if k != "report"}


__all__ = ["accuracy_json", "print_accuracy"]
