"""What accuracy costs: work-precision data for the reference ODE and for MuJoCo.

:mod:`.common` (the columns, the reference run, scoring), :mod:`.ode_study`,
:mod:`.mujoco_study`, :mod:`.pareto` (the cheapest point per accuracy), :mod:`.figures` and
:mod:`.study` (:func:`run_accuracy`, with its :class:`OdeGrid` and :class:`MujocoGrid`,
``tippetop bench accuracy``). The study is described in docs/design.md.
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "ACCURACY_COLUMNS": "common",
    "ATOL_PER_RTOL": "common",
    "DEFAULT_THRESHOLDS": "common",
    "REFERENCE_RTOL": "common",
    "STATUS_DIVERGED": "common",
    "STATUS_OK": "common",
    "STATUS_SKIPPED": "common",
    "Reference": "common",
    "reference_run": "common",
    "DEFAULT_BUDGET_S": "ode_study",
    "DEFAULT_METHODS": "ode_study",
    "PEER_METHODS": "ode_study",
    "default_methods": "ode_study",
    "DEFAULT_TOLERANCES": "ode_study",
    "ode_work_precision": "ode_study",
    "DEFAULT_INTEGRATORS": "mujoco_study",
    "DEFAULT_MODES": "mujoco_study",
    "DEFAULT_MUJOCO_BUDGET_S": "mujoco_study",
    "DEFAULT_TIMESTEPS": "mujoco_study",
    "MUJOCO_NOTES": "mujoco_study",
    "mujoco_work_precision": "mujoco_study",
    "mujoco_pareto_markdown": "pareto",
    "pareto_front": "pareto",
    "pareto_markdown": "pareto",
    "pareto_table": "pareto",
    "series_summary": "pareto",
    "mujoco_work_precision_figure": "figures",
    "work_precision_figure": "figures",
    "AccuracyResult": "study",
    "MujocoGrid": "study",
    "OdeGrid": "study",
    "run_accuracy": "study",
})

__all__ = [
    "ACCURACY_COLUMNS", "AccuracyResult", "ATOL_PER_RTOL", "DEFAULT_BUDGET_S",
    "DEFAULT_INTEGRATORS",
    "DEFAULT_METHODS", "PEER_METHODS", "default_methods", "DEFAULT_MODES",
    "DEFAULT_MUJOCO_BUDGET_S", "DEFAULT_THRESHOLDS",
    "DEFAULT_TIMESTEPS", "DEFAULT_TOLERANCES", "MUJOCO_NOTES", "MujocoGrid", "OdeGrid",
    "REFERENCE_RTOL",
    "STATUS_DIVERGED", "STATUS_OK", "STATUS_SKIPPED", "Reference", "mujoco_pareto_markdown",
    "mujoco_work_precision", "mujoco_work_precision_figure", "ode_work_precision",
    "pareto_front", "pareto_markdown", "pareto_table", "reference_run", "run_accuracy",
    "series_summary", "work_precision_figure",
]
