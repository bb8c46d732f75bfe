"""Work-precision figures: error against wall time and against the deterministic cost."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tippetop.compare.running.io import write_atomic
from tippetop.compare.studies.accuracy.common import (
    DEFAULT_THRESHOLDS,
    PLOT_ERR_FLOOR,
    STATUS_DIVERGED,
    STATUS_OK,
)
from tippetop.compare.studies.accuracy.mujoco_study import DEFAULT_INTEGRATORS, MUJOCO_NOTES
from tippetop.compare.studies.accuracy.pareto import pareto_front


def work_precision_figure(df: pd.DataFrame, path: str | Path, *, title: str | None = None) -> None:
    """Plot max |theta error| against wall time on log axes, one line per method.

    Written atomically as PNG. ``df`` should hold one scene of one engine; the frontier is
    drawn as a grey step line. A second panel plots the same errors against the
    deterministic cost (``n_rhs``; ``n_steps`` for MuJoCo), which does not depend on the
    machine's load.

    Args:
        df: Work-precision rows.
        path: The PNG file.
        title: The figure title; by default the scene, the engine and the reference.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(12.0, 5.0), sharey=True)
    try:
        ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
        cost = "n_steps" if (df["engine"] == "mujoco").all() else "n_rhs"
        for method, g in ok.groupby("method", sort=False):
            g = g.sort_values("wall_s")
            err = np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR)
            line = ax.loglog(g["wall_s"], err, "o-", ms=4, label=str(method))[0]
            g = g.sort_values(cost)
            ax_n.loglog(g[cost], np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR), "o-", ms=4,
                        color=line.get_color())
        front = pareto_front(df)
        if not front.empty:
            ax.step(front["wall_s"], np.maximum(front["theta_max_err"], PLOT_ERR_FLOOR),
                    where="post", color="0.6", lw=3, alpha=0.4, zorder=0, label="frontier")
        ref = df.attrs.get("reference")
        if ref and ref.get("floor"):
            for a in (ax, ax_n):
                a.axhline(ref["floor"], color="0.3", ls=":", lw=1,
                          label=f"reference floor ({ref['floor']:.0e} rad)")
        ax.set_xlabel("wall time (s)")
        ax_n.set_xlabel("right-hand-side evaluations" if cost == "n_rhs" else "steps")
        ax.set_ylabel("max |theta - theta_ref| (rad)")
        if title is None:
            scenes = ", ".join(sorted(df["scene"].unique()))
            engines = ", ".join(sorted(df["engine"].unique()))
            title = f"{scenes} [{engines}]: work-precision"
            if ref:
                title += f"; reference: {ref['method']} at rtol {ref['rtol']:g}"
        fig.suptitle(title, fontsize=10)
        ax.set_title("error against wall time (this machine)", fontsize=9)
        ax_n.set_title("error against evaluations (deterministic)", fontsize=9)
        for a in (ax, ax_n):
            a.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def mujoco_work_precision_figure(df: pd.DataFrame, path: str | Path, *,
                                 title: str | None = None) -> None:
    """Plot MuJoCo's max |theta error| against wall time and against steps, on log axes.

    One colour per integrator, solid for paper mode and dashed for native mode; the frontier
    as a grey step line. The steps panel carries the timestep on its top axis and marks the
    diverged (x) and skipped (|) points along its top edge, so that every point of the table
    shows. The notes under the panels (:data:`MUJOCO_NOTES`) say what limits each mode's
    error. Written atomically as PNG; ``df`` should hold one scene of the MuJoCo engine.

    Args:
        df: MuJoCo work-precision rows of one scene.
        path: The PNG file.
        title: The figure title; by default the scene, the engine and the reference.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(13.0, 6.2), sharey=True)
    try:
        colours = {i: f"C{k}" for k, i in enumerate(
            dict.fromkeys([*DEFAULT_INTEGRATORS, *(m.split("/")[0] for m in df["method"])]))}
        styles = {"paper": ("-", "o"), "native": ("--", "s")}
        ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
        for method, g in ok.groupby("method", sort=False):
            integrator, mode = str(method).split("/")
            ls, marker = styles.get(mode, (":", "^"))
            kw = {"color": colours[integrator], "ls": ls, "marker": marker, "ms": 4}
            g = g.sort_values("n_steps")
            err = np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR)
            ax.loglog(g["wall_s"], err, label=str(method), **kw)
            ax_n.loglog(g["n_steps"], err, **kw)
        front = pareto_front(df)
        if not front.empty:
            ax.step(front["wall_s"], np.maximum(front["theta_max_err"], PLOT_ERR_FLOOR),
                    where="post", color="0.6", lw=3, alpha=0.4, zorder=0, label="frontier")
        if not ok.empty:
            lo = float(np.maximum(ok["theta_max_err"], PLOT_ERR_FLOOR).min())
            hi = float(ok["theta_max_err"].max())
            ax.set_ylim(lo / 3, hi * 8)
        for x in DEFAULT_THRESHOLDS:
            lo_y, hi_y = ax.get_ylim()
            if lo_y < x < hi_y:
                for a in (ax, ax_n):
                    a.axhline(x, color="0.75", ls=":", lw=1, zorder=0)
        # every point that has no error: diverged (x) and skipped (|) along the top edge
        T = float(df["t_end_s"].iloc[0]) if len(df) else 1.0
        # one row per method along the top edge, in the legend's order
        rows_y = {m: ax.get_ylim()[1] / 1.5 / 1.4**k
                  for k, m in enumerate(dict.fromkeys(df["method"]))}
        for kind, marker in ((STATUS_DIVERGED, "x"), ("skipped", "|"), ("failed", "+")):
            bad = df[df["status"].str.startswith(kind)]
            for method, g in bad.groupby("method", sort=False):
                integrator, mode = str(method).split("/")
                ax_n.plot(T / g["timestep_s"], np.full(len(g), rows_y[method]), ls="none",
                          marker=marker, ms=7, mew=1.5, color=colours[integrator],
                          alpha=1.0 if mode == "paper" else 0.55)
        for kind, marker in ((STATUS_DIVERGED, "x"), ("skipped: over budget", "|"),
                             ("failed", "+")):
            n = int(df["status"].str.startswith(kind.split(":")[0]).sum())
            if n:
                ax_n.plot([], [], ls="none", marker=marker, color="0.3", label=f"{kind} ({n})")
        if T > 0:
            top = ax_n.secondary_xaxis("top", functions=(lambda n: T / np.maximum(n, 1e-300),
                                                         lambda d: T / np.maximum(d, 1e-300)))
            top.set_xlabel("timestep dt (s)", fontsize=8)
        from matplotlib.ticker import FuncFormatter

        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(FuncFormatter(
            lambda v, _: f"{v:g}" if f"{v:.1e}"[0] in "25" else ""))
        ax.set_xlabel("wall time (s)")
        ax_n.set_xlabel("steps")
        ax.set_ylabel("max |theta - theta_ref| (rad)")
        ref = df.attrs.get("reference")
        if title is None:
            scenes = ", ".join(sorted(df["scene"].unique()))
            title = (f"{scenes} [mujoco, {T:g} s simulated]: work-precision against the reference "
                     "ODE")
            if ref:
                title += f" ({ref['method']} at rtol {ref['rtol']:g})"
            title += ("\nnative mode is MuJoCo's soft friction, not the paper's law: its error "
                      "floors at the friction-model difference")
        fig.suptitle(title, fontsize=10)
        ax.set_title("error against wall time (this machine)", fontsize=9)
        ax_n.set_title("error against steps (deterministic)", fontsize=9)
        for a in (ax, ax_n):
            a.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        if ax_n.get_legend_handles_labels()[0]:
            ax_n.legend(fontsize=7, loc="lower left")
        notes = "\n".join(f"- {n}" for n in MUJOCO_NOTES)
        fig.text(0.01, 0.01, notes, fontsize=7, va="bottom", ha="left", wrap=True)
        fig.tight_layout(rect=(0, 0.1, 1, 1))
        write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)
