"""The verdict's checks of a run against the theory and the reference.

Shared by ``validate`` and the tuning (:mod:`tippetop.compare.studies.tune`): a finished run
as the checks read it (:func:`run_entry`), and one check per (check, run) (:func:`verdict`).
Runs are named ``ENGINE/MODE`` (:func:`tippetop.models.modes.run_label`).
"""

from __future__ import annotations

from typing import Any

from tippetop.compare.measures.series import classify_outcome
from tippetop.compare.measures.summary import describe_ran
from tippetop.models.modes import REFERENCE_RUN, split_label
from tippetop.models.numbers import number_text
from tippetop.models.resolve import nice_step_below

#: An event time (inversion, first stem contact) agrees with the reference's within the larger
#: of this (s) ...
EVENT_TOL_S = 0.1
#: ... and this fraction of the reference's time: a run's event time is as sensitive to the
#: contact model as 10 % of a slow rise (the calibrated native settings reach it on the
#: paper's tops, README).
EVENT_RTOL = 0.1
#: Jellett's constant before the stem's first contact: conserved by any force through the
#: contact point (the paper's eq. 2.10). A drift above this means a torque that is not (a
#: soft contact's shifted point, torsional or rolling friction).
J_TOL = {"ode": 1e-6, "mujoco": 1e-3}
#: MuJoCo's first-order integrators. A step advances the angular velocity with the gyroscopic
#: torque (omega x I omega) of its start and then turns the body, and its inertia, with the new
#: velocity: the angular momentum of a top with A != C moves by O(dt^2) a step, so Jellett's
#: constant drifts in proportion to dt over a run (exactly nothing at A = C, where that torque
#: is zero; O(dt^4) with RK4). Measured in paper mode (docs/design.md, paper mode's callback):
#: 2.1e-3 at dt = 1e-4 s and 2.1e-4 at 1e-5 s on a top with A/C = 1.09, 1.1e-8 and 2e-12
#: with RK4, 1e-14 at A/C = 1.
FIRST_ORDER = ("Euler", "implicit", "implicitfast")
#: |A/C - 1| at or below this: the top's inertia about G is isotropic (no gyroscopic torque).
ISOTROPIC_TOL = 1e-9
#: MuJoCo's energy E (the rigid body's) may rise by the elastic energy its soft contacts hold
#: and give back as they spring out, at most the normal force times the depth (the run's
#: ``contact_energy_bound_J``; measured rises are 2-10x below it on the examples), plus this
#: fraction of E0 for the integration itself; a diverging step rises far more.
ENERGY_RISE_FLOOR = 1e-6


def mode_of(key: str) -> str:
    """The mode of a run's name (``mujoco==3.3.7/file`` -> ``file``)."""
    return split_label(key)[1]


def engine_of(key: str) -> str:
    """The engine of a run's name (``mujoco==3.3.7/file`` -> ``mujoco==3.3.7``)."""
    return split_label(key)[0]


def _end_state(summary: dict[str, Any], outcome: str) -> str:
    phases = summary.get("phases") or []
    if phases and phases[-1]["contact"] in ("stem", "both"):
        return "on its stem" if phases[-1]["contact"] == "stem" else "on ball and stem"
    return outcome


def _check(check: str, run: str, passed: bool | None, value: Any, tolerance: str,
           note: str) -> dict[str, Any]:
    engine, mode = split_label(run)
    return {"check": check, "run": run, "engine": engine, "mode": mode, "passed": passed,
            "value": value, "tolerance": tolerance, "note": note}


def _event_check(name: str, mode: str, mine: float | None, ref: float | None,
                 what: str) -> dict[str, Any]:
    tol = max(EVENT_TOL_S, EVENT_RTOL * ref) if ref is not None else EVENT_TOL_S
    text = f"|dt| <= max({EVENT_TOL_S:g} s, {100 * EVENT_RTOL:g} % of the reference's)"
    if mine is None and ref is None:
        return _check(name, mode, True, None, text, f"neither {what}")
    if mine is None or ref is None:
        who = "the reference only" if mine is None else "this run only"
        return _check(name, mode, False, None, text, f"{what}: {who}")
    d = mine - ref
    return _check(name, mode, abs(d) <= tol, d, text,
                  f"{what} at {number_text(mine, 's')}, the reference at "
                  f"{number_text(ref, 's')}")


def gyroscopic_drift(run: dict[str, Any], A_over_C: float | None) -> str | None:
    """Why a MuJoCo run's Jellett drift is its integrator's, or None if it need not be.

    The reason is a clause to follow the integrator's name ("first order: ..."): a first-order
    integrator (:data:`FIRST_ORDER`) on a top with A != C moves Jellett's constant in
    proportion to dt, and the clause names the step that keeps it within ``J_TOL["mujoco"]``
    (the drift scaled down linearly, the 1-2-5 step at or below).
    """
    integ, dt, j = run.get("integrator"), run.get("timestep_s"), run.get("J_rel_drift")
    if (integ not in FIRST_ORDER or A_over_C is None or abs(A_over_C - 1.0) <= ISOTROPIC_TOL
            or not dt or not j or j <= 0.0):
        return None
    tol = J_TOL["mujoco"]
    keep = nice_step_below(dt * tol / j) if j > tol else dt
    return (f"first order: it integrates the gyroscopic torque of this top (A/C = "
            f"{number_text(A_over_C)}, not 1) from each step's start, which moves J in "
            f"proportion to dt (none at A = C, dt^4 with RK4): dt <= {keep:g} s or RK4 keeps it "
            f"within {tol:g}")


def run_entry(res: Any) -> dict[str, Any]:
    """A finished run as :func:`verdict` reads it.

    The summary's keys, ``outcome``, ``end_state``, ``ran`` (one line), ``E0_J`` and
    ``error`` (None, or why it failed).
    """
    if res.error or res.summary is None:
        return {"status": "error", "message": res.error, "t_invert": None, "t_stem": None,
                "theta_final": None, "error": res.error or "no result", "outcome": None,
                "end_state": None, "ran": None, "E0_J": None}
    s = dict(res.summary)
    outcome = (classify_outcome(res.table) if s.get("theta_final") is not None
               and res.table is not None and len(res.table) > 2 else "failed")
    return {**s, "t_invert": s.get("t_invert"), "t_stem": s.get("t_stem"),
            "status": s.get("status"), "error": None, "outcome": outcome,
            "end_state": _end_state(s, outcome), "ran": describe_ran(s),
            "E0_J": (float(res.table["E"].iloc[0]) if res.table is not None
                     and len(res.table) else None)}


def verdict(runs: dict[str, dict[str, Any]], theory_outcome: str,
            A_over_C: float | None = None,
            reference: str = REFERENCE_RUN) -> list[dict[str, Any]]:
    """One check per (check, run): the run's outcome, events, Jellett, energy.

    Args:
        runs: Run name (``ENGINE/MODE``) -> the run as :func:`run_entry` reads it.
        theory_outcome: The theory's outcome for the runs' start.
        A_over_C: The top's; a MuJoCo paper-mode run whose Jellett drift departs under a
            first-order integrator is then said to be the integrator's
            (:func:`gyroscopic_drift`): the law acts at the contact point and keeps J.
        reference: The reference's run among ``runs``.
    """
    out: list[dict[str, Any]] = []
    ref = runs.get(reference, {})
    for mode, r in runs.items():
        s = r
        if r.get("error") or s.get("theta_final") is None:
            out.append(_check("completed", mode, False, s.get("status", "error"), "ok",
                              r.get("error") or s.get("message", "")))
            continue
        end = r["end_state"]
        turned = s.get("t_stem") is not None or r["outcome"] == "inverted"
        passed = (turned if theory_outcome == "inverted" else r["outcome"] == theory_outcome)
        out.append(_check("outcome", mode, passed, end, f"the theory's: {theory_outcome}",
                          "a top that reaches its stem counts as turned over"))
        if mode != reference and ref.get("theta_final") is not None:
            rs = ref
            out.append(_event_check("t_invert", mode, s.get("t_invert"), rs.get("t_invert"),
                                    "turns over (theta = pi/2)"))
            if s.get("t_stem") is not None or rs.get("t_stem") is not None:
                out.append(_event_check("t_stem", mode, s.get("t_stem"), rs.get("t_stem"),
                                        "the stem touches"))
        j = s.get("J_rel_drift")
        tol = J_TOL["ode" if engine_of(mode) == "ode" else "mujoco"]
        note = "relative drift of Jellett's constant while the ball alone touches"
        cause = gyroscopic_drift(s, A_over_C) if j is not None and j > tol else None
        if cause and mode_of(mode) == "paper" and engine_of(mode) != "ode":
            note += ("; not the law's: it acts at the contact point, where it keeps J (to "
                     f"1e-14 at A = C under any integrator); {s['integrator']} is {cause}")
        out.append(_check("jellett_before_stem", mode, j is not None and j <= tol, j,
                          f"<= {tol:g}", note))
        rise = s.get("energy_rise_rel")
        if engine_of(mode) == "ode":
            ok, tol_text = bool(s.get("energy_monotone")), "within the integration tolerance"
        else:
            held = (s.get("contact_energy_bound_J") or 0.0) / abs(r["E0_J"])
            limit = held + ENERGY_RISE_FLOOR
            ok = rise is not None and rise <= limit
            tol_text = (f"<= {number_text(limit, 'relative')} of E0 (the elastic energy the "
                        f"soft contacts held: force x depth)")
        out.append(_check("energy_never_rises", mode, ok, rise, tol_text,
                          "largest rise of E above its running minimum, as a fraction of E0: "
                          "friction and inelastic impacts only take energy"))
    return out


__all__ = ["ENERGY_RISE_FLOOR", "EVENT_RTOL", "EVENT_TOL_S", "FIRST_ORDER", "ISOTROPIC_TOL",
           "J_TOL", "REFERENCE_RUN", "engine_of", "gyroscopic_drift", "mode_of", "run_entry",
           "verdict"]
