"""``tippetop sweep``: theta_asymp against n0 per mode, with the theory's theta_s(n0)."""

from __future__ import annotations

import argparse
import sys

from tippetop.compare.commands.options import (
    ENGINE_HELP,
    EXIT_RUN_FAILED,
    MODE_HELP,
    add_force_option,
    add_json_option,
    add_parallel_options,
    add_set_option,
    print_json,
    set_overrides,
)
from tippetop.compare.presentation.terminal import cache_line
from tippetop.models.errors import TippetopError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop sweep`` and its options."""
    p = sub.add_parser("sweep", help="theta_asymp against n0 per engine and mode, with "
                       "theta_s(n0)",
                       description="theta_asymp against the initial spin n0 on each engine in "
                       "each mode, with the theory's theta_s(n0) (the paper's Figs. 9, 10). "
                       "Every pairing of --engines and --modes that can run is swept.")
    p.add_argument("scene", help="scene .toml file or catalogue name (required)")
    p.add_argument("--n0", required=True, metavar="START:STOP:STEP",
                   help="initial spins, rad/s; STOP is included when it falls on the grid, "
                   "at most 2000 points (no default: required)")
    p.add_argument("--engines", metavar="ENGINE,...", help="comma-separated engines: "
                   + ENGINE_HELP.removeprefix("the engine that integrates the run: ")
                   + " (default: ode)")
    p.add_argument("--modes", metavar="MODE,...", help="comma-separated modes: "
                   + MODE_HELP.removeprefix("the mode, how the contact force is made: ")
                   + " (default: paper)")
    add_set_option(p)
    p.add_argument("--out", metavar="DIR", help="folder for sweep.csv, theory.csv and "
                   "sweep.png (default: none, printed only)")
    add_force_option(p, help="overwrite results in --out")
    add_parallel_options(p)
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop sweep``: theta_asymp against n0 per mode, optionally written to ``--out``."""
    from pathlib import Path

    from tippetop.compare.commands.options import engines_and_modes
    from tippetop.compare.presentation.figures import sweep_figure
    from tippetop.compare.presentation.sweep import print_sweep
    from tippetop.compare.running.io import check_writable, hold_output_lock, write_atomic
    from tippetop.compare.studies.sweep import parse_range, run_sweep

    n0s = parse_range(args.n0)
    runs = engines_and_modes(args, engines="ode", modes="paper")
    out_dir = None
    if args.out:
        out_dir = Path(args.out)
        files = [out_dir / "sweep.csv", out_dir / "theory.csv", out_dir / "sweep.png"]
        if out_dir.exists() and not out_dir.is_dir():
            raise TippetopError(f"--out: expected a folder, got the file {str(out_dir)!r}")
        if any(f.exists() for f in files) and not args.force:
            raise TippetopError(f"--out: expected a folder without sweep results (or --force), "
                                f"got {str(out_dir)!r} which has them")
        base = out_dir if out_dir.is_dir() else out_dir.parent
        if not base.is_dir():
            raise TippetopError(f"--out: expected an existing parent folder, got {str(base)!r}")
        check_writable(base)  # before the runs, not after them
        hold_output_lock(out_dir)  # a second sweep into it is refused now
    res = run_sweep(args.scene, n0s, runs, set_overrides(args), scheduler=args.scheduler,
                    workers=args.workers, use_cache=not args.no_cache)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(files[0], lambda tmp: res.table.to_csv(tmp, index=False))
        write_atomic(files[1], lambda tmp: res.theory.to_csv(tmp, index=False))
        sweep_figure(res, files[2])
    if args.json:
        print_json(res.to_json())
    else:
        print_sweep(res)
        print(cache_line(res.computed, res.cached, not args.no_cache))
        if out_dir is not None:
            print("wrote " + ", ".join(str(f) for f in files))
        else:
            print("not written: --out DIR writes sweep.csv, theory.csv and sweep.png")
    # a failed run is a row with its status (the others kept), and the command exits 1
    failed = res.failed()
    if len(failed):
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(res.table)} runs failed "
                         f"({', '.join(sorted(set(failed['status'])))}); each is a row with "
                         "its status\n")
        return EXIT_RUN_FAILED
    return 0
