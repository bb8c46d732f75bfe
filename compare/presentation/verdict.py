"""The verdict against the theory: a row per run (scene, engine, mode), for summary and report.

Each run's outcome and theta_asymp against the theory's, its inversion time against the
reference's and its Jellett drift (:func:`tippetop.compare.measures.verdict.crossval_row`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from tippetop.compare.measures.verdict import crossval_row, predicted_outcome
from tippetop.models.modes import OLD_NAMES, REFERENCE_RUN, run_label, split_label
from tippetop.models.params import TopParams

#: The runs (``ENGINE/MODE``) the verdict table shows first, in this order; others follow as
#: they ran.
MAIN_RUNS = ("ode/paper", "mujoco/paper", "mujoco/native")


def run_of(rec: Mapping[str, Any]) -> str:
    """A case record's run, ``ENGINE/MODE``.

    A record of the release before named it by a compound mode (``mujoco-native``) and,
    on another engine, its ``engine_spec``: read as today's name.
    """
    if rec.get("run"):
        return str(rec["run"])
    old = OLD_NAMES.get(str(rec.get("mode")))
    if old is None:
        return run_label(str(rec.get("engine", "?")), str(rec.get("mode", "?")))
    spec = rec.get("engine_spec")
    engine = spec if spec not in (None, "mujoco", "ode") else old[0]
    return run_label(engine, old[1] or "paper")


def scene_key(rec: Mapping[str, Any]) -> str:
    """Runs of the same scene with the same ``set`` overrides share a row and their figures.

    A case that changes its scene (``set``) is named by the case, whose name says what runs
    (``groupII-A105-e010``), with its overrides; a case of a scene as it is, by the scene.
    """
    extra = ", ".join(rec.get("set") or [])
    if not extra:
        return f"{rec['scene']}"
    return f"{rec.get('name') or rec['scene']} ({extra})"


def top_of(params: Mapping[str, Any]) -> TopParams:
    """The top of a case record's ``params``."""
    return TopParams(R_m=params["R_m"], a_m=params["a_m"], M_kg=params["M_kg"],
                     A_kgm2=params["A_kgm2"], C_kgm2=params["C_kgm2"],
                     g_mps2=params["g_mps2"])


def crossval_rows(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The ``crossval`` list of results.json: a row per run case, in catalogue order.

    Each row: ``scene, mode, outcome, theory_outcome, theta_asymp, theta_s, d_theta_asymp,
    t_invert, d_t_invert, J_rel_drift, agrees`` plus ``engine``, ``run`` (``ENGINE/MODE``),
    ``case`` (its id), ``category``,
    ``paper_theta_asymp`` (the paper's printed value, when the scene has one), ``t_invert_ref``,
    ``theta_trend_rad_s``, ``reasons``, ``notes`` and ``error``.
    """
    runs = [r for r in records if r["kind"] == "run"]
    ref_t: dict[str, float | None] = {}
    for r in runs:
        if run_of(r) == REFERENCE_RUN and r.get("error") is None:
            ref_t.setdefault(scene_key(r), (r.get("values") or {}).get("t_invert"))
    rows = []
    for r in runs:
        key = scene_key(r)
        engine, mode = split_label(run_of(r))
        v = r.get("values") or {}
        th = r.get("theory") or {}
        theta_s, theory_out = th.get("theta_s"), th.get("outcome")
        if r.get("J0") is not None:
            try:
                theta_s, theory_out = predicted_outcome(top_of(r["params"]), r["J0"])
            except (ValueError, ArithmeticError):
                pass
        error = r.get("error")
        if error is None and v.get("status") == "diverged":
            error = (r.get("summary") or {}).get("message") or "the run diverged"
        if error is not None:
            row = crossval_row(key, mode, engine=engine, outcome="failed", theta_asymp=None,
                               theta_s=theta_s, theory_outcome=theory_out, t_invert=None,
                               error=error)
        else:
            row = crossval_row(key, mode, engine=engine, outcome=v.get("outcome"),
                               theta_asymp=v.get("theta_asymp"), theta_s=theta_s,
                               theory_outcome=theory_out, t_invert=v.get("t_invert"),
                               t_invert_ref=ref_t.get(key), J_rel_drift=v.get("J_rel_drift"),
                               trend=r.get("theta_trend_rad_s"),
                               reference=run_of(r) == REFERENCE_RUN,
                               t_span_s=(r.get("summary") or {}).get("t_end_s")
                               or r["params"].get("t_end_s"))
        expect = r.get("expect") or {}
        row.update(case=r["id"], name=r["name"], category=r["category"],
                   paper_theta_asymp=expect.get("theta_asymp"),
                   expected_departure=r.get("expected_departure"))
        rows.append(row)
    return rows


def run_order(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The verdict table's columns: the main runs that ran, then the others in catalogue order."""
    seen = list(dict.fromkeys(r["run"] for r in rows))
    return [m for m in MAIN_RUNS if m in seen] + [m for m in seen if m not in MAIN_RUNS]


def agreement_counts(rows: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, int]]:
    """Per run (``ENGINE/MODE``): how many agree, depart, are inconclusive or failed."""
    out: dict[str, dict[str, int]] = {}
    for r in rows:
        c = out.setdefault(r["run"], {"runs": 0, "agree": 0, "depart": 0, "inconclusive": 0,
                                       "failed": 0})
        c["runs"] += 1
        c[cell_class(r)] += 1
    return out


def expected_reason(row: Mapping[str, Any]) -> str | None:
    """The catalogue's reason when the row departs as the catalogue expects it to, else None."""
    why = row.get("expected_departure")
    return why if why and cell_class(row) == "depart" else None


def cell_class(row: Mapping[str, Any]) -> str:
    """``agree``, ``depart``, ``inconclusive`` or ``failed``."""
    if row.get("error") is not None or row.get("outcome") == "failed":
        return "failed"
    if row["agrees"]:
        return "agree"
    return "inconclusive" if row.get("still_moving") or row.get("outcome") == "inconclusive" \
        else "depart"
