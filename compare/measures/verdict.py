"""Whether a run agrees: one rule for ``validate``, ``matrix``, ``compare`` and the nightly.

A run is judged by its checks (:func:`judge`): it completed; its outcome is the theory's (the
class, and theta_asymp within :data:`~.metrics.THETA_S_TOL` of theta_s), or, where the top
reaches its stem and the ball-only theory no longer applies, the reference's; its inversion
and stem times are the reference's within max(0.1 s, 10 %); the ball stays on the table where
the reference's does; Jellett's constant is kept while the ball alone touches the table; the
energy never rises. It agrees when no check departs, and says what it was judged against
(``against``: ``theory`` or ``reference``). Every tolerance is a metric's declared
``agreement`` (:mod:`.metrics`).

Pure functions of a run's numbers (:func:`run_facts`): nothing here starts a run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import pandas as pd

from tippetop.compare.measures import theory
from tippetop.compare.measures.metrics import (
    EVENT_RTOL,
    EVENT_TOL_S,
    J_TOL,
    METRICS,
    THETA_S_TOL,
    event_tolerance,
)
from tippetop.compare.measures.series import (
    FLIGHT_RISE_M,
    HOP_MIN_S,
    classify_outcome,
    outcome_of_angle,
    theta_trend,
)
from tippetop.compare.measures.summary import describe_ran, run_failed
from tippetop.models.modes import REFERENCE_RUN, split_label
from tippetop.models.numbers import number_text, signed_text
from tippetop.models.params import TopParams
from tippetop.models.resolve import nice_step_below

#: The run every other is compared with: the reference ODE in the scene's own law.
REFERENCE_ENGINE = "ode"
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
ENERGY_RISE_FLOOR = METRICS["energy_rise_rel"].agreement.value  # type: ignore[union-attr]
#: The checks of a run, in the order they are listed.
CHECKS = ("completed", "outcome", "t_invert", "t_stem", "stays_on_table",
          "jellett_before_stem", "energy_never_rises")
#: What each check compares, in words (the glossary, ``tippetop metrics``).
CHECK_MEANINGS = {
    "completed": "the run finished (it did not diverge or stop short)",
    "outcome": "the run ends as the theory says (the class, and theta_asymp within 0.05 rad "
               "of theta_s); a top that reaches its stem, where the ball-only theory stops, "
               "as the reference's does",
    "t_invert": "it turns over (theta = pi/2) when the reference's does, within max(0.1 s, "
                "10 % of the reference's time)",
    "t_stem": "its stem first touches the table when the reference's does, within max(0.1 s, "
              "10 %)",
    "stays_on_table": "the ball stays on the table until the stem lands, as the reference's",
    "jellett_before_stem": "Jellett's constant is kept while the ball alone touches the table "
                           "(before the stem lands and before any flight): 1e-6 for the "
                           "reference, 1e-3 for MuJoCo",
    "energy_never_rises": "the energy never rises (beyond the integration's own error, or "
                          "what MuJoCo's soft contacts held)",
}


def mode_of(key: str) -> str:
    """The mode of a run's name (``mujoco==3.3.7/file`` -> ``file``)."""
    return split_label(key)[1]


def engine_of(key: str) -> str:
    """The engine of a run's name (``mujoco==3.3.7/file`` -> ``mujoco==3.3.7``)."""
    return split_label(key)[0]


def _finite(x: Any) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) \
        and math.isfinite(x) else None


def _end_state(summary: Mapping[str, Any], outcome: str) -> str:
    phases = summary.get("phases") or []
    if phases and phases[-1]["contact"] in ("stem", "both"):
        return "on its stem" if phases[-1]["contact"] == "stem" else "on ball and stem"
    return outcome


# ---------------------------------------------------------------- a run's facts
def run_facts(summary: Mapping[str, Any] | None, table: pd.DataFrame | None = None, *,
              error: str | None = None, **known: Any) -> dict[str, Any]:
    """A run as the verdict reads it: its summary's keys and what its table says.

    Args:
        summary: The run's summary (None: the run did not produce one).
        table: Its observables; gives ``outcome`` (:func:`classify_outcome`),
            ``theta_trend_rad_s``, ``E0_J`` and ``t_span_s``.
        error: Why the run failed, if it did.
        **known: Any of those four known without the table (a nightly record's), or any
            other key.

    Returns:
        The summary's keys, ``outcome`` (``failed`` for a failed run), ``end_state`` (``on
        its stem``, ``on ball and stem`` or the outcome), ``ran`` (one line), ``E0_J``,
        ``theta_trend_rad_s``, ``t_span_s`` and ``error`` (None, or why it failed).
    """
    s = dict(summary or {})
    failed = error is not None or summary is None or run_failed(s) \
        or s.get("theta_final") is None
    out: dict[str, Any] = {**s, "error": error or (s.get("message") or s.get("status")
                                                    or "no result" if failed else None)}
    have = table is not None and len(table) > 2 and not failed
    out["outcome"] = "failed" if failed else (
        classify_outcome(table) if have else known.get("outcome"))
    out["theta_trend_rad_s"] = theta_trend(table) if have else known.get("theta_trend_rad_s")
    out["E0_J"] = (float(table["E"].iloc[0]) if table is not None and len(table)
                   else known.get("E0_J"))
    out["t_span_s"] = (float(table["t"].iloc[-1] - table["t"].iloc[0]) if have
                       else known.get("t_span_s"))
    out["end_state"] = None if failed else _end_state(s, str(out["outcome"]))
    out["ran"] = describe_ran(s) if summary is not None else None
    for k, v in known.items():
        out.setdefault(k, v)
    return out


def run_entry(res: Any) -> dict[str, Any]:
    """A finished task's run as :func:`judge` reads it (:func:`run_facts` of its result)."""
    return run_facts(res.summary, res.table, error=res.error)


# ---------------------------------------------------------------- the checks
def _check(check: str, run: str, passed: bool | None, value: Any, tolerance: str,
           note: str, against: str = "reference") -> dict[str, Any]:
    engine, mode = split_label(run)
    return {"check": check, "run": run, "engine": engine, "mode": mode, "passed": passed,
            "value": value, "tolerance": tolerance, "note": note, "against": against}


def _event_check(name: str, run: str, mine: float | None, ref: float | None,
                 what: str) -> dict[str, Any]:
    text = f"|dt| <= max({EVENT_TOL_S:g} s, {100 * EVENT_RTOL:g} % of the reference's)"
    if mine is None and ref is None:
        return _check(name, run, True, None, text, f"neither {what}")
    if mine is None or ref is None:
        who = "the reference only" if mine is None else "this run only"
        return _check(name, run, False, None, text, f"{what}: {who}")
    d = mine - ref
    return _check(name, run, abs(d) <= event_tolerance(ref), d, text,
                  f"{what} at {number_text(mine, 's')}, the reference at "
                  f"{number_text(ref, 's')}")


def gyroscopic_drift(run: Mapping[str, Any], A_over_C: float | None) -> str | None:
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


def _outcome_vs_theory(label: str, r: Mapping[str, Any], theta_s: float | None,
                       theory_outcome: str | None, stem_rule: bool) -> dict[str, Any]:
    """The outcome check against the theory: the class and theta_asymp.

    With ``stem_rule`` (a top that reaches its stem, and no reference to follow): turned over
    or not.
    """
    outcome, end = r.get("outcome"), r.get("end_state") or r.get("outcome")
    tol_text = (f"the theory's: {theory_outcome}" + (
        f", theta_asymp within {number_text(THETA_S_TOL, 'rad')} of theta_s "
        f"{number_text(theta_s, 'rad')}" if theta_s is not None and not stem_rule else ""))
    if stem_rule:
        turned = r.get("t_stem") is not None or outcome == "inverted"
        passed = turned if theory_outcome == "inverted" else outcome == theory_outcome
        return _check("outcome", label, passed, end, tol_text,
                      "a top that reaches its stem counts as turned over (the ball-only "
                      "theory ends where the stem lands)", "theory")
    trend, theta_asymp = _finite(r.get("theta_trend_rad_s")), _finite(r.get("theta_asymp"))
    chk = _check("outcome", label, True, end, tol_text, "", "theory")
    if outcome == "inconclusive":
        rate = f" at {signed_text(trend, 'rad/s')}" if trend is not None else ""
        return {**chk, "passed": False, "still_moving": True,
                "note": f"theta is still moving at the end{rate}: inconclusive, not "
                        f"{theory_outcome}"}
    if outcome != theory_outcome:
        return {**chk, "passed": False, "note": f"ends {outcome}, the theory {theory_outcome}"}
    if theta_s is None or theta_asymp is None:
        return {**chk, "note": f"ends {outcome}, as the theory"}
    d = theta_asymp - theta_s
    if abs(d) <= THETA_S_TOL:
        return {**chk, "note": f"ends {outcome}: theta_asymp {number_text(theta_asymp, 'rad')}, "
                               f"theta_s {number_text(theta_s, 'rad')}"}
    span = _finite(r.get("t_span_s"))
    closing = (trend is not None and span is not None and trend * d < 0
               and abs(trend) * span >= abs(d) - THETA_S_TOL)
    if closing:
        return {**chk, "passed": False, "still_moving": True,
                "note": f"not settled: theta_asymp {number_text(theta_asymp, 'rad')} is "
                        f"{number_text(abs(d), 'rad')} short of theta_s "
                        f"{number_text(theta_s, 'rad')} and still moving towards it at "
                        f"{signed_text(trend, 'rad/s')} (a longer run would tell)"}
    return {**chk, "passed": False,
            "note": f"theta_asymp {number_text(theta_asymp, 'rad')} against theta_s "
                    f"{number_text(theta_s, 'rad')} ({signed_text(d, 'rad')}, beyond "
                    f"{number_text(THETA_S_TOL, 'rad')})"}


def _outcome_vs_reference(label: str, r: Mapping[str, Any],
                          ref: Mapping[str, Any]) -> dict[str, Any]:
    """The outcome check of a top that reaches its stem: the reference's end, not the theory's.

    The ball-only theory ends where the stem lands; the reference follows the stem.
    """
    mine, theirs = r.get("t_stem"), ref.get("t_stem")
    end = r.get("end_state") or r.get("outcome")
    ref_end = ref.get("end_state") or ref.get("outcome")
    tol_text = f"the reference's: {ref_end}"
    if mine is not None and theirs is not None:
        return _check("outcome", label, True, end, tol_text,
                      f"reaches its stem, as the reference's ({end}; the reference "
                      f"{ref_end})")
    if mine is not None:
        return _check("outcome", label, False, end, tol_text,
                      f"reaches its stem at {number_text(mine, 's')}; the reference's never "
                      f"does (it ends {ref_end})")
    return _check("outcome", label, False, end, tol_text,
                  f"never reaches its stem (it ends {end}); the reference's does at "
                  f"{number_text(theirs, 's')}")


def _ref_misses_theory(ref: Mapping[str, Any], theta_s: float | None,
                       theory_outcome: str | None) -> str | None:
    """Why the reference itself does not end as the theory says within its run, or None.

    The theory's angle is an asymptote: a start that leaves a large nutation, or a spin near a
    threshold, may not reach it within the run's time, in the reference either. A run is then
    judged against the reference, not held to what the reference does not reach.
    """
    outcome, theta = ref.get("outcome"), _finite(ref.get("theta_asymp"))
    if outcome != theory_outcome:
        return f"the reference itself ends {outcome}, the theory {theory_outcome}"
    if theta_s is not None and theta is not None and abs(theta - theta_s) > THETA_S_TOL:
        return (f"the reference itself ends {number_text(abs(theta - theta_s), 'rad')} from "
                f"theta_s within the run's time")
    return None


def _outcome_vs_reference_angle(label: str, r: Mapping[str, Any], ref: Mapping[str, Any],
                                why: str) -> dict[str, Any]:
    """The outcome check where the reference does not reach the theory's end.

    The reference's class, and theta_asymp within :data:`THETA_S_TOL` of the reference's.
    """
    outcome, ref_out = r.get("outcome"), ref.get("outcome")
    mine, theirs = _finite(r.get("theta_asymp")), _finite(ref.get("theta_asymp"))
    tol_text = (f"the reference's: {ref_out}, theta_asymp within "
                f"{number_text(THETA_S_TOL, 'rad')} of its {number_text(theirs, 'rad')}")
    chk = _check("outcome", label, True, r.get("end_state") or outcome, tol_text, "")
    if outcome != ref_out:
        return {**chk, "passed": False, "note": f"ends {outcome}, the reference {ref_out} "
                                                f"({why})"}
    if mine is None or theirs is None:
        return {**chk, "note": f"ends {outcome}, as the reference ({why})"}
    d = mine - theirs
    if abs(d) <= THETA_S_TOL:
        return {**chk, "note": f"ends {outcome} as the reference: theta_asymp "
                               f"{number_text(mine, 'rad')}, the reference's "
                               f"{number_text(theirs, 'rad')} ({why})"}
    return {**chk, "passed": False,
            "note": f"theta_asymp {number_text(mine, 'rad')} against the reference's "
                    f"{number_text(theirs, 'rad')} ({signed_text(d, 'rad')}, beyond "
                    f"{number_text(THETA_S_TOL, 'rad')}; {why})"}


def flight_text(r: Mapping[str, Any]) -> str:
    """``the ball leaves the table at 1.397 s (3 flights, up to 32 ms and 1.2 mm high)``."""
    t = r.get("t_left_table")
    fl = r.get("flights") or {}
    if t is None:
        if fl.get("count"):
            n = int(fl["count"])
            high = fl.get("height_m")
            rise = (f" and {number_text(1e6 * high, 'um')} high" if high is not None else "")
            return (f"the ball stays on the table (its contact chatters: {n} stretch"
                    f"{'es' if n != 1 else ''} without contact of at most "
                    f"{number_text(1e3 * fl['longest_s'], 'ms')}{rise}, no flight)")
        return "the ball stays on the table"
    more = ""
    if fl.get("hops"):
        n = int(fl["hops"])
        longest = fl.get("longest_hop_s") or fl.get("longest_s")
        high = fl.get("hop_height_m")
        more = (f" ({n} flight{'s' if n != 1 else ''}, up to "
                f"{number_text(1e3 * longest, 'ms')}"
                + (f" and {number_text(1e3 * high, 'mm')} high" if high is not None else "")
                + ")")
    return f"the ball leaves the table at {number_text(t, 's')}{more}"


def _table_check(label: str, r: Mapping[str, Any], ref: Mapping[str, Any]) -> dict[str, Any]:
    mine, theirs = r.get("t_left_table"), ref.get("t_left_table")
    tol_text = ("on the table until the stem lands, as the reference's (a flight, "
                f"{number_text(1e3 * HOP_MIN_S, 'ms')} or more without contact at any step "
                f"and risen {number_text(1e6 * FLIGHT_RISE_M, 'um')} or more, leaves it)")
    if mine is None:
        return _check("stays_on_table", label, True, None, tol_text,
                      flight_text(r) + (
                          "; the reference's leaves it at " + number_text(theirs, "s")
                          if theirs is not None else ", as the reference's"))
    if theirs is None:
        return _check("stays_on_table", label, False, mine, tol_text,
                      f"{flight_text(r)}; the reference's stays on")
    return _check("stays_on_table", label, True, mine, tol_text,
                  f"{flight_text(r)}, as the reference's does at {number_text(theirs, 's')}")


def _jellett_check(label: str, r: Mapping[str, Any],
                   A_over_C: float | None) -> dict[str, Any]:
    j = _finite(r.get("J_rel_drift"))
    tol = tolerance_of("J_rel_drift", engine_of(label))
    note = ("relative drift of Jellett's constant while the ball alone touches the table "
            "(before the stem lands and before any flight: J is not kept in flight)")
    cause = gyroscopic_drift(r, A_over_C) if j is not None and j > tol else None
    if cause and mode_of(label) == "paper" and engine_of(label) != REFERENCE_ENGINE:
        note += ("; not the law's: it acts at the contact point, where it keeps J (to "
                 f"1e-14 at A = C under any integrator); {r['integrator']} is {cause}")
    return _check("jellett_before_stem", label, j is not None and j <= tol, j, f"<= {tol:g}",
                  note)


def _energy_check(label: str, r: Mapping[str, Any]) -> dict[str, Any]:
    rise = _finite(r.get("energy_rise_rel"))
    why = ("largest rise of E above its running minimum, as a fraction of E0: friction and "
           "inelastic impacts only take energy")
    if engine_of(label) == REFERENCE_ENGINE:
        return _check("energy_never_rises", label, bool(r.get("energy_monotone")), rise,
                      "within the integration tolerance", why)
    E0 = _finite(r.get("E0_J"))
    if E0 is None or E0 == 0.0 or rise is None:
        return _check("energy_never_rises", label, None, rise, "-",
                      "not measured (no energy at the start recorded)")
    held = (_finite(r.get("contact_energy_bound_J")) or 0.0) / abs(E0)
    limit = held + ENERGY_RISE_FLOOR
    return _check("energy_never_rises", label, rise <= limit, rise,
                  f"<= {number_text(limit, 'relative')} of E0 (the elastic energy the soft "
                  f"contacts held: force x depth)", why)


def judge(label: str, run: Mapping[str, Any], ref: Mapping[str, Any] | None, *,
          theory_outcome: str | None, theta_s: float | None = None,
          A_over_C: float | None = None, is_reference: bool | None = None) -> dict[str, Any]:
    """Whether one run agrees: its checks, what it was judged against, and why not.

    Args:
        label: The run's name (``ENGINE/MODE``).
        run: The run (:func:`run_facts`).
        ref: The reference's run (:func:`run_facts`), or None when it has none (or failed).
        theory_outcome: The theory's outcome for the run's start (its Jellett constant).
        theta_s: The theory's asymptotic angle (rad); None: the class alone is checked.
        A_over_C: The top's; names a first-order integrator's Jellett drift.
        is_reference: This is the reference's run (default: its engine is ``ode`` and the
            run is named as :data:`REFERENCE_RUN`).

    Returns:
        ``run``, ``engine``, ``mode``, ``against`` (``theory`` or ``reference``: what the
        outcome was judged against), ``agrees`` (no check departs), ``still_moving``,
        ``checks`` (one per check, :data:`CHECKS`, each with ``passed`` True, False or None
        for not judged), ``reasons`` (the departing checks' notes) and ``error``.
    """
    is_ref = label == REFERENCE_RUN if is_reference is None else is_reference
    engine, mode = split_label(label)
    if run.get("error") or run.get("outcome") == "failed" or run.get("theta_final") is None:
        chk = _check("completed", label, False, run.get("status", "error"), "ok",
                     str(run.get("error") or run.get("message") or "no result"))
        return {"run": label, "engine": engine, "mode": mode, "against": "theory",
                "agrees": False, "still_moving": False, "checks": [chk],
                "reasons": [f"the run failed: {chk['note']}"], "error": chk["note"]}
    ref_ok = ref is not None and not is_ref and not ref.get("error") \
        and ref.get("outcome") != "failed" and ref.get("theta_final") is not None
    stem = run.get("t_stem") is not None or (ref_ok and ref.get("t_stem") is not None)
    checks: list[dict[str, Any]] = []
    short = (_ref_misses_theory(ref, theta_s, theory_outcome) if ref_ok and ref is not None
             and not stem else None)
    if stem and ref_ok:
        assert ref is not None
        checks.append(_outcome_vs_reference(label, run, ref))
    elif short is not None:
        assert ref is not None
        checks.append(_outcome_vs_reference_angle(label, run, ref, short))
    else:
        checks.append(_outcome_vs_theory(label, run, theta_s, theory_outcome, stem))
    against = checks[0]["against"]
    if ref_ok:
        assert ref is not None
        checks.append(_event_check("t_invert", label, run.get("t_invert"), ref.get("t_invert"),
                                   "turns over (theta = pi/2)"))
        if stem:
            checks.append(_event_check("t_stem", label, run.get("t_stem"), ref.get("t_stem"),
                                       "the stem touches"))
        checks.append(_table_check(label, run, ref))
    elif run.get("t_left_table") is not None:
        checks.append(_check("stays_on_table", label, None, run["t_left_table"],
                             "on the table until the stem lands",
                             f"{flight_text(run)}: " + (
                                 "the paper's model ends there (it does not follow a flight)"
                                 if is_ref else "no reference run to compare it with")))
    checks.append(_jellett_check(label, run, A_over_C))
    checks.append(_energy_check(label, run))
    reasons = [c["note"] for c in checks if c["passed"] is False]
    return {"run": label, "engine": engine, "mode": mode, "against": against,
            "agrees": not reasons, "still_moving": bool(checks[0].get("still_moving")),
            "checks": [{k: v for k, v in c.items() if k != "still_moving"} for c in checks],
            "reasons": reasons, "error": None}


def verdict(runs: Mapping[str, Mapping[str, Any]], theory_outcome: str | None,
            A_over_C: float | None = None, reference: str = REFERENCE_RUN, *,
            theta_s: float | None = None) -> list[dict[str, Any]]:
    """Every check of every run (:func:`judge`), in run order: ``validate``'s list.

    Args:
        runs: Run name (``ENGINE/MODE``) -> the run (:func:`run_facts`).
        theory_outcome: The theory's outcome for the runs' start.
        A_over_C: The top's (:func:`gyroscopic_drift`).
        reference: The reference's run among ``runs``.
        theta_s: The theory's asymptotic angle (rad), if known.
    """
    ref = runs.get(reference)
    return [c for label, r in runs.items()
            for c in judge(label, r, ref, theory_outcome=theory_outcome, theta_s=theta_s,
                           A_over_C=A_over_C, is_reference=label == reference)["checks"]]


# ---------------------------------------------------------------- the verdict table's row
def crossval_row(scene: str, label: str, run: Mapping[str, Any],
                 ref: Mapping[str, Any] | None, *, theta_s: float | None,
                 theory_outcome: str | None, A_over_C: float | None = None,
                 is_reference: bool | None = None) -> dict[str, Any]:
    """One run of one scene as the verdict tables show it (:func:`judge`, flattened).

    Args:
        scene: The scene's name (with its overrides, if any).
        label: The run's name (``ENGINE/MODE``).
        run: The run (:func:`run_facts`).
        ref: The reference's run, or None.
        theta_s: The theory's asymptotic angle for the run's Jellett constant (rad).
        theory_outcome: The theory's outcome class.
        A_over_C: The top's.
        is_reference: This is the reference's run.

    Returns:
        ``scene, mode, outcome, theory_outcome, theta_asymp, theta_s, d_theta_asymp, t_invert,
        d_t_invert, J_rel_drift, agrees`` (the contract), plus ``engine``, ``run``,
        ``against`` (``theory`` or ``reference``), ``t_invert_ref``, ``t_stem``,
        ``t_stem_ref``, ``t_left_table``, ``theta_trend_rad_s``, ``still_moving``,
        ``reasons`` (why it does not agree), ``notes`` (the checks not judged), ``checks``
        and ``error``.
    """
    j = judge(label, run, ref, theory_outcome=theory_outcome, theta_s=theta_s,
              A_over_C=A_over_C, is_reference=is_reference)
    is_ref = label == REFERENCE_RUN if is_reference is None else is_reference
    failed = j["error"] is not None
    theta_asymp = None if failed else _finite(run.get("theta_asymp"))
    theta_s = _finite(theta_s)
    t_inv = None if failed else _finite(run.get("t_invert"))
    t_ref = None if ref is None or ref.get("error") else _finite(ref.get("t_invert"))
    return {"scene": scene, "engine": j["engine"], "mode": j["mode"], "run": label,
            "outcome": "failed" if failed else run.get("outcome"),
            "theory_outcome": theory_outcome, "theta_asymp": theta_asymp, "theta_s": theta_s,
            "d_theta_asymp": (theta_asymp - theta_s if theta_asymp is not None
                              and theta_s is not None else None),
            "t_invert": t_inv,
            "d_t_invert": (t_inv - t_ref if t_inv is not None and t_ref is not None
                           and not is_ref else None),
            "J_rel_drift": None if failed else _finite(run.get("J_rel_drift")),
            "agrees": j["agrees"], "against": j["against"], "t_invert_ref": t_ref,
            "t_stem": None if failed else _finite(run.get("t_stem")),
            "t_stem_ref": None if ref is None else _finite(ref.get("t_stem")),
            "t_left_table": None if failed else _finite(run.get("t_left_table")),
            "theta_trend_rad_s": None if failed else _finite(run.get("theta_trend_rad_s")),
            "still_moving": j["still_moving"], "reasons": j["reasons"],
            "notes": [c["note"] for c in j["checks"] if c["passed"] is None],
            "checks": j["checks"], "error": j["error"]}


#: metric -> (tolerance, why): how far a run may be from the reference's value and still
#: agree, as :mod:`.metrics` declares it (``compare``'s list of differences); the tolerance of
#: a run on an engine, at the reference's event time, is :func:`tolerance_of`'s.
TOLERANCES: dict[str, tuple[float, str]] = {
    name: (METRICS[name].agreement_bound(), METRICS[name].agreement.why)  # type: ignore[union-attr]
    for name in ("theta_asymp", "t_invert", "theta_rms", "J_rel_drift")}


def tolerance_of(metric: str, engine: str = "mujoco", ref: float | None = None) -> float:
    """The agreement tolerance of ``metric`` for a run on ``engine`` (an event's at ``ref``).

    The declaration's rule (:meth:`~.metrics.Metric.agreement_bound`): an event's bound
    grows with the reference's time, Jellett's drift is the reference's or an engine's.
    """
    family = REFERENCE_ENGINE if engine == REFERENCE_ENGINE else "mujoco"
    return METRICS[metric].agreement_bound(family, ref)


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


