"""``tippetop threshold``: a critical spin measured in an engine, against the theory."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from tippetop.compare.commands.options import (
    EXIT_RUN_FAILED,
    add_engine_option,
    add_force_option,
    add_json_option,
    add_mode_option,
    add_parallel_options,
    add_set_option,
    engine_and_mode,
    finite_float,
    json_text,
    print_json,
    set_overrides,
)
from tippetop.compare.presentation.terminal import cache_line

if TYPE_CHECKING:
    from tippetop.compare.results.threshold import ThresholdResult


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop threshold`` and its options."""
    p = sub.add_parser("threshold", help="measure n1, n4 or nc on an engine, against the "
                       "theory",
                       description="Measure a critical spin in an engine's own dynamics (in a "
                       "mode) and compare it with the theory: by default from growth rates "
                       "(short runs started 0.01 rad from the upright or inverted state; the "
                       "spin where "
                       "the tilt stops decaying), or by bisection on n0 over full runs (their "
                       "final states; the bracket's ends are rerun over twice the horizon).")
    p.add_argument("scene", nargs="?", help="scene (default: fig11_n060, the Fig. 9 (a) top "
                   "from theta0 = 0.01 over 60 s)")
    add_engine_option(p)
    add_mode_option(p)
    p.add_argument("--which", required=True, choices=("n1", "n4", "nc"),
                   help="n1: the spin above which theta = 0 is unstable; n4: the spin at "
                   "theta = 0 that keeps the inverted state stable; nc: the spin above which "
                   "a Group II top inverts fully, max(n1, n4) (no default: required)")
    p.add_argument("--method", choices=("growth", "bisect"), default=None,
                   help="growth: the zero of the steady state's growth rate, from 2-s runs "
                   "(any of n1, n4, nc); bisect: the outcome of runs over the scene's "
                   "run.t_end_s (n1 or nc) (default growth)")
    add_set_option(p)
    p.add_argument("--rel-tol", dest="rel_tol", type=finite_float, default=None,
                   metavar="REL", help="stop when the spin is known to this, relative "
                   "(default 1e-5 for growth, 0.005, i.e. 0.5 %%, for bisect)")
    p.add_argument("--out", metavar="DIR", help="folder for threshold.json (the --json "
                   "result) and runs.csv (every n0 run), new or empty, or --force (default: "
                   "none, printed only)")
    add_force_option(p, help="write into a non-empty --out")
    add_parallel_options(p)
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop threshold``: n1 or nc by bisection on n0; ``--out`` writes the runs."""
    from tippetop.compare.presentation.threshold import print_threshold
    from tippetop.compare.studies.threshold import measure_threshold

    out_dir = None
    if getattr(args, "out", None):
        from tippetop.compare.running.io import check_output_dir, hold_output_lock

        out_dir = check_output_dir(args.out, force=args.force)
        hold_output_lock(out_dir)  # a second run into it is refused now, not mixed in later
    method = {"method": args.method} if getattr(args, "method", None) else {}
    spec, mode, extra = engine_and_mode(args)
    res = measure_threshold(args.scene, spec.spec, args.which, (*extra, *set_overrides(args)),
                            rel_tol=args.rel_tol, scheduler=args.scheduler,
                            workers=args.workers, use_cache=not args.no_cache, mode=mode,
                            **method)
    files = _write_threshold(res, out_dir) if out_dir is not None else []
    if args.json:
        print_json(res.to_json())
    else:
        print_threshold(res)
        print(cache_line(None, None, not args.no_cache))
        if files:
            print("wrote " + ", ".join(str(f) for f in files))
    if res.failed_runs:  # every run is reported above; the failure in one line
        sys.stderr.write(f"tippetop: run failed: {res.warning}\n")
        return EXIT_RUN_FAILED
    return 0


def _write_threshold(res: ThresholdResult, out: Any) -> list[Any]:
    """``threshold.json`` (the ``--json`` result) and ``runs.csv`` (every run) into ``out``."""
    import csv

    from tippetop.compare.running.io import staged_output_dir

    names = ["threshold.json", "runs.csv"]
    with staged_output_dir(out) as stage:  # all files or none
        (stage / names[0]).write_text(json_text(res.to_json(), indent=1) + "\n", "utf-8")
        runs = [{k: v for k, v in r.items() if not isinstance(v, (list, dict))}
                for r in res.runs]  # nested values stay in threshold.json
        cols = list(dict.fromkeys(k for r in runs for k in r)) or ["n0"]
        with open(stage / names[1], "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            w.writeheader()
            w.writerows(runs)
    return [out / n for n in names]

