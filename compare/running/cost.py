"""The cost model: how long a run is expected to take, and the note before a long one.

:func:`expected_cost_s` is a run's expected wall time from its plan, :func:`schedule_s` a
batch's on the workers. The runner starts the longest runs first, the progress bar
(:class:`~tippetop.compare.running.progress.WorkProgress`) weighs each run by its cost, and a
computation expected to take over :data:`LONG_RUN_S` says so first (:func:`say_long_run`).

This module imports only the standard library (a run plan is read, never imported).
"""

from __future__ import annotations

import heapq
import sys
from collections.abc import Sequence
from typing import Any, TextIO

# ---------------------------------------------------------------- cost of a run
#: Expected wall time of one MuJoCo step, any integrator and mode (s). Measured on a 2-core
#: machine: 21-90 us a step over the cached paper- and native-mode runs (median about 65 us;
#: recording the observables costs as much as the physics). The bar measures the real speed.
MUJOCO_STEP_S = 65e-6
#: Fixed cost of a run in a worker: building the model or problem, the table, the cache (s).
TASK_OVERHEAD_S = 0.3
#: Expected wall time of the compiled reference ODE per simulated second (s): median 5 ms,
#: at most 15 ms over the cached reference runs, so far below MuJoCo's (about 26 s at 2.5 us).
ODE_PER_SIM_S = 0.01


def expected_cost_s(plan: Any) -> float:
    """The expected wall time of one run on one core (s), from its plan.

    MuJoCo: the plan's steps times :data:`MUJOCO_STEP_S`; the reference ODE:
    :data:`ODE_PER_SIM_S` per simulated second; both plus :data:`TASK_OVERHEAD_S`. Only the
    ratios matter to the bar; its ETA uses the speed measured while it runs.

    Args:
        plan: A :class:`tippetop.models.plan.RunPlan`.
    """
    if plan.mujoco is not None:
        return TASK_OVERHEAD_S + mujoco_steps(plan) * MUJOCO_STEP_S
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


def long_run_note(plans: Sequence[Any], slots: int = 1) -> str | None:
    """The line to print before running ``plans`` on ``slots`` workers, or None if short.

    The estimate is the one the progress bar starts from (:func:`expected_cost_s`), scheduled
    on the workers that will run it (:func:`schedule_s`).

    Args:
        plans: Run plans (:class:`tippetop.models.plan.RunPlan`).
        slots: Runs going at once.

    Returns:
        ``tippetop: about 40 min of computing (2.0e+08 MuJoCo steps at ~65 us, on 2
        workers)``, or None under :data:`LONG_RUN_S`.
    """
    if not plans:
        return None
    wall = schedule_s([], [expected_cost_s(p) for p in plans], max(1, slots))
    if wall <= LONG_RUN_S:
        return None
    steps = sum(mujoco_steps(p) for p in plans)
    parts = []
    if steps:
        parts.append(f"{steps:.1e} MuJoCo steps at ~{MUJOCO_STEP_S * 1e6:.0f} us")
    n_ode = sum(1 for p in plans if mujoco_steps(p) == 0)
    if n_ode:
        parts.append(f"{n_ode} reference run{'s' if n_ode > 1 else ''}")
    if slots > 1:
        parts.append(f"on {slots} workers")
    return f"tippetop: about {_duration(wall)} of computing ({', '.join(parts)})"


def say_long_run(plans: Sequence[Any], slots: int = 1, stream: TextIO | None = None) -> None:
    """Print :func:`long_run_note` on stderr (or ``stream``) when there is one.

    Only on stderr, never into ``--json`` output, and whether or not stderr is a terminal.
    """
    note = long_run_note(plans, slots)
    if note is not None:
        out = stream or sys.stderr
        out.write(note + "\n")
        out.flush()


__all__ = ["LONG_RUN_S", "MUJOCO_STEP_S", "ODE_PER_SIM_S",
           "TASK_OVERHEAD_S", "expected_cost_s", "long_run_note", "mujoco_steps",
           "say_long_run", "schedule_s"]
