"""What ``tippetop sweep`` prints: theta_asymp per run and n0 against theta_s(n0)."""

from __future__ import annotations

import math

from tippetop.compare.presentation.terminal import fmt, fmt_value, table
from tippetop.compare.results.sweep import SweepResult


def print_sweep(res: SweepResult) -> None:
    """A sweep for a person: per run and n0, theta_asymp against the theory's theta_s(n0)."""
    import numpy as np

    rows_in = res.table.to_dict(orient="records")
    th = res.theory
    print(f"{res.scene}: theta_asymp against n0, with the theory's theta_s(n0)")
    rows = []
    for r in rows_in:
        t_inv = r.get("t_invert")
        if isinstance(t_inv, float) and math.isnan(t_inv):
            r["t_invert"] = None  # pandas holds "never turned over" as NaN
        theta_s = None
        if th is not None and len(th):
            theta_s = float(np.interp(r["n0"], th["n0"], th["theta_s"]))
        rows.append((r.get("run"), fmt(r.get("n0"), "rad/s"), fmt(r.get("theta_asymp"), "rad"),
                     fmt(theta_s, "rad"), fmt(r.get("outcome")),
                     fmt_value("t_invert", r.get("t_invert")).split(" (")[0],
                     fmt(r.get("J_rel_drift"), "relative"), fmt(r.get("status")),
                     "cache" if r.get("cached") else "run"))
    print(table(("run", "n0", "theta_asymp", "theta_s", "outcome", "t_invert", "J drift",
                 "status", "from"), rows))


__all__ = ["print_sweep"]
