"""Run a MuJoCo plan and return its result: the shared observables table and what ran.

:func:`simulate_plan` takes a :class:`~tippetop.models.plan.MujocoPlan` (made by
:func:`tippetop.models.resolve.resolve_plan`, the one place a scene is resolved), compiles its
MJCF text (:func:`~.settings.build_model`), steps it as the plan says (:mod:`.stepping`) and
computes the rest from the recorded samples (:mod:`.results`). It decides nothing: the
timestep, the sample grid, the law, the start are the plan's.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from tippetop.models.plan import MujocoPlan
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.results import MujocoResult, result_from_samples
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.stepping import step_top_model


def simulate_plan(plan: MujocoPlan, *,
                  progress: Callable[[float], None] | None = None) -> MujocoResult:
    """Run a plan.

    Args:
        plan: What to run.
        progress: Called with the simulated time (s) now and then (at most every
            :data:`~.stepping.PROGRESS_INTERVAL_S` of wall time, and at the end).

    Returns:
        The run, with ``ran`` read back from the model that ran.

    Raises:
        TippetopError: For MJCF this MuJoCo cannot compile as the plan says (nothing is
            simulated then).
    """
    return run_compiled(build_model(plan), plan, progress=progress)


def run_compiled(top_model: TopModel, plan: MujocoPlan, *,
                 progress: Callable[[float], None] | None = None) -> MujocoResult:
    """Run a plan on its compiled model (:func:`~.settings.build_model` of the plan).

    The stepping records the state at each sample and checks it for NaN and MuJoCo warnings
    as it goes (stopping at the first failed sample); :func:`~.results.result_from_samples`
    computes everything else afterwards.
    """
    # a run that blows up says so in its status and one-line message; numpy's overflow
    # warnings on the way (energies of a diverging state) would only add a second line
    with np.errstate(over="ignore", invalid="ignore"):
        record, failure, wall_s, ran = step_top_model(top_model, plan, progress=progress)
        result = result_from_samples(top_model, record, plan, failure=failure, wall_s=wall_s,
                                     ran=ran)
    if progress is not None and len(result.table):
        progress(float(result.table["t"].iloc[-1]))
    return result


__all__ = ["run_compiled", "simulate_plan"]
