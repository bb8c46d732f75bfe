"""Defaults that a command's parser shows and its work uses: importing this costs nothing."""

from __future__ import annotations

#: ``tippetop atlas``: the grid, A/C and a/R as ``LO:HI:N``, and the engines and modes measured
#: (every pairing of the two that can run).
DEFAULT_A_OVER_C = "0.8:1.4:4"
DEFAULT_A_OVER_R = "0.05:0.25:3"
DEFAULT_ENGINES_TEXT = "ode,mujoco"
DEFAULT_MODES_TEXT = "paper,native"

#: ``tippetop validate``: simulated seconds of every run unless --t-end-s says otherwise.
DEFAULT_T_END_S = 8.0
#: ``tippetop validate`` and ``calibrate --mjcf``: MuJoCo runs the tuning may use
#: (``--budget-runs``): its seeds, its fits' rollouts and its verification runs. The paper's
#: top takes about 60; at this many the tuning ends with its best so far, verified.
TUNE_BUDGET_RUNS = 200
