"""What ``tippetop bench ode`` prints: the solvers' times and ratios, or the sweep's tables."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from tippetop.compare.results.bench import (
    MOONSHOT_VS_PEER,
    SCIPY,
    TARGET_SPEEDUP,
    TARGET_THETA_AGREEMENT,
    TARGET_VS_PEER,
    BenchOdeResult,
)
from tippetop.compare.results.work_precision import (
    TARGET_RATIO,
    WorkPrecisionResult,
    WorkPrecisionTop,
)

#: Each metric's title in the tables and the figures.
METRIC_TITLES = {"theta": "theta(t_end) error (rad)", "t_invert": "t_invert error (s)",
                 "J_drift": "Jellett's drift |J/J0 - 1|"}


# ---------------------------------------------------------------- bench ode
def _row(res: BenchOdeResult, name: str, s: float, n_rhs: int, theta: float | None,
         note: str = "") -> str:
    """A solver's line of the report, its ratio and |dtheta| against the kernel's."""
    d = "" if theta is None else f"{abs(theta - res.theta_final_kernel):9.1e}"
    ratio = s / res.ours_kernel_s
    return f"  {name:<24s} {s:9.4f} {n_rhs:>9,d} {ratio:8.2f}  {d:>9s}  {note}".rstrip()


def _header_lines(res: BenchOdeResult) -> list[str]:
    """The report's title, its column heads and the kernel's (baseline) row."""
    return [
        f"reference ODE benchmark: Fig. 11 top (A/C = 1, a/R = 0.15), n0 = {res.n0:g} rad/s, "
        f"{res.t_end_s:g} s simulated, rtol = {res.rtol:g}, atol = {res.atol:g}; one compiled "
        f"right-hand side; CPU time, best of {res.rounds} round(s) (solvers alternated; scipy: "
        f"{res.scipy_rounds}); the reference's default (ode.method = auto) at this rtol runs "
        f"{res.method} at rtol {res.method_rtol:g}, atol {res.method_atol:g}",
        f"  {'solver':<24s} {'s':>9s} {'n_rhs':>9s} {'ratio':>8s}  {'|dtheta|':>9s}",
        _row(res, res.ours, res.ours_kernel_s, res.ours_kernel_n_rhs, None,
             "(baseline: one kernel call)"),
    ]


def _peer_lines(res: BenchOdeResult) -> list[str]:
    """The report's lines of the peers, or the one saying why they did not run."""
    if not res.peers["available"]:
        return [f"  numbalsoda peers: not run ({res.peers['reason']})"]
    lines = []
    for name, sv in res.peers["solvers"].items():
        note = (f"{sv['s_at_equal_error']:.4f} s at our error" if sv["equal_accuracy"]
                else "does not reach our error at any rtol of its sweep")
        lines.append(_row(res, name, sv["s"], sv["n_rhs"], sv["theta_final"], note))
    return lines


def _vs_peer_line(res: BenchOdeResult) -> str:
    """The report's line of the speed-up against the fastest peer at our error."""
    peers, best_peer, vs_peer = res.peers, res.best_peer, res.speedup_vs_best_peer
    if not peers["available"]:
        return "  speed-up vs the best peer: not measured (numbalsoda is not installed)"
    if best_peer is None or vs_peer is None:
        return ("  speed-up vs the best peer: no peer reaches our error "
                f"({peers['ours_theta_err']:.1e} rad against the truth)")
    return (f"  speed-up vs the fastest peer at equal achieved error ({best_peer}, at our "
            f"{peers['ours_theta_err']:.1e} rad): {vs_peer:.2f} x "
            f"(peer time / tippetop's; target >= {TARGET_VS_PEER:g} x: "
            f"{'met' if vs_peer >= TARGET_VS_PEER else 'NOT met'}; moonshot "
            f"{MOONSHOT_VS_PEER:g} x: {'met' if vs_peer >= MOONSHOT_VS_PEER else 'not met'})")


def _scipy_lines(res: BenchOdeResult) -> list[str]:
    """The report's closing lines: simulate_ode against scipy, and the cost of an evaluation."""
    ratio, dtheta = res.speedup, res.theta_final_abs_diff
    per = "jet (a Taylor step)" if res.method == "taylor" else "rhs evaluation"
    lines = [
        f"  tippetop simulate_ode     {res.ours_s:9.4f} s (the whole call, observables table "
        f"included), n_rhs = {res.ours_n_rhs:,d}",
        f"  speed-up vs scipy         {ratio:9.1f} x   (scipy / simulate_ode; target >= "
        f"{TARGET_SPEEDUP:g} x: {'met' if ratio >= TARGET_SPEEDUP else 'NOT met'})",
        f"  final theta               {res.theta_final_ours:.10f} vs "
        f"{res.theta_final_scipy:.10f} rad, "
        f"|diff| = {dtheta:.2e} (target <= {TARGET_THETA_AGREEMENT:g}: "
        f"{'met' if dtheta <= TARGET_THETA_AGREEMENT else 'NOT met'})",
        f"  per {per:<22s}{1e9 * res.ours_kernel_s / res.ours_kernel_n_rhs:9.1f} ns (kernel) vs "
        f"{res.scipy_ns_per_rhs:.1f} ns per rhs evaluation (scipy) "
        "(whole run / n_rhs)",
    ]
    if res.method == "taylor":
        lines.append("  (the Taylor method's n_rhs counts its jets, one a step: a jet is the "
                     "whole series of the step, not one evaluation)")
    return lines


def bench_ode_report(res: BenchOdeResult) -> str:
    """The printed report of ``bench ode``: a row per solver, then the ratios and targets."""
    return "\n".join([
        *_header_lines(res),
        *_peer_lines(res),
        _row(res, SCIPY, res.scipy_s, res.scipy_n_rhs, res.theta_final_scipy),
        _vs_peer_line(res),
        *_scipy_lines(res),
    ])


def print_bench_ode(res: BenchOdeResult) -> None:
    """``bench ode``'s report, as the study wrote it."""
    print(res.report or bench_ode_report(res))


# ---------------------------------------------------------------- bench ode --sweep
def format_ratio(r: float | str | None) -> str:
    """A ratio for a table: ``1.35x``, ``inf`` (no peer reaches), ``-`` (we do not).

    The JSON's ``"inf"`` reads as inf.
    """
    if r is None:
        return "-"
    return "inf" if r == "inf" or math.isinf(float(r)) else f"{r:.2f}x"


def _level_cells(row: Mapping, solvers: Sequence[str], width: int) -> list[str]:
    """A level's cells: each solver's time (ms) there, or its smallest error (not reached)."""
    cells = []
    for s in solvers:
        t = row["times"].get(s)
        if t is not None:
            cells.append(f"{1e3 * t:>{width - 3}.2f} ms")
        else:
            e = row["smallest"].get(s)
            cells.append(f"{'n/r' if e is None else f'n/r {e:.0e}':>{width}s}")
    return cells


def level_table(title: str, unit: str, rows: Sequence[Mapping], solvers: Sequence[str],
                cancelled: Mapping[str, Sequence[float]] | None = None) -> str:
    """The printed table: rows = levels, columns = solvers' times (ms), then the ratios.

    Rows with ``ratio_steady`` (the ratio without cancellations) get that column too, and
    ``cancelled`` (per solver, the rtols set aside) is listed under the table.
    """
    width = max(11, *(len(s) for s in solvers)) if solvers else 11
    head = f"  {'level':>9s}  " + " ".join(f"{s:>{width}s}" for s in solvers)
    steady = any("ratio_steady" in r for r in rows)
    lines = [title, head + f"  {'peer/ref':>9s} {'peer/auto':>9s}"
             + (f" {'steady':>9s}" if steady else "") + f"  target >= {TARGET_RATIO:g}x"]
    for row in rows:
        cells = _level_cells(row, solvers, width)
        verdict = "met" if row["met"] else "NOT met"
        if row["ratio"] is not None and row["met"] != row["met_auto"]:
            verdict += f" (auto: {'met' if row['met_auto'] else 'NOT met'})"
        if steady and not row["met"] and row.get("met_steady"):
            verdict += " (met without cancellations)"
        lines.append(f"  {row['level']:>7.0e} {unit:<2s} " + " ".join(cells)
                     + f"  {format_ratio(row['ratio']):>9s} {format_ratio(row['ratio_auto']):>9s}"
                     + (f" {format_ratio(row.get('ratio_steady')):>9s}" if steady else "")
                     + f"  {verdict}")
    lines.append("  (ms of CPU time at the level, on each solver's frontier; n/r = not reached, "
                 "with the smallest error reached; peer/ref = the fastest peer's time over the "
                 "fastest reference method's" + ("; steady = the same with every solver's "
                                                  "cancellations set aside" if steady else "")
                 + ")")
    if cancelled:
        lines.append("  cancellations (an error below the next tighter rtol's), set aside in "
                     "steady: " + "; ".join(f"{n} at rtol {', '.join(f'{r:g}' for r in rs)}"
                                           for n, rs in cancelled.items()))
    return "\n".join(lines)


def _truth_lines(top: WorkPrecisionTop) -> list[str]:
    """The top's title and its truth: theta(t_end), and t_invert where it inverts."""
    tr = top.truth
    lines = [f"== {top.name}: {top.title}, {top.t_end_s:g} s simulated",
             f"  truth: {tr['methods'][0]} vs {tr['methods'][1]} at rtol {tr['rtol']:g} "
             f"(law throughout): theta(t_end) = {tr['theta']:.15f} rad, |diff| = "
             f"{tr['theta_diff']:.1e} rad"]
    if tr["t_invert"] is None:
        lines.append("  the top does not invert within t_end: no t_invert table")
    else:
        loc = tr.get("t_invert_locate_err")
        lines.append(f"  t_invert = {tr['t_invert']:.12f} s, |diff| = {tr['t_invert_diff']:.1e}"
                     " s; " + ("the peers' inversion located from samples: not measured (no "
                               "peer)" if loc is None else
                               f"the peers' inversion located from samples to about {loc:.0e} "
                               f"s (spline on {tr['locator']}'s dense output, 201 vs 101 "
                               "samples)"))
    return lines


def top_report(top: WorkPrecisionTop, slow_peers: Mapping[str, tuple[int, float]]) -> str:
    """The printed tables of one top.

    Args:
        top: The top's sweep.
        slow_peers: Per Python-driven peer, the tolerances it runs of the full sweep and its
            CPU-time budget (s): one that ran fewer stopped over its budget.
    """
    lines = _truth_lines(top)
    for n, why in top.skipped.items():
        lines.append(f"  skipped {n}: {why}")
    solvers = list(top.solvers)
    for n, sv in top.solvers.items():
        stopped = [p for p in sv["points"] if p["status"] != "ok"]
        if stopped:
            p = stopped[0]
            lines.append(f"  {n}: stopped at rtol {p['rtol']:g} ({p['status']})")
        elif n in slow_peers and sv["points"] and len(sv["points"]) < slow_peers[n][0]:
            lines.append(f"  {n}: stopped after rtol {sv['points'][-1]['rtol']:g} (over its "
                         f"{slow_peers[n][1]:g} s budget)")
    for n, sv in top.solvers.items():
        said = [p for p in sv["points"] if p.get("printed")]
        if said:
            lines.append(f"  {n}: its compiled code printed {sum(p['printed'] for p in said)} "
                         f"line(s) at {len(said)} of its {len(sv['points'])} tolerances, kept "
                         "off the terminal (Hairer's DOP853: \"the problem seems to become "
                         "stiff\"; the run goes on)")
    if top.stiff:
        lines.append("  (the reference runs its rolling phases where the law is stiff; the "
                     "truth and the peers integrate the law: the reference's error includes "
                     "the rolling phases' modelling error)")
    for metric, lv in top.levels.items():
        lines.append(level_table(f"  {METRIC_TITLES[metric]}", lv["unit"], lv["rows"],
                                 solvers, lv.get("cancellations")))
    return "\n".join(lines)


def work_precision_report(res: WorkPrecisionResult,
                          slow_peers: Mapping[str, tuple[int, float]]) -> str:
    """The printed report of ``bench ode --sweep`` (``report.txt``): a head, then each top's.

    Args:
        res: The benchmark.
        slow_peers: As :func:`top_report`'s.
    """
    head = (f"work-precision benchmark: every solver's error against a converged truth, "
            f"rtol {max(res.tolerances):g}..{min(res.tolerances):g}, atol = 1e-3 rtol; CPU "
            f"time, best of {res.rounds} round(s), {res.short_rounds} for a run under "
            f"{res.short_s * 1e3:g} ms (the Python-driven peers: 1 round, every other rtol; the "
            f"reference: the integration's CPU time inside simulate_ode, OdeResult.cpu_s, "
            f"without its fixed ~3 ms of table building); "
            f"the reference = its fastest method at each level (target: the fastest peer >= "
            f"{res.target_ratio:g}x the reference's time)")
    return "\n\n".join([head, *(top_report(t, slow_peers) for t in res.tops.values()),
                        f"({res.elapsed_s:.0f} s wall for the whole benchmark)"])


def print_work_precision(res: WorkPrecisionResult,
                         slow_peers: Mapping[str, tuple[int, float]]) -> None:
    """``bench ode --sweep``'s report (what ``report.txt`` holds)."""
    print(work_precision_report(res, slow_peers))


__all__ = ["METRIC_TITLES", "bench_ode_report", "format_ratio", "level_table",
           "print_bench_ode", "print_work_precision", "top_report", "work_precision_report"]
