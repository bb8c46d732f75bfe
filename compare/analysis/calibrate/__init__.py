"""``tippetop calibrate``: fit MuJoCo's native contact settings to the reference ODE.

MuJoCo's own friction is a soft constraint: below saturation it acts like a steep viscous law
whose slope depends on the friction cone, ``impratio``, ``solref``, ``solimp`` and the timestep,
and with MuJoCo's defaults the paper's Fig. 3 top settles into rolling instead of turning over.
This package picks the native settings (``mu``, ``cone``, ``impratio``, ``solref``, ``solimp``
at a fixed integrator and timestep) that make native runs follow the reference ODE (the paper's
modified Coulomb law) on a *calibration* set of scenes, and then measures how well the chosen
settings do on *held-out* scenes that the fit never saw.

MuJoCo's defaults, against which the result is reported, are read from a fresh MuJoCo model
(:func:`.scoring.mujoco_defaults`: pyramidal cone, impratio 1, solref (0.02 s, 1), solimp
(0.9, 0.95, 1 mm, 0.5, 2) in MuJoCo 4.0.0), at the paper's mu = 0.1 rather than MuJoCo's 1.

The solref damping ratio (1), the solimp tail (dmax 0.95, width 1 mm, midpoint 0.5, power 2),
the integrator and the timestep are fixed during the search and written with the settings.
MuJoCo's ``solreffriction`` is not fitted: :func:`models.mjcf.make_mjcf` does not write it, so
friction rows share the contact's solref.

Modules: :mod:`.scoring` (candidates, scenes, residuals and the objective), :mod:`.fit`
(the evaluator, the grid and compass search, the timestep check), :mod:`.output` (findings,
the TOML file), :mod:`.config` (:class:`CalibrateConfig`, the defaults) and :mod:`.run`
(:func:`calibrate`); the command is :mod:`tippetop.compare.commands.calibrate`.
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
