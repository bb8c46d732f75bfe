"""The cost model: how long a run is expected to take, and the note before a long one.

:func:`expected_cost_s` is a run's expected wall time from its plan, :func:`schedule_s` a
batch's on the workers. The runner starts the longest runs first, the progress bar
(:class:`~tippetop.compare.running.progress.WorkProgress`) weighs each run by its cost, and a
computation expected to take over :data:`LONG_RUN_S` says so first (:func:`say_long_run`).

A MuJoCo step's cost is measured on the machine: every batch and ``simulate`` of the MuJoCo
installed here records its runs' wall time per step (:func:`record_mujoco_runs`) in the run
cache folder, and the next estimate starts from that (:func:`mujoco_step_s`); until then it
starts from :data:`MUJOCO_STEP_S`.

This module imports only the standard library and :mod:`tippetop.models.resources` (a run
plan is read, never imported).
"""

from __future__ import annotations

import heapq
import json
import math
import os
import statistics
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TextIO

# ---------------------------------------------------------------- cost of a run
#: Expected wall time of one step of the MuJoCo installed here, any integrator and mode (s),
#: until runs on this machine have measured it. Measured on the project's 2-core machine with
#: MuJoCo 4.0.0: 16.5 us a step for fig3 in native (2e-4 s) and paper mode (2e-5 s, the
#: compiled callback) alone, about 30 us with the other core busy; recording the observables
#: is part of it. The bar measures the real speed as it goes.
MUJOCO_STEP_S = 20e-6
#: The file in the run cache folder that keeps the measured cost of a step.
STEP_COST_FILE = "step_cost.json"
#: Runs of fewer steps are not measured: their fixed costs (the model, the table) dominate.
MIN_MEASURED_STEPS = 10_000
#: Weight of a new batch's median step cost in the kept figure (the rest is the old figure):
#: one unusually loaded batch moves it halfway, not all the way.
LEARN_RATE = 0.5
#: A step cost outside this range (s) is neither kept nor believed (a suspended machine, a
#: file edited by hand).
PLAUSIBLE_STEP_S = (1e-7, 1e-2)
#: Fixed cost of a run in a worker: building the model or problem, the table, the cache (s).
TASK_OVERHEAD_S = 0.3
#: Expected wall time of the compiled reference ODE per simulated second (s): median 5 ms,
#: at most 15 ms over the cached reference runs, so far below MuJoCo's.
ODE_PER_SIM_S = 0.01


def _step_cost_path() -> Path | None:
    from tippetop.models.errors import TippetopError
    from tippetop.models.resources import user_cache_dir

    try:
        return user_cache_dir() / STEP_COST_FILE
    except TippetopError:  # no usable cache folder: the prior, and nothing kept
        return None


def _read_doc(path: Path) -> dict[str, Any]:
    """The kept step costs, ``{}`` if there are none or the file is unusable.

    Read each time (a few tens of microseconds): a file's mtime moves in steps of
    milliseconds, too coarse to tell two quick writes apart for a cache.
    """
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) and isinstance(doc.get("engines"), dict) else {}


def _plausible(value: Any) -> float | None:
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and PLAUSIBLE_STEP_S[0] <= value <= PLAUSIBLE_STEP_S[1])
    return float(value) if ok else None


def mujoco_step_s(engine: str = "mujoco") -> tuple[float, bool]:
    """The expected wall time of one MuJoCo step on ``engine`` (s), and whether so.

    Args:
        engine: A MuJoCo engine (:mod:`tippetop.models.engines`): ``mujoco``, the one
            installed here (its compiled stepper), or another, through its worker.

    Returns:
        ``(seconds, measured)``: the figure kept from this machine's runs on that engine and
        True, else :data:`MUJOCO_STEP_S` and False.
    """
    path = _step_cost_path()
    doc = _read_doc(path) if path is not None else {}
    entry = doc.get("engines", {}).get(engine)
    measured = _plausible(entry.get("step_s")) if isinstance(entry, dict) else None
    return (measured, True) if measured is not None else (MUJOCO_STEP_S, False)


def record_mujoco_runs(runs: Iterable[tuple[int, float]],
                       engine: str = "mujoco") -> float | None:
    """Keep what runs on ``engine`` cost a step, for the next estimate.

    The median over the runs of at least :data:`MIN_MEASURED_STEPS` steps, blended into the
    figure kept for that engine with :data:`LEARN_RATE`, written atomically to the run cache
    folder beside the other engines' figures. Nothing is written when no run qualifies or
    there is no usable cache folder; a failed write is ignored (an estimate is never worth an
    error).

    Args:
        runs: ``(n_steps, wall_s)`` of each run computed (not read from the cache).
        engine: The engine that ran them.

    Returns:
        The figure kept (s a step), or None when nothing was written.
    """
    costs = [wall / steps for steps, wall in runs
             if steps >= MIN_MEASURED_STEPS and wall > 0 and math.isfinite(wall)
             and PLAUSIBLE_STEP_S[0] <= wall / steps <= PLAUSIBLE_STEP_S[1]]
    path = _step_cost_path()
    if not costs or path is None:
        return None
    new = statistics.median(costs)
    old, measured = mujoco_step_s(engine)
    kept = old + LEARN_RATE * (new - old) if measured else new
    doc = _read_doc(path) or {"engines": {}}
    doc["note"] = ("wall time of one MuJoCo step on this machine, by engine, as tippetop "
                   "measured it; delete to start again from the default")
    doc["engines"][engine] = {"step_s": kept, "runs": len(costs), "last_median_s": new}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        return None
    return kept


def expected_cost_s(plan: Any, engine: str | None = None) -> float:
    """The expected wall time of one run on one core (s), from its plan.

    MuJoCo: the plan's steps times :func:`mujoco_step_s` of the engine it runs on; the
    reference ODE: :data:`ODE_PER_SIM_S` per simulated second; both plus
    :data:`TASK_OVERHEAD_S`. Only the ratios matter to the bar; its ETA uses the speed
    measured while it runs.

    Args:
        plan: A :class:`tippetop.models.plan.RunPlan`.
        engine: The engine a MuJoCo plan runs on (default: the plan's own).
    """
    if plan.mujoco is not None:
        return TASK_OVERHEAD_S + mujoco_steps(plan) * mujoco_step_s(engine or plan.engine)[0]
    return TASK_OVERHEAD_S + float(plan.t_end_s) * ODE_PER_SIM_S


def schedule_s(running: Sequence[float], pending: Sequence[float], slots: int) -> float:
    """Time until all work is done on ``slots`` workers.

    The running remainders go first, then the pending runs in order, each on the first
    worker to come free (a pool's first-in first-out queue).

    Args:
        running: Remaining time of each run going now.
        pending: Time of each run not started, in the order they start.
        slots: Workers.

    Returns:
        The makespan (same units as the inputs).
    """
    slots = max(1, slots)
    free = sorted(list(running)[:slots] + [0.0] * max(0, slots - len(running)))
    extra = list(running)[slots:]  # more running than slots: treat as queued first
    heapq.heapify(free)
    for c in [*extra, *pending]:
        heapq.heappush(free, heapq.heappop(free) + c)
    return max(free) if free else 0.0


# ---------------------------------------------------------------- the note before a long run
#: Expected wall time (s) above which a computation says how long it will take.
LONG_RUN_S = 60.0


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def mujoco_steps(plan: Any) -> int:
    """MuJoCo steps of a run plan (0 for the reference ODE): the plan's own count."""
    return 0 if plan.mujoco is None else plan.mujoco.n_steps


def long_run_note(plans: Sequence[Any], slots: int = 1,
                  engines: Sequence[str] | None = None) -> str | None:
    """The line to print before running ``plans`` on ``slots`` workers, or None if short.

    The estimate is the one the progress bar starts from (:func:`expected_cost_s`), scheduled
    on the workers that will run it (:func:`schedule_s`).

    Args:
        plans: Run plans (:class:`tippetop.models.plan.RunPlan`).
        slots: Runs going at once.
        engines: The engine each plan runs on (default: each plan's own).

    Returns:
        ``tippetop: about 33 min of computing (2.0e+08 MuJoCo steps at ~20 us, as measured
        here, on 2 workers)``, or None under :data:`LONG_RUN_S`; each engine other than
        ``mujoco`` has its own part (``1.0e+06 MuJoCo steps on mjx at ~1000 us, not yet
        measured here``).
    """
    if not plans:
        return None
    engines = list(engines) if engines is not None else [p.engine for p in plans]
    wall = schedule_s([], [expected_cost_s(p, e) for p, e in zip(plans, engines, strict=True)],
                      max(1, slots))
    if wall <= LONG_RUN_S:
        return None
    steps: dict[str, int] = {}
    for p, e in zip(plans, engines, strict=True):
        if mujoco_steps(p):
            steps[e] = steps.get(e, 0) + mujoco_steps(p)
    parts = []
    for engine, n in steps.items():
        step_s, measured = mujoco_step_s(engine)
        us = step_s * 1e6
        on = "" if engine == "mujoco" else f" on {engine}"
        parts.append(f"{n:.1e} MuJoCo steps{on} at ~{us:.0f} us" if us >= 100 else
                     f"{n:.1e} MuJoCo steps{on} at ~{us:.3g} us")
        parts[-1] += ", as measured here" if measured else ", not yet measured here"
    n_ode = sum(1 for p in plans if mujoco_steps(p) == 0)
    if n_ode:
        parts.append(f"{n_ode} reference run{'s' if n_ode > 1 else ''}")
    if slots > 1:
        parts.append(f"on {slots} workers")
    return f"tippetop: about {_duration(wall)} of computing ({', '.join(parts)})"


def say_long_run(plans: Sequence[Any], slots: int = 1, stream: TextIO | None = None,
                 engines: Sequence[str] | None = None) -> None:
    """Print :func:`long_run_note` on stderr (or ``stream``) when there is one.

    Only on stderr, never into ``--json`` output, and whether or not stderr is a terminal.
    """
    note = long_run_note(plans, slots, engines)
    if note is not None:
        out = stream or sys.stderr
        out.write(note + "\n")
        out.flush()


__all__ = ["LONG_RUN_S", "MUJOCO_STEP_S", "ODE_PER_SIM_S", "STEP_COST_FILE",
           "TASK_OVERHEAD_S", "expected_cost_s", "long_run_note", "mujoco_step_s",
           "mujoco_steps", "record_mujoco_runs", "say_long_run", "schedule_s"]
