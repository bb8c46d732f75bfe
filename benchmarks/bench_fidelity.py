"""The fidelity map's cost: ``tippetop fidelity --grid small`` timed point by point.

One run of the small grid (2 A/C x 2 a/R x 2 mu = 8 points, every group of the paper at mu
0.1 and 1), neither reading nor writing the run cache nor the tunings' (``use_cache=False``:
every reference run, fit and verification is computed). Printed: each point's wall time, fit
rollouts and answer, their mean and total, and the default grid's cost estimated from them
(its point count x the mean per point: the points cost alike within a factor of about two,
the fit's horizon following each top's first event).

Run: ``python benchmarks/bench_fidelity.py [--grid small] [--t-end-s 8] [--budget-runs 200]
[--workers N] [--json] [--out DIR]``. Measured 2026-11-27 (docs/guide/fidelity.md): the default
grid in 1821 s (30.3 min, 101 s a point) on 2 cores also running the test suite; ``--out DIR``
writes the map as ``tippetop fidelity --out`` does (docs/data/fidelity-default.json is that
run's results.json).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time


def main() -> int:
    """Run the grid and print the per-point cost."""
    from pathlib import Path

    from tippetop.compare.commands.fidelity import (
        DEFAULT_BUDGET_RUNS,
        table_lines,
        write_fidelity,
    )
    from tippetop.compare.running.io import check_output_dir
    from tippetop.compare.studies.fidelity import (
        DEFAULT_GRID,
        DEFAULT_T_END_S,
        GRIDS,
        make_grid,
        run_fidelity,
    )

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="small")
    ap.add_argument("--t-end-s", dest="t_end_s", type=float, default=DEFAULT_T_END_S)
    ap.add_argument("--budget-runs", dest="budget_runs", type=int, default=DEFAULT_BUDGET_RUNS)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", metavar="DIR", default=None,
                    help="also write the map (results.json, fidelity.png, report.html) here, "
                         "as `tippetop fidelity --out DIR` does (new or empty folder)")
    args = ap.parse_args()
    grid = make_grid(args.grid)
    out_dir = check_output_dir(args.out, force=False) if args.out else None
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    res = run_fidelity(grid, t_end_s=args.t_end_s, workers=args.workers, use_cache=False,
                       budget_runs=args.budget_runs, progress=True)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    res["budget_runs"] = args.budget_runs
    if out_dir is not None:
        write_fidelity(res, Path(out_dir))
    pts = res["points"]
    mean = sum(p["wall_s"] for p in pts) / len(pts)
    default_n = len(GRIDS[DEFAULT_GRID].points())
    out = {"grid": res["grid"], "cores": os.cpu_count(), "t_end_s": args.t_end_s,
           "budget_runs": args.budget_runs, "wall_s": wall, "main_process_cpu_s": cpu,
           "mean_point_s": mean, "default_grid_points": default_n,
           "default_grid_estimate_s": default_n * mean,
           "points": [{k: p[k] for k in ("A_over_C", "a_over_R", "mu", "group", "agrees",
                                         "residual", "runs", "wall_s", "cause")}
                      for p in pts]}
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"grid {grid.name} ({len(pts)} points), t_end {args.t_end_s:g} s, --budget-runs "
          f"{args.budget_runs}, {os.cpu_count()} cores, no cache")
    print(f"{'A/C':>5} {'a/R':>5} {'mu':>4} {'group':>5} {'agrees':>6} {'rollouts':>8} "
          f"{'wall s':>7}")
    for p in pts:
        print(f"{p['A_over_C']:>5.3g} {p['a_over_R']:>5.3g} {p['mu']:>4.3g} {p['group']:>5} "
              f"{'yes' if p['agrees'] else 'no':>6} {p['runs'] or 0:>8} {p['wall_s']:>7.0f}")
    print("the command's table (tippetop fidelity --grid " + grid.name + "):")
    for line in table_lines(res):
        print(line)
    print(f"total {wall:.0f} s ({wall / 60:.1f} min); mean {mean:.0f} s a point; the default "
          f"grid ({default_n} points) about {default_n * mean / 60:.0f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
