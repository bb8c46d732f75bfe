"""Fit MuJoCo's native contact settings to the reference ODE (``tippetop calibrate``).

:mod:`.scoring` (candidates, scenes, residuals and the objective), :mod:`.fit` (the evaluator,
the grid and compass search, the timestep check), :mod:`.output` (findings, the TOML file),
:mod:`.config` (:class:`CalibrateConfig`, the defaults) and :mod:`.run` (:func:`calibrate`).
Why and how: docs/design.md.
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate": "run",
    "reproduce_command": "run",
    "DEFAULT_BUDGET_RUNS": "config",
    "DEFAULT_CALIBRATION": "config",
    "DEFAULT_HOLDOUT": "config",
    "DEFAULT_INTEGRATOR": "config",
    "DEFAULT_OUT": "config",
    "DEFAULT_TIMESTEP_S": "config",
    "CalibrateConfig": "config",
    "FAIL_COST": "scoring",
    "J_MAX": "scoring",
    "MUJOCO_DEFAULTS": "scoring",
    "mujoco_defaults": "scoring",
    "mujoco_defaults_label": "scoring",
    "W_J": "scoring",
    "W_T": "scoring",
    "Candidate": "scoring",
    "Residual": "scoring",
    "SceneSpec": "scoring",
    "objective": "scoring",
    "parse_scene_list": "scoring",
    "residual": "scoring",
    "findings": "output",
    "render_toml": "output",
    "GRID": "fit",
    "Evaluation": "fit",
    "Evaluator": "fit",
    "grid_candidates": "fit",
    "neighbours": "fit",
    "search": "fit",
    "timestep_check": "fit",
})

__all__ = [
    "DEFAULT_BUDGET_RUNS", "DEFAULT_CALIBRATION", "DEFAULT_HOLDOUT", "DEFAULT_INTEGRATOR",
    "DEFAULT_OUT", "DEFAULT_TIMESTEP_S", "FAIL_COST", "GRID", "J_MAX", "MUJOCO_DEFAULTS", "W_J",
    "W_T", "CalibrateConfig", "Candidate", "Evaluation", "Evaluator", "Residual", "SceneSpec",
    "calibrate", "findings", "grid_candidates", "mujoco_defaults", "mujoco_defaults_label",
    "neighbours", "objective", "parse_scene_list", "render_toml", "reproduce_command", "residual",
    "search", "timestep_check",
]
