"""Run summaries computed from the observables table, the same for every engine."""

from __future__ import annotations

import math
from collections.abc import Mapping
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


#: A stretch of steps without contact is the ball leaving the table (a flight, a "hop") when it
#: lasts at least this long (s) and the ball rises at least :data:`FLIGHT_RISE_M` in it; a
#: shorter or lower one is its soft contact chattering. Both are measured at every step (the
#: stepping adds each step's contact and the ball's gap to its sample's window), whatever the
#: sample spacing.
HOP_MIN_S = 0.01
#: The least rise of the ball above the table in a stretch without contact that makes it a
#: flight (m). Measured at every step (``python scripts/contact_census.py``, 2026-11-29): the
#: tuned contacts of the fidelity map's nine points that departed on 2026-11-27, each from its
#: four starts, and the calibrated contact on nine catalogue scenes chatter in 23,569 stretches
#: without contact of at most 9.2 ms; in those of 5 ms or more the ball rises at most 3.3 um, in
#: any at most 11 um (in 3 ms): its lowest point follows the top's turning, where a ball that
#: left the table for 10 ms on its own would rise g t^2 / 8 = 0.12 mm. MuJoCo's tutorial top
#: in its own contact (solref 20 ms) leaves the table in 25 flights of 10-32 ms that rise
#: 13-154 um.
FLIGHT_RISE_M = 1e-5


def flights(t: np.ndarray, gaps: Mapping[str, np.ndarray], t_stem: float | None,
            settling_s: float = SETTLING_S, hop_min_s: float = HOP_MIN_S,
            rise_min_m: float = FLIGHT_RISE_M) -> dict[str, Any] | None:
    """The ball's stretches without contact before the stem lands, and its flights among them.

    Args:
        t: The samples' times (s), one per window.
        gaps: A MuJoCo run's stretches of steps without contact, located to the step
            (:meth:`tippetop.mujoco_runner.results.MujocoResult.gaps`): ``t_start``,
            ``duration_s`` and ``height_m`` per stretch, and ``count`` and ``airborne_s`` per
            sample's window.
        t_stem: The stem's first contact (s); None: never.
        settling_s: The start in which the ball may still settle into its contact.
        hop_min_s: What makes a stretch a flight: its least length (s) ...
        rise_min_m: ... and its least rise (m).

    Returns:
        ``{count, longest_s, airborne_s, t_first, height_m, hops, t_first_hop,
        longest_hop_s, hop_height_m, hop_min_s, rise_min_m, measured}``: how many stretches
        without contact, the longest, their total, the first's start (s) and the highest's
        rise (m); how many are flights (``hops``: at least ``hop_min_s`` long and risen at least
        ``rise_min_m``), the first's start, the longest's length and the highest's rise (None:
        no flight); the rule; ``measured``: at every step. None when the top touches at every
        step (after ``settling_s``, until the stem lands or the run ends).
    """
    t = np.asarray(t, dtype=float)
    start = np.asarray(gaps["t_start"], dtype=float)
    length = np.asarray(gaps["duration_s"], dtype=float)
    height = np.asarray(gaps["height_m"], dtype=float)
    eps = 1e-9 * max(float(t[-1]) if len(t) else 0.0, 1.0)
    mine = start >= settling_s - eps
    # a window holds the steps after the sample before it: window i ends at t[i]
    counted = t > settling_s + eps
    if t_stem is not None:
        mine &= start < t_stem - eps
        counted &= t <= t_stem + eps
    count = int(np.asarray(gaps["count"])[counted].sum())
    if not mine.any():
        return None
    start, length, height = start[mine], length[mine], height[mine]
    hop = (length >= hop_min_s * (1.0 - 1e-9)) & (height >= rise_min_m)
    return {"count": max(count, int(mine.sum())), "longest_s": float(length.max()),
            "airborne_s": float(np.asarray(gaps["airborne_s"])[counted].sum()),
            "t_first": float(start[0]), "height_m": float(height.max()),
            "hops": int(hop.sum()),
            "t_first_hop": float(start[hop][0]) if hop.any() else None,
            "longest_hop_s": float(length[hop].max()) if hop.any() else None,
            "hop_height_m": float(height[hop].max()) if hop.any() else None,
            "hop_min_s": hop_min_s, "rise_min_m": rise_min_m, "measured": "at every step"}


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
