"""The report's figure sections: theta(t), xi(t) and the slip per scene; theta_asymp against n0."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.report.markup import esc, html_table, png, pyplot
from tippetop.compare.report.sections import scene_key

_LABEL_MARKERS = {"(a)": "o", "(b)": "s", "(c)": "D", "(d)": "X"}
#: Rows of a run's table drawn in its figures.
PLOT_ROWS = 1500


def _top(params: Mapping[str, Any]):
    from tippetop.models.params import TopParams

    return TopParams(R_m=params["R_m"], a_m=params["a_m"], M_kg=params["M_kg"],
                     A_kgm2=params["A_kgm2"], C_kgm2=params["C_kgm2"],
                     g_mps2=params["g_mps2"])


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
    plt = pyplot()
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
    return png(fig)


def timeseries_section(results: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]) -> str:
    """theta(t), xi(t) and the slip, one figure per scene (every engine/mode overlaid)."""
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in results.get("cases", []):
        if r["kind"] == "run" and r["id"] in tables:
            groups.setdefault(scene_key(r), []).append(r)
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
                     f"<figcaption><b>{esc(key)}</b>: {esc(desc)}</figcaption></figure>")
    return "".join(parts)


def sweeps_section(results: Mapping[str, Any]) -> str:
    """theta_asymp against n0 with the theory's theta_s(n0), one figure per paper figure."""
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
    plt = pyplot()
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
        parts.append(f"<figure>{png(fig)}<figcaption>{esc(title)}: {esc(caption)}"
                     "</figcaption></figure>")
        parts.append(html_table(["top", "mode", "A/C", "a/R", "group", "n1", "n4", "points",
                                 "max |theta_asymp - theta_s|", "median"], rows))
    return "".join(parts)
