"""``tippetop validate MODEL.xml``: an MJCF top against the theory and the reference."""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_parallel_options,
    finite_float,
    print_json,
)
from tippetop.compare.studies.defaults import DEFAULT_T_END_S
from tippetop.compare.tuning import TUNE_BUDGET_RUNS

EXIT_AGREES, EXIT_DEPARTS = 0, 1


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop validate`` and its options."""
    p = sub.add_parser(
        "validate", help="the model-validation report of your own MJCF top",
        description="Run an MJCF top as its file says, in the reference ODE (with the file's "
        "mu and stem), with the paper's law in the same model, and with the calibrated native "
        "settings; check each against the theory and the reference; write report.html, "
        "results.json and the tables into --out. Exit 1 if a check departs.")
    p.add_argument("model", help="the MJCF file of the top (required)")
    p.add_argument("--out", metavar="DIR", help="folder for report.html, results.json and "
                   "tables/ (new or empty, or --force; default: none, printed only)")
    p.add_argument("--t-end-s", dest="t_end_s", type=finite_float, default=DEFAULT_T_END_S,
                   metavar="S", help=f"simulated time of every run (s; default "
                   f"{DEFAULT_T_END_S:g})")
    p.add_argument("--keyframe", metavar="NAME", help="start from this keyframe of the file "
                   "(default: its first)")
    p.add_argument("--engines", default="mujoco", metavar="SPEC,SPEC,...", help="the engines "
                   "the MuJoCo runs run on: mujoco (the installed one), mujoco==X.Y.Z, "
                   "mujoco@PYTHON, mjx, mjx-f32, warp; each runs the file and the paper's "
                   "law, named ENGINE/MODE (mujoco==3.3.7/file); the reference ode/paper "
                   "always runs (default: mujoco)")
    p.add_argument("--no-tune", dest="tune", action="store_false", help="skip the tuning: "
                   "the file's contact settings fitted to the reference at its start and "
                   "verified from held-out starts (the results' 'tuned')")
    p.add_argument("--budget-runs", dest="budget_runs", type=int, default=TUNE_BUDGET_RUNS,
                   metavar="N", help="MuJoCo runs the tuning may use (its seeds, its fits' "
                   "rollouts, its verification runs); where they run out it ends with its best "
                   "so far, verified and labelled budget-limited; one in three is kept for "
                   "the widening where the fits depart (the answer with one choice changed, a "
                   "fit again, then draws about the best so far: docs/guide/tuning.md) (at "
                   f"least 5; default {TUNE_BUDGET_RUNS}: the paper's top takes about 60)")
    add_force_option(p, help="write into a non-empty --out")
    add_parallel_options(p)
    add_json_option(p)
    p.set_defaults(func=run)


def check_budget_runs(n: int) -> None:
    """``--budget-runs`` of the tuning: at least one seed scored and every start verified."""
    from tippetop.compare.tuning.tune import min_budget_runs
    from tippetop.models.errors import expect

    expect(n >= min_budget_runs(), "--budget-runs", f"at least {min_budget_runs()} MuJoCo "
           "runs (one seed scored, then every start verified)", n)


def run(args: argparse.Namespace) -> int:
    """``tippetop validate``: run, write the report folder, print the verdict.

    Exit status 0 when every check agrees, 1 when one departs (2: bad input).
    """
    from tippetop.compare.running.io import check_output_dir, staged_output_dir, write_table
    from tippetop.compare.studies.validate import ValidateConfig, validate
    from tippetop.models.engines import parse_engines

    engines = tuple(e.spec for e in parse_engines(args.engines, mujoco_only=True))
    check_budget_runs(args.budget_runs)

    out = check_output_dir(args.out, force=args.force) if args.out else None
    if out is not None:
        from tippetop.compare.running.io import hold_output_lock

        hold_output_lock(out)
    config = ValidateConfig(model=Path(os.path.abspath(args.model)), t_end_s=args.t_end_s,
                            keyframe=args.keyframe, scheduler=args.scheduler,
                            workers=args.workers, use_cache=not args.no_cache,
                            engines=engines, tune=args.tune, progress=not args.json,
                            budget_runs=args.budget_runs)
    res = validate(config)
    if out is not None:
        from tippetop.compare.report.validate import render
        from tippetop.compare.running.io import json_ready

        text = json.dumps(json_ready(res.to_json()), indent=1) + "\n"
        html = render(res)
        with staged_output_dir(out) as stage:  # all files or none, even on Ctrl-C
            (stage / "tables").mkdir()
            for mode, table in res.tables.items():
                # a run's name holds a "/" (ENGINE/MODE), and an engine may hold a path
                name = re.sub(r"[^A-Za-z0-9._=@+-]", "_", mode)
                write_table(table, stage / "tables" / f"{name}.csv")
            (stage / "results.json").write_text(text, "utf-8")
            (stage / "report.html").write_text(html, "utf-8")
    if args.json:
        print_json(res.to_json())
    else:
        from tippetop.compare.presentation.validate import print_validate

        print_validate(res, out)
    sys.stdout.flush()
    return EXIT_AGREES if res.agrees else EXIT_DEPARTS
