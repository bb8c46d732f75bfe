"""Cross-validation of one scene across engines and friction modes, against the reference.

``tippetop compare`` runs a scene in each mode, classifies each run's final state against the
theory's prediction (:mod:`tippetop.compare.measures.verdict`), and lists every metric where a
mode departs from the reference (mode ``ode``: the paper's equations with the scene's friction
law) beyond its tolerance.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from tippetop.compare.measures import theory
from tippetop.compare.measures.series import classify_outcome, theta_rms, theta_trend
from tippetop.compare.measures.summary import describe_ran, run_failed
from tippetop.compare.measures.verdict import (
    MODE_NOTES,
    REFERENCE_MODE,
    THETA_S_TOL,
    TOLERANCES,
    crossval_row,
    predicted_outcome,
)
from tippetop.compare.running.runner import Task, TaskResult, run_tasks
from tippetop.models.errors import TippetopError
from tippetop.models.modes import MODES, mode_task_parts
from tippetop.models.numbers import number_text


def compare_scene(scene: str | None, modes: list[str], overrides: tuple[str, ...] = (), *,
                  scheduler: str | None = None, workers: int | None = None,
                  use_cache: bool = True) -> dict[str, Any]:
    """Run ``scene`` in every mode (and the reference) and compare them.

    Returns:
        ``scene``, ``group``, ``theory`` (predicted theta_s and outcome), ``modes`` (per mode:
        the simulate summary keys plus ``outcome``, ``matches_theory`` (outcome class and
        theta_asymp within ``THETA_S_TOL`` of theta_s), ``d_theta_asymp``,
        ``theta_trend_rad_s``, ``theta_rms_vs_ref``), ``crossval`` (one :func:`crossval_row`
        per mode), ``differences`` (mode, metric, value, reference, tolerance, why),
        ``tolerances``.
    """
    for m in modes:
        if m not in MODES:
            raise TippetopError(f"--modes: expected modes from {', '.join(MODES)}, got {m!r}")
    run_modes = list(dict.fromkeys([REFERENCE_MODE, *modes]))
    tasks = []
    for m in run_modes:
        engine, mo = mode_task_parts(m)
        tasks.append(Task(scene, (*overrides, *mo), engine))
    results: dict[str, TaskResult] = dict(zip(run_modes, run_tasks(
        tasks, scheduler=scheduler, workers=workers, use_cache=use_cache, label="compare"),
        strict=True))
    for m, r in results.items():
        if r.error:
            raise TippetopError(f"{m}: {r.error}")
    sc = tasks[0].load()
    top = tasks[0].plan(sc).top  # for an MJCF top, the parameters read from its file
    ref = results[REFERENCE_MODE]
    ref_failed = run_failed(ref.summary)
    # Jellett's constant at t = 0 from a run that has a table (a failed run has none)
    tables = [r.table for r in results.values() if not run_failed(r.summary) and len(r.table)]
    th_pred, out_pred = (predicted_outcome(top, float(tables[0]["J"].iloc[0])) if tables
                         else (math.nan, None))
    per_mode: dict[str, Any] = {}
    diffs: list[dict[str, Any]] = []
    rows: list[dict[str, Any]] = []
    ref_t = None if ref_failed else ref.summary.get("t_invert")
    for m in modes:
        r = results[m]
        s = dict(r.summary)
        if run_failed(s):
            s.update(outcome="failed", matches_theory=False, theta_rms_vs_ref=None)
            diffs.append({"mode": m, "metric": "status", "value": s.get("status"),
                          "reference": ref.summary.get("status", "ok"), "tolerance": None,
                          "note": s.get("message", "")})
            per_mode[m] = s
            rows.append(crossval_row(sc.name, m, outcome="failed", theta_asymp=None,
                                     theta_s=th_pred, theory_outcome=out_pred, t_invert=None,
                                     error=s.get("message") or str(s.get("status"))))
            continue
        s["outcome"] = classify_outcome(r.table)
        s["theta_trend_rad_s"] = theta_trend(r.table)
        row = crossval_row(sc.name, m, outcome=s["outcome"], theta_asymp=s["theta_asymp"],
                           theta_s=th_pred, theory_outcome=out_pred, t_invert=s["t_invert"],
                           t_invert_ref=ref_t, J_rel_drift=s["J_rel_drift"],
                           trend=s["theta_trend_rad_s"], reference=m == REFERENCE_MODE,
                           t_span_s=float(r.table["t"].iloc[-1] - r.table["t"].iloc[0]))
        rows.append(row)
        s["matches_theory"] = row["agrees"]
        s["d_theta_asymp"] = row["d_theta_asymp"]
        s["theta_rms_vs_ref"] = (0.0 if m == REFERENCE_MODE else None if ref_failed
                                 else theta_rms(r.table, ref.table))
        s["energy_dissipated_J"] = float(r.table["E"].iloc[0] - r.table["E"].iloc[-1])
        s["note"] = MODE_NOTES.get(m, "")
        per_mode[m] = s
        if m == REFERENCE_MODE or ref_failed:  # nothing to compare with a failed reference
            continue
        ref_s = ref.summary
        ref_out = classify_outcome(ref.table)
        if s["outcome"] != ref_out:
            diffs.append({"mode": m, "metric": "outcome", "value": s["outcome"],
                          "reference": ref_out, "tolerance": None})
        checks = {
            "theta_asymp": (s["theta_asymp"], ref_s["theta_asymp"]),
            "theta_rms": (s["theta_rms_vs_ref"], 0.0),
        }
        if (s["t_invert"] is None) != (ref_s["t_invert"] is None):
            diffs.append({"mode": m, "metric": "t_invert", "value": s["t_invert"],
                          "reference": ref_s["t_invert"], "tolerance": None})
        elif s["t_invert"] is not None:
            checks["t_invert"] = (s["t_invert"], ref_s["t_invert"])
        for metric, (v, rv) in checks.items():
            tol, why = TOLERANCES[metric]
            if not math.isfinite(v) or abs(v - rv) > tol:
                diffs.append({"mode": m, "metric": metric, "value": v, "reference": rv,
                              "tolerance": tol, "why": why})
        tol, why = TOLERANCES["J_rel_drift"]
        if s["J_rel_drift"] > tol:
            diffs.append({"mode": m, "metric": "J_rel_drift", "value": s["J_rel_drift"],
                          "reference": ref_s["J_rel_drift"], "tolerance": tol, "why": why})
    # each MuJoCo mode's realised law, rerun in the reference: does it explain the mode?
    mj = {m: per_mode[m] for m in modes if m.startswith("mujoco") and m != REFERENCE_MODE
          and (per_mode[m].get("friction_realised") or {}).get("samples")}
    if mj:
        from tippetop.compare.studies.refit import attach_refits

        ref_engine, ref_over = mode_task_parts(REFERENCE_MODE)
        attach_refits({REFERENCE_MODE: dict(ref.summary), **mj},
                      {k: results[k].table for k in (REFERENCE_MODE, *mj)}, REFERENCE_MODE,
                      lambda ov: Task(scene, (*overrides, *ref_over, *ov), ref_engine),
                      {"scheduler": scheduler, "workers": workers, "use_cache": use_cache})
    return {
        "scene": sc.name,
        "group": theory.group(top),
        "theory": {"theta_s": th_pred, "outcome": out_pred, "theta_s_tol": THETA_S_TOL[0],
                   "theta_s_tol_why": THETA_S_TOL[1]},
        "modes": per_mode,
        "crossval": rows,
        "differences": diffs,
        "tolerances": {k: v[0] for k, v in TOLERANCES.items()} | {"theta_s": THETA_S_TOL[0]},
    }


FRICTION_LAW_MODES = ("ode", "ode-coulomb", "ode-viscous", "ode-coulomb_viscous",
                      "mujoco-paper", "mujoco-native", "mujoco-native-elliptic",
                      "mujoco-native-pyramidal", "mujoco-native-condim4",
                      "mujoco-native-condim6")


def friction_law_table(result: dict[str, Any]) -> pd.DataFrame:
    """The friction-law table of a :func:`compare_scene` result, one row per mode.

    Columns: inverts or not, inversion time, theta_asymp, J drift, energy dissipated, a
    sentence on where (from the numbers) and why (from the law) it departs from the paper's,
    and what ran (the settings read back from the engine, :func:`describe_ran`).
    """
    rows = []
    for m, s in result["modes"].items():
        if s.get("outcome") == "failed":
            rows.append({"mode": m, "inverts": None, "t_invert_s": None, "theta_asymp": None,
                         "J_rel_drift": None, "energy_dissipated_J": None,
                         "departs": f"the run failed: {s.get('message', '')}",
                         "ran": describe_ran(s)})
            continue
        mine = [d for d in result["differences"] if d["mode"] == m]
        if m == REFERENCE_MODE:
            verdict = "The reference"
        elif not mine:
            verdict = "Agrees with the paper's law within tolerance"
        else:
            parts = []
            for d in mine:
                if d["metric"] == "outcome":
                    parts.append(f"ends {d['value']} where the paper's law ends {d['reference']}")
                elif d["metric"] == "t_invert":
                    parts.append("inverts at a different time" if d["value"] is not None and
                                 d["reference"] is not None else
                                 ("never inverts" if d["value"] is None else "inverts, the "
                                  "reference does not"))
                elif d["metric"] == "J_rel_drift":
                    parts.append("loses Jellett's constant (drift "
                                 f"{number_text(d['value'], 'relative')})")
                elif d["metric"] == "theta_asymp":
                    parts.append(f"settles at {number_text(d['value'], 'rad')}, not "
                                 f"{number_text(d['reference'], 'rad')}")
            verdict = "Departs: " + "; ".join(dict.fromkeys(parts)) if parts else \
                "Follows a different theta(t) (RMS over tolerance) but ends the same"
        note = s.get("note", "")
        rows.append({
            "mode": m,
            "inverts": s["t_invert"] is not None,
            "t_invert_s": s["t_invert"],
            "theta_asymp": s["theta_asymp"],
            "J_rel_drift": s["J_rel_drift"],
            "energy_dissipated_J": s.get("energy_dissipated_J"),
            "departs": f"{verdict}{': ' + note if note and m != REFERENCE_MODE else ''}.",
            "ran": describe_ran(s),
        })
    return pd.DataFrame(rows)
