"""Smoke test of benchmarks/bench_engines.py: what it prepares matches what the matrix runs.

The benchmark seeds a results cache with the reference's entries and times the matrix on the
engine's; if its tasks' cache keys drifted from ``run_matrix``'s, the "reference cached" figure
would silently time the reference too (or nothing). Nothing here runs a simulation.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

from tippetop.compare.running.runner import task_key
from tippetop.compare.studies import matrix
from tippetop.models.engines import parse_engines

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_engines.py"


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_engines", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


class _Captured(Exception):
    pass


def test_the_benchmarks_tasks_are_the_matrixs(monkeypatch: pytest.MonkeyPatch) -> None:
    bench = _bench()
    seen: list = []

    def capture(tasks, **_kwargs):  # noqa: ANN001, ANN202 - run_tasks's stand-in
        seen.extend(tasks)
        raise _Captured

    monkeypatch.setattr(matrix, "run_tasks", capture)
    spec = "mujoco==3.3.7"
    with pytest.raises(_Captured):
        matrix.run_matrix(["fig3", "fig6"], parse_engines(spec), ["native", "paper"],
                          ("run.t_end_s=1.0",))
    ode, eng = bench.matrix_tasks(["fig3", "fig6"], spec, ["native", "paper"], 1.0)
    theirs = {(t.engine, t.mode, task_key(t)) for t in seen}
    ours = {(t.engine, t.mode, task_key(t)) for t in [*ode, *eng]}
    assert ours == theirs and len(ours) == 6
    cmd = bench.matrix_command(["fig3", "fig6"], spec, ["native", "paper"], 1.0, 1)
    assert cmd[cmd.index("--set") + 1] == "run.t_end_s=1.0"
    assert cmd[cmd.index("--engines") + 1] == spec and "--json" in cmd


def test_split_longest_first() -> None:
    split = _bench().split_longest_first
    assert split([1.0, 5.0, 2.0, 4.0], 2) == [[1, 0], [3, 2]]  # loads 6 and 6
    assert split([3.0, 1.0], 1) == [[0, 1]]
    assert split([3.0], 4) == [[0]]
