"""Whether a run agrees with the theory, and where it departs from the reference.

The rule every command judges a run by (``compare``, ``matrix``, the nightly, ``validate``):
its outcome class and theta_asymp against the theory's, its inversion time against the
reference's and its Jellett drift. Pure functions of a run's numbers: nothing here starts a run.
"""

from __future__ import annotations

import math
from typing import Any

from tippetop.compare.measures import theory
from tippetop.compare.measures.series import outcome_of_angle
from tippetop.models.modes import run_label
from tippetop.models.numbers import number_text, signed_text
from tippetop.models.params import TopParams

#: The run every other is compared with: the reference ODE in the scene's own law.
REFERENCE_ENGINE = "ode"

#: metric -> (tolerance, why). A mode "differs" where |value - reference| exceeds it.
TOLERANCES: dict[str, tuple[float, str]] = {
    "theta_asymp": (0.05, "rad; the paper's Figs. 9-10 scatter and the approach to theta_s"),
    "t_invert": (0.1, "s; 1 ms sampling plus the nutation phase's sensitivity to contact"),
    "theta_rms": (0.05, "rad; RMS of theta(t) - theta_ref(t) over the run"),
    "J_rel_drift": (1e-4, "relative; J is exact for any force through P (eq. 2.10)"),
}

#: A run matches the theory when it ends in the theory's outcome class AND its theta_asymp lies
#: within this of theta_s (rad), with the reason the tolerance is what it is.
THETA_S_TOL: tuple[float, str] = (
    0.05, "rad; a run's theta_asymp is a mean over its last 10 %: the nutation left there after "
    "a start at theta0 = 0.1 or 0.01 moves it by under 0.03 rad in the reference (Figs. 6-8, "
    "11), and the paper prints Fig. 11's theta_asymp to 0.01 rad")


def matches_theory(outcome: str | None, theta_asymp: float | None, theta_s: float | None,
                   theory_outcome: str | None) -> bool:
    """The outcome class is the theory's AND |theta_asymp - theta_s| <= ``THETA_S_TOL``.

    A run still moving at its end (``inconclusive``) or one that failed never matches.
    """
    if outcome is None or outcome != theory_outcome or outcome in ("inconclusive", "failed"):
        return False
    if theta_asymp is None or theta_s is None:
        return False
    d = theta_asymp - theta_s
    return math.isfinite(d) and abs(d) <= THETA_S_TOL[0]


def _finite(x: float | None) -> float | None:
    return x if x is not None and math.isfinite(x) else None


def crossval_row(scene: str, mode: str, *, engine: str = "ode", outcome: str | None,
                 theta_asymp: float | None,
                 theta_s: float | None, theory_outcome: str | None, t_invert: float | None,
                 t_invert_ref: float | None = None, J_rel_drift: float | None = None,
                 trend: float | None = None, error: str | None = None,
                 reference: bool = False, t_span_s: float | None = None) -> dict[str, Any]:
    """One scene and mode against the theory (and its inversion time against the reference).

    Args:
        scene: The scene's name (with its overrides, if any).
        mode: The run's mode (``paper``, ``native``, ...).
        engine: The engine it ran on (``ode``, ``mujoco``, ``mujoco==3.3.7``, ...).
        outcome: The run's outcome class (``failed`` if it did not run).
        theta_asymp: Mean theta over the run's last 10 % (rad).
        theta_s: The theory's asymptotic angle for the run's Jellett constant (rad).
        theory_outcome: The theory's outcome class.
        t_invert: The run's first inversion time (s), None if it never turns over.
        t_invert_ref: The reference ODE's for the same scene, if known.
        J_rel_drift: The run's Jellett drift (relative).
        trend: How fast theta still moves at the end (rad/s), :func:`theta_trend`.
        error: Why the run failed, if it did.
        reference: This row is the reference ODE's (no inversion-time difference).
        t_span_s: The run's length (s). A run whose theta_asymp misses theta_s while theta
            still moves towards it fast enough to close the gap within one more run length
            is ``still_moving``: not settled, so neither agreeing nor departing.

    Returns:
        ``scene, mode, outcome, theory_outcome, theta_asymp, theta_s, d_theta_asymp, t_invert,
        d_t_invert, J_rel_drift, agrees`` (the contract), plus ``engine``, ``run``
        (``ENGINE/MODE``), ``t_invert_ref``,
        ``theta_trend_rad_s``, ``still_moving``, ``reasons`` (why it does not agree, in
        words), ``notes``
        (differences from the reference beyond their tolerances) and ``error``.
    """
    theta_asymp, theta_s, J_rel_drift, trend = (_finite(theta_asymp), _finite(theta_s),
                                                _finite(J_rel_drift), _finite(trend))
    d_th = theta_asymp - theta_s if theta_asymp is not None and theta_s is not None else None
    d_t = (t_invert - t_invert_ref if t_invert is not None and t_invert_ref is not None
           and not reference else None)
    agrees = error is None and matches_theory(outcome, theta_asymp, theta_s, theory_outcome)
    reasons: list[str] = []
    tol = THETA_S_TOL[0]
    if error is not None:
        outcome = "failed"
        reasons.append(f"the run failed: {error}")
    elif outcome == "inconclusive":
        rate = f" at {signed_text(trend, 'rad/s')}" if trend is not None else ""
        reasons.append(f"theta is still moving at the end{rate}: inconclusive, not "
                       f"{theory_outcome}")
    elif outcome != theory_outcome:
        reasons.append(f"ends {outcome}, the theory {theory_outcome}")
    still_moving = outcome == "inconclusive"
    if error is None and d_th is not None and abs(d_th) > tol:
        closing = (trend is not None and t_span_s is not None and trend * d_th < 0
                   and abs(trend) * t_span_s >= abs(d_th) - tol)
        if closing and outcome == theory_outcome:
            still_moving = True
            reasons.append(f"not settled: theta_asymp {number_text(theta_asymp, 'rad')} is "
                           f"{number_text(abs(d_th), 'rad')} short of theta_s "
                           f"{number_text(theta_s, 'rad')} and still moving towards it at "
                           f"{signed_text(trend, 'rad/s')} (a longer run would tell)")
        else:
            reasons.append(f"theta_asymp {number_text(theta_asymp, 'rad')} against theta_s "
                           f"{number_text(theta_s, 'rad')} ({signed_text(d_th, 'rad')}, beyond "
                           f"{number_text(tol, 'rad')})")
    notes: list[str] = []
    if error is None and not reference:
        t_tol = TOLERANCES["t_invert"][0]
        if d_t is not None and abs(d_t) > t_tol:
            notes.append(f"turns over {number_text(abs(d_t), 's')} "
                         f"{'later' if d_t > 0 else 'earlier'} than the reference (beyond "
                         f"{number_text(t_tol, 's')})")
        elif (t_invert is None) != (t_invert_ref is None) and t_invert_ref is not None:
            notes.append("never turns over; the reference does")
        elif (t_invert is None) != (t_invert_ref is None) and t_invert is not None:
            notes.append("turns over; the reference does not")
    j_tol = TOLERANCES["J_rel_drift"][0]
    if error is None and J_rel_drift is not None and J_rel_drift > j_tol:
        notes.append(f"Jellett's J drifts by {number_text(J_rel_drift, 'relative')} (beyond "
                     f"{number_text(j_tol, 'relative')})")
    return {"scene": scene, "engine": engine, "mode": mode, "run": run_label(engine, mode),
            "outcome": outcome, "theory_outcome": theory_outcome,
            "theta_asymp": theta_asymp, "theta_s": theta_s, "d_theta_asymp": d_th,
            "t_invert": t_invert, "d_t_invert": d_t, "J_rel_drift": J_rel_drift,
            "agrees": bool(agrees), "t_invert_ref": t_invert_ref,
            "theta_trend_rad_s": trend, "still_moving": bool(still_moving and error is None),
            "reasons": reasons, "notes": notes, "error": error}


#: A pyramidal friction cone bounds the force along each pyramid edge (the table's axes) by mu N,
#: so along a diagonal the force is at most mu N times this (a box slid at 45 degrees decelerates
#: at about 0.71 mu g; tests/mujoco_runner/test_mujoco_cone.py measures it).
PYRAMIDAL_DIAGONAL = 1.0 / math.sqrt(2.0)


def calibrated_native_text() -> str:
    """The calibrated native settings, as shipped (cone, impratio, solref, mu)."""
    from tippetop.models.calibrated import calibrated_native_settings

    cal = calibrated_native_settings()
    if not cal:
        return "no calibration file: MuJoCo's own contact settings"
    ref = cal.get("solref")
    parts = [f"{cal.get('cone', '?')} cone", f"impratio {cal['impratio']:g}"
             if "impratio" in cal else "",
             f"solref [{ref[0]:g}, {ref[1]:g}]" if ref else "",
             f"mu {cal['mu']:g}" if "mu" in cal else ""]
    return ", ".join(p for p in parts if p)


#: Why each run departs from the paper's law where it does (the numbers say whether it does),
#: by engine family and mode.
MODE_NOTES: dict[tuple[str, str], str] = {
    ("ode", "paper"): "the reference: the paper's equations (Appendix A) with the scene's law",
    ("ode", "coulomb"): "exact Coulomb keeps the full mu N down to v_P = 0, so slip is killed "
                        "quickly and the top rolls instead of sliding",
    ("ode", "viscous"): "viscous friction with the paper's slope at v_P = 0: the same below "
                        "Lambda, unbounded above it",
    ("ode", "coulomb_viscous"): "Or's hybrid: exact Coulomb plus the viscous term",
    ("mujoco", "paper"): "the paper's law applied by the harness in MuJoCo (normal force lagged "
                         "by one evaluation, soft contact)",
    ("mujoco", "native"): f"MuJoCo's own soft friction with the calibrated settings "
                          f"({calibrated_native_text()}), a steep viscous law below saturation "
                          f"set by solref/impratio and dt",
    ("mujoco", "file"): "MuJoCo's own friction with the model's own settings (a loaded MJCF "
                        "file as it says)",
    ("mujoco", "native-pyramidal"): f"pyramidal cone: the friction bound mu N holds along each "
                                    f"pyramid edge (the table's axes), so along a diagonal the "
                                    f"force is at most mu N / sqrt(2) = "
                                    f"{PYRAMIDAL_DIAGONAL:.2f} mu N: the friction depends on "
                                    f"the slip direction",
    ("mujoco", "native-elliptic"): "elliptic cone: |F| <= mu N in every direction, as in "
                                   "Coulomb's law",
    ("mujoco", "native-condim4"): "torsional friction adds a torque about the normal that is "
                                  "not through P: Jellett's constant is no longer conserved",
    ("mujoco", "native-condim6"): "torsional and rolling friction add torques not through P: J "
                                  "is not conserved and the spin is damped",
}


def mode_note(engine: str, mode: str) -> str:
    """Why a run on ``engine`` in ``mode`` may depart from the paper's law ("" if unknown)."""
    family = "ode" if engine == REFERENCE_ENGINE else "mujoco"
    return MODE_NOTES.get((family, mode), "")


def predicted_outcome(top: TopParams, J0: float) -> tuple[float, str]:
    """The theory's asymptotic angle and outcome for a run with Jellett's constant J0.

    theta_s is evaluated at the spin with the same J started upright, n = J0 / (C (R - a)),
    which is n0 for theta0 -> 0.
    """
    n_equiv = J0 / (top.C_kgm2 * (top.R_m - top.a_m))
    th = theory.theta_s(top, n_equiv)
    return th, outcome_of_angle(th)


