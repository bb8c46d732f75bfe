"""Figures drawn with matplotlib (headless): the sweep's and the atlas's, and ``pyplot`` itself."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from tippetop.compare.measures import theory
from tippetop.compare.results.sweep import SweepResult
from tippetop.compare.running.io import write_atomic


def pyplot():
    """matplotlib.pyplot on the Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def sweep_figure(result: SweepResult, path: Path) -> None:
    """theta_asymp against n0 per run, with theta_s(n0) and the critical spins (PNG/SVG)."""
    plt = pyplot()
    top = result.top
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    th = result.theory
    ax.plot(th["n0"], th["theta_s"], "k-", lw=1, label=r"theory $\theta_s(n_0)$")
    markers = iter("os^vD<>p*")
    for run, grp in result.table.groupby("run", sort=False):
        ax.plot(grp["n0"], grp["theta_asymp"], next(markers), mfc="none", label=run)
    for name, val in (("n1", theory.n1(top)), ("n4", theory.n4(top))):
        if val is not None and th["n0"].min() <= val <= th["n0"].max():
            ax.axvline(val, color="0.6", ls=":", lw=1)
            ax.text(val, 0.05, f" {name}", color="0.4", fontsize=8)
    ax.set_xlabel(r"$n_0$ (rad/s)")
    ax.set_ylabel(r"$\theta_{asymp}$ (rad)")
    ax.set_ylim(-0.1, math.pi + 0.15)
    ax.set_title(f"{result.scene}: A/C = {top.A_over_C:.3g}, a/R = {top.a_over_R:.3g} "
                 f"(Group {theory.group(top)})", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".")))
    plt.close(fig)


_MARKERS = {"ode/paper": "o", "mujoco/paper": "s", "mujoco/native": "^"}
_GROUP_COLOURS = {"I": "#1565c0", "II": "#e65100", "III": "#6a1b9a"}


def atlas_figure(result: dict[str, Any]) -> Any:
    """The (a/R, A/C) plane with each run's (engine and mode's) measured groups.

    The boundaries A/C = 1 -+ a/R and r_c are drawn; each run's measured group is a marker
    (colour: group; shape: run); departures from the theory are circled.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 5.6))
    xs = np.linspace(0.0, 1.0, 400)
    grid = result["grid"]
    x_hi = max(0.3, 1.15 * max(grid["a_over_R"]))
    y_lo = min(0.7, 0.95 * min(grid["A_over_C"]))
    y_hi = max(1.5, 1.05 * max(grid["A_over_C"]))
    ax.plot(xs, 1 - xs, "k-", lw=1.2, label="A/C = 1 - a/R (I | II)")
    ax.plot(xs, 1 + xs, "k--", lw=1.2, label="A/C = 1 + a/R (II | III)")
    from tippetop.models.params import TopParams

    rc = [theory.r_c(TopParams(R_m=1.0, a_m=x, M_kg=1.0, A_kgm2=1.0, C_kgm2=1.0))
          for x in xs[1:-1]]
    ax.plot(xs[1:-1], rc, ":", color="0.3", lw=1.2, label="A/C = r_c (n_c = n1 | n4)")
    engines = result["runs"]
    k = len(engines)
    dx = 0.012 * (x_hi / 0.3)
    for j, eng in enumerate(engines):
        pts = [p for p in result["points"] if p["run"] == eng]
        off = (j - (k - 1) / 2) * dx
        for p in pts:
            x, y = p["a_over_R"] + off, p["A_over_C"]
            ax.plot(x, y, _MARKERS.get(eng, "v"), ms=7,
                    color=_GROUP_COLOURS[p["group_measured"]], mec="k", mew=0.5)
            if not p["agrees"]:
                ax.plot(x, y, "o", ms=15, mfc="none", mec="#d50000", mew=1.6)
    from matplotlib.lines import Line2D

    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], ls="", marker="o", color=c, mec="k", label=f"measured Group {g}")
                for g, c in _GROUP_COLOURS.items()]
    handles += [Line2D([], [], ls="", marker=_MARKERS.get(e, "v"), color="w", mec="k",
                       label=e) for e in engines]
    handles.append(Line2D([], [], ls="", marker="o", ms=12, mfc="none", mec="#d50000",
                          mew=1.6, label="departs from the theory"))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlim(0.0, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.set_xlabel("a/R")
    ax.set_ylabel("A/C")
    ax.set_title("Groups measured from n1 and n4 (growth rates), each engine and mode",
                 fontsize=10)
    ax.grid(alpha=0.3)
    fig.subplots_adjust(left=0.09, right=0.70, bottom=0.1, top=0.93)
    return fig
