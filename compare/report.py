"""The model-validation report: one self-contained HTML page.

Everything is inline: figures are base64 PNG ``<img>`` tags, styles sit in one ``<style>``
element, there is no script, and a Content-Security-Policy forbids loading anything from
outside the page. Sections:

1. the verdict of the nightly checks (regressions and new metrics by name);
2. the scenes: parameters, group and the theory's numbers per case;
3. theta(t) and xi(t) with the xi_plus / xi_minus curves, every engine/mode of a scene
   overlaid (the paper's Figs. 3-8), and the slip trajectory (vPX, vPY) (Fig. 5);
4. theta_asymp against n0 with the theory curves theta_s(n0) (Figs. 9 and 10);
5. the group map in the (a/R, A/C) plane with the simulated outcomes;
6. the friction-law table with one sentence per row, written from the numbers;
7. the threshold table (theory against measured, per engine);
8. accuracy against cost (PNG files from a folder, when there are any);
9. every check, and the environment.

:func:`build_report` takes the nightly's results (the ``results.json`` dictionary or its
path). Run tables come from ``tables=`` or from the ``tables/`` files the nightly wrote beside
``results.json``. ``python -m tippetop.compare.report RESULTS.json [--out report.html]
[--accuracy-dir DIR]`` rebuilds a report from a nightly folder.
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.io import write_atomic
from tippetop.models.errors import TippetopError

#: Order of the rows of the friction-law table, with what each mode is.
FRICTION_MODES: dict[str, str] = {
    "ode": "reference ODE, modified Coulomb (the paper's eq. 2.12)",
    "ode-coulomb": "reference ODE, exact Coulomb",
    "ode-viscous": "reference ODE, viscous F = -c v_P",
    "ode-coulomb_viscous": "reference ODE, Coulomb + viscous",
    "mujoco-paper": "MuJoCo, the paper's law applied at the contact point",
    "mujoco-native": "MuJoCo native friction (elliptic cone, condim 3)",
    "mujoco-native-elliptic": "MuJoCo native friction, elliptic cone",
    "mujoco-native-pyramidal": "MuJoCo native friction, pyramidal cone",
    "mujoco-native-condim4": "MuJoCo native friction + torsional (condim 4)",
    "mujoco-native-condim6": "MuJoCo native friction + torsional + rolling (condim 6)",
}
#: The scene whose runs fill the friction-law table.
FRICTION_SCENE = "fig3"
#: Why a mode departs from the paper's law (used when its numbers depart), and why it agrees.
_WHY_DEPART: dict[str, str] = {
    "ode-coulomb": "exact Coulomb has no smoothing at v_P = 0, so the slip dies out, the top "
                   "sticks into rolling and the sliding friction that lifts it vanishes",
    "ode-viscous": "viscous friction has the paper's slope at v_P = 0 (c = mu M g / Lambda) "
                   "but does not saturate at mu N, so it is stronger at large slip and lifts "
                   "the top faster; it still vanishes with v_P, so the final state is the "
                   "paper's (its Sec. 4.4 argument)",
    "ode-coulomb_viscous": "its Coulomb part is discontinuous at v_P = 0 like exact Coulomb, so "
                           "the slip dies out and the top sticks into rolling",
    "mujoco-paper": "the law is the paper's, but MuJoCo's soft contact (penetration, its "
                    "normal force) and the fixed timestep change N and the contact point",
    "mujoco-native": "MuJoCo's own friction is a soft-constraint Coulomb cone whose behaviour "
                     "at small slip is set by solref/impratio, not by Lambda",
    "mujoco-native-elliptic": "MuJoCo's own friction is a soft-constraint Coulomb cone whose "
                              "behaviour at small slip is set by solref/impratio, not by Lambda",
    "mujoco-native-pyramidal": "a soft-constraint Coulomb cone as in native mode, here "
                               "pyramidal (friction depends on the slip direction), whose "
                               "behaviour at small slip is set by solref/impratio, not by "
                               "Lambda",
    "mujoco-native-condim4": "torsional friction adds a torque about the contact normal that "
                             "the paper's model does not have: it brakes the spin and J",
    "mujoco-native-condim6": "torsional and rolling friction add torques the paper's model "
                             "does not have: rolling resistance opposes the motion that lifts "
                             "the top",
}
_WHY_AGREE: dict[str, str] = {
    "ode-coulomb": "exact Coulomb differs from the paper's law only below Lambda",
    "ode-viscous": "viscous friction is continuous and vanishes with v_P like the paper's law, "
                   "so the steady states are the same (the paper's Sec. 4.4 argument) and only "
                   "the rate differs",
    "ode-coulomb_viscous": "the viscous part keeps the law continuous near v_P = 0",
    "mujoco-paper": "the paper's law applied at MuJoCo's contact point",
    "mujoco-native": "MuJoCo's own friction, calibrated against the reference",
    "mujoco-native-elliptic": "MuJoCo's own friction, calibrated against the reference",
    "mujoco-native-pyramidal": "the pyramidal cone's anisotropy is small here",
    "mujoco-native-condim4": "the torsional torque is small against the sliding friction",
    "mujoco-native-condim6": "the torsional and rolling torques are small against the sliding "
                             "friction",
}
_OUTCOME_COLOURS = {"upright": "#1f77b4", "intermediate": "#ff7f0e", "inverted": "#2ca02c",
                    "inconclusive": "#7f7f7f", None: "#d62728"}
_ENGINE_MARKERS = {"ode": "o", "mujoco-paper": "s", "mujoco-native": "^"}
_LABEL_MARKERS = {"(a)": "o", "(b)": "s", "(c)": "D", "(d)": "X"}
_FIG_DPI = 90
#: Rows of a run's table drawn in its figures.
PLOT_ROWS = 1500

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:1.5em auto;
max-width:1280px;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.6em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.86em;display:block;overflow-x:auto}
td.wide{min-width:18em}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
.pass{background:#e8f5e9}.fail{background:#ffebee;font-weight:600}.new{background:#fff8e1}
.error{background:#fce4ec;font-weight:600}.verdict{font-size:1.3em;padding:.3em .8em;
display:inline-block;border-radius:4px}.ok{background:#c8e6c9}.bad{background:#ffcdd2}
img{max-width:100%;height:auto;display:block;margin:.5em 0}figure{margin:1em 0}
figcaption{font-size:.88em;color:#444}code{background:#f5f5f5;padding:0 .2em}
.note{font-size:.9em;color:#333;max-width:40em}nav ul{columns:2}
"""


# ---------------------------------------------------------------------------------- helpers
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any) -> str:
    """The figure as an ``<img>`` with a base64 PNG data URI; closes the figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_FIG_DPI)
    _plt().close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img alt="figure" src="data:image/png;base64,{data}">'


def _e(x: Any) -> str:
    return html.escape(str(x))


def _num(v: Any, fmt: str = ".4g", unit: str = "") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return f"{v:{fmt}}{(' ' + unit) if unit else ''}"
    return _e(v)


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]],
           classes: Iterable[str] | None = None) -> str:
    """An HTML table; cells are pre-rendered HTML strings or plain values (escaped)."""
    out = ["<table><thead><tr>", *(f"<th>{_e(h)}</th>" for h in header), "</tr></thead><tbody>"]
    cls_iter = iter(classes) if classes is not None else None
    for row in rows:
        cls = next(cls_iter, "") if cls_iter is not None else ""
        out.append(f'<tr class="{_e(cls)}">' if cls else "<tr>")
        for cell in row:
            if isinstance(cell, _Html):
                out.append(f"<td>{cell}</td>")
            elif isinstance(cell, (int, float)) and not isinstance(cell, bool):
                out.append(f'<td class="num">{_num(cell)}</td>')
            else:
                out.append(f"<td>{_num(cell)}</td>")
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


class _Html(str):
    """A table cell that is already HTML."""


def _scene_key(rec: Mapping[str, Any]) -> str:
    """Runs of the same scene with the same ``set`` overrides share their figures."""
    extra = ", ".join(rec.get("set") or [])
    return f"{rec['scene']}" + (f" ({extra})" if extra else "")


def _top(params: Mapping[str, Any]):
    from tippetop.models.params import TopParams

    return TopParams(R_m=params["R_m"], a_m=params["a_m"], M_kg=params["M_kg"],
                     A_kgm2=params["A_kgm2"], C_kgm2=params["C_kgm2"],
                     g_mps2=params["g_mps2"])


def _load_tables(results: Mapping[str, Any], base_dir: Path,
                 tables: Mapping[str, pd.DataFrame] | None) -> dict[str, pd.DataFrame]:
    out: dict[str, pd.DataFrame] = dict(tables or {})
    for rec in results.get("cases", []):
        rel = rec.get("table")
        if rec["id"] in out or not rel:
            continue
        p = base_dir / rel
        if p.is_file():
            out[rec["id"]] = pd.read_parquet(p)
    return out


# ---------------------------------------------------------------------------------- sections
def _header(results: Mapping[str, Any]) -> str:
    env = results.get("environment", {})
    c = results.get("counts", {})
    verdict = results.get("verdict", "?")
    cls = "ok" if verdict == "OK" else "bad"
    pk = env.get("packages", {})
    commit = env.get("git_commit") or "unknown"
    if env.get("git_dirty"):
        commit += " (with uncommitted changes)"
    return (
        f"<h1>tippetop model-validation report</h1>"
        f'<p><span class="verdict {cls}">{_e(verdict)}</span> '
        f"profile <b>{_e(results.get('profile'))}</b>: {c.get('cases', 0)} cases, "
        f"{c.get('checks', 0)} checks: {c.get('checks_pass', 0)} pass, "
        f"{c.get('checks_fail', 0)} fail, {c.get('checks_new', 0)} new, "
        f"{c.get('checks_error', 0)} error; {results.get('wall_s', 0):.0f} s.</p>"
        f"<p class='note'>{_e(results.get('profile_description', ''))}</p>"
        f"<p>Started {_e(results.get('started'))}; git {_e(commit)}; MuJoCo "
        f"{_e(pk.get('mujoco'))}; Python {_e(env.get('python'))} on {_e(env.get('platform'))}"
        f"; baseline <code>{_e(results.get('baseline_file'))}</code>.</p>")


def _verdict_section(results: Mapping[str, Any]) -> str:
    recs = results.get("cases", [])
    parts = ["<h2 id='checks'>Regression checks</h2>"]
    fails = [(r, ch) for r in recs for ch in r["checks"] if ch["status"] == "fail"]
    errors = [r for r in recs if r["status"] == "error"]
    new = [(r, ch) for r in recs for ch in r["checks"] if ch["status"] == "new"]
    if not (fails or errors or new):
        parts.append("<p>Every metric is within its tolerance of the stored baseline.</p>")
    if fails:
        parts.append("<h3>Regressions</h3>" + _table(
            ["case", "metric", "message"],
            [(r["id"], ch["metric"], ch["message"]) for r, ch in fails],
            ["fail"] * len(fails)))
    if errors:
        parts.append("<h3>Cases that did not run</h3>" + _table(
            ["case", "error"], [(r["id"], r["error"]) for r in errors], ["error"] * len(errors)))
    if new:
        by_case: dict[str, list[str]] = {}
        for r, ch in new:
            by_case.setdefault(r["id"], []).append(ch["metric"])
        parts.append(f"<details><summary>New (no baseline yet): {len(new)} metrics of "
                     f"{len(by_case)} cases; <code>--update-baseline</code> adds them</summary>"
                     + _table(["case", "metrics"], [(k, ", ".join(v))
                                                    for k, v in by_case.items()],
                              ["new"] * len(by_case)) + "</details>")
    videos = results.get("videos", {})
    if videos.get("requested"):
        links = "".join(f'<li><a href="{_e(rel)}">{_e(name)}</a></li>'
                        for name, rel in sorted(videos.get("files", {}).items()))
        parts.append(f"<p>Videos (MuJoCo left, the reference ODE replayed right): "
                     f"{_e(videos['status'])}.</p>" + (f"<ul>{links}</ul>" if links else ""))
    return "".join(parts)


def _scenes_section(results: Mapping[str, Any]) -> str:
    runs = [r for r in results.get("cases", []) if r["kind"] == "run"]
    by_scene: dict[str, list[Mapping[str, Any]]] = {}
    for r in runs:
        by_scene.setdefault(_scene_key(r), []).append(r)
    rows = []
    for key, recs in by_scene.items():
        p, th = recs[0]["params"], recs[0].get("theory", {})
        outcomes = "; ".join(f"{r['mode']}: {r['values'].get('outcome', 'error')}"
                             for r in recs)
        desc = _Html(f"<div style='min-width:16em'>{_e(recs[0].get('description', ''))}</div>")
        rows.append((
            key, desc, th.get("group", "-"), p["A_over_C"],
            p["a_over_R"], p["C_factor"], p["R_m"], p["a_m"], p["M_kg"], p["law"], p["mu"],
            p["Lambda_mps"], p["theta0"], p["n0"], p["t_end_s"], th.get("n1"), th.get("n4"),
            th.get("nc"), th.get("theta_s"), th.get("outcome", "-"),
            (recs[0].get("expect") or {}).get("outcome", "-"), outcomes))
    return ("<h2 id='scenes'>Scenes, parameters and groups</h2>"
            "<p class='note'>SI units: R, a in m, M in kg, Lambda in m/s, angles in rad, spins "
            "in rad/s. n1, n4, n_c and theta_s(n0) are the theory's (eq. 4.13, Sec. 4.3, "
            "F(x) = kappa); theta_s assumes a start near theta = 0.</p>"
            + _table(["scene", "description", "group", "A/C", "a/R", "C factor", "R", "a", "M",
                      "law", "mu", "Lambda", "theta0", "n0", "t_end (s)", "n1", "n4", "n_c",
                      "theta_s(n0)", "theory outcome", "expected", "simulated"], rows))


def _thin(table: pd.DataFrame, rows: int = PLOT_ROWS) -> pd.DataFrame:
    """Every k-th row (and the last), at most about ``rows`` rows: enough for a line plot."""
    step = max(1, math.ceil(len(table) / rows))
    return table.iloc[list(range(0, len(table), step)) + ([len(table) - 1] if
                                                            (len(table) - 1) % step else [])]


def _xi_limits(frames: Sequence[pd.DataFrame]) -> tuple[float, float]:
    vals = np.concatenate([f["xi"].to_numpy(dtype=float) for f in frames])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return -1.0, 1.0
    lo, hi = np.quantile(vals, [0.002, 0.998])
    lo, hi = min(lo, 0.0), max(hi, 0.0)
    pad = 0.15 * (hi - lo or abs(hi) or 1e-6)
    return float(lo - pad), float(hi + pad)


def _timeseries_figure(key: str, recs: Sequence[Mapping[str, Any]],
                       tables: Mapping[str, pd.DataFrame]) -> str:
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 3.6), gridspec_kw={"width_ratios": [4, 4, 3]})
    ax_t, ax_x, ax_s = axes
    frames = [_thin(tables[r["id"]]) for r in recs]
    scale = 1e6  # xi in 1e-6 kg m^2/s
    for i, (r, f) in enumerate(zip(recs, frames, strict=True)):
        lw = 1.4 if i == 0 else 1.0
        ax_t.plot(f["t"], f["theta"], lw=lw, label=r["mode"])
        ax_x.plot(f["t"], f["xi"] * scale, lw=lw, label=f"xi [{r['mode']}]")
        ax_s.plot(f["vPX"], f["vPY"], lw=0.7, label=r["mode"])
    ref = frames[0]
    lo, hi = _xi_limits(frames)
    for col, style in (("xi_plus", "k--"), ("xi_minus", "k:")):
        # xi_+- diverge where R cos(theta) = a: break the line there instead of drawing the jump
        y = ref[col].to_numpy(dtype=float)
        y = np.where((y > lo - (hi - lo)) & (y < hi + (hi - lo)), y, np.nan)
        jump = np.abs(np.diff(y, prepend=y[:1])) > 0.5 * (hi - lo)
        y[jump] = np.nan
        ax_x.plot(ref["t"], y * scale, style, lw=0.9, label=col)
    ax_x.set_ylim(lo * scale, hi * scale)
    th = recs[0].get("theory", {})
    p = recs[0]["params"]
    if th.get("theta_s") is not None and p["theta0"] <= 0.1:
        ax_t.axhline(th["theta_s"], color="0.4", ls=":", lw=1,
                     label=f"theory theta_s = {th['theta_s']:.3g}")
    ax_t.set_ylim(-0.05, math.pi + 0.1)
    ax_t.set_xlabel("t (s)")
    ax_t.set_ylabel("theta (rad)")
    ax_x.set_xlabel("t (s)")
    ax_x.set_ylabel("xi (1e-6 kg m^2/s)")
    ax_s.set_xlabel("vPX (m/s)")
    ax_s.set_ylabel("vPY (m/s)")
    ax_t.set_title("theta(t)", fontsize=9)
    ax_x.set_title("xi(t) with xi_plus, xi_minus", fontsize=9)
    ax_s.set_title("slip of the contact point", fontsize=9)
    for ax, loc in zip(axes, ("center right", "upper right", "upper right"), strict=True):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc=loc)  # a fixed place: loc="best" costs seconds per figure
    fig.suptitle(key, fontsize=10)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.14, top=0.86, wspace=0.25)
    return _png(fig)


def _timeseries_section(results: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]) -> str:
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in results.get("cases", []):
        if r["kind"] == "run" and r["id"] in tables:
            groups.setdefault(_scene_key(r), []).append(r)
    parts = ["<h2 id='timeseries'>theta(t), xi(t) and the slip (Figs. 3-8)</h2>",
             "<p class='note'>Every engine/mode run of a scene is overlaid. xi = 0 is the "
             "gyroscopic balance condition; xi_plus and xi_minus are its two steady values "
             "(N = M g) along the first run's trajectory. The right panel is the slip velocity "
             "of the contact point (the paper's Fig. 5).</p>"]
    if not groups:
        parts.append("<p>No run tables in these results.</p>")
    for key, recs in groups.items():
        desc = recs[0].get("description", "")
        parts.append(f"<figure>{_timeseries_figure(key, recs, tables)}"
                     f"<figcaption><b>{_e(key)}</b>: {_e(desc)}</figcaption></figure>")
    return "".join(parts)


def _sweeps_section(results: Mapping[str, Any]) -> str:
    from tippetop.compare import theory

    sweeps = [r for r in results.get("cases", []) if r["kind"] == "sweep" and r.get("points")]
    parts = ["<h2 id='sweeps'>theta_asymp against n0 (Figs. 9, 10)</h2>",
             "<p class='note'>Markers: simulated theta_asymp (mean theta over the last 10 % of "
             "the run) from theta0 = 0.01; lines: the theory's theta_s(n0) from F(x) = kappa. "
             "Near n1 and n4 the approach to the steady state is slower than the horizon.</p>"]
    if not sweeps:
        parts.append("<p>No sweeps in this profile.</p>")
        return "".join(parts)
    figures: dict[str, list[Mapping[str, Any]]] = {}
    for r in sweeps:
        figures.setdefault(r.get("figure") or r["name"], []).append(r)
    plt = _plt()
    for title, recs in figures.items():
        fig, ax = plt.subplots(figsize=(7.5, 4.6))
        drawn: set[str] = set()
        rows = []
        for r in recs:
            label = r.get("label") or r["name"]
            top = _top(r["params"])
            n0s = [p["n0"] for p in r["points"]]
            if label not in drawn:
                grid = np.linspace(min(n0s), max(n0s), 300)
                ax.plot(grid, theory.theta_s_curve(top, grid), "-", lw=0.9, color="0.2")
                ax.text(grid[-1], float(theory.theta_s(top, grid[-1])), f" {label}",
                        fontsize=8, va="center")
                drawn.add(label)
            mk = _LABEL_MARKERS.get(label, "o")
            ax.plot(n0s, [p["theta_asymp"] for p in r["points"]], mk, ms=5,
                    mfc="none" if r["mode"] != "ode" else None,
                    label=f"{label} {r['mode']}")
            dev = [abs(p["theta_asymp"] - theory.theta_s(top, p["n0"])) for p in r["points"]
                   if p["theta_asymp"] is not None]
            th = r.get("theory", {})
            rows.append((label, r["mode"], r["params"]["A_over_C"], r["params"]["a_over_R"],
                         th.get("group", "-"), th.get("n1"), th.get("n4"), len(n0s),
                         max(dev) if dev else None, float(np.median(dev)) if dev else None))
        ax.set_xlabel("n0 (rad/s)")
        ax.set_ylabel("theta_asymp (rad)")
        ax.set_ylim(-0.1, math.pi + 0.15)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
        ax.set_title(f"{title}: theta_asymp against n0", fontsize=10)
        fig.tight_layout()
        caption = "; ".join(f"{r.get('label') or r['name']} {r['mode']}: "
                            f"{r.get('description', '')}" for r in recs)
        parts.append(f"<figure>{_png(fig)}<figcaption>{_e(title)}: {_e(caption)}"
                     "</figcaption></figure>")
        parts.append(_table(["top", "mode", "A/C", "a/R", "group", "n1", "n4", "points",
                             "max |theta_asymp - theta_s|", "median"], rows))
    return "".join(parts)


def _draw_groups(ax: Any, xlim: tuple[float, float], ylim: tuple[float, float]) -> None:
    """Shade Groups I/II/III and draw the lines A/C = 1 - a/R and 1 + a/R."""
    xs = np.linspace(0.0, 1.0, 200)
    ax.fill_between(xs, 0.0, 1 - xs, color="#bbdefb", alpha=0.6, lw=0)
    ax.fill_between(xs, 1 - xs, 1 + xs, color="#ffe0b2", alpha=0.6, lw=0)
    ax.fill_between(xs, 1 + xs, 5.0, color="#c8e6c9", alpha=0.6, lw=0)
    ax.plot(xs, 1 - xs, "k-", lw=1, label="_A/C = 1 - a/R")
    ax.plot(xs, 1 + xs, "k-", lw=1, label="_A/C = 1 + a/R")
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_xlabel("a/R")
    ax.set_ylabel("A/C")


def _group_map_section(results: Mapping[str, Any]) -> str:
    plt = _plt()
    from matplotlib.lines import Line2D
    from matplotlib.transforms import offset_copy

    recs = [r for r in results.get("cases", []) if r["kind"] in ("run", "sweep")]
    points: dict[tuple[float, float], list[Mapping[str, Any]]] = {}
    for r in recs:
        p = r["params"]
        points.setdefault((round(p["a_over_R"], 6), round(p["A_over_C"], 6)), []).append(r)
    fig, (ax_all, ax_zoom) = plt.subplots(1, 2, figsize=(13, 5.4),
                                          gridspec_kw={"width_ratios": [1, 1.3]})
    _draw_groups(ax_all, (0.0, 0.7), (0.5, 2.0))
    ax_all.text(0.55, 0.58, "I", fontsize=16, weight="bold")
    ax_all.text(0.6, 1.0, "II", fontsize=16, weight="bold")
    ax_all.text(0.05, 1.85, "III", fontsize=16, weight="bold")
    ax_all.text(0.40, 0.51, "A/C = 1 - a/R", fontsize=8, rotation=-25)
    ax_all.text(0.40, 1.45, "A/C = 1 + a/R", fontsize=8, rotation=25)
    xs = [x for x, _ in points] or [0.1]
    ys = [y for _, y in points] or [1.0]
    zx = (max(0.0, min(xs) - 0.03), max(xs) + 0.03)
    zy = (min(ys) - 0.08, max(ys) + 0.08)
    _draw_groups(ax_zoom, zx, zy)
    ax_all.add_patch(plt.Rectangle((zx[0], zy[0]), zx[1] - zx[0], zy[1] - zy[0], fill=False,
                                   ls="--", lw=0.8, color="0.3"))
    rows = []
    for num, ((x, y), group) in enumerate(sorted(points.items()), start=1):
        runs = [r for r in group if r["kind"] == "run"]
        radius = 0.0 if len(runs) <= 1 else 4.0 + 1.2 * len(runs)  # (points) around the top
        for ax in (ax_all, ax_zoom):
            ax.annotate(str(num), (x, y), xytext=(radius + 6, 4), textcoords="offset points",
                        fontsize=7 if ax is ax_all else 8, color="0.15")
        if not runs:
            for ax in (ax_all, ax_zoom):
                ax.plot(x, y, "+", ms=9, color="0.3")
        for k, r in enumerate(runs):
            ang = 2 * math.pi * k / max(1, len(runs))
            shift = offset_copy(ax_zoom.transData, fig=fig, units="points",
                                x=radius * math.cos(ang), y=radius * math.sin(ang))
            outcome = (r.get("values") or {}).get("outcome")
            mk = _ENGINE_MARKERS.get(r["mode"], "o" if r["engine"] == "ode" else "v")
            colour = _OUTCOME_COLOURS.get(outcome, "#7f7f7f")
            ax_all.plot(x, y, mk, ms=5, color=colour, mec="k", mew=0.4)
            ax_zoom.plot(x, y, mk, ms=6, color=colour, mec="k", mew=0.4, transform=shift)
        if len(runs) > 1:
            ax_zoom.plot(x, y, ".", ms=2, color="k")
        names = ", ".join(f"{r['name']}[{r['mode']}]: {(r.get('values') or {}).get('outcome')}"
                          if r["kind"] == "run" else f"{r['name']}[{r['mode']}]: sweep"
                          for r in group)
        th = group[0].get("theory", {})
        rows.append((num, x, y, th.get("group", "-"), names))
    handles = [Line2D([], [], ls="", marker="o", color=c, mec="k", mew=0.4, label=o)
               for o, c in _OUTCOME_COLOURS.items() if o is not None]
    handles += [Line2D([], [], ls="", marker=m, color="w", mec="k", label=e)
                for e, m in _ENGINE_MARKERS.items()]
    handles.append(Line2D([], [], ls="", marker="+", color="0.3", label="swept top"))
    ax_zoom.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax_all.set_title("the (a/R, A/C) plane", fontsize=10)
    ax_zoom.set_title("the catalogue's tops (runs of one top spread around its point)",
                      fontsize=10)
    fig.subplots_adjust(left=0.06, right=0.89, bottom=0.1, top=0.93, wspace=0.18)
    return ("<h2 id='groups'>Group map</h2><p class='note'>Group I (A/C &lt; 1 - a/R, blue): "
            "theta = 0 is stable for every spin; Group II (between the lines, orange): the top "
            "can turn over; Group III (A/C &gt; 1 + a/R, green): it rises to an intermediate "
            "angle below theta_f. Marker colour: the simulated outcome; shape: the engine/mode. "
            "Numbers refer to the table below.</p>"
            f"<figure>{_png(fig)}</figure>"
            + _table(["#", "a/R", "A/C", "group", "cases and simulated outcomes"], rows))


def _friction_rows(results: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    rows = [r for r in results.get("cases", []) if r["kind"] == "run"
            and r["scene"] == FRICTION_SCENE and not r.get("set") and r["mode"] in
            FRICTION_MODES and r.get("error") is None]
    seen: dict[str, Mapping[str, Any]] = {}
    for r in rows:
        seen.setdefault(r["mode"], r)
    return [seen[m] for m in FRICTION_MODES if m in seen]


def friction_note(row: Mapping[str, Any], ref: Mapping[str, Any] | None) -> str:
    """One sentence on where and why a friction mode departs from the paper's law.

    The sentence is built from the row's numbers against the reference row (the paper's law in
    the reference ODE): whether it inverts, when, the final angle, J drift and the energy lost.
    """
    v = row["values"]
    mode = row["mode"]
    if ref is None or row is ref:
        return ("The paper's law in the reference ODE: the row the others are compared with"
                + (f"; it inverts at {v['t_invert']:.2f} s." if v.get("t_invert") is not None
                   else "."))
    rv = ref["values"]
    t, rt = v.get("t_invert"), rv.get("t_invert")
    same_outcome = v.get("outcome") == rv.get("outcome")
    close_time = (t is None and rt is None) or (t is not None and rt is not None
                                                and abs(t / rt - 1) < 0.05)
    j, rj = v.get("J_rel_drift") or 0.0, rv.get("J_rel_drift") or 0.0
    j_bad = j > max(100 * rj, 1e-6)
    agree = same_outcome and close_time and not j_bad
    why = (_WHY_AGREE if agree else _WHY_DEPART).get(mode, "")
    facts = []
    if t is None and rt is not None:
        facts.append(f"it does not invert within {row['params']['t_end_s']:g} s "
                     f"(theta_asymp = {v['theta_asymp']:.3g} rad, the paper's law inverts at "
                     f"{rt:.2f} s)")
    elif t is not None and rt is None:
        facts.append(f"it inverts at {t:.2f} s where the paper's law does not")
    elif t is not None and rt is not None:
        facts.append(f"it inverts at {t:.2f} s against {rt:.2f} s "
                     f"({100 * (t / rt - 1):+.0f} %), theta_asymp {v['theta_asymp']:.3g} rad "
                     f"against {rv['theta_asymp']:.3g}")
    else:
        facts.append(f"theta_asymp {v['theta_asymp']:.3g} rad against "
                     f"{rv['theta_asymp']:.3g}")
    e0 = row.get("E0")
    el, rel_ = v.get("energy_lost"), rv.get("energy_lost")
    if el is not None and rel_:
        pct = f" ({100 * el / e0:.0f} % of E0)" if e0 else ""
        facts.append(f"it dissipates {el * 1e3:.3g} mJ{pct} against {rel_ * 1e3:.3g} mJ")
    stick, rstick = row.get("slip_small_frac"), ref.get("slip_small_frac")
    if stick is not None and rstick is not None and abs(stick - rstick) > 0.2:
        lead = "the slip dies out: " if stick > 0.8 else ""
        facts.append(f"{lead}|v_P| stays below Lambda/10 in {100 * stick:.0f} % of the "
                     f"samples (paper's law: {100 * rstick:.0f} %)")
    if j_bad:
        facts.append(f"Jellett's J drifts by {j:.1e} (paper's law {rj:.1e})")
    head = FRICTION_MODES.get(mode, mode)
    text = f"{head}: {why}; " if why else f"{head}: "
    return text + "; ".join(facts) + "."


def _friction_section(results: Mapping[str, Any]) -> str:
    rows = _friction_rows(results)
    parts = ["<h2 id='friction'>Friction laws</h2>",
             f"<p class='note'>The Fig. 3 top ({FRICTION_SCENE}: A/C = 1, a/R = 0.1, theta0 = "
             "0.1, n0 = 100 rad/s, 8 s) under each law and MuJoCo mode. Energy dissipated is "
             "E0 - E_end. The note compares each row with the paper's law in the reference "
             "ODE (first row).</p>"]
    if not rows:
        parts.append("<p>No friction-law runs in these results.</p>")
        return "".join(parts)
    ref = next((r for r in rows if r["mode"] == "ode"), None)
    table_rows = []
    for r in rows:
        v = r["values"]
        inverts = v.get("t_invert") is not None
        table_rows.append((
            r["mode"], FRICTION_MODES[r["mode"]], "yes" if inverts else "no",
            v.get("t_invert"), v.get("theta_asymp"), v.get("outcome"),
            _Html(_num(v.get("J_rel_drift"), ".2e")), v.get("energy_lost"),
            _Html(_e(friction_note(r, ref)))))
    parts.append(_table(["mode", "law / contact", "inverts", "t_invert (s)",
                         "theta_asymp (rad)", "outcome", "J drift", "E0 - E_end (J)", "note"],
                        table_rows))
    return "".join(parts)


def _threshold_section(results: Mapping[str, Any]) -> str:
    recs = [r for r in results.get("cases", []) if r["kind"] == "threshold"]
    parts = ["<h2 id='thresholds'>Thresholds: theory against measured</h2>",
             "<p class='note'>Critical spins found by bisection on n0 (n1: theta = 0 turns "
             "unstable; n_c: full inversion), each run over the scene's horizon. The measured "
             "value is the final bracket's midpoint.</p>"]
    if not recs:
        parts.append("<p>No threshold cases in this profile.</p>")
        return "".join(parts)
    rows, classes = [], []
    for r in recs:
        th = r.get("threshold")
        if th is None:
            rows.append((r["scene_name"], r["name"], r["mode"], "-", "-", "-", "-", "-", "-",
                         "-", f"error: {r.get('error')}"))
            classes.append("error")
            continue
        rows.append((r["scene_name"], th["which"], r["mode"], th["theory"], th["measured"],
                     _Html(f"{100 * th['rel_diff']:+.2f} %"),
                     _Html(f"[{th['bracket'][0]:.4g}, {th['bracket'][1]:.4g}]"),
                     th.get("rel_tol"), th["n_runs"], th.get("horizon_s"),
                     "converged" if th.get("converged") else "not converged"))
        classes.append(r["status"])
    parts.append(_table(["scene", "which", "mode", "theory (rad/s)", "measured (rad/s)",
                         "measured / theory - 1", "bracket", "rel_tol", "runs", "horizon (s)",
                         "bisection"], rows, classes))
    return "".join(parts)


def _accuracy_section(accuracy_dir: Path | None) -> str:
    head = "<h2 id='accuracy'>Accuracy against cost</h2>"
    pngs = sorted(Path(accuracy_dir).glob("*.png")) if accuracy_dir else []
    if not pngs:
        where = f" in <code>{_e(accuracy_dir)}</code>" if accuracy_dir else ""
        return head + (f"<p>No accuracy-versus-cost figures were found{where}; they are "
                       "embedded here once their PNG files are given (nightly option "
                       "<code>--accuracy-dir DIR</code>).</p>")
    parts = [head]
    for p in pngs:
        data = base64.b64encode(p.read_bytes()).decode("ascii")
        parts.append(f'<figure><img alt="{_e(p.stem)}" src="data:image/png;base64,{data}">'
                     f"<figcaption>{_e(p.name)}</figcaption></figure>")
    for md in sorted(Path(accuracy_dir).glob("*.md")):
        parts.append(f"<details><summary>{_e(md.name)}</summary><pre>"
                     f"{_e(md.read_text(encoding='utf-8'))}</pre></details>")
    return "".join(parts)


def _checks_section(results: Mapping[str, Any]) -> str:
    rows, classes = [], []
    for r in results.get("cases", []):
        for ch in r["checks"]:
            val = ch["value"]
            shown = f"{len(val)} points" if isinstance(val, dict) else _num(val, ".6g")
            base = ch["baseline"]
            bshown = f"{len(base)} points" if isinstance(base, dict) else _num(base, ".6g")
            rows.append((r["id"], ch["metric"], _Html(shown), _Html(bshown),
                         ch["tolerance"]["text"], ch["status"]))
            classes.append(ch["status"])
    tol_rows = [(k, t["text"], t["why"]) for k, t in results.get("tolerances", {}).items()]
    return ("<h2 id='all'>Every check</h2><details><summary>"
            f"{len(rows)} checks (click to open)</summary>"
            + _table(["case", "metric", "value", "baseline", "tolerance", "status"], rows,
                     classes) + "</details><h3>Tolerances</h3>"
            + _table(["metric", "tolerance", "why"], tol_rows))


def _environment_section(results: Mapping[str, Any]) -> str:
    env = results.get("environment", {})
    rows = [(k, v) for k, v in env.items() if k != "packages"]
    rows += [(f"package {k}", v) for k, v in (env.get("packages") or {}).items()]
    rows.append(("command", " ".join(results.get("command", []))))
    return "<h2 id='env'>Environment</h2>" + _table(["what", "value"], rows)


_NAV = ("<nav><ul><li><a href='#checks'>Regression checks</a></li>"
        "<li><a href='#scenes'>Scenes and groups</a></li>"
        "<li><a href='#timeseries'>theta(t), xi(t), slip (Figs. 3-8)</a></li>"
        "<li><a href='#sweeps'>theta_asymp against n0 (Figs. 9, 10)</a></li>"
        "<li><a href='#groups'>Group map</a></li><li><a href='#friction'>Friction laws</a></li>"
        "<li><a href='#thresholds'>Thresholds</a></li>"
        "<li><a href='#accuracy'>Accuracy against cost</a></li>"
        "<li><a href='#all'>Every check</a></li><li><a href='#env'>Environment</a></li>"
        "</ul></nav>")


def render_report(results: Mapping[str, Any], tables: Mapping[str, pd.DataFrame],
                  accuracy_dir: Path | None = None) -> str:
    """The report's HTML text."""
    body = [_header(results), _NAV, _verdict_section(results), _scenes_section(results),
            _timeseries_section(results, tables), _sweeps_section(results),
            _group_map_section(results), _friction_section(results),
            _threshold_section(results), _accuracy_section(accuracy_dir),
            _checks_section(results), _environment_section(results)]
    title = f"tippetop report ({results.get('profile', '')}, {results.get('verdict', '')})"
    return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; "
            "img-src data:; style-src 'unsafe-inline'\">"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>"
            + "\n".join(body) + "</body></html>\n")


def build_report(results: Mapping[str, Any] | str | Path, path: str | Path, *,
                 tables: Mapping[str, pd.DataFrame] | None = None,
                 accuracy_dir: str | Path | None = None,
                 base_dir: str | Path | None = None) -> Path:
    """Write the self-contained HTML report.

    Args:
        results: The nightly's results dictionary, or the path of its ``results.json``.
        path: The HTML file to write (atomically).
        tables: Case id -> observables table; missing ones are read from the ``tables/``
            files named in ``results``, relative to ``base_dir``.
        accuracy_dir: A folder of accuracy-versus-cost PNG figures to embed (optional).
        base_dir: Where the results' relative table paths start (default: the folder of
            ``results.json``, or of ``path``).

    Returns:
        The path written.
    """
    if isinstance(results, (str, Path)):
        rpath = Path(results)
        try:
            data = json.loads(rpath.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise TippetopError(f"report: expected a readable results.json, got "
                                f"{str(rpath)!r} ({exc})") from None
        base = Path(base_dir) if base_dir else rpath.parent
    else:
        data = dict(results)
        base = Path(base_dir) if base_dir else Path(path).parent
    if "cases" not in data:
        raise TippetopError("report: expected nightly results with a 'cases' list, got none")
    acc = Path(accuracy_dir) if accuracy_dir else None
    text = render_report(data, _load_tables(data, base, tables), acc)
    out = Path(path)
    write_atomic(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m tippetop.compare.report RESULTS.json [--out FILE] [--accuracy-dir DIR]``."""
    p = argparse.ArgumentParser(prog="python -m tippetop.compare.report",
                                description="Rebuild the validation report from a nightly's "
                                "results.json.")
    p.add_argument("results", help="results.json of a nightly run")
    p.add_argument("--out", help="HTML file (default: report.html beside results.json)")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", help="folder of PNG figures")
    p.add_argument("--force", action="store_true", help="overwrite an existing --out")
    args = p.parse_args(argv)
    out = Path(args.out) if args.out else Path(args.results).parent / "report.html"
    try:
        if out.exists() and not args.force:
            raise TippetopError(f"--out: expected a path that does not exist yet (or --force), "
                                f"got existing {str(out)!r}")
        build_report(args.results, out, accuracy_dir=args.accuracy_dir)
    except TippetopError as exc:
        sys.stderr.write(f"tippetop: error: {exc}\n")
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
