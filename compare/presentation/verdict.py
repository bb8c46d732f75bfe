"""The verdict against the theory: a row per run (scene, engine, mode), for summary and report.

Each run's outcome and theta_asymp against the theory's, its inversion time against the
reference's and its Jellett drift (:func:`tippetop.compare.measures.verdict.crossval_row`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from tippetop.compare.measures.verdict import crossval_row, predicted_outcome, run_facts
from tippetop.models.modes import REFERENCE_RUN, run_label
from tippetop.models.params import TopParams
from tippetop.models.spellings import OLD_NAMES

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


def record_facts(rec: Mapping[str, Any]) -> dict[str, Any]:
    """A nightly run record as the verdict reads a run (:func:`run_facts`)."""
    v = rec.get("values") or {}
    error = rec.get("error")
    summary = rec.get("summary")
    if error is None and v.get("status") == "diverged":
        error = (summary or {}).get("message") or "the run diverged"
    if error is None and summary is None:  # a record of the release before: its values only
        summary = {k: v.get(k) for k in ("theta_asymp", "t_invert", "J_rel_drift",
                                          "energy_monotone", "contact_lost", "status")}
        summary["theta_final"] = v.get("theta_asymp")
    params = rec.get("params") or {}
    return run_facts(summary, None, error=error, outcome=v.get("outcome"),
                     theta_trend_rad_s=rec.get("theta_trend_rad_s"), E0_J=rec.get("E0"),
                     t_span_s=(summary or {}).get("t_end_s") or params.get("t_end_s"))


def crossval_rows(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The ``crossval`` list of results.json: a row per run case, in catalogue order.

    Each row is the verdict on the run (:func:`crossval_row`: the rule every command judges
    a run by), with the reference's run of the same scene: ``scene, mode, outcome,
    theory_outcome, theta_asymp, theta_s, d_theta_asymp, t_invert, d_t_invert, J_rel_drift,
    agrees`` plus ``engine``, ``run`` (``ENGINE/MODE``), ``against``, ``case`` (its id),
    ``category``, ``paper_theta_asymp`` (the paper's printed value, when the scene has one),
    ``t_invert_ref``, ``theta_trend_rad_s``, ``reasons``, ``notes``, ``checks`` and
    ``error``.
    """
    runs = [r for r in records if r["kind"] == "run"]
    refs: dict[str, dict[str, Any]] = {}
    for r in runs:
        if run_of(r) == REFERENCE_RUN and r.get("error") is None:
            refs.setdefault(scene_key(r), record_facts(r))
    rows = []
    for r in runs:
        key = scene_key(r)
        label = run_of(r)
        th = r.get("theory") or {}
        theta_s, theory_out = th.get("theta_s"), th.get("outcome")
        A_over_C = None
        if r.get("params"):
            try:
                top = top_of(r["params"])
                A_over_C = top.A_over_C
                if r.get("J0") is not None:
                    theta_s, theory_out = predicted_outcome(top, r["J0"])
            except (KeyError, ValueError, ArithmeticError):
                pass
        is_ref = label == REFERENCE_RUN
        row = crossval_row(key, label, record_facts(r), None if is_ref else refs.get(key),
                           theta_s=theta_s, theory_outcome=theory_out, A_over_C=A_over_C,
                           is_reference=is_ref)
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
    if row.get("against") == "reference":  # the stem's end, not the angle's class
        return "depart"
    return "inconclusive" if row.get("still_moving") or row.get("outcome") == "inconclusive" \
        else "depart"
