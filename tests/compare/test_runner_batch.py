"""The runner: MuJoCo tasks on threads (one batch), longest first, cache writes in the background.

A sweep's MuJoCo runs go through :func:`tippetop.mujoco_runner.batch.iter_simulate_plans` in
the main process; their summaries and tables must be those of single runs
(:func:`tippetop.compare.running.runner.execute`), compared with ``==`` (the batch steps the same
floating-point operations; see tests/mujoco_runner/test_batch.py). Only the wall time differs,
and the run's one line that quotes it.
"""

from __future__ import annotations

import re
import threading
from importlib.util import find_spec
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from tippetop.compare.running import runner
from tippetop.compare.running.cache import CacheWriter
from tippetop.compare.running.cost import expected_cost_s
from tippetop.compare.running.pool import sigint_deferred
from tippetop.compare.running.runner import ResultCache, Task, execute, run_tasks, task_key

pytestmark = pytest.mark.skipif(find_spec("mujoco.batch") is None,
                                reason="this MuJoCo has no mujoco.batch")

SHORT = ("run.t_end_s=0.1",)


def _timing_free(summary: dict[str, Any]) -> dict[str, Any]:
    # the wall time, and how the samples were stepped (a batch, or the single run's compiled
    # loop: both said, read back, and different); the numbers must be the same
    out = {k: v for k, v in summary.items() if k not in ("wall_s", "path")}
    out["message"] = re.sub(r" in [0-9.e+-]+ s$", "", str(out.get("message")))
    return out


def _sweep_tasks() -> list[Task]:
    tasks = [Task("fig3", (*SHORT, f"mujoco.friction={mode}", f"init.n0={n0!r}"), "mujoco")
             for mode in ("paper", "native") for n0 in (50.0, 90.0, 130.0)]
    tasks.append(Task("fig3", (*SHORT, "mujoco.friction=paper", "init.n0=90.0"), "mujoco",
                      label="a duplicate: one run, two rows"))
    return tasks


def test_a_mujoco_sweep_through_the_batch_equals_single_runs(tmp_path: Path) -> None:
    tasks = _sweep_tasks()
    results = run_tasks(tasks, workers=2, cache_dir=tmp_path)
    assert not any(r.cached for r in results)
    for task, res in zip(tasks, results, strict=True):
        alone = execute(task)
        assert res.error is None and "error" not in alone
        assert _timing_free(res.summary) == _timing_free(alone["summary"])
        pd.testing.assert_frame_equal(res.table, alone["table"], check_exact=True)
    assert results[-1].summary == results[1].summary  # the duplicate ran once


def test_failed_and_refused_runs_are_their_own_rows(tmp_path: Path) -> None:
    tasks = [Task("fig3", (*SHORT, "mujoco.friction=paper"), "mujoco"),
             # the paper's law cannot be followed at this step: refused before running
             Task("fig3", (*SHORT, "mujoco.friction=paper", "mujoco.timestep_s=0.01"), "mujoco"),
             # the ball sinks through the table: a failed run, with its reason
             Task("fig3", ("mujoco.friction=paper", "effects.sliding=false",
                           "mujoco.integrator=Euler", "mujoco.timestep_s=0.02",
                           "run.t_end_s=1"), "mujoco")]
    ok, refused, sank = run_tasks(tasks, workers=2, cache_dir=tmp_path)
    assert ok.error is None and ok.summary["status"] == "ok"
    assert refused.summary is None and refused.error == execute(tasks[1])["error"]
    assert sank.error is None and sank.summary["status"] == "diverged"
    assert "the ball sank" in sank.summary["message"] and sank.summary["theta_final"] is None
    assert _timing_free(sank.summary) == _timing_free(execute(tasks[2])["summary"])


def test_the_longest_runs_start_first(tmp_path: Path, monkeypatch) -> None:
    tasks = [Task("fig3", ("run.t_end_s=0.1",), "mujoco"),
             Task("fig3", ("run.t_end_s=0.5",), "ode"),
             Task("fig3", ("run.t_end_s=0.3",), "mujoco"),
             Task("fig3", ("run.t_end_s=2",), "ode"),
             Task("fig3", ("run.t_end_s=0.2",), "mujoco")]
    seen: list[float] = []

    def fake_dispatch(unique, scheduler, workers, bar, plans, pythons=None):
        for key, _task in unique:
            seen.append(expected_cost_s(plans[key]))
            yield key, {"error": "not run"}

    monkeypatch.setattr(runner, "_dispatch", fake_dispatch)
    run_tasks(tasks, cache_dir=tmp_path)
    assert len(seen) == len(tasks) and len(set(seen)) == len(tasks)
    assert seen == sorted(seen, reverse=True)


def test_every_run_is_cached_before_run_tasks_returns(tmp_path: Path) -> None:
    tasks = _sweep_tasks()[:3]
    first = run_tasks(tasks, workers=2, cache_dir=tmp_path)
    cache = ResultCache(tmp_path)
    for task, res in zip(tasks, first, strict=True):
        hit = cache.get(task_key(task))
        assert hit is not None and hit[0] == res.summary
        pd.testing.assert_frame_equal(hit[1], res.table, check_exact=True)
    again = run_tasks(tasks, workers=2, cache_dir=tmp_path)
    assert all(r.cached for r in again)


class _SlowCache:
    """A cache whose writes wait for a signal (or fail), to see who waits for them."""

    def __init__(self, fail: bool = False) -> None:
        self.release = threading.Event()
        self.written: list[str] = []
        self.fail = fail

    def put(self, key: str, summary: dict[str, Any], table: pd.DataFrame) -> None:
        self.release.wait(10.0)
        if self.fail:
            raise OSError(28, "No space left on device")
        self.written.append(key)


def test_cache_writes_are_off_the_runs_path_and_done_by_close() -> None:
    cache = _SlowCache()
    writer = CacheWriter(cache)  # type: ignore[arg-type]
    table = pd.DataFrame({"t": [0.0]})
    for key in ("a", "b"):
        writer.put(key, {"k": key}, table)  # returns at once: the write has not happened
    assert cache.written == []
    cache.release.set()
    writer.close()
    assert cache.written == ["a", "b"]


def test_a_failed_cache_write_is_raised_by_close() -> None:
    cache = _SlowCache(fail=True)
    writer = CacheWriter(cache)  # type: ignore[arg-type]
    writer.put("a", {}, pd.DataFrame({"t": [0.0]}))
    cache.release.set()
    with pytest.raises(OSError, match="No space left"):
        writer.close()


def test_mujoco_runs_start_no_worker_process(tmp_path: Path, monkeypatch) -> None:
    # MuJoCo runs go on threads here: no worker pays a process start, imports or the callback
    def no_pool(n: int):
        raise AssertionError("a worker pool was started for MuJoCo runs")

    monkeypatch.setattr(runner, "local_pool", no_pool)
    results = run_tasks(_sweep_tasks()[:4], workers=2, cache_dir=tmp_path)
    assert all(r.error is None and r.summary["status"] == "ok" for r in results)


def test_ctrl_c_during_the_first_imports_is_held_back_then_raised() -> None:
    # A Ctrl-C while MuJoCo/numba are first imported would become an ImportError (or be lost
    # in an optional import): held back, and raised once the block is done
    import os
    import signal

    done = []
    with pytest.raises(KeyboardInterrupt):
        with sigint_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs between bytecodes: give it some
                sum(range(100))
            done.append(True)
    assert done == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
