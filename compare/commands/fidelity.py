"""``tippetop fidelity``: where MuJoCo's own contact, tuned, follows the paper's law."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from tippetop.compare.commands.options import (
    NO_CACHE_HELP,
    add_force_option,
    add_json_option,
    add_scheduler_option,
    add_workers_option,
    engine_spec,
    json_text,
    number,
    print_json,
)
from tippetop.compare.tuning import TUNE_BUDGET_RUNS

if TYPE_CHECKING:
    from tippetop.compare.results.fidelity import FidelityResult

#: ``--budget-runs``'s default: validate's (the runs one point's tuning may use).
DEFAULT_BUDGET_RUNS = TUNE_BUDGET_RUNS
#: The files ``--out`` holds.
OUT_FILES = ("results.json", "fidelity.png", "report.html")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop fidelity`` and its options."""
    from tippetop.compare.studies.defaults import DEFAULT_GRID, DEFAULT_T_END_S, GRIDS

    grids = ", ".join(f"'{n}' is A/C {','.join(f'{v:g}' for v in g.A_over_C)} x a/R "
                      f"{','.join(f'{v:g}' for v in g.a_over_R)} x mu "
                      f"{','.join(f'{v:g}' for v in g.mu)}" for n, g in GRIDS.items())
    p = sub.add_parser(
        "fidelity", help="the fidelity map: where MuJoCo's own contact, tuned to the "
        "reference, follows the paper's law over a grid of tops and mu, and why not",
        description="At every point of a grid of tops (A/C, a/R: the paper's Groups I, II, "
        "III) and friction coefficients mu, fit MuJoCo's native contact to the reference and "
        "verify it from held-out starts, as 'tippetop validate' tunes a file; print one row "
        "per point (agrees, the fit's residual, and the cause where it does not). The points are "
        "tuned several at once (--workers), or one task each on a Dask cluster (--scheduler); "
        "the default grid took 14.4 minutes on 2 cores, two points at once, 7-413 s a point "
        "(docs/guide/fidelity.md, 'Cost').")
    p.add_argument("--grid", default=DEFAULT_GRID, metavar="NAME",
                   help=f"a named grid of A/C x a/R x mu ({grids}) (default: the one named "
                   f"{DEFAULT_GRID})")
    p.add_argument("--a-over-c", "--A-over-C", dest="A_over_C", metavar="LIST",
                   help="A/C values, comma-separated or LO:HI:N, replacing the grid's "
                   "(default: the grid's)")
    p.add_argument("--a-over-r", "--a-over-R", dest="a_over_R", metavar="LIST",
                   help="a/R values in (0, 1), comma-separated or LO:HI:N, replacing the "
                   "grid's (default: the grid's)")
    p.add_argument("--mu", metavar="LIST", help="friction coefficients mu (relative: the "
                   "law's, > 0), comma-separated, replacing the grid's (default: the grid's)")
    p.add_argument("--t-end-s", dest="t_end_s", type=number, default=DEFAULT_T_END_S,
                   metavar="S", help=f"simulated time of each verification run (s; default "
                   f"{DEFAULT_T_END_S:g}, validate's)")
    p.add_argument("--budget-runs", dest="budget_runs", type=int, default=DEFAULT_BUDGET_RUNS,
                   metavar="N", help=f"MuJoCo runs each point's tuning may use, its fit's "
                   f"rollouts and its verification together: a point that reaches it ends with "
                   f"its best so far, verified and labelled (default {DEFAULT_BUDGET_RUNS}, "
                   f"validate's)")
    p.add_argument("--engine", type=engine_spec, default="mujoco", metavar="ENGINE",
                   help="the MuJoCo engine tuned: mujoco, the MuJoCo installed with tippetop "
                   "(the tuning fits with its mujoco.sysid; other engines are not tuned yet) "
                   "(default mujoco)")
    p.add_argument("--out", metavar="DIR", help="folder for results.json, fidelity.png and "
                   "report.html, new or empty, or --force (default: none, printed only)")
    add_force_option(p, help="write into a non-empty --out")
    add_scheduler_option(p)
    add_workers_option(p, help="points tuned at once on this machine (processes), each in a "
                       "process of its own (default: all cores; 1: one point at a time in this "
                       "process). "
                       "With --scheduler every point is one task on the cluster, its whole "
                       "tuning there")
    p.add_argument("--no-cache", action="store_true", help=NO_CACHE_HELP)
    add_json_option(p, help="print {points: [{A_over_C, a_over_R, mu, group, agrees, "
                    "settings, residual, cause, ...}], grid, agreement, engine, ...} as JSON "
                    "instead of the table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop fidelity``: tune and verify at every point, print or write the map (exit 0).

    A point that does not agree is a finding, printed and written, not a failure.
    """
    import math

    from tippetop.compare.presentation.fidelity import print_fidelity
    from tippetop.compare.studies.fidelity import make_grid, run_fidelity
    from tippetop.compare.tuning.tune import min_budget_runs
    from tippetop.models.engines import parse_engine
    from tippetop.models.errors import TippetopError

    grid = make_grid(args.grid, args.A_over_C, args.a_over_R, args.mu)
    if not (math.isfinite(args.t_end_s) and 0 < args.t_end_s <= 600):
        raise TippetopError(f"--t-end-s: expected a number of seconds in (0, 600], got "
                            f"{args.t_end_s:g}")
    if args.budget_runs < min_budget_runs():
        raise TippetopError(f"--budget-runs: expected at least {min_budget_runs()} MuJoCo runs "
                            f"(one seed scored, then every start verified), got "
                            f"{args.budget_runs}")
    engine = parse_engine(args.engine)
    if engine.spec != "mujoco":
        raise TippetopError(f"--engine: expected mujoco (the MuJoCo installed with tippetop: "
                            f"the tuning fits with its mujoco.sysid), got {args.engine!r}")
    out_dir = None
    if args.out:
        from tippetop.compare.running.io import check_output_dir, hold_output_lock

        out_dir = check_output_dir(args.out, force=args.force)  # before any run
        hold_output_lock(out_dir)
    res = run_fidelity(grid, t_end_s=args.t_end_s, scheduler=args.scheduler,
                       workers=args.workers, use_cache=not args.no_cache,
                       budget_runs=args.budget_runs,
                       progress=not args.json)
    files = write_fidelity(res, out_dir) if out_dir is not None else []
    if args.json:
        print_json(res.to_json())
    else:
        print_fidelity(res)
        if files:
            print("wrote " + ", ".join(str(f) for f in files))
    return 0


def write_fidelity(res: FidelityResult, out_dir: Path) -> list[Path]:
    """Write results.json, fidelity.png and report.html into ``out_dir``, all or nothing.

    The folder is checked (new, empty or ``--force``) by the caller before the work.
    """
    from tippetop.compare.presentation.figures import pyplot
    from tippetop.compare.report.fidelity import fidelity_figure, report_page
    from tippetop.compare.running.io import staged_output_dir

    data = res.to_json()  # the page and the figure read the map's JSON
    with staged_output_dir(Path(out_dir)) as tmp:
        (tmp / "results.json").write_text(json_text(data, indent=1), encoding="utf-8")
        fig = fidelity_figure(data)
        fig.savefig(tmp / "fidelity.png", dpi=110)
        pyplot().close(fig)
        (tmp / "report.html").write_text(report_page(data), encoding="utf-8")
    return [Path(out_dir) / n for n in OUT_FILES]
