"""``tippetop threshold``: a critical spin measured in an engine, against the theory."""

from __future__ import annotations

import argparse
import sys
from typing import Any

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
from tippetop.compare.presentation.terminal import cache_line, fmt, fmt_percent, table


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
        print_json(res)
    else:
        print_threshold(res)
        print(cache_line(None, None, not args.no_cache))
        if files:
            print("wrote " + ", ".join(str(f) for f in files))
    if res.get("failed_runs"):  # every run is reported above; the failure in one line
        sys.stderr.write(f"tippetop: run failed: {res['warning']}\n")
        return EXIT_RUN_FAILED
    return 0


def _write_threshold(res: dict[str, Any], out: Any) -> list[Any]:
    """``threshold.json`` (the ``--json`` result) and ``runs.csv`` (every run) into ``out``."""
    import csv

    from tippetop.compare.running.io import staged_output_dir

    names = ["threshold.json", "runs.csv"]
    with staged_output_dir(out) as stage:  # all files or none
        (stage / names[0]).write_text(json_text(res, indent=1) + "\n", "utf-8")
        runs = [{k: v for k, v in r.items() if not isinstance(v, (list, dict))}
                for r in res.get("runs") or []]  # nested values stay in threshold.json
        cols = list(dict.fromkeys(k for r in runs for k in r)) or ["n0"]
        with open(stage / names[1], "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            w.writeheader()
            w.writerows(runs)
    return [out / n for n in names]


#: Where the theory's value of each threshold comes from.
THRESHOLD_THEORY = {"n1": "eq. 4.13", "n4": "n3 (1 + a/R) / (1 - a/R)",
                    "nc": "Sec. 4.3: n4, or n1 for A/C <= rc"}


def print_threshold(res: dict[str, Any]) -> None:
    """A measured critical spin for a person.

    The measured spin against the theory's, how it was measured (growth rates or a
    bisection), the check at twice the horizon (bisection), and a warning when the answer is
    not to be trusted.
    """
    which = res.get("which", "?")
    horizon = res.get("horizon_s")
    method = res.get("method", "bisect")
    runs = res.get("runs") or []
    n_runs = res.get("n_runs", len(runs))
    if method == "growth":
        how = f"from growth rates of {n_runs} runs of {fmt(horizon, 's')} near the steady state"
    else:
        how = f"by bisection on n0 over {n_runs} runs of {fmt(horizon, 's')}"
    print(f"{which} of {res.get('scene', '?')} on {res.get('engine', '?')} in mode "
          f"{res.get('mode', '?')}, {how}:")
    bracket = res.get("bracket") or [None, None]
    rows = [
        ("measured", fmt(res.get("measured"), "rad/s"),
         f"bracket {fmt(bracket[0])} to {fmt(bracket[-1], 'rad/s')}"),
        ("theory", fmt(res.get("theory"), "rad/s"), THRESHOLD_THEORY.get(which, "")),
        ("difference", fmt_percent(res.get("rel_diff")), "measured / theory - 1"),
    ]
    if which == "nc" and method == "growth":
        rows += [(k, fmt(res.get(k), "rad/s"), "measured") for k in ("n1", "n4")
                 if k in res]
    print(table(("", "value", ""), rows, indent="  ", header=False))
    check = res.get("horizon_check")
    if isinstance(check, dict):
        h2 = fmt(check.get("horizon_s"), "s")
        if check.get("depends_on_horizon"):
            print(f"  horizon check: over {h2} the bracket's ends change side")
        else:
            print(f"  horizon check: over {h2} the bracket's ends keep their side")
    if method == "growth" and "settled" in res:
        print("  fits: " + ("every run is two modes, cleanly" if res["settled"] else
                            "some runs are not two clean modes (see runs in --json)"))
    elif res.get("unsettled_n0"):
        print("  still moving at the end of their runs: n0 = "
              + ", ".join(fmt(n) for n in res["unsettled_n0"]) + " rad/s")
    conv = res.get("converged")
    if conv is not None:
        why = []
        if res.get("bracket_converged") is False:
            why.append("the bracket is wider than --rel-tol after the rounds allowed")
        if res.get("depends_on_horizon"):
            why.append("the answer depends on the run length")
        if method == "growth" and res.get("settled") is False:
            why.append("a fit is not clean")
        print(f"  converged: {fmt(conv)}" + (f" ({'; '.join(why)})" if why and not conv
                                              else ""))
    if res.get("warning"):
        print(f"  warning: {res['warning']}")
