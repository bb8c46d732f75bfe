"""The cheapest point that gets theta right: Pareto frontiers, tables and their Markdown."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.studies.accuracy.common import (
    DEFAULT_THRESHOLDS,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_SKIPPED,
)
from tippetop.compare.studies.accuracy.mujoco_study import MUJOCO_NOTES


def pareto_front(df: pd.DataFrame) -> pd.DataFrame:
    """The completed points not beaten by any other in both wall time and theta error.

    Args:
        df: Rows of one scene and engine (:data:`ACCURACY_COLUMNS`).

    Returns:
        The frontier rows, sorted by wall time.
    """
    ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
    ok = ok.sort_values(["wall_s", "theta_max_err"])
    keep = []
    best = math.inf
    for idx, row in ok.iterrows():
        if row["theta_max_err"] < best:
            keep.append(idx)
            best = row["theta_max_err"]
    return ok.loc[keep]


def setting_text(row: pd.Series) -> str:
    """``rtol 1e-06`` (ODE) or ``dt = 0.0001 s in paper mode`` (MuJoCo) for a row."""
    if row["engine"] == "ode":
        return f"rtol {row['rtol']:g}"
    return f"dt = {row['timestep_s']:g} s in {row['formulation']} mode"


def num_or_none(v: Any) -> float | None:
    """A float, or None for a missing or NaN value."""
    return None if v is None or math.isnan(float(v)) else float(v)


def mujoco_use(row: pd.Series) -> str:
    """``RK4 at dt = 0.0001 s in paper mode`` for a MuJoCo row."""
    integrator = str(row["method"]).split("/")[0]
    return f"{integrator} at {setting_text(row)}"


def pareto_table(df: pd.DataFrame,
                 thresholds: Iterable[float] = DEFAULT_THRESHOLDS) -> list[dict[str, Any]]:
    """For each scene, engine and threshold: the cheapest point whose theta error meets it.

    Args:
        df: Work-precision rows (:data:`ACCURACY_COLUMNS`), any number of scenes and engines.
        thresholds: Bounds on max |theta error| (rad).

    Returns:
        One dictionary per (engine, scene, threshold): ``engine``, ``scene``, ``threshold``,
        ``method``, ``setting``, ``rtol``, ``timestep_s``, ``wall_s``, ``wall_per_sim_s``,
        ``n_rhs_per_sim_s``, ``n_steps_per_sim_s``, ``theta_max_err`` (None where no point
        qualifies), ``best_theta_max_err`` and ``best_method``/``best_setting`` (the smallest
        error of any completed point, None if none completed) and ``text``. ODE: "to get theta
        right to X rad, use METHOD at SETTING; it costs Y s per simulated second", or "...
        none reached". MuJoCo: "to get theta right to X rad, use INTEGRATOR at dt = D s in
        MODE mode; it costs Y s per simulated second", or "... not reached (best error E rad,
        INTEGRATOR at dt = D s in MODE mode)".
    """
    out: list[dict[str, Any]] = []
    for (engine, scene), g in df.groupby(["engine", "scene"], sort=False):
        ok = g[(g["status"] == STATUS_OK) & g["theta_max_err"].notna()]
        best = ok.loc[ok["theta_max_err"].idxmin()] if not ok.empty else None
        for x in thresholds:
            q = ok[ok["theta_max_err"] <= x]
            entry: dict[str, Any] = {"engine": engine, "scene": scene, "threshold": float(x)}
            if q.empty:
                if engine == "ode":
                    text = f"to get theta right to {x:g} rad: none reached"
                elif best is None:
                    text = f"to get theta right to {x:g} rad: not reached (no point completed)"
                else:
                    text = (f"to get theta right to {x:g} rad: not reached (best error "
                            f"{best['theta_max_err']:.1e} rad, {mujoco_use(best)})")
                entry.update(method=None, setting=None, rtol=None, timestep_s=None,
                             wall_s=None, wall_per_sim_s=None, n_rhs_per_sim_s=None,
                             n_steps_per_sim_s=None, theta_max_err=None, text=text)
            else:
                row = q.loc[q["wall_s"].idxmin()]
                setting = setting_text(row)
                use = (f"{row['method']} at {setting}" if engine == "ode"
                       else mujoco_use(row))
                entry.update(
                    method=row["method"], setting=setting,
                    rtol=num_or_none(row["rtol"]), timestep_s=num_or_none(row["timestep_s"]),
                    wall_s=float(row["wall_s"]), wall_per_sim_s=float(row["wall_per_sim_s"]),
                    n_rhs_per_sim_s=num_or_none(row["n_rhs"] / row["t_end_s"]),
                    n_steps_per_sim_s=num_or_none(row["n_steps"] / row["t_end_s"]),
                    theta_max_err=float(row["theta_max_err"]),
                    text=(f"to get theta right to {x:g} rad, use {use}; "
                          f"it costs {row['wall_per_sim_s']:.3g} s per simulated second "
                          f"(theta error {row['theta_max_err']:.1e} rad)"))
            entry.update(
                best_theta_max_err=None if best is None else float(best["theta_max_err"]),
                best_method=None if best is None else best["method"],
                best_setting=None if best is None else setting_text(best))
            out.append(entry)
    return out


def pareto_markdown(entries: list[dict[str, Any]], references: dict[str, dict]) -> str:
    """The Pareto table as Markdown, one section per scene."""
    lines = ["# Reference ODE: accuracy against cost", ""]
    for scene in dict.fromkeys(e["scene"] for e in entries):
        ref = references.get(scene, {})
        lines += [f"## {scene}", ""]
        if ref:
            lines += [f"Errors are max |theta - theta_ref| over the run, the reference being "
                      f"{ref['method']} at rtol {ref['rtol']:g}, atol {ref['atol']:g} (its "
                      f"distance from a run at 10x the tolerance: {ref['floor']:.1e} rad).", ""]
        lines += ["| theta right to (rad) | method | setting | s per simulated s "
                  "| rhs evaluations per simulated s | theta error reached (rad) |",
                  "|---|---|---|---|---|---|"]
        for e in entries:
            if e["scene"] != scene:
                continue
            if e["method"] is None:
                lines.append(f"| {e['threshold']:g} | none reached | | | | |")
            else:
                lines.append(f"| {e['threshold']:g} | {e['method']} | {e['setting']} | "
                             f"{e['wall_per_sim_s']:.3g} | {e['n_rhs_per_sim_s']:.3g} | "
                             f"{e['theta_max_err']:.1e} |")
        lines += [""] + [f"- {e['text']}" for e in entries if e["scene"] == scene] + [""]
    return "\n".join(lines)


def series_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per method of one scene and engine: its best point and what did not complete.

    Args:
        df: Work-precision rows of one scene (:data:`ACCURACY_COLUMNS`).

    Returns:
        One row per method: ``method``, ``best_theta_max_err``, ``best_setting``,
        ``best_timestep_s``,
        ``best_wall_per_sim_s``, ``n_ok``, ``n_diverged`` (with ``diverged_at``, the settings,
        and ``diverged_dt``, the timesteps),
        ``n_skipped``, ``n_failed``, and ``wall_per_step_s`` and ``wall_fixed_s``, a
        least-squares fit wall = fixed + per_step * n_steps over the completed points (None
        with fewer than two).
    """
    out = []
    for method, g in df.groupby("method", sort=False):
        ok = g[(g["status"] == STATUS_OK) & g["theta_max_err"].notna()]
        div = g[g["status"].str.startswith(STATUS_DIVERGED)]
        best = ok.loc[ok["theta_max_err"].idxmin()] if not ok.empty else None
        n_skip = int((g["status"] == STATUS_SKIPPED).sum())
        per_step = fixed = None
        fit = ok[(ok["n_steps"] > 0) & ok["wall_s"].notna()]
        if fit["n_steps"].nunique() >= 2:
            b, a = np.polyfit(fit["n_steps"].astype(float), fit["wall_s"], 1)
            per_step, fixed = float(b), float(a)
        out.append({
            "method": method,
            "best_theta_max_err": None if best is None else float(best["theta_max_err"]),
            "best_setting": None if best is None else setting_text(best),
            "best_timestep_s": None if best is None else num_or_none(best["timestep_s"]),
            "best_wall_per_sim_s": None if best is None else float(best["wall_per_sim_s"]),
            "n_ok": len(ok), "n_diverged": len(div),
            "diverged_at": [setting_text(r) for _, r in div.iterrows()],
            "diverged_dt": [float(t) for t in div["timestep_s"]],
            "n_skipped": n_skip, "n_failed": len(g) - len(ok) - len(div) - n_skip,
            "wall_per_step_s": per_step, "wall_fixed_s": fixed})
    return pd.DataFrame(out)


def mujoco_pareto_markdown(entries: list[dict[str, Any]], references: dict[str, dict],
                           df: pd.DataFrame | None = None) -> str:
    """The MuJoCo Pareto table as Markdown, one section per scene.

    Args:
        entries: :func:`pareto_table` entries of the MuJoCo engine.
        references: The reference of each scene (``df.attrs["reference"]``).
        df: The MuJoCo rows, for the per-series summary (optional).

    Returns:
        The Markdown text.
    """
    lines = ["# MuJoCo: accuracy against cost", "",
             *[f"- {n}" for n in MUJOCO_NOTES], ""]
    for scene in dict.fromkeys(e["scene"] for e in entries):
        ref = references.get(scene, {})
        g = df[df["scene"] == scene] if df is not None else None
        T = f" ({g['t_end_s'].iloc[0]:g} s simulated)" if g is not None and len(g) else ""
        lines += [f"## {scene}{T}", ""]
        if ref:
            lines += [f"Errors are max |theta - theta_ref| over the run, the reference being the "
                      f"ODE's {ref['method']} at rtol {ref['rtol']:g} (its own error is below "
                      f"{ref['floor']:.1e} rad).", ""]
        lines += ["| theta right to (rad) | integrator | friction mode | dt (s) "
                  "| s per simulated s | steps per simulated s | theta error reached (rad) |",
                  "|---|---|---|---|---|---|---|"]
        for e in entries:
            if e["scene"] != scene:
                continue
            if e["method"] is None:
                best = ("no point completed" if e["best_theta_max_err"] is None else
                        f"best {e['best_theta_max_err']:.1e} "
                        f"({str(e['best_method']).split('/')[0]} at {e['best_setting']})")
                lines.append(f"| {e['threshold']:g} | not reached | | | | | {best} |")
            else:
                integrator, mode = str(e["method"]).split("/")
                lines.append(f"| {e['threshold']:g} | {integrator} | {mode} | "
                             f"{e['timestep_s']:g} | {e['wall_per_sim_s']:.3g} | "
                             f"{e['n_steps_per_sim_s']:,.0f} | {e['theta_max_err']:.1e} |")
        lines += [""] + [f"- {e['text']}" for e in entries if e["scene"] == scene] + [""]
        if g is not None and len(g):
            lines += ["Best point of each integrator and mode:", "",
                      "| integrator/mode | best theta error (rad) | at dt (s) | s per simulated s "
                      "| ok | diverged | skipped (over budget) | failed | us per step (fit) "
                      "| fixed s per run (fit) |",
                      "|---|---|---|---|---|---|---|---|---|---|"]
            for _, r in series_summary(g).iterrows():
                best = ("-" if r["best_theta_max_err"] is None
                        else f"{r['best_theta_max_err']:.1e}")
                cost = ("-" if r["best_wall_per_sim_s"] is None
                        else f"{r['best_wall_per_sim_s']:.3g}")
                div = (f"{r['n_diverged']} (dt = "
                       f"{', '.join(f'{t:g}' for t in r['diverged_dt'])} s)"
                       if r["n_diverged"] else "0")
                dt = "-" if r["best_timestep_s"] is None else f"{r['best_timestep_s']:g}"
                us = ("-" if r["wall_per_step_s"] is None
                      else f"{1e6 * r['wall_per_step_s']:.3g}")
                fixed = "-" if r["wall_fixed_s"] is None else f"{r['wall_fixed_s']:.3g}"
                lines.append(f"| {r['method']} | {best} | {dt} | {cost} "
                             f"| {r['n_ok']} | {div} | {r['n_skipped']} | {r['n_failed']} "
                             f"| {us} | {fixed} |")
            lines.append("")
    return "\n".join(lines)
