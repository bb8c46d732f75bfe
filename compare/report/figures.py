"""The report's figure sections: theta(t), xi(t) and the slip per scene; theta_asymp against n0."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.presentation.verdict import run_of, scene_key, top_of
from tippetop.compare.report.markup import esc, html_table, png

_LABEL_MARKERS = {"(a)": "o", "(b)": "s", "(c)": "D", "(d)": "X"}
#: Rows of a run's table drawn in its figures.
PLOT_ROWS = 1500


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
    """theta(t) with a difference panel under it, xi(t), and the slip speed on a log scale.

    The first record is the reference the differences are taken against (the ``ode`` run when
    the scene has one). Legends sit outside the data, above the panels.
    """
    plt = pyplot()
    from matplotlib.ticker import MaxNLocator

    fig = plt.figure(figsize=(13.5, 4.6))
    gs = fig.add_gridspec(2, 3, height_ratios=[3, 1.25], width_ratios=[4, 4, 3], hspace=0.08,
                          wspace=0.27, left=0.055, right=0.99, bottom=0.11, top=0.80)
    ax_t = fig.add_subplot(gs[0, 0])
    ax_d = fig.add_subplot(gs[1, 0], sharex=ax_t)
    ax_x = fig.add_subplot(gs[:, 1])
    ax_s = fig.add_subplot(gs[:, 2])
    frames = [_thin(tables[r["id"]]) for r in recs]
    ref_rec, ref = recs[0], frames[0]
    scale = 1e6  # xi in 1e-6 kg m^2/s
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (r, f) in enumerate(zip(recs, frames, strict=True)):
        c = colours[i % len(colours)]
        lw = 1.4 if i == 0 else 1.0
        ax_t.plot(f["t"], f["theta"], lw=lw, color=c, label=run_of(r))
        ax_x.plot(f["t"], f["xi"] * scale, lw=lw, color=c)
        slip = np.hypot(f["vPX"].to_numpy(dtype=float), f["vPY"].to_numpy(dtype=float))
        ok = np.isfinite(slip) & (slip > 0)
        # points, not lines: no straight segments between sparse samples
        ax_s.plot(f["t"].to_numpy()[ok], slip[ok], ".", ms=1.6, color=c, alpha=0.7)
        if i > 0:
            th = np.interp(ref["t"], f["t"], f["theta"], right=np.nan)
            ax_d.plot(ref["t"], th - ref["theta"].to_numpy(), lw=1.0, color=c)
    ax_d.axhline(0.0, color="0.3", lw=0.6)
    if len(recs) == 1:
        ax_d.text(0.5, 0.5, "no other engine in this scene", transform=ax_d.transAxes,
                  ha="center", va="center", fontsize=8, color="0.4")
    lo, hi = _xi_limits(frames)
    for col, style in (("xi_plus", "k--"), ("xi_minus", "k:")):
        # xi_+- diverge where R cos(theta) = a: break the line there instead of drawing the jump
        y = ref[col].to_numpy(dtype=float)
        y = np.where((y > lo - (hi - lo)) & (y < hi + (hi - lo)), y, np.nan)
        jump = np.abs(np.diff(y, prepend=y[:1])) > 0.5 * (hi - lo)
        y[jump] = np.nan
        ax_x.plot(ref["t"], y * scale, style, lw=0.9, label=col)
    ax_x.set_ylim(lo * scale, hi * scale)
    th = ref_rec.get("theory", {})
    p = ref_rec["params"]
    if th.get("theta_s") is not None and p["theta0"] <= 0.1:
        ax_t.axhline(th["theta_s"], color="0.4", ls=":", lw=1.2,
                     label=f"theory theta_s = {th['theta_s']:.3g}")
    printed = (ref_rec.get("expect") or {}).get("theta_asymp")
    if printed is not None:
        ax_t.axhline(printed, color="#d62728", ls=(0, (1, 3)), lw=2.0,
                     label=f"paper's printed {printed:g}")
    lam = p.get("Lambda_mps")
    if lam:
        ax_s.axhline(lam, color="0.3", ls="--", lw=0.8, label=f"Lambda = {lam:g} m/s")
        ax_s.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.02), frameon=False)
    ax_t.set_ylim(-0.05, math.pi + 0.1)
    ax_t.tick_params(labelbottom=False)
    ax_t.set_ylabel("theta (rad)")
    ax_d.set_xlabel("t (s)")
    ax_d.set_ylabel("minus ref.", fontsize=8)
    ax_d.yaxis.set_major_locator(MaxNLocator(3))
    ax_x.set_xlabel("t (s)")
    ax_x.set_ylabel("xi (1e-6 kg m^2/s)")
    ax_s.set_xlabel("t (s)")
    ax_s.set_ylabel("|v_P| (m/s)")
    ax_s.set_yscale("log")
    ax_s.xaxis.set_major_locator(MaxNLocator(5))
    ax_t.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.02), ncol=3,
                frameon=False)
    ax_x.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.02), ncol=2,
                frameon=False)
    for ax in (ax_t, ax_d, ax_x, ax_s):
        ax.grid(alpha=0.3)
    fig.text(0.01, 0.97, f"{key}: theta(t) and theta - theta[{run_of(ref_rec)}]; xi(t) with "
             "xi_plus, xi_minus; slip speed of the contact point", fontsize=9, va="top")
    return png(fig)


def timeseries_section(results: Mapping[str, Any], tables: Mapping[str, pd.DataFrame]) -> str:
    """theta(t), xi(t) and the slip, one figure per scene: the main runs, the rest folded."""
    from tippetop.compare.presentation.verdict import MAIN_RUNS, REFERENCE_RUN

    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in results.get("cases", []):
        if r["kind"] == "run" and r["id"] in tables:
            groups.setdefault(scene_key(r), []).append(r)
    parts = ["<h2 id='timeseries'>theta(t), xi(t) and the slip (Figs. 3-8)</h2>",
             "<p class='note'>The main runs (the reference ODE, MuJoCo with the paper's law, "
             "MuJoCo's calibrated native friction) are overlaid; under theta(t), each one's "
             "difference from the reference. Other runs of a scene are one click away. xi = 0 "
             "is the gyroscopic balance condition; xi_plus and xi_minus are its two steady "
             "values (N = M g) along the reference's trajectory. Right: the slip speed of the "
             "contact point (the paper's Fig. 5) on a log scale, each sample a dot.</p>"]
    if not groups:
        parts.append("<p>No run tables in these results.</p>")
    for key, recs in groups.items():
        recs = sorted(recs, key=lambda r: (run_of(r) != REFERENCE_RUN,))
        main = [r for r in recs if run_of(r) in MAIN_RUNS]
        rest = [r for r in recs if run_of(r) not in MAIN_RUNS]
        desc = recs[0].get("description", "")
        first = main or rest[:1]
        parts.append(f"<figure>{_timeseries_figure(key, first, tables)}"
                     f"<figcaption><b>{esc(key)}</b>: {esc(desc)}</figcaption></figure>")
        others = [r for r in rest if r not in first]
        if others:
            ref = [r for r in first if run_of(r) == REFERENCE_RUN]
            parts.append(f"<details><summary>{esc(key)}: {len(others)} more runs ("
                         f"{esc(', '.join(run_of(r) for r in others))})</summary>"
                         f"<figure>{_timeseries_figure(key, [*ref, *others], tables)}"
                         "</figure></details>")
    return "".join(parts)


#: Samples drawn per run in a friction-law figure: a readable cloud (every n-th beyond it).
FRICTION_POINTS = 3000


def friction_law_figure(runs: Sequence[tuple[str, str, pd.DataFrame, Mapping[str, Any]]], *,
                        title: str | None = None, height: float = 4.2) -> str:
    """|F_t| / (mu N) against the slip speed (log axis), as ``<img>`` HTML.

    Args:
        runs: (label, colour, table, its ``friction_realised``) per run: its samples that touch
            and slip before ``before_t_s`` (the stem) as points.
        title: The axes' title, if any.
        height: Figure height (inches).

    The curve is the paper's law, at the first run's ``mu_law`` and ``Lambda_law_mps``.
    """
    from tippetop.compare.measures.friction_realised import law_mu, samples

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9.0, height))
    mu, lam = runs[0][3]["mu_law"], runs[0][3]["Lambda_law_mps"]
    lo, hi = [], []
    for label, colour, table, fr in runs:
        before = fr.get("before_t_s")
        smp = samples(table if before is None else table[table["t"] < before])
        if not len(smp):
            continue
        if len(smp) > FRICTION_POINTS:
            smp = smp.iloc[:: len(smp) // FRICTION_POINTS + 1]
        ax.plot(smp["slip"], smp["mu_eff"] / mu, ".", ms=2.5, alpha=0.5, color=colour,
                label=label)
        lo.append(float(smp["slip"].min()))
        hi.append(float(smp["slip"].max()))
    if lo:
        v = np.logspace(math.log10(min(lo)), math.log10(max(hi)), 200)
        ax.plot(v, law_mu(v, mu, lam) / mu, "k-", lw=1.2,
                label=f"the paper's law (mu {mu:g}, Lambda {1e3 * lam:g} mm/s)")
    ax.set_xscale("log")
    ax.set_xlabel("slip speed |v_P| (m/s)")
    ax.set_ylabel("|F_t| / (mu N)")
    if title:
        ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    return png(fig)


def sweeps_section(results: Mapping[str, Any]) -> str:
    """theta_asymp against n0 with the theory's theta_s(n0), one figure per paper figure."""
    from tippetop.compare.measures import theory

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
            top = top_of(r["params"])
            n0s = [p["n0"] for p in r["points"]]
            if label not in drawn:
                grid = np.linspace(min(n0s), max(n0s), 300)
                ax.plot(grid, theory.theta_s_curve(top, grid), "-", lw=0.9, color="0.2")
                ax.text(grid[-1], float(theory.theta_s(top, grid[-1])), f" {label}",
                        fontsize=8, va="center")
                drawn.add(label)
            mk = _LABEL_MARKERS.get(label, "o")
            ax.plot(n0s, [p["theta_asymp"] for p in r["points"]], mk, ms=5,
                    mfc="none" if r.get("engine") != "ode" else None,
                    label=f"{label} {run_of(r)}")
            dev = [abs(p["theta_asymp"] - theory.theta_s(top, p["n0"])) for p in r["points"]
                   if p["theta_asymp"] is not None]
            th = r.get("theory", {})
            rows.append((label, run_of(r), r["params"]["A_over_C"], r["params"]["a_over_R"],
                         th.get("group", "-"), th.get("n1"), th.get("n4"), len(n0s),
                         max(dev) if dev else None, float(np.median(dev)) if dev else None))
        ax.set_xlabel("n0 (rad/s)")
        ax.set_ylabel("theta_asymp (rad)")
        ax.set_ylim(-0.1, math.pi + 0.15)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
        ax.set_title(f"{title}: theta_asymp against n0", fontsize=10)
        fig.tight_layout()
        caption = "; ".join(f"{r.get('label') or r['name']} {run_of(r)}: "
                            f"{r.get('description', '')}" for r in recs)
        parts.append(f"<figure>{png(fig)}<figcaption>{esc(title)}: {esc(caption)}"
                     "</figcaption></figure>")
        parts.append(html_table(["top", "run", "A/C", "a/R", "group", "n1", "n4", "points",
                                 "max |theta_asymp - theta_s|", "median"], rows))
    return "".join(parts)
