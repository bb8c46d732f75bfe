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
from tippetop.compare.measures.metrics import METRICS, THETA_S_TOL
from tippetop.compare.measures.series import theta_rms
from tippetop.compare.measures.summary import describe_ran, run_failed
from tippetop.compare.measures.verdict import (
    TOLERANCES,
    crossval_row,
    mode_note,
    predicted_outcome,
    run_facts,
    tolerance_of,
)
from tippetop.compare.results.crossval import CompareResult, Prediction
from tippetop.compare.running.runner import Task, TaskResult, run_tasks
from tippetop.compare.studies.sweep import Run
from tippetop.models.errors import TippetopError
from tippetop.models.modes import run_label
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override


def compare_scene(scene: str | None, runs: list[Run], overrides: tuple[Override, ...] = (), *,
                  scheduler: str | None = None, workers: int | None = None,
                  use_cache: bool = True) -> CompareResult:
    """Run ``scene`` on every (engine, mode) of ``runs`` and the reference, and compare them.

    Args:
        scene: A scene name or file.
        runs: (engine, mode or None for the scene's, more scene keys) of each run
            (:data:`~tippetop.compare.studies.sweep.Run`). The reference (``ode`` in the
            scene's own law) runs whether it is among them or not.
        overrides: Scene overrides for every run.
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes.
        use_cache: Read and write the run cache.

    Returns:
        A :class:`~tippetop.compare.results.crossval.CompareResult`: ``scene``, ``group``,
        ``theory`` (predicted theta_s and outcome), ``reference``, ``runs`` (one per
        run asked for, the reference first if asked: ``engine``, ``mode``, ``run``
        (``ENGINE/MODE``), the simulate summary keys, ``outcome``, ``agrees`` (the verdict,
        :func:`~tippetop.compare.measures.verdict.judge`), ``against`` (``theory`` or
        ``reference``), ``reasons``, ``matches_theory`` (``agrees``, its name before),
        ``d_theta_asymp``, ``theta_trend_rad_s``, ``theta_rms_vs_ref``, ``reference``),
        ``crossval`` (one :func:`crossval_row` per run), ``differences`` (engine, mode, run,
        metric, value, reference, tolerance, why), ``tolerances``.
    """
    options = {"scheduler": scheduler, "workers": workers, "use_cache": use_cache}
    tasks, results = _run_all(scene, runs, overrides, options)
    sc = tasks[0].load()
    top = tasks[0].plan(sc).top  # for an MJCF top, the parameters read from its file
    ref = results[0]
    ref_label = run_label(ref.summary["engine"], ref.summary["mode"])
    ref_failed = run_failed(ref.summary)
    # Jellett's constant at t = 0 from a run that has a table (a failed run has none)
    tables = [r.table for r in results if not run_failed(r.summary) and len(r.table)]
    th_pred, out_pred = (predicted_outcome(top, float(tables[0]["J"].iloc[0])) if tables
                         else (math.nan, None))
    mine: dict[str, TaskResult] = {}
    for r in results[1:]:
        mine.setdefault(run_label(r.summary["engine"], r.summary["mode"]), r)
    per_run: dict[str, Any] = {}
    diffs: list[dict[str, Any]] = []
    rows: list[dict[str, Any]] = []
    ref_facts = run_facts(ref.summary, ref.table)
    for label, r in mine.items():
        s = dict(r.summary)
        is_ref = label == ref_label
        who = {"engine": s["engine"], "mode": s["mode"], "run": label}
        facts = ref_facts if is_ref else run_facts(r.summary, r.table)
        row = crossval_row(sc.name, label, facts, None if is_ref else ref_facts,
                           theta_s=th_pred, theory_outcome=out_pred, A_over_C=top.A_over_C,
                           is_reference=is_ref)
        rows.append(row)
        s.update(run=label, reference=is_ref, outcome=facts["outcome"], agrees=row["agrees"],
                 against=row["against"], matches_theory=row["agrees"],
                 reasons=row["reasons"])
        if run_failed(s):
            s.update(theta_rms_vs_ref=None)
            diffs.append({**who, "metric": "status", "value": s.get("status"),
                          "reference": ref.summary.get("status", "ok"), "tolerance": None,
                          "note": s.get("message", "")})
            per_run[label] = s
            continue
        s["theta_trend_rad_s"] = facts["theta_trend_rad_s"]
        s["d_theta_asymp"] = row["d_theta_asymp"]
        s["theta_rms_vs_ref"] = (0.0 if is_ref else None if ref_failed
                                 else theta_rms(r.table, ref.table))
        s["energy_dissipated_J"] = float(r.table["E"].iloc[0] - r.table["E"].iloc[-1])
        s["note"] = mode_note(s["engine"], s["mode"])
        per_run[label] = s
        if is_ref or ref_failed:  # nothing to compare with a failed reference
            continue
        diffs += _differences(who, s, ref.summary, ref_facts["outcome"])
    _attach_refits(per_run, mine, ref, scene, overrides, options)
    return CompareResult(
        scene=sc.name,
        group=theory.group(top),
        theory=Prediction(th_pred, out_pred, THETA_S_TOL,
                          METRICS["theta_asymp"].agreement.why),  # type: ignore[union-attr]
        reference=ref_label,
        runs=tuple(per_run.values()),
        crossval=tuple(rows),
        differences=tuple(diffs),
        tolerances={k: v[0] for k, v in TOLERANCES.items()} | {"theta_s": THETA_S_TOL},
    )


def _run_all(scene: str | None, runs: list[Run], overrides: tuple[Override, ...],
             options: dict[str, Any]) -> tuple[list[Task], list[TaskResult]]:
    """The tasks, the reference's first, and their results (raises for a run that errored)."""
    tasks = [Task(scene, overrides, "ode")]  # the reference: the scene's own law
    tasks += [Task(scene, (*overrides, *extra), engine, mode) for engine, mode, extra in runs]
    results: list[TaskResult] = run_tasks(tasks, **options, label="compare")
    for task, r in zip(tasks, results, strict=True):
        if r.error:
            raise TippetopError(f"{run_label(task.engine, task.mode or 'scene')}: {r.error}")
    return tasks, results


def _differences(who: dict[str, Any], s: dict[str, Any], ref_s: dict[str, Any],
                 ref_out: str) -> list[dict[str, Any]]:
    """The differences (one per metric) where a run's summary ``s`` departs from the reference."""
    diffs: list[dict[str, Any]] = []
    if s["outcome"] != ref_out:
        diffs.append({**who, "metric": "outcome", "value": s["outcome"],
                      "reference": ref_out, "tolerance": None})
    if (s.get("t_left_table") is None) != (ref_s.get("t_left_table") is None):
        diffs.append({**who, "metric": "t_left_table", "value": s.get("t_left_table"),
                      "reference": ref_s.get("t_left_table"), "tolerance": None,
                      "why": METRICS["t_left_table"].meaning})
    checks = {
        "theta_asymp": (s["theta_asymp"], ref_s["theta_asymp"]),
        "theta_rms": (s["theta_rms_vs_ref"], 0.0),
    }
    if (s["t_invert"] is None) != (ref_s["t_invert"] is None):
        diffs.append({**who, "metric": "t_invert", "value": s["t_invert"],
                      "reference": ref_s["t_invert"], "tolerance": None})
    elif s["t_invert"] is not None:
        checks["t_invert"] = (s["t_invert"], ref_s["t_invert"])
    for metric, (v, rv) in checks.items():
        tol = tolerance_of(metric, s["engine"], rv)
        why = TOLERANCES[metric][1]
        if not math.isfinite(v) or abs(v - rv) > tol:
            diffs.append({**who, "metric": metric, "value": v, "reference": rv,
                          "tolerance": tol, "why": why})
    tol = tolerance_of("J_rel_drift", s["engine"])
    if s["J_rel_drift"] is not None and s["J_rel_drift"] > tol:
        diffs.append({**who, "metric": "J_rel_drift", "value": s["J_rel_drift"],
                      "reference": ref_s["J_rel_drift"], "tolerance": tol,
                      "why": TOLERANCES["J_rel_drift"][1]})
    return diffs


def _attach_refits(per_run: dict[str, Any], mine: dict[str, TaskResult], ref: TaskResult,
                   scene: str | None, overrides: tuple[Override, ...],
                   options: dict[str, Any]) -> None:
    """Each MuJoCo run's realised law rerun in the reference, put in its entry of ``per_run``."""
    mj = {k: v for k, v in per_run.items() if v["engine"] != "ode"
          and (v.get("friction_realised") or {}).get("samples")}
    if mj:
        from tippetop.compare.studies.refit import attach_refits

        ref_key = "reference"
        mj_tables = {k: mine[k].table for k in mj}
        attach_refits({ref_key: dict(ref.summary), **mj}, {ref_key: ref.table, **mj_tables},
                      ref_key, lambda ov: Task(scene, (*overrides, *ov), "ode"), options)


#: The friction-law runs: the reference in each of its laws, MuJoCo in each of its modes.
FRICTION_LAW_RUNS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("ode", "paper", ()), ("ode", "coulomb", ()), ("ode", "viscous", ()),
    ("ode", "coulomb_viscous", ()), ("mujoco", "paper", ()), ("mujoco", "native", ()),
    ("mujoco", "native-elliptic", ()), ("mujoco", "native-pyramidal", ()),
    ("mujoco", "native-condim4", ()), ("mujoco", "native-condim6", ()))


def friction_law_table(result: CompareResult) -> pd.DataFrame:
    """The friction-law table of a :func:`compare_scene` result, one row per run.

    Columns: the run (``ENGINE/MODE``), inverts or not, inversion time, theta_asymp, J drift,
    energy dissipated, a sentence on where (from the numbers) and why (from the law) it
    departs from the paper's, and what ran (the settings read back from the engine,
    :func:`describe_ran`).
    """
    rows = []
    for s in result.runs:
        label = s["run"]
        if s.get("outcome") == "failed":
            rows.append({"run": label, "inverts": None, "t_invert_s": None,
                         "theta_asymp": None, "J_rel_drift": None, "energy_dissipated_J": None,
                         "departs": f"the run failed: {s.get('message', '')}",
                         "ran": describe_ran(s)})
            continue
        mine = [d for d in result.differences if d["run"] == label]
        if s.get("reference"):
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
            "run": label,
            "inverts": s["t_invert"] is not None,
            "t_invert_s": s["t_invert"],
            "theta_asymp": s["theta_asymp"],
            "J_rel_drift": s["J_rel_drift"],
            "energy_dissipated_J": s.get("energy_dissipated_J"),
            "departs": f"{verdict}{': ' + note if note and not s.get('reference') else ''}.",
            "ran": describe_ran(s),
        })
    return pd.DataFrame(rows)
