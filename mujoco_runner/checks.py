"""The checks that end a MuJoCo run, each with its one-line reason and what to change.

A state that is not finite, a MuJoCo warning, the ball sinking into the table, the energy
rising, the contact lost.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from tippetop.mujoco_runner.model import MUJOCO_WARNINGS, TopModel
from tippetop.mujoco_runner.record import SampleRecord, WindowRecord
from tippetop.mujoco_runner.settings import integrator_name

#: Deepest admissible penetration of the ball into the table, in radii (the soft contact sinks
#: ~0.025 R at rest with the default solref; more than this means the contact failed).
MAX_PENETRATION_R = 0.2
#: A stretch of steps without contact in which the ball's lowest point rose no more than this
#: above the table is not the top leaving it (m).
CONTACT_GAP_M = 1e-6
#: Longer than this without contact at any step, the ball risen, is "contact lost" (s); the
#: paper assumes permanent contact.
MAX_AIRBORNE_S = 0.05
#: A rise of the mechanical energy by more than this fraction of its initial value marks an
#: unstable integration (friction and the contact can only dissipate energy).
MAX_ENERGY_RISE = 0.1
#: The failure reason of a sample whose qpos or qvel is not finite (``; fix`` follows).
NONFINITE_REASON = "NaN or Inf in qpos/qvel"


def warning_reason(counts: np.ndarray, text: str | None = None,
                   names: Sequence[str] | None = None) -> str:
    """The failure reason for MuJoCo's warning counters ``counts`` (``mjData.warning.number``).

    ``text``: MuJoCo's own text of the warning (default: the last one the warning handler kept,
    :data:`~mujoco_runner.model.MUJOCO_WARNINGS`). ``names``: the counters' names, from the
    release that stepped (default: this process's ``mujoco.mjtWarning``).
    """
    counts = np.asarray(counts)
    i = int(np.flatnonzero(counts)[0])
    name = mujoco.mjtWarning(i).name if names is None else names[i]
    if text is None:
        text = MUJOCO_WARNINGS[-1] if MUJOCO_WARNINGS else ""
    text = f": {text.removeprefix('WARNING: ')}" if text else ""
    return f"MuJoCo warning {name} ({int(counts[i])}x){text}, the integration is unstable"


def divergence_fix(model: mujoco.MjModel) -> str:
    """What to change when a run diverges."""
    dt = float(model.opt.timestep)
    integrator = integrator_name(int(model.opt.integrator))
    return f"reduce timestep_s (now {dt:g} s)" + (
        "" if integrator == "RK4" else f" or use integrator RK4 (now {integrator})")


def step_failure(record: SampleRecord) -> tuple[int, str | None]:
    """(first sample that failed while stepping, its reason) or (len(record), None)."""
    n = len(record)
    bad = ~(np.isfinite(record.qpos).all(axis=1) & np.isfinite(record.qvel).all(axis=1))
    warned = (np.zeros(n, dtype=bool) if record.warnings is None
              else np.asarray(record.warnings).any(axis=1))
    hits = np.flatnonzero(bad | warned)
    if not hits.size:
        return n, None
    i = int(hits[0])
    if bad[i]:
        return i, NONFINITE_REASON
    return i, warning_reason(record.warnings[i], record.warning_text, record.warning_names)


def check_failure(top_model: TopModel, t: np.ndarray, windows: WindowRecord, steps: int,
                   dt: float, energy: np.ndarray, fix: str,
                   on_table: bool = True) -> tuple[int, str | None]:
    """The divergence checks over all samples: (first failing sample, reason) or (n, None).

    A sample fails when the ball sank more than :data:`MAX_PENETRATION_R` R into the table at
    a step of its window (its centre below R (1 - MAX_PENETRATION_R)), when the energy at the
    sample rose more than :data:`MAX_ENERGY_RISE` above the first sample's, or when the top
    has not touched at any step for more than :data:`MAX_AIRBORNE_S` and the ball rose more
    than :data:`CONTACT_GAP_M` meanwhile. With ``on_table`` False (contacts disabled: the top
    falls freely, as asked) only the energy is checked.
    """
    n = len(t)
    if not n:
        return 0, None
    R = top_model.top.R_m
    e0 = energy[0]
    sunk = -windows.float_column("gap_min")[:n]  # the ball's deepest, at any step
    sink = sunk > MAX_PENETRATION_R * R if on_table else np.zeros(n, dtype=bool)
    with np.errstate(invalid="ignore"):
        rise = energy - e0 > MAX_ENERGY_RISE * abs(e0)
    lost = np.zeros(n, dtype=bool)
    since = np.full(n, np.nan)
    if on_table:
        gaps = windows.head(n).gaps(steps)
        limit = int(math.floor(MAX_AIRBORNE_S / dt + 1e-9)) + 1  # passes beyond the limit
        long = gaps[(gaps["passes"] >= limit) & (gaps["height_m"] > CONTACT_GAP_M)]
        for start in long["start"].tolist():
            # the sample whose window holds the stretch's pass past MAX_AIRBORNE_S
            row = math.ceil((start + limit - 1) / steps)
            if row < n and not lost[row]:
                lost[row], since[row] = True, start * dt
    hits = np.flatnonzero(sink | rise | lost)
    if not hits.size:
        return n, None
    i = int(hits[0])
    if sink[i]:
        return i, (f"the ball sank {sunk[i] * 1e3:.3g} mm into the table (bound "
                   f"{MAX_PENETRATION_R:g} R); stiffen solref or {fix}")
    if rise[i]:
        return i, (f"the energy rose {100 * (energy[i] / e0 - 1):.3g}% above its "
                   f"initial value (friction can only dissipate it); {fix}")
    return i, (f"contact lost: the top left the table at t = {since[i]:.6g} s "
               f"for more than {MAX_AIRBORNE_S:g} s (the model follows it on the table only)")


__all__ = ["CONTACT_GAP_M", "MAX_AIRBORNE_S", "MAX_ENERGY_RISE", "MAX_PENETRATION_R",
           "NONFINITE_REASON", "check_failure", "divergence_fix", "step_failure",
           "warning_reason"]
