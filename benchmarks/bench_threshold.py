"""n1 in MuJoCo's paper mode: growth rates against a bisection, in one run, on the same top.

Both measure n1 of the Fig. 9 (a) top (theory 34.35 rad/s) in MuJoCo with the paper's law at
the same timestep, with the run cache off so every run is computed:

* growth: :func:`tippetop.compare.studies.growth.measure_growth`, 2-s runs started 0.01 rad
  from the spinning upright state, false position on the zero of the growth rate (``rel_tol`` 1e-5);
* bisect: :func:`tippetop.compare.studies.threshold.bisect_threshold`, full runs over a horizon
  (default 20 s, as the nightly's quick profile) to a 0.5 % bracket, the bracket's ends run
  again over twice the horizon.

It prints each method's answer, its error against the theory, its runs, simulated seconds and
wall time, and the ratio growth / bisect of the wall times (target: at most 0.25 with n1
within 0.5 % of the theory).

Run: ``python benchmarks/bench_threshold.py [--timestep-s 1e-4] [--horizon-s 20] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import time

from tippetop.compare.running.options import RunOptions
from tippetop.compare.studies.growth import measure_growth
from tippetop.compare.studies.threshold import BisectOptions, bisect_threshold


def main() -> None:
    """Run both methods and print the comparison."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--timestep-s", type=float, default=1e-4, help="MuJoCo timestep (s), "
                   "default 1e-4 (paper mode within 3e-4 rad of 1.25e-5 s on this top)")
    p.add_argument("--horizon-s", type=float, default=20.0, help="the bisection's run length "
                   "(s), default 20")
    p.add_argument("--workers", type=int, default=2, help="worker processes, default 2")
    args = p.parse_args()
    over = ("mujoco.friction=paper", f"mujoco.timestep_s={args.timestep_s!r}")
    rows = []
    t0 = time.perf_counter()
    run = RunOptions(workers=args.workers, use_cache=False)
    g = measure_growth(None, "mujoco", "n1", over, run=run)
    rows.append(("growth", g, time.perf_counter() - t0, g.n_runs * g.horizon_s))
    t0 = time.perf_counter()
    b = bisect_threshold(None, "mujoco", "n1", (*over, f"run.t_end_s={args.horizon_s!r}"),
                         search=BisectOptions(rel_tol=0.005), run=run)
    extra = 2 * 2 * args.horizon_s  # the horizon check: two runs over twice the horizon
    rows.append(("bisect", b, time.perf_counter() - t0, b.n_runs * args.horizon_s + extra))
    print(f"n1 of the Fig. 9 (a) top in MuJoCo paper mode, dt = {args.timestep_s:g} s "
          f"(theory {g.theory:.5f} rad/s)")
    print(f"{'method':8s} {'n1 (rad/s)':>12s} {'vs theory':>10s} {'runs':>5s} "
          f"{'sim s':>7s} {'wall s':>7s}")
    for name, res, wall, sim in rows:
        print(f"{name:8s} {res.measured:12.5f} {100 * res.rel_diff:+9.4f}% "
              f"{res.n_runs:5d} {sim:7.0f} {wall:7.1f}")
    ratio = rows[0][2] / rows[1][2]
    print(f"wall time growth / bisect: {ratio:.3f} (target <= 0.25); growth within "
          f"{100 * abs(g.rel_diff):.4f} % of the theory (target <= 0.5 %)")


if __name__ == "__main__":
    main()
