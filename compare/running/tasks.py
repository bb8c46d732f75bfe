"""One run as a task: what it is (:class:`Task`), how it runs in a process, what it gave.

:func:`execute` plans and runs a task in this process, :func:`execute_plan` runs a plan sent as
its JSON (what a worker process or a Dask cluster is given), and a :class:`TaskResult` is what
came back. :mod:`.runner` runs many at once.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from tippetop.compare.measures.summary import RunSummary
from tippetop.compare.running.engines import plan_for, run_plan
from tippetop.models.errors import TippetopError
from tippetop.models.plan import RunPlan
from tippetop.models.scene import Override, Scene, load_scene

#: Rows kept of each run's observables table in the cache (for figures and reports).
CACHED_TABLE_ROWS = 4000


class SchedulerError(TippetopError):
    """The Dask cluster itself, not a run: no scheduler there, no worker, or it went away.

    Raised by a ``--scheduler`` batch (:mod:`.cluster`) in one line; a study that keeps a
    failed run as its own row (or skips a release that cannot run) lets this one through.
    """


class SchedulerLost(SchedulerError):
    """The Dask scheduler (or the connection to it) went away while runs were going.

    Raised by a ``--scheduler`` batch (:mod:`.cluster`); the runs finished before it are in the
    cache. Studies that keep a failed piece of work as their own row let this one through.
    """


@dataclass(frozen=True)
class Task:
    """One run: a scene, its overrides, the engine it runs on and the mode it runs in.

    ``overrides``: :class:`tippetop.models.scene.Override` values (a study's), or ``--set``
    text (a user's, as typed).

    ``engine``: ``ode``, ``mujoco``, ``mujoco==X.Y.Z``, ``mujoco@PYTHON``, ``mjx``,
    ``mjx-f32`` or ``warp`` (:mod:`tippetop.models.engines`); ``mode``: how the contact force
    is made (:mod:`tippetop.models.modes`), None for what the scene says.
    """

    scene: str | None
    overrides: tuple[Override | str, ...] = ()
    engine: str = "ode"
    mode: str | None = None
    label: str = field(default="", compare=False)

    def load(self) -> Scene:
        """The validated scene."""
        return load_scene(self.scene, list(self.overrides))

    def plan(self, scene: Scene | None = None) -> RunPlan:
        """The run plan (:func:`tippetop.compare.running.engines.plan_for`)."""
        return plan_for(scene or self.load(), self.engine, self.mode)


@dataclass
class TaskResult:
    """A finished task: its summary (or error), its table, and whether it came from the cache."""

    task: Task
    key: str
    summary: RunSummary | None
    table: pd.DataFrame | None
    error: str | None
    cached: bool


def downsample(table: pd.DataFrame, rows: int = CACHED_TABLE_ROWS) -> pd.DataFrame:
    """About ``rows`` evenly spaced rows of ``table``, its last row always kept."""
    if table.empty:  # a run that failed before its first sample
        return table.reset_index(drop=True)
    step = max(1, len(table) // rows)
    out = table.iloc[::step]
    if out.index[-1] != table.index[-1]:
        out = pd.concat([out, table.iloc[[-1]]])
    return out.reset_index(drop=True)


#: Where a run going in this process says how far it got, ``(report_key, fraction)``: the
#: progress bar's in the main process, a queue to it in a worker; None: nobody is listening.
_REPORTER: Callable[[str, float], None] | None = None


def set_reporter(reporter: Callable[[str, float], None] | None
                 ) -> Callable[[str, float], None] | None:
    """Where runs going in this process report ``(key, fraction)`` from now on; the old one."""
    global _REPORTER
    before, _REPORTER = _REPORTER, reporter
    return before


def execute(task: Task, report_key: str | None = None) -> dict[str, Any]:
    """Plan and run one task in this process; returns its summary and a downsampled table.

    Bad input is returned as ``{"error": message}`` rather than raised, so that one bad task
    in a sweep is reported with the others.

    Args:
        task: The run.
        report_key: See :func:`execute_plan`.
    """
    try:
        plan = task.plan()
    except TippetopError as exc:
        return {"error": str(exc)}
    return execute_plan(plan.to_json(), report_key)


def execute_plan(plan_json: str, report_key: str | None = None) -> dict[str, Any]:
    """Run one plan, given as its JSON (:meth:`RunPlan.to_json`), in this process.

    What the process pool's workers and a Dask cluster are sent: the plan as data, which any
    process of this package can run without resolving a scene. Returns its summary and a
    downsampled table, or ``{"error": message}`` for a plan this engine refuses.

    Args:
        plan_json: The plan.
        report_key: With a progress bar listening, a MuJoCo run reports the fraction of its
            simulated time done under this key now and then (the reference ODE is too quick to
            bother; the results are the same either way).
    """
    from tippetop.mujoco_runner.model import TopModelWarning

    with warnings.catch_warnings():
        # The main process resolved the same plan and said each model warning once already.
        warnings.simplefilter("ignore", TopModelWarning)
        try:
            plan = RunPlan.from_json(plan_json)
            progress: bool | Callable[[float], None] = False
            reporter = _REPORTER
            if report_key is not None and reporter is not None and not plan.is_reference \
                    and plan.t_end_s > 0:
                t_end = plan.t_end_s

                def progress(t: float) -> None:
                    reporter(report_key, t / t_end)

            run = run_plan(plan, progress=progress)
        except TippetopError as exc:
            return {"error": str(exc)}
    return {"summary": run.summary, "table": downsample(run.table)}


def strip_timing(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without its wall time (for comparing runs made on different machines)."""
    return {k: v for k, v in summary.items() if k != "wall_s"}


__all__ = ["CACHED_TABLE_ROWS", "SchedulerError", "SchedulerLost", "Task", "TaskResult",
           "downsample", "execute", "execute_plan", "set_reporter", "strip_timing"]
