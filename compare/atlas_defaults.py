"""The defaults of ``tippetop atlas``, shared by its parser and its work (no imports)."""

from __future__ import annotations

#: The grid: A/C and a/R as ``LO:HI:N``, and the modes measured.
DEFAULT_A_OVER_C = "0.8:1.4:4"
DEFAULT_A_OVER_R = "0.05:0.25:3"
DEFAULT_ENGINES_TEXT = "ode,mujoco-paper,mujoco-native"
