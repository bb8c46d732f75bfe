"""``tippetop calibrate``: fit MuJoCo's native contact settings to the reference ODE."""

from __future__ import annotations

import argparse

from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_parallel_options,
    number,
    print_json,
)
from tippetop.compare.studies.defaults import DEFAULT_T_END_S
from tippetop.compare.tuning import TUNE_BUDGET_RUNS
from tippetop.compare.tuning.calibrate.config import (
    DEFAULT_BUDGET_RUNS,
    DEFAULT_CALIBRATION,
    DEFAULT_HOLDOUT,
    DEFAULT_INTEGRATOR,
    DEFAULT_OUT,
    DEFAULT_TIMESTEP_S,
    CalibrateConfig,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop calibrate`` and its options."""
    p = sub.add_parser(
        "calibrate", help="fit MuJoCo's native contact settings to the reference ODE",
        description="Fit mu, cone, impratio, solref and solimp of MuJoCo's native friction to "
        "the reference ODE on calibration scenes, report residuals on held-out scenes, and "
        "write the settings with their provenance.")
    p.add_argument("--calibration", default=DEFAULT_CALIBRATION, metavar="SCENES",
                   help=f"scenes fitted, NAME[:T_END_S],... with T_END_S the simulated time "
                   f"(s) (default {DEFAULT_CALIBRATION})")
    p.add_argument("--holdout", default=DEFAULT_HOLDOUT, metavar="SCENES",
                   help=f"scenes only reported, NAME[:T_END_S],... (default {DEFAULT_HOLDOUT})")
    p.add_argument("--out", default=str(DEFAULT_OUT), metavar="FILE",
                   help="the calibration file (.toml; default models/calibrated_native.toml)")
    add_force_option(p)
    p.add_argument("--budget-runs", dest="budget_runs", type=int, default=None,
                   metavar="N", help=f"runs the search may use, candidates times scenes; "
                   f"with --search sysid it sets the fits' iterations (runs / (12 x scenes)), "
                   f"and the "
                   f"rollouts used are reported, not capped (default {DEFAULT_BUDGET_RUNS}); "
                   f"with --mjcf the MuJoCo runs the tuning may use, seeds, fits and "
                   f"verification, after which it ends with its best so far, verified and "
                   f"labelled budget-limited (at least 5; default {TUNE_BUDGET_RUNS})")
    p.add_argument("--timestep-s", dest="timestep_s", type=number, default=DEFAULT_TIMESTEP_S,
                   metavar="S", help=f"MuJoCo timestep of the fit (s; default "
                   f"{DEFAULT_TIMESTEP_S:g})")
    p.add_argument("--integrator", default=DEFAULT_INTEGRATOR, metavar="NAME",
                   help=f"MuJoCo integrator of the fit: Euler, implicit, implicitfast or RK4 "
                   f"(default {DEFAULT_INTEGRATOR})")
    p.add_argument("--search", default="sysid", metavar="NAME", help="sysid (MuJoCo's "
                   "identification, mujoco.sysid; the default) or compass (the hand-written "
                   "grid and compass search, kept to compare)")
    p.add_argument("--mjcf", metavar="FILE", help="tune this MJCF top's own contact settings "
                   "instead: fitted to the reference at the file's start and verified from "
                   "held-out starts, printed as MJCF (validate's 'tuned', without the report; "
                   "nothing is written; default: none, the paper's calibration)")
    p.add_argument("--t-end-s", dest="t_end_s", type=number, default=None, metavar="S",
                   help=f"with --mjcf: simulated time of the verification runs (s; default "
                   f"{DEFAULT_T_END_S:g}, validate's)")
    add_parallel_options(p)
    add_json_option(p, help="print the report as one JSON object instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop calibrate``: run, write the file, print the report.

    With ``--mjcf FILE``: tune the file's own settings (exit 0 if they agree from every
    start, 1 if a check departs).
    """
    if args.mjcf is not None:
        return run_mjcf(args)
    config = CalibrateConfig(
        calibration=args.calibration, holdout=args.holdout, out=args.out, force=args.force,
        budget_runs=DEFAULT_BUDGET_RUNS if args.budget_runs is None else args.budget_runs,
        timestep_s=args.timestep_s, integrator=args.integrator,
        scheduler=args.scheduler, workers=args.workers, use_cache=not args.no_cache,
        progress=not args.json, search=args.search)
    from tippetop.compare.tuning.calibrate.run import calibrate

    report = calibrate(config)
    if args.json:
        print_json(report)
    else:
        from tippetop.compare.presentation.calibrate import print_report

        print_report(report)
    return 0


def run_mjcf(args: argparse.Namespace) -> int:
    """``tippetop calibrate --mjcf FILE``: the file's contact settings tuned and verified."""
    import math
    import os
    from pathlib import Path

    from tippetop.compare.commands.validate import check_budget_runs
    from tippetop.compare.studies.validate import tune_only
    from tippetop.models.errors import expect

    t_end = DEFAULT_T_END_S if args.t_end_s is None else args.t_end_s
    expect(math.isfinite(t_end) and 0 < t_end <= 600, "--t-end-s",
           "a number of seconds in (0, 600]", t_end)
    budget = TUNE_BUDGET_RUNS if args.budget_runs is None else args.budget_runs
    check_budget_runs(budget)
    res = tune_only(Path(os.path.abspath(args.mjcf)), t_end, scheduler=args.scheduler,
                    workers=args.workers, use_cache=not args.no_cache, progress=not args.json,
                    budget_runs=budget)
    if args.json:
        print_json(res.to_json())
    else:
        from tippetop.compare.presentation.validate import print_tune_only

        print_tune_only(res)
    return 0 if res.tuned.agrees else 1
