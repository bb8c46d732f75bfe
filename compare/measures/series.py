"""Run summaries computed from the observables table, the same for every engine."""

from __future__ import annotations

import math
from typing import Any

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
    """First sampled time theta crosses pi/2 from below, or None.

    As the reference locates it (cos theta from > 0 to <= 0): a top that starts above pi/2 (a
    file whose centre of mass lies above the ball's centre, say) has not turned over at t = 0.
    """
    above = table["theta"].to_numpy() >= math.pi / 2
    up = np.flatnonzero(above[1:] & ~above[:-1]) + 1
    return float(table["t"].iloc[up[0]]) if up.size else None


def jellett_drift(table: pd.DataFrame, J_scale: float | None = None) -> float:
    """Max |J - J0| / |J0| over the run.

    When J0 = 0 (no spin and no precession at the start) the relative drift is undefined;
    then the drift is taken relative to ``J_scale`` (an upper bound of R |L| over the run,
    from :func:`jellett_scale`), or it is NaN if none is given.
    """
    J = table["J"].to_numpy()
    den = abs(J[0]) if J[0] != 0 else (J_scale if J_scale else math.nan)
    return float(np.max(np.abs(J - J[0])) / den)


#: The start of a run in which the ball may still be settling into the table (s): a MuJoCo
#: ball placed at touching height sinks into its soft contact over a few time constants (the
#: calibrated solref is 2 ms, paper mode's 0.5 ms, MuJoCo's default 20 ms), and a sample with
#: no contact then is not the ball leaving the table.
SETTLING_S = 0.05


#: A flight at least this long is the ball leaving the table (s); a shorter one is its soft
#: contact chattering. Measured on MuJoCo's soft contacts: the calibrated native settings
#: chatter in flights of at most 6 ms on Fig. 3 (269 of them while it rises) and 8 ms on the
#: tutorial's top, the tuned settings at most 5 ms on the paper's top and 1 ms on the
#: tutorial's, each rising at most g t^2 / 8 = 0.08 mm, and Jellett's constant, which a flight
#: does not keep, moves by under 2e-4 through them; the tutorial top's own contact (MuJoCo's
#: default solref, 20 ms) hops for up to 32 ms at a time.
HOP_MIN_S = 0.01


def flights(t: np.ndarray, touching: np.ndarray, t_stem: float | None,
            settling_s: float = SETTLING_S, hop_min_s: float = HOP_MIN_S
            ) -> dict[str, Any] | None:
    """The ball's flights before the stem's first contact: stretches of samples with no contact.

    Returns:
        ``{count, longest_s, airborne_s, t_first, hops, t_first_hop}``: how many flights, the
        longest and their total (each a flight's samples times the spacing), the first's
        start (s), how many lasted ``hop_min_s`` or more (the ball leaving the table, not
        its contact chattering) and the first of those's start (None: none); None when the
        ball never leaves the table (after ``settling_s``, until the stem lands or the run
        ends).
    """
    t = np.asarray(t, dtype=float)
    free = (t >= settling_s) & ~np.asarray(touching, dtype=bool)
    if t_stem is not None:
        free &= t < t_stem
    if not free.any():
        return None
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
    edges = np.diff(np.concatenate(([0], free.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    lengths = (ends - starts) * dt
    hops = np.flatnonzero(lengths >= hop_min_s * (1.0 - 1e-9))
    return {"count": int(len(starts)), "longest_s": float(lengths.max()),
            "airborne_s": float(lengths.sum()), "t_first": float(t[starts[0]]),
            "hops": int(len(hops)),
            "t_first_hop": float(t[starts[hops[0]]]) if hops.size else None}


def ball_alone_end(t_stem: float | None, t_left_table: float | None) -> float | None:
    """The end of the time the ball alone touches the table (None: the whole run).

    The stem's first contact or the ball's first flight, whichever is first.
    """
    ends = [x for x in (t_stem, t_left_table) if x is not None]
    return min(ends) if ends else None


def jellett_scale(table: pd.DataFrame, R_m: float, A: float, C: float) -> float:
    """An upper bound of R |L| over a run: R (C max|n| + A max|theta_dot| + A max|Omega|)."""

    def peak(col: str) -> float:
        v = np.abs(table[col].to_numpy())
        v = v[np.isfinite(v)]
        return float(v.max()) if v.size else 0.0

    return R_m * (C * peak("n") + A * peak("theta_dot") + A * peak("Omega"))


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
    mode: str,
    rtol: float,
    t_invert: float | None,
    contact_lost: bool,
    wall_s: float,
    J_scale: float | None = None,
    **counters: int,
) -> dict:
    """The run summary the ``simulate`` command prints (keys are a contract).

    Args:
        table: The observables table.
        engine: The engine that ran it, as given (``ode``, ``mujoco``, ``mujoco==3.3.7`` ...).
        mode: The mode it ran in (``paper``, ``native`` ...).
        rtol: The relative accuracy the run was computed to (for the energy check).
        t_invert: First time theta > pi/2 if the engine located it; None if never.
        contact_lost: Whether the run stopped because the sphere left the table.
        wall_s: Wall time of the simulation (s).
        J_scale: Scale for Jellett's drift when J0 = 0 (see :func:`jellett_drift`).
        **counters: Cost counters, ``n_rhs`` for the ODE or ``n_steps`` for MuJoCo.
    """
    return {
        "engine": engine,
        "mode": mode,
        "theta_final": float(table["theta"].iloc[-1]),
        "theta_asymp": theta_asymp(table),
        "t_invert": t_invert,
        "J_rel_drift": jellett_drift(table, J_scale),
        "energy_monotone": energy_monotone(table, rtol),
        "energy_rise_rel": energy_rise(table) / max(abs(float(table["E"].iloc[0])), 1e-300),
        "contact_lost": bool(contact_lost),
        "wall_s": float(wall_s),
        **{k: int(v) for k, v in counters.items()},
    }


#: theta_asymp below this is "upright", above pi minus this "inverted" (rad). Wide enough for
#: the nutation left after a start at theta0 = 0.1 (Figs. 6-8 end within 0.03 rad of 0).
OUTCOME_MARGIN = 0.15
#: A run is "inconclusive" if the mean theta of its last 5 % differs from that of the 5 %
#: before by more than this (rad): theta is still moving when the horizon ends.
DRIFT_TOL = 0.02


def outcome_of_angle(theta: float) -> str:
    """``upright``, ``intermediate`` or ``inverted`` for an asymptotic angle (rad).

    Applied both to a run's theta_asymp and to the theory's theta_s, so that both sides of a
    comparison are classified the same way.
    """
    if theta < OUTCOME_MARGIN:
        return "upright"
    if theta > math.pi - OUTCOME_MARGIN:
        return "inverted"
    return "intermediate"


def theta_drift(table: pd.DataFrame) -> float:
    """Mean theta over the last 5 % of the run minus the mean over the 5 % before (rad)."""
    t = table["t"].to_numpy()
    th = table["theta"].to_numpy()
    span = t[-1] - t[0]
    last = t >= t[-1] - 0.05 * span
    before = (t >= t[-1] - 0.10 * span) & ~last
    if not last.any() or not before.any():
        return math.nan
    return float(np.mean(th[last]) - np.mean(th[before]))


def theta_trend(table: pd.DataFrame) -> float:
    """How fast theta still moves at the end of the run (rad/s).

    :func:`theta_drift` over the time between the centres of its two windows (5 % of the run).
    """
    t = table["t"].to_numpy()
    span = float(t[-1] - t[0])
    drift = theta_drift(table)
    return drift / (0.05 * span) if span > 0 and math.isfinite(drift) else math.nan


def classify_outcome(table: pd.DataFrame) -> str:
    """The run's final state.

    ``upright``, ``intermediate`` or ``inverted`` by theta_asymp, or ``inconclusive`` when theta
    is still moving at the end of the horizon: by more than ``DRIFT_TOL`` between the last two
    5 % windows, or at a rate that would change the class within one more run length.
    """
    drift = theta_drift(table)
    if not math.isfinite(drift) or abs(drift) > DRIFT_TOL:
        return "inconclusive"
    now = outcome_of_angle(theta_asymp(table))
    # the trend carried on for one more run length (20 windows of 5 %) must not change class
    later = outcome_of_angle(theta_asymp(table) + 20.0 * drift)
    return now if later == now else "inconclusive"


def theta_rms(table: pd.DataFrame, ref: pd.DataFrame) -> float:
    """RMS of theta(t) - theta_ref(t) over the reference's samples (rad).

    ``table``'s theta interpolated at the reference's times; times past its end are left out.
    """
    t = np.asarray(ref["t"])
    th = np.interp(t, table["t"], table["theta"], right=np.nan)
    ok = np.isfinite(th)
    return float(np.sqrt(np.mean((th[ok] - ref["theta"].to_numpy()[ok]) ** 2)))
