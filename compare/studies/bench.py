"""Benchmarks that print a ratio against a baseline measured in the same run."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tippetop.compare.presentation.bench import bench_ode_report
from tippetop.compare.results.bench import (
    EQUAL_ACCURACY_RAD,
    MOONSHOT_VS_PEER,
    SCIPY,
    TARGET_SPEEDUP,
    TARGET_THETA_AGREEMENT,
    TARGET_VS_PEER,
    BenchOdeResult,
)
from tippetop.compare.studies.accuracy.common import ATOL_PER_RTOL, REFERENCE_RTOL
from tippetop.compare.studies.frontier import ERROR_FLOOR, time_at_error
from tippetop.compare.studies.peer_runs import theta_of_states
from tippetop.models.options import OdeOptions, taylor_runs
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.methods import Method, get_method
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.peers import (
    NUMBALSODA_METHODS,
    PeerRun,
    numbalsoda_missing,
    run_numbalsoda,
    run_reference_kernel,
)
from tippetop.reference_ode.solve import (
    OdeResult,
    initial_state_vector,
    scipy_rhs,
    simulate_ode,
)
from tippetop.reference_ode.taylor_peer import HEYOKA, TaylorPeer, heyoka_missing, unsupported

#: The truth of the equal-error comparison: the reference's kernel at its tightest rtol.
TRUTH_RTOL = REFERENCE_RTOL
#: The peers' small tolerance sweep (atol = ATOL_PER_RTOL rtol) for their frontier.
PEER_SWEEP_RTOLS: tuple[float, ...] = tuple(10.0**-k for k in range(5, 14))


def _theta_of_vector_state(y: np.ndarray) -> float:
    return float(theta_of_states(y)[0])


def _scipy_run(fun, y0: np.ndarray, t_end_s: float, rtol: float, atol: float):
    from scipy.integrate import solve_ivp

    t0 = time.process_time()
    sol = solve_ivp(fun, (0.0, t_end_s), y0, method="DOP853", rtol=rtol, atol=atol)
    return time.process_time() - t0, sol


def _heyoka_solver(p: np.ndarray, y0: np.ndarray, t_end_s: float, rtol: float, rounds: int,
                   theta_kernel: float, theta_truth: float, our_err: float,
                   t_kernel: float) -> dict:
    """The row of heyoka's Taylor method: its run at tol = rtol, its frontier over the sweep.

    The sweep is :data:`PEER_SWEEP_RTOLS`, as the numbalsoda peers'.

    Each tolerance is compiled (LLVM) before it is timed; its ``n_rhs`` is its steps (one
    Taylor jet each).
    """
    pts = []
    at_rtol = None
    for tol in sorted({rtol, *PEER_SWEEP_RTOLS}, reverse=True):
        peer = TaylorPeer(p, tol)
        peer.run(y0, min(t_end_s, 0.01))
        runs_ = [peer.run(y0, t_end_s) for _ in range(rounds)]
        run = min(runs_, key=lambda x: x.s)
        err = abs(_theta_of_vector_state(run.y_final) - theta_truth)
        if tol == rtol:
            at_rtol = run
        if tol in PEER_SWEEP_RTOLS and run.success:
            pts.append({"rtol": tol, "s": run.s, "theta_err": err})
    assert at_rtol is not None
    theta = _theta_of_vector_state(at_rtol.y_final)
    diff = abs(theta - theta_kernel)
    t_eq = time_at_error([(q["theta_err"], q["s"]) for q in pts], our_err)
    return {"s": at_rtol.s, "n_rhs": at_rtol.n_rhs, "theta_final": theta,
            "theta_abs_diff": diff, "success": at_rtol.success,
            "ratio": at_rtol.s / t_kernel, "sweep": pts, "s_at_equal_error": t_eq,
            "equal_accuracy": t_eq is not None,
            "ratio_at_equal_error": None if t_eq is None else t_eq / t_kernel}


@dataclass(frozen=True)
class _Problem:
    """The benchmarked run: the Fig. 11 top, its state, and the tolerances each solver uses."""

    top: TopParams
    fr: FrictionParams
    init: InitialState
    opts: OdeOptions
    y0: np.ndarray
    p: np.ndarray
    n0: float
    t_end_s: float
    rtol: float
    atol: float
    method: Method
    k_rtol: float
    k_atol: float
    ours: str


@dataclass(frozen=True)
class _Baselines:
    """The best runs of the reference's kernel, of simulate_ode and of scipy, compared."""

    kernel: PeerRun
    res: OdeResult
    sol: Any
    t_kernel: float
    t_ours: float
    t_scipy: float
    theta_kernel: float
    theta_ours: float
    theta_scipy: float
    ratio: float
    dtheta: float


def _problem(n0: float, t_end_s: float, rtol: float, atol: float) -> _Problem:
    """The benchmarked run, with the default (auto) method resolved at ``rtol``."""
    top = TopParams.from_ratios(1.0, 0.15)
    fr = FrictionParams()
    init = InitialState(theta0=0.01, n0=n0)
    # the default (auto) at this rtol: the method it runs and the tolerances it runs it at
    method, factor = get_method("auto", rtol, taylor_runs("vector", fr.law, stem=False))
    k_rtol, k_atol = rtol * factor, atol * factor
    ours = f"tippetop {method.name}"
    opts = OdeOptions(rtol=rtol, atol=atol)
    y0 = initial_state_vector(top, init)
    p = pack_params(top, fr)
    return _Problem(top=top, fr=fr, init=init, opts=opts, y0=y0, p=p, n0=n0, t_end_s=t_end_s,
                    rtol=rtol, atol=atol, method=method, k_rtol=k_rtol, k_atol=k_atol,
                    ours=ours)


def _warm_up(pb: _Problem, peer_names: list[str]) -> Callable:
    """Scipy's right-hand side, once every solver is loaded (compiled) off the clock."""
    # compile / load everything first (scipy_rhs compiles its rhs before returning)
    warm = min(pb.t_end_s, 0.01)
    simulate_ode(pb.top, pb.fr, pb.init, t_end_s=warm, options=pb.opts)
    run_reference_kernel(pb.y0, pb.p, warm, pb.k_rtol, pb.k_atol, method=pb.method.name)
    for name in peer_names:
        run_numbalsoda(name, pb.y0, pb.p, warm, pb.rtol, pb.atol)
    return scipy_rhs(pb.top, pb.fr, "vector")


def _run_rounds(pb: _Problem, peer_names: list[str], fun: Callable, rounds: int,
                scipy_rounds: int) -> tuple[dict[str, float], dict[str, Any]]:
    """Each solver's best CPU time over the rounds, and the run that made it."""
    best: dict[str, float] = {}
    runs: dict[str, Any] = {}

    def keep(name: str, s: float, run: object) -> None:
        if s < best.get(name, math.inf):
            best[name] = s
            runs[name] = run

    y0, p, t_end_s, rtol, atol = pb.y0, pb.p, pb.t_end_s, pb.rtol, pb.atol
    for r in range(rounds):
        order = [pb.ours, "simulate", *peer_names]
        shift = r % len(order)  # alternate who goes first
        for name in order[shift:] + order[:shift]:
            if name == pb.ours:
                run = run_reference_kernel(y0, p, t_end_s, pb.k_rtol, pb.k_atol,
                                           method=pb.method.name)
                keep(name, run.s, run)
            elif name == "simulate":
                t0 = time.process_time()
                res = simulate_ode(pb.top, pb.fr, pb.init, t_end_s=t_end_s, sample_dt_s=t_end_s,
                                   options=pb.opts)
                keep(name, time.process_time() - t0, res)
            else:
                run = run_numbalsoda(name, y0, p, t_end_s, rtol, atol)
                keep(name, run.s, run)
        if r < scipy_rounds:
            s, sol = _scipy_run(fun, y0, t_end_s, rtol, atol)
            keep(SCIPY, s, sol)
    return best, runs


def _baselines(ours: str, best: dict[str, float], runs: dict[str, Any]) -> _Baselines:
    """The kernel's, simulate_ode's and scipy's best runs, their times and final thetas."""
    kernel = runs[ours]
    res = runs["simulate"]
    sol = runs[SCIPY]
    t_kernel = best[ours]
    t_ours = best["simulate"]
    t_scipy = best[SCIPY]
    theta_kernel = _theta_of_vector_state(kernel.y_final)
    theta_ours = float(res.table["theta"].iloc[-1])
    theta_scipy = _theta_of_vector_state(sol.y[:, -1])
    ratio = t_scipy / t_ours
    dtheta = abs(theta_ours - theta_scipy)
    return _Baselines(kernel=kernel, res=res, sol=sol, t_kernel=t_kernel, t_ours=t_ours,
                      t_scipy=t_scipy, theta_kernel=theta_kernel, theta_ours=theta_ours,
                      theta_scipy=theta_scipy, ratio=ratio, dtheta=dtheta)


def _peer_at_rtol(run: PeerRun, s: float, base: _Baselines) -> dict:
    """A numbalsoda peer's entry at the shared rtol: its time, count and final theta."""
    theta = _theta_of_vector_state(run.y_final)
    diff = abs(theta - base.theta_kernel)
    return {
        "s": s, "n_rhs": run.n_rhs, "theta_final": theta,
        "theta_abs_diff": diff, "success": run.success,
        "equal_accuracy": bool(run.success and diff <= EQUAL_ACCURACY_RAD),
        "ratio": s / base.t_kernel,
    }


def _peer_frontier(pb: _Problem, name: str, rounds: int, theta_truth: float, our_err: float,
                   t_kernel: float) -> dict:
    """A numbalsoda peer's frontier over :data:`PEER_SWEEP_RTOLS`, and its time at our error."""
    pts = []
    for r_ in PEER_SWEEP_RTOLS:
        runs_ = [run_numbalsoda(name, pb.y0, pb.p, pb.t_end_s, r_, ATOL_PER_RTOL * r_)
                 for _ in range(rounds)]
        if all(x.success for x in runs_):
            err = abs(_theta_of_vector_state(runs_[0].y_final) - theta_truth)
            pts.append({"rtol": r_, "s": min(x.s for x in runs_), "theta_err": err})
    t_eq = time_at_error([(q["theta_err"], q["s"]) for q in pts], our_err)
    return {"sweep": pts, "s_at_equal_error": t_eq, "equal_accuracy": t_eq is not None,
            "ratio_at_equal_error": None if t_eq is None else t_eq / t_kernel}


def _compare_peers(pb: _Problem, peer_names: list[str], best: dict[str, float],
                   runs: dict[str, Any], base: _Baselines, rounds: int) -> dict:
    """The peers' entry of the result: each peer at the shared rtol and at our error."""
    t_kernel, theta_kernel = base.t_kernel, base.theta_kernel
    solvers = {name: _peer_at_rtol(runs[name], best[name], base) for name in peer_names}
    # equal achieved error: each peer's time at our error, on its own frontier
    truth = run_reference_kernel(pb.y0, pb.p, pb.t_end_s, TRUTH_RTOL,
                                 ATOL_PER_RTOL * TRUTH_RTOL)
    theta_truth = _theta_of_vector_state(truth.y_final)
    our_err = max(abs(theta_kernel - theta_truth), ERROR_FLOOR)
    for name in peer_names:
        solvers[name].update(_peer_frontier(pb, name, rounds, theta_truth, our_err, t_kernel))
    names = list(peer_names)
    if heyoka_missing() is None and unsupported(pb.p) is None:
        # heyoka's Taylor method: the same equations in its own expressions (taylor_peer)
        solvers[HEYOKA] = _heyoka_solver(pb.p, pb.y0, pb.t_end_s, pb.rtol, rounds, theta_kernel,
                                         theta_truth, our_err, t_kernel)
        names.append(HEYOKA)
    equal = [n for n in names if solvers[n]["equal_accuracy"]]
    best_peer = min(equal, key=lambda n: solvers[n]["s_at_equal_error"]) if equal else None
    return {
        "solvers": solvers, "equal_accuracy_rad": EQUAL_ACCURACY_RAD,
        "best_equal_accuracy": best_peer,
        "not_equal_accuracy": [n for n in names if not solvers[n]["equal_accuracy"]],
        "theta_truth": theta_truth, "truth_rtol": TRUTH_RTOL,
        "ours_theta_err": our_err,
        "equal_error": "each peer's time at the reference's achieved |theta(t_end) - truth|,"
                       " log-log interpolated on its frontier over a sweep of rtol "
                       f"{PEER_SWEEP_RTOLS[0]:g}..{PEER_SWEEP_RTOLS[-1]:g}",
    }


def bench_ode(n0: float = 60.0, t_end_s: float = 60.0, rtol: float = 1e-9,
              atol: float = 1e-12, rounds: int = 5, scipy_rounds: int = 1) -> BenchOdeResult:
    """Fig. 11 top: the reference's default method against its peers and scipy, at equal error.

    Every solver integrates the same compiled right-hand side (vector formulation, the paper's
    friction) from the same state to ``t_end_s``: the kernel of the reference's default method
    (``ode.method = auto`` resolved at ``rtol``: the method and the tolerances it runs at, one
    call, as :func:`simulate_ode` makes it; ``method``, ``method_rtol`` in the result),
    numbalsoda's DOP853 and LSODA through a
    cfunc (if numbalsoda is installed: ``pip install -e '.[peers]'``), and
    ``scipy.integrate.solve_ivp(method="DOP853")`` calling it from its Python step loop. The
    solvers take turns over ``rounds`` rounds (scipy in the first ``scipy_rounds`` only: it
    is ~60x slower, and its noise does not move its ratio); each keeps its best CPU time.
    Everything is loaded (compiled) before the first round.

    Returns:
        The times, evaluation counts, final thetas and ratios, and the printed ``report``
        (:class:`BenchOdeResult`).
        ``ours_s`` is the whole :func:`simulate_ode` call (the observables table included),
        ``ours_kernel_s`` the kernel's; ``speedup`` is scipy's time over ``ours_s``,
        ``speedup_vs_best_peer`` the fastest peer's time at tippetop's achieved error
        (|theta(t_end) - truth|, the truth the kernel at :data:`TRUTH_RTOL`; each peer's time
        there log-log interpolated on its frontier over :data:`PEER_SWEEP_RTOLS`, best of the
        rounds) over ``ours_kernel_s`` (None when no peer reaches that error). A peer's
        ``equal_accuracy``: it reaches it; ``theta_abs_diff`` is still its distance from
        tippetop at the shared rtol.
    """
    rounds = max(1, int(rounds))
    scipy_rounds = min(max(1, int(scipy_rounds)), rounds)
    pb = _problem(n0, t_end_s, rtol, atol)
    missing = numbalsoda_missing()
    peer_names = list(NUMBALSODA_METHODS) if missing is None else []
    fun = _warm_up(pb, peer_names)
    best, runs = _run_rounds(pb, peer_names, fun, rounds, scipy_rounds)
    base = _baselines(pb.ours, best, runs)
    t_kernel, t_ours, t_scipy = base.t_kernel, base.t_ours, base.t_scipy
    kernel, res, sol = base.kernel, base.res, base.sol

    peers: dict = {"available": missing is None}
    best_peer = None
    if missing is not None:
        peers["reason"] = missing
    else:
        peers.update(_compare_peers(pb, peer_names, best, runs, base, rounds))
        best_peer = peers["best_equal_accuracy"]
    vs_peer = (peers["solvers"][best_peer]["s_at_equal_error"] / t_kernel if best_peer
               else None)
    out = BenchOdeResult(
        n0=n0, t_end_s=t_end_s, rtol=rtol, atol=atol,
        method=pb.method.name, method_rtol=pb.k_rtol, method_atol=pb.k_atol,
        timing="CPU time (time.process_time), best of the rounds",
        rounds=rounds, scipy_rounds=scipy_rounds,
        ours_s=t_ours, ours_n_rhs=res.n_rhs,
        ours_kernel_s=t_kernel, ours_kernel_n_rhs=kernel.n_rhs,
        theta_final_kernel=base.theta_kernel,
        scipy_s=t_scipy, scipy_n_rhs=int(sol.nfev),
        speedup=base.ratio, theta_final_ours=base.theta_ours,
        theta_final_scipy=base.theta_scipy,
        theta_final_abs_diff=base.dtheta,
        ours_ns_per_rhs=1e9 * t_ours / res.n_rhs,
        scipy_ns_per_rhs=1e9 * t_scipy / sol.nfev,
        target_speedup_met=base.ratio >= TARGET_SPEEDUP,
        target_theta_met=base.dtheta <= TARGET_THETA_AGREEMENT,
        peers=peers,
        speedup_vs_best_peer=vs_peer,
        best_peer=best_peer,
        target_vs_peer_met=None if vs_peer is None else vs_peer >= TARGET_VS_PEER,
    )
    return replace(out, report=bench_ode_report(out))


__all__ = ["EQUAL_ACCURACY_RAD", "MOONSHOT_VS_PEER", "PEER_SWEEP_RTOLS", "SCIPY",
           "TARGET_SPEEDUP", "TARGET_THETA_AGREEMENT", "TARGET_VS_PEER", "TRUTH_RTOL",
           "BenchOdeResult", "bench_ode"]
