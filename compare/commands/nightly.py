"""``tippetop nightly``: the regression suite, with its report; ``python -m ...nightly``.

The nightly (:mod:`tippetop.compare.nightly`) runs and checks; the report
(:mod:`tippetop.compare.report`) draws; this command composes the two (:func:`write_report`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tippetop.compare.commands.history import add_history_options
from tippetop.compare.commands.options import (
    Parser,
    add_force_option,
    add_scheduler_option,
    add_workers_option,
    comma_list,
    run_main,
)
from tippetop.models.engines import FAMILIES


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop nightly`` and its options."""
    p = sub.add_parser(
        "nightly", help="the regression suite: catalogue vs stored baselines; exit 1 on "
        "regression",
        description="Run the nightly catalogue (models/nightly.toml), compare every metric with "
        "the stored baselines, write results.json, junit.xml and report.html into --out, and "
        "exit 1 on any regression.")
    p.add_argument("--profile", default="quick", help="a profile of the catalogue: quick, "
                   "every paper scene, a few minutes on 2 cores; full, both MuJoCo modes and "
                   "every sweep, up to an hour; stress, hard cases (default quick)")
    p.add_argument("--baseline", metavar="DIR", help="folder of <profile>.json baselines "
                   "(default: compare/baselines in the repository)")
    p.add_argument("--update-baseline", dest="update_baseline", action="store_true",
                   help="store this run's values as the baselines (the only way they change)")
    p.add_argument("--no-baseline", dest="no_baseline", action="store_true",
                   help="run with no baseline on purpose: every check is new, nothing is "
                   "compared (default: off; a missing baseline file is an error, exit 2)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: a new "
                   "nightly-YYYYMMDD-HHMMSS in the current folder)")
    add_force_option(p, help="write into a non-empty --out")
    p.add_argument("--engines", default=",".join(FAMILIES), metavar="ENGINE,...",
                   help="comma-separated engines: ode (the reference) and the MuJoCo engines "
                   "the catalogue's MuJoCo cases run on: mujoco (the installed one), "
                   "mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32, warp; each MuJoCo engine keeps "
                   "its own baseline file, <profile>@<engine>.json beside <profile>.json "
                   f"(default: {','.join(FAMILIES)})")
    p.add_argument("--modes", metavar="MODE,...", help="only the cases in these comma-"
                   "separated modes, e.g. paper or native,native-condim4 (default: every mode "
                   "of the catalogue)")
    p.add_argument("--cases", metavar="GLOBS", help="only case ids matching these "
                   "comma-separated globs, e.g. 'paper/*[ode/*]' (default: every case of the "
                   "profile)")
    p.add_argument("--catalogue", metavar="FILE", help="catalogue file (default: "
                   "models/nightly.toml)")
    p.add_argument("--models", nargs="+", metavar="FILE", help="MJCF tops to run with the "
                   "profile's cases, each as case models/<file's stem>, in the modes file and "
                   "paper (or --modes) on every engine that can run them, compared with its "
                   "baseline like the catalogue's cases; --cases 'models/*' runs them alone "
                   "(default: none)")
    add_scheduler_option(p)
    add_workers_option(p)
    add_history_options(p, "this run's values, engine versions, commit and machine")
    p.add_argument("--cache", action="store_true", help="reuse the shared run cache (default: "
                   "recompute every run)")
    p.add_argument("--videos", action="store_true", help="also render a short side-by-side "
                   "video of each paper scene (MuJoCo | reference), linked from the report")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", metavar="DIR", help="folder of "
                   "accuracy-versus-cost figures and Pareto tables to embed in the report, as "
                   "'tippetop bench accuracy --out DIR' writes them (default: none)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop nightly``: build the :class:`NightlyOptions` and run them, with the report."""
    from tippetop.compare.nightly.baselines import BASELINE_DIR
    from tippetop.compare.nightly.suite import NightlyOptions, run_nightly
    from tippetop.models.modes import parse_modes

    opts = NightlyOptions(
        profile=args.profile, catalogue=Path(args.catalogue) if args.catalogue else None,
        baseline_dir=Path(args.baseline) if args.baseline else BASELINE_DIR,
        update_baseline=args.update_baseline, no_baseline=args.no_baseline, out=args.out,
        force=args.force,
        engines=comma_list(args.engines), cases=comma_list(args.cases or ""),
        modes=tuple(parse_modes(args.modes)) if args.modes else (),
        scheduler=args.scheduler, workers=args.workers, cache=args.cache, videos=args.videos,
        accuracy_dir=Path(args.accuracy_dir) if args.accuracy_dir else None,
        history=Path(args.history) if args.history else None, no_history=args.no_history,
        models=tuple(args.models or ()),
        argv=tuple(getattr(args, "_argv", ()) or sys.argv[2:]))
    return run_nightly(opts, write_report=write_report)


def write_report(results: Mapping[str, Any], path: Path, tables: Mapping[str, Any],
                 accuracy_dir: Path | None) -> None:
    """The nightly's ``report.html``: :func:`tippetop.compare.report.build.build_report`."""
    from tippetop.compare.report.build import build_report

    build_report(results, path, tables=tables, accuracy_dir=accuracy_dir)


def main(argv: list[str] | None = None) -> int:
    """``tippetop nightly [options]`` as a function of its arguments (for tests and tools)."""
    parser = Parser(prog="tippetop")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    add_parser(sub)
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(["nightly", *argv])
    args._argv = argv
    return run_main(args)
