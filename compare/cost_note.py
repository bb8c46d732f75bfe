"""Before a long computation starts, one line on stderr says about how long it will take.

The estimate is the one the progress bar starts from (:func:`tippetop.compare.terminal.
expected_cost_s`: MuJoCo steps times :data:`tippetop.compare.terminal.MUJOCO_STEP_S`, the
cost per step measured over the cached runs; the reference ODE per simulated second),
scheduled on the workers that will run it. It is printed only above :data:`LONG_RUN_S`, only
on stderr (never into ``--json`` output), and whether or not stderr is a terminal.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any, TextIO

from tippetop.compare.terminal import (
    MUJOCO_DEFAULT_TIMESTEP_S,
    MUJOCO_STEP_S,
    expected_cost_s,
    schedule_s,
)

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


def mujoco_steps(plan: Any) -> float:
    """MuJoCo steps of a run plan (0 for the reference ODE): simulated time / timestep."""
    mj = getattr(plan, "mujoco", None)
    if getattr(plan, "engine", "ode") == "ode" or mj is None:
        return 0.0
    dt = getattr(mj, "timestep_s", None) or MUJOCO_DEFAULT_TIMESTEP_S
    return float(mj.t_end_s) / dt


def long_run_note(plans: Sequence[Any], slots: int = 1) -> str | None:
    """The line to print before running ``plans`` on ``slots`` workers, or None if short.

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
    """Print :func:`long_run_note` on stderr (or ``stream``) when there is one."""
    note = long_run_note(plans, slots)
    if note is not None:
        out = stream or sys.stderr
        out.write(note + "\n")
        out.flush()


__all__ = ["LONG_RUN_S", "long_run_note", "mujoco_steps", "say_long_run"]
