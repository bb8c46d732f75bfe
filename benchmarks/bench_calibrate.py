"""The calibration's two searches, old against new, on the shipped calibration set (issue 22).

In one run, neither reading nor writing the results cache (nothing reused between them):

* ``compass`` (the baseline): the hand-written grid (24 candidates) and compass search that
  wrote ``models/calibrated_native.toml``, at its budget of 160 runs;
* ``sysid``: MuJoCo's own identification (``mujoco.sysid``,
  :mod:`tippetop.compare.tuning.calibrate.identify`) from the shipped settings and MuJoCo's
  defaults, at the same ``--budget-runs``.

Both on the shipped calibration set (``fig3:6,fig11_n070:6``) and scored the same way: the
objective of the best settings on the calibration scenes and on the 8 held-out scenes (the
provenance's ``objective`` and ``holdout_objective``, through the harness's own runs), the
runs each search used (harness runs for compass; MuJoCo rollouts for sysid) and the wall time.
Printed as a table and as ratios new / old.

Run: ``python benchmarks/bench_calibrate.py [--budget-runs 160] [--calibration ...]
[--holdout ...] [--json]``. About 15 min on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


def one(search: str, args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """One calibration with ``search`` into ``folder``, the results cache left alone."""
    from tippetop.compare.tuning.calibrate.config import CalibrateConfig
    from tippetop.compare.tuning.calibrate.run import calibrate

    config = CalibrateConfig(calibration=args.calibration, holdout=args.holdout,
                             out=folder / f"{search}.toml", budget_runs=args.budget_runs,
                             use_cache=False, progress=False, search=search)
    t0 = time.perf_counter()
    rep = calibrate(config)
    wall = time.perf_counter() - t0
    p = rep["provenance"]
    return {"search": search, "settings": rep["settings"], "objective": p["objective"],
            "holdout_objective": p["holdout_objective"], "runs": p["runs_used"],
            "runs_computed": p["runs_computed"], "wall_s": wall,
            "objective_mujoco_defaults": p["objective_mujoco_defaults"]}


def main() -> int:
    """Run both searches and print the comparison."""
    from tippetop.compare.tuning.calibrate.config import (
        DEFAULT_BUDGET_RUNS,
        DEFAULT_CALIBRATION,
        DEFAULT_HOLDOUT,
    )

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget-runs", type=int, default=DEFAULT_BUDGET_RUNS)
    ap.add_argument("--calibration", default=DEFAULT_CALIBRATION)
    ap.add_argument("--holdout", default=DEFAULT_HOLDOUT)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-calibrate-") as tmp:
        rows = []
        for search in ("compass", "sysid"):
            folder = Path(tmp) / search
            folder.mkdir()
            rows.append(one(search, args, folder))
    old, new = rows
    ratios = {k: new[k] / old[k] for k in ("objective", "holdout_objective", "runs", "wall_s")}
    if args.json:
        print(json.dumps({"old": old, "new": new, "ratios_new_over_old": ratios}, indent=1))
        return 0
    print(f"calibration set {args.calibration}, held out {args.holdout}, --budget-runs "
          f"{args.budget_runs}")
    print(f"{'search':<8} {'objective':>9} {'held-out':>9} {'runs':>5} {'wall s':>7}  settings")
    for r in rows:
        s = r["settings"]
        print(f"{r['search']:<8} {r['objective']:>9.4f} {r['holdout_objective']:>9.4f} "
              f"{r['runs']:>5} {r['wall_s']:>7.0f}  {s['cone']} impratio={s['impratio']:g} "
              f"solref={s['solref']} d0={s['solimp'][0]:g} mu={s['mu']:g}")
    print("new / old: " + ", ".join(f"{k} {v:.2f}x" for k, v in ratios.items()))
    print(f"(MuJoCo's defaults score {old['objective_mujoco_defaults']:.3f} on the calibration "
          "set)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
