"""``tippetop calibrate``: the parser and the command; the work is in :mod:`.run`.

Imports only what building the parser needs: ``tippetop --help`` and ``tippetop theory`` do not
pay for the calibration's dependencies.
"""

from __future__ import annotations

import argparse
from typing import Any

from tippetop.compare.analysis.calibrate.config import (
    DEFAULT_BUDGET_RUNS,
    DEFAULT_CALIBRATION,
    DEFAULT_HOLDOUT,
    DEFAULT_INTEGRATOR,
    DEFAULT_OUT,
    DEFAULT_TIMESTEP_S,
    CalibrateConfig,
)
from tippetop.compare.common_args import (
    add_force_option,
    add_json_option,
    add_parallel_options,
    number,
    print_json,
)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``tippetop calibrate``: run, write the file, print the report."""
    config = CalibrateConfig(
        calibration=args.calibration, holdout=args.holdout, out=args.out, force=args.force,
        budget_runs=args.budget_runs, timestep_s=args.timestep_s, integrator=args.integrator,
        scheduler=args.scheduler, workers=args.workers, use_cache=not args.no_cache,
        progress=not args.json)
    from tippetop.compare.analysis.calibrate.output import print_report
    from tippetop.compare.analysis.calibrate.run import calibrate

    report = calibrate(config)
    if args.json:
        print_json(report)
    else:
        print_report(report)
    return 0


def add_calibrate_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``calibrate`` subcommand to ``tippetop``'s subparsers.

    Args:
        subparsers: The object ``ArgumentParser.add_subparsers`` returned.

    Returns:
        The new subparser (its ``func`` default is :func:`cmd_calibrate`).
    """
    c = subparsers.add_parser(
        "calibrate", help="fit MuJoCo's native contact settings to the reference ODE",
        description="Fit mu, cone, impratio, solref and solimp of MuJoCo's native friction to "
        "the reference ODE on calibration scenes, report residuals on held-out scenes, and "
        "write the settings with their provenance.")
    c.add_argument("--calibration", default=DEFAULT_CALIBRATION, metavar="SCENES",
                   help=f"scenes fitted, NAME[:T_END_S],... with T_END_S the simulated time "
                   f"(s) (default {DEFAULT_CALIBRATION})")
    c.add_argument("--holdout", default=DEFAULT_HOLDOUT, metavar="SCENES",
                   help=f"scenes only reported, NAME[:T_END_S],... (default {DEFAULT_HOLDOUT})")
    c.add_argument("--out", default=str(DEFAULT_OUT), metavar="FILE",
                   help="the calibration file (.toml; default models/calibrated_native.toml)")
    add_force_option(c)
    c.add_argument("--budget-runs", dest="budget_runs", type=int, default=DEFAULT_BUDGET_RUNS,
                   metavar="N", help=f"runs the search may use, candidates times scenes "
                   f"(default {DEFAULT_BUDGET_RUNS})")
    c.add_argument("--timestep-s", dest="timestep_s", type=number, default=DEFAULT_TIMESTEP_S,
                   metavar="S", help=f"MuJoCo timestep of the fit (s; default "
                   f"{DEFAULT_TIMESTEP_S:g})")
    c.add_argument("--integrator", default=DEFAULT_INTEGRATOR, metavar="NAME",
                   help=f"MuJoCo integrator of the fit: Euler, implicit, implicitfast or RK4 "
                   f"(default {DEFAULT_INTEGRATOR})")
    add_parallel_options(c)
    add_json_option(c, help="print the report as one JSON object instead of text")
    c.set_defaults(func=cmd_calibrate)
    return c
