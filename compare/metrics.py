"""Run summaries computed from the observables table, the same for every engine."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

#: theta_asymp is the mean of theta over this last fraction of the run.
ASYMP_FRACTION = 0.10

#: Energy may rise by this many times rtol * |E0| between samples and still count as monotone
#: (the integrator's local error, not physics: dE/dt = F . v_P <= 0 exactly).
ENERGY_RISE_RTOL_FACTOR = 100.0


def theta_asymp(table: pd.DataFrame) -> float:
    """Mean theta over the last 10% of the run's duration (rad)."""
    t = table["t"].to_numpy()
    keep = t >= t[0] + (1.0 - ASYMP_FRACTION) * (t[-1] - t[0])
    return float(np.mean(table["theta"].to_numpy()[keep]))


def first_inversion_time(table: pd.DataFrame) -> float | None:
    """First sampled time with theta > pi/2, or None (engines with events report it exactly)."""
    above = np.flatnonzero(table["theta"].to_numpy() > math.pi / 2)
    return float(table["t"].iloc[above[0]]) if above.size else None


def jellett_drift(table: pd.DataFrame) -> float:
    """Max |J / J0 - 1| over the run."""
    J = table["J"].to_numpy()
    return float(np.max(np.abs(J / J[0] - 1.0)))


def energy_rise(table: pd.DataFrame) -> float:
    """Largest rise of E above its running minimum (J); 0 for a non-increasing energy."""
    E = table["E"].to_numpy()
    return float(np.max(E - np.minimum.accumulate(E)))


def energy_monotone(table: pd.DataFrame, rtol: float) -> bool:
    """True if E never rises by more than ``ENERGY_RISE_RTOL_FACTOR * rtol * |E0|``."""
    E0 = abs(float(table["E"].iloc[0]))
    return energy_rise(table) <= ENERGY_RISE_RTOL_FACTOR * rtol * E0


def summary(
    table: pd.DataFrame,
    *,
    engine: str,
    rtol: float,
    t_invert: float | None,
    contact_lost: bool,
    wall_s: float,
    **counters: int,
) -> dict:
    """The run summary the ``simulate`` command prints (keys are a contract).

    Args:
        table: The observables table.
        engine: ``ode`` or ``mujoco``.
        rtol: The relative accuracy the run was computed to (for the energy check).
        t_invert: First time theta > pi/2 if the engine located it; None if never.
        contact_lost: Whether the run stopped because the sphere left the table.
        wall_s: Wall time of the simulation (s).
        **counters: Cost counters, ``n_rhs`` for the ODE or ``n_steps`` for MuJoCo.
    """
    return {
        "engine": engine,
        "theta_final": float(table["theta"].iloc[-1]),
        "theta_asymp": theta_asymp(table),
        "t_invert": t_invert,
        "J_rel_drift": jellett_drift(table),
        "energy_monotone": energy_monotone(table, rtol),
        "contact_lost": bool(contact_lost),
        "wall_s": float(wall_s),
        **{k: int(v) for k, v in counters.items()},
    }
