"""The checks of a case against its baseline, and the case's results.json entry."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from tippetop.compare.measures.tolerances import (
    GROWTH_MEASURED,
    TOLERANCES,
    Tolerance,
    compare_value,
    format_value,
)
from tippetop.compare.nightly.catalogue import Case
from tippetop.compare.nightly.running import CaseRun, error_text, expectation
from tippetop.compare.running.engines import plan_for
from tippetop.models.plan import NATIVE_LAW, RunPlan
from tippetop.models.scene import Scene, load_scene, override_texts


def tolerance_for(metric: str, case: Case) -> Tolerance:
    """The tolerance of ``metric`` for ``case`` (a threshold's is at least its ``rel_tol``).

    A probe's quantity (``probe.<probe>.<quantity>``) has its declared metric's.
    """
    if metric.startswith("probe."):
        from tippetop.compare.probes import probe_metric

        probe_tol = probe_metric(metric).tolerance
        assert probe_tol is not None
        return probe_tol
    tol = TOLERANCES[metric]
    if metric == "measured" and case.method == "growth":
        return GROWTH_MEASURED
    if metric == "measured" and case.rel_tol is not None and case.rel_tol > tol.value:
        return Tolerance(tol.kind, case.rel_tol, tol.floor, tol.unit, tol.why)
    return tol


def check_case(cr: CaseRun, baseline: Mapping[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One check per listed metric: value, baseline, tolerance, status and message."""
    c = cr.case
    base = baseline.get(c.id)
    checks = []
    for m in c.metrics:
        tol = tolerance_for(m, c)
        value = cr.values.get(m)
        b = None if base is None else base.get(m)
        chk: dict[str, Any] = {"metric": m, "value": value, "baseline": b,
                               "tolerance": {"kind": tol.kind, "value": tol.value,
                                             "floor": tol.floor, "unit": tol.unit,
                                             "text": tol.describe(), "why": tol.why}}
        if cr.error is not None:
            chk.update(status="error", message=f"{m}: the case did not run: {cr.error}")
        elif base is None or m not in base:
            chk.update(status="new", message=f"{m}: {format_value(value, tol.unit)} (no "
                       f"baseline yet; --update-baseline adds it)")
        else:
            ok, msg = compare_value(value, b, tol)
            chk.update(status="pass" if ok else "fail",
                       message=f"{m}: {msg}" if ok else f"{m} regressed: {msg}")
        checks.append(chk)
    return checks


def case_status(checks: Sequence[dict[str, Any]]) -> str:
    """``error``, ``fail``, ``new`` or ``pass`` (the worst of the checks)."""
    for s in ("error", "fail", "new"):
        if any(ch["status"] == s for ch in checks):
            return s
    return "pass"


def _law(plan: RunPlan) -> tuple[str, float | None, float | None]:
    """(law, mu, Lambda) that run: the reference's or paper mode's law, or native friction."""
    if plan.ode is not None:
        fr = plan.ode.friction
    elif plan.mujoco is not None and plan.mujoco.law is not None:
        fr = plan.mujoco.law
    else:
        contact = plan.mujoco.ball_contact if plan.mujoco is not None else None
        native = plan.mujoco is not None and plan.mujoco.friction == "native"
        # MuJoCo's own friction: the ball's contact's mu; no friction at all: mu 0
        mu = (contact.friction[0] if native and contact is not None
              else None if contact is None else 0.0)
        return NATIVE_LAW if native else "none", mu, None
    return fr.law, fr.mu, fr.Lambda_mps


def _top_record(scene: Scene, plan: RunPlan) -> tuple[dict[str, Any], dict[str, Any]]:
    from tippetop.compare.measures import theory
    from tippetop.compare.measures.series import outcome_of_angle

    top, ini = plan.top, plan.init
    law, mu, lam = _law(plan)
    params = {
        "A_over_C": top.A_over_C, "a_over_R": top.a_over_R,
        "C_factor": top.C_kgm2 / (0.4 * top.M_kg * top.R_m**2),
        "R_m": top.R_m, "a_m": top.a_m, "M_kg": top.M_kg, "A_kgm2": top.A_kgm2,
        "C_kgm2": top.C_kgm2, "g_mps2": top.g_mps2,
        "law": law, "mu": mu, "Lambda_mps": lam,
        "theta0": ini.theta0, "thetadot0": ini.thetadot0, "Omega0": ini.Omega0, "n0": ini.n0,
        "t_end_s": scene.run.t_end_s,
    }
    try:
        th: dict[str, Any] = dict(theory.summary(top, n0=ini.n0))
        th["outcome"] = outcome_of_angle(float(th["theta_s"]))
    except (ValueError, ArithmeticError) as exc:
        th = {"error": error_text(exc)}
    return params, th


def case_record(cr: CaseRun, checks: list[dict[str, Any]]) -> dict[str, Any]:
    """The results.json entry of a case."""
    c = cr.case
    if c.kind == "probe":
        return {"id": c.id, "name": c.name, "category": c.category, "kind": c.kind,
                "engine": c.engine, "mode": c.mode, "run": c.run, "scene": c.scene,
                "scene_name": f"probe {c.scene}", "set": list(c.set), "overrides": list(c.set),
                "description": c.description, "metrics": list(c.metrics),
                "status": case_status(checks), "error": cr.error, "expected_departure": None,
                "wall_s": cr.wall_s, "values": cr.values, "checks": checks, **cr.detail}
    scene = load_scene(c.scene_arg, list(c.overrides))
    params, th = _top_record(scene, plan_for(scene, c.engine, c.mode))
    rec: dict[str, Any] = {
        "id": c.id, "name": c.name, "category": c.category, "kind": c.kind,
        "engine": c.engine, "mode": c.mode, "run": c.run,
        "scene": c.scene, "scene_name": scene.name, "set": list(c.set),
        "overrides": override_texts(c.overrides), "description": c.description or scene.description,
        "metrics": list(c.metrics), "status": case_status(checks), "error": cr.error,
        "expected_departure": c.departs or None,
        "wall_s": cr.wall_s, "params": params, "theory": th, "expect": expectation(c, scene),
        "values": cr.values, "checks": checks, **cr.detail,
    }
    if c.kind == "sweep":
        rec.update(figure=c.figure, label=c.label, n0_grid=list(c.n0))
    return rec
