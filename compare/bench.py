"""Benchmarks that print a ratio against a baseline measured in the same run."""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.solve import initial_state_vector, scipy_rhs, simulate_ode

#: The issue's target: the compiled integrator at least this many times faster than scipy.
TARGET_SPEEDUP = 60.0
#: ... with the final theta agreeing to this (rad).
TARGET_THETA_AGREEMENT = 1e-6


def _theta_of_vector_state(y: np.ndarray) -> float:
    qw, qx, qy, qz = y[4:8] / np.linalg.norm(y[4:8])
    kz = qw * qw - qx * qx - qy * qy + qz * qz
    s = math.hypot(2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx))
    return math.atan2(s, kz)


def bench_ode(n0: float = 60.0, t_end_s: float = 60.0, rtol: float = 1e-9,
              atol: float = 1e-12, repeats: int = 3) -> dict:
    """Fig. 11 top: the compiled DOP853 against ``scipy.integrate.solve_ivp(method="DOP853")``.

    Both integrate the same compiled right-hand side (vector formulation, the paper's friction)
    at the same tolerances; scipy calls it from its Python step loop. Returns the times (best
    of ``repeats`` for the compiled path, one scipy run), n_rhs, the ratio and the final-theta
    difference, with a printable ``report``.
    """
    top = TopParams.from_ratios(1.0, 0.15)
    fr = FrictionParams()
    init = InitialState(theta0=0.01, n0=n0)
    opts = OdeOptions(rtol=rtol, atol=atol)
    y0 = initial_state_vector(top, init)
    # compile / load everything first (scipy_rhs compiles its rhs before returning)
    simulate_ode(top, fr, init, t_end_s=min(t_end_s, 0.01), options=opts)
    fun = scipy_rhs(top, fr, "vector")
    ours = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        res = simulate_ode(top, fr, init, t_end_s=t_end_s, sample_dt_s=t_end_s, options=opts)
        ours.append(time.perf_counter() - t0)
    theta_ours = float(res.table["theta"].iloc[-1])

    t0 = time.perf_counter()
    sol = solve_ivp(fun, (0.0, t_end_s), y0, method="DOP853", rtol=rtol, atol=atol)
    t_scipy = time.perf_counter() - t0
    theta_scipy = _theta_of_vector_state(sol.y[:, -1])
    t_ours = min(ours)
    ratio = t_scipy / t_ours
    dtheta = abs(theta_ours - theta_scipy)
    report = "\n".join([
        f"reference ODE benchmark: Fig. 11 top (A/C = 1, a/R = 0.15), n0 = {n0:g} rad/s, "
        f"{t_end_s:g} s simulated, rtol = {rtol:g}, atol = {atol:g}",
        f"  compiled DOP853 (ours)      {t_ours:9.4f} s  n_rhs = {res.n_rhs:>9d}  "
        f"(best of {len(ours)})",
        f"  scipy solve_ivp(DOP853)     {t_scipy:9.4f} s  n_rhs = {sol.nfev:>9d}  "
        f"(same compiled rhs, baseline)",
        f"  speed-up                    {ratio:9.1f} x   (target >= {TARGET_SPEEDUP:g} x: "
        f"{'met' if ratio >= TARGET_SPEEDUP else 'NOT met'})",
        f"  final theta                 {theta_ours:.10f} vs {theta_scipy:.10f} rad, "
        f"|diff| = {dtheta:.2e} (target <= {TARGET_THETA_AGREEMENT:g}: "
        f"{'met' if dtheta <= TARGET_THETA_AGREEMENT else 'NOT met'})",
        f"  per rhs evaluation          {1e9 * t_ours / res.n_rhs:9.1f} ns vs "
        f"{1e9 * t_scipy / sol.nfev:.1f} ns (whole run / n_rhs)",
    ])
    return {
        "n0": n0, "t_end_s": t_end_s, "rtol": rtol, "atol": atol,
        "ours_s": t_ours, "ours_n_rhs": res.n_rhs,
        "scipy_s": t_scipy, "scipy_n_rhs": int(sol.nfev),
        "speedup": ratio, "theta_final_ours": theta_ours, "theta_final_scipy": theta_scipy,
        "theta_final_abs_diff": dtheta,
        "ours_ns_per_rhs": 1e9 * t_ours / res.n_rhs,
        "scipy_ns_per_rhs": 1e9 * t_scipy / sol.nfev,
        "target_speedup_met": ratio >= TARGET_SPEEDUP,
        "target_theta_met": dtheta <= TARGET_THETA_AGREEMENT,
        "report": report,
    }
