"""The bisect fixture's cases, run by tests/stored/make.py (the stored outputs) and by the test.

Each case is a fake release range and a fake runner (tests/compare/test_bisect.py's
``FakeRunner``: no environment made, each release's metrics from a formula), bisected over the
named metrics; its result's JSON is what is stored.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

#: name: (releases, metrics, value(i), broken releases, budget)
CASES: dict[str, tuple[int, tuple[str, ...], Callable[[int], dict[str, Any]], tuple[str, ...],
                       int | None]] = {
    "one_move": (16, ("t_invert",), lambda i: {"t_invert": 1.206 if i < 6 else 1.042}, (), None),
    "no_move": (16, ("t_invert",), lambda i: {"t_invert": 1.2 + 1e-4 * i}, (), None),
    "two_moves": (16, ("t_invert",),
                  lambda i: {"t_invert": 1.5 if i < 5 else 1.3 if i < 11 else 1.0}, (), None),
    "away_and_back": (16, ("t_invert", "theta_asymp"),
                      lambda i: {"t_invert": 1.2 if i < 8 else 1.0,
                                 "theta_asymp": 3.0 if 6 <= i <= 9 else 2.9}, (), None),
    "budget": (50, ("t_invert",), lambda i: {"t_invert": 5.0 - 0.25 * (i // 5)}, (), 10),
    "cannot_run": (8, ("t_invert",), lambda i: {"t_invert": 1.206 if i < 4 else 1.042},
                   ("mujoco==3.3.0", "mujoco==3.4.0"), None),
    "end_cannot_run": (8, ("t_invert",), lambda i: {"t_invert": 1.206 if i < 5 else 1.042},
                       ("mujoco==3.0.0",), None),
}


def _attribution(a: str, b: str) -> dict[str, Any]:
    """The attribution every move gets: 'the solver', with no reruns."""
    return {"follows": "the solver", "evidence": [], "removed_by": [], "kept_by": [],
            "metric": "t_invert", "engines": [a, b], "theta_gap_rad": None}


def _runner(n: int, value: Callable[[int], dict[str, Any]], broken: tuple[str, ...]) -> Any:
    """tests/compare/test_bisect.py's fake runner, its attribution whole in either code.

    Before issue 42 a runner's ``attribute`` returned the matrix's dictionary, after it the
    matrix's result; both say the same attribution.
    """
    from tests.compare.test_bisect import FakeRunner, _names

    class Runner(FakeRunner):
        def attribute(self, a: str, b: str) -> Any:
            self.attributed.append((a, b))
            diff = {"scene": "fig3", "mode": "native", "engines": [a, b], "metric": "t_invert",
                    "values": [None, None], "tolerance": 0.1, "why": "",
                    "attribution": _attribution(a, b), "closer": None}
            from tippetop.compare.studies import matrix

            if not hasattr(matrix, "MatrixResult"):  # the code before issue 42
                return {"differences": [diff]}
            from tippetop.compare.results.matrix import MatrixDifference, MatrixResult

            return MatrixResult((), (), (MatrixDifference.from_json(diff),), True, {},
                                ("native",), ("fig3",), {})

    return Runner(_names(n), value, broken=broken)


def run_case(name: str) -> dict[str, Any]:
    """The case's bisect, as its JSON (the result's ``to_json()`` where it has one)."""
    from tests.compare.test_bisect import _cands
    from tippetop.compare.studies.bisect import bisect

    n, metrics, value, broken, budget = CASES[name]
    lines: list[str] = []
    res = bisect(_cands(n), list(metrics), _runner(n, value, broken), budget=budget,
                 say=lines.append)
    out = res.to_json() if hasattr(res, "to_json") else res
    return {"result": out, "said": lines}
