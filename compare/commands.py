"""The bodies of the ``tippetop`` commands theory, simulate, compare, threshold, sweep, bench.

Each ``cmd_x(args)`` reads its parsed arguments, calls the function that does the work with
plain values, prints the result (text, or one JSON object with ``--json``) and returns the exit
status. Their parsers are in :mod:`tippetop.compare.cli`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from tippetop.compare.common_args import EXIT_RUN_FAILED, comma_list, print_json
from tippetop.models.errors import TippetopError


def _print_human(d: dict[str, Any]) -> None:
    width = max(len(k) for k in d)
    for k, v in d.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        print(f"{k:<{width}}  {v}")


# ---------------------------------------------------------------- theory
def cmd_theory(args: argparse.Namespace) -> int:
    """``tippetop theory``: the paper's predictions for a top."""
    from tippetop.compare import theory
    from tippetop.models.params import TopParams

    extra: dict[str, Any] = {}
    if args.mjcf:
        from tippetop.mujoco_runner.model import top_from_mjcf_file

        top = top_from_mjcf_file(args.mjcf)
        extra = {"R_m": top.R_m, "a_m": top.a_m, "A": top.A_kgm2, "C": top.C_kgm2,
                 "M_kg": top.M_kg, "A_over_C": top.A_over_C, "a_over_R": top.a_over_R}
    else:
        if args.A_over_C is None or args.a_over_R is None:
            raise TippetopError("theory: expected --A-over-C and --a-over-R (or --mjcf FILE), "
                                "got neither")
        top = TopParams.from_ratios(args.A_over_C, args.a_over_R, args.C_factor,
                                    R_m=args.R_m, M_kg=args.M_kg, g_mps2=args.g_mps2)
    out = theory.summary(top, n0=args.n0)
    out.update(extra)
    if args.json:
        print_json(out)
    else:
        _print_human(out)
    return 0


# ---------------------------------------------------------------- simulate
def _load(args: argparse.Namespace):
    from tippetop.models.scene import load_scene

    overrides = list(args.set or [])
    if getattr(args, "mjcf", None):
        # relative to the working folder, not to the scene file
        overrides.append(f"top.mjcf={json.dumps(os.path.abspath(args.mjcf))}")
    if getattr(args, "keyframe", None):
        overrides.append(f"init.keyframe={json.dumps(args.keyframe)}")
    return load_scene(args.scene, overrides)


def cmd_simulate(args: argparse.Namespace) -> int:
    """``tippetop simulate``: one scene in one engine; exit 1 when the run failed."""
    from tippetop.compare.engines import run_engine
    from tippetop.compare.io import TABLE_SUFFIXES, check_output_path, write_table

    scene = _load(args)
    out_path = None
    target = args.out or scene.outputs.table
    if target:
        if not args.out and scene.path is not None:
            target = str(scene.path.parent / target)
        out_path = check_output_path(target, force=args.force, suffixes=TABLE_SUFFIXES)
    run = run_engine(scene, args.engine)
    failed = run.status not in ("ok", "contact_lost", "hop")
    if out_path is not None and not failed:
        write_table(run.table, out_path)
    if args.json:
        print_json(run.summary)
    else:
        _print_human({"scene": scene.name, **run.summary})
    if failed:
        sys.stderr.write(f"tippetop: run failed: {run.message}\n")
        return EXIT_RUN_FAILED
    return 0


# ---------------------------------------------------------------- bench
def cmd_bench(args: argparse.Namespace) -> int:
    """``tippetop bench ode`` or ``tippetop bench accuracy``."""
    if args.what == "accuracy":
        from tippetop.compare.accuracy import (
            DEFAULT_BUDGET_S,
            DEFAULT_MUJOCO_BUDGET_S,
            run_accuracy,
        )

        engines = list(comma_list(args.engines))
        if args.budget_s is not None and args.budget_s <= 0:
            raise TippetopError(f"--budget-s: expected a number > 0, got {args.budget_s}")
        res = run_accuracy([args.scene] if args.scene else ["fig3", "fig11_n060"],
                           args.out or "accuracy", force=args.force, engines=engines,
                           budget_s=args.budget_s or DEFAULT_BUDGET_S,
                           mujoco_budget_s=args.budget_s or DEFAULT_MUJOCO_BUDGET_S,
                           workers=args.workers,
                           log=None if args.json else (lambda m: print(m, file=sys.stderr)))
        if args.json:
            print_json({k: v for k, v in res.items() if k != "report"})
        else:
            print(res["report"])
        return 0
    from tippetop.compare.bench import bench_ode

    if args.what != "ode":
        raise TippetopError(f"bench: expected 'ode' or 'accuracy', got {args.what!r}")
    res = bench_ode(n0=args.n0, t_end_s=args.t_end_s, rtol=args.rtol, repeats=args.repeats)
    if args.json:
        print_json(res)
    else:
        print(res.pop("report"))
    return 0


# ---------------------------------------------------------------- compare
def cmd_compare(args: argparse.Namespace) -> int:
    """``tippetop compare``: one scene in several engines/modes, against the theory."""
    from tippetop.compare.crossval import compare_scene, friction_law_table
    from tippetop.models.modes import parse_modes

    res = compare_scene(args.scene, parse_modes(args.modes), tuple(args.set or []),
                        scheduler=args.scheduler, workers=args.workers,
                        use_cache=not args.no_cache)
    if args.json:
        print_json(res)
    else:
        print(f"scene {res['scene']} (Group {res['group']}): theory predicts "
              f"{res['theory']['outcome']} (theta_s = {res['theory']['theta_s']:.3f} rad)")
        import pandas as pd

        with pd.option_context("display.width", 200, "display.max_colwidth", 120):
            print(friction_law_table(res).to_string(index=False))
        for d in res["differences"]:
            print(f"  differs: {d['mode']} {d['metric']} = {d['value']} "
                  f"(reference {d['reference']}, tolerance {d['tolerance']})")
    return 0


# ---------------------------------------------------------------- threshold
def cmd_threshold(args: argparse.Namespace) -> int:
    """``tippetop threshold``: n1 or nc by bisection on n0."""
    from tippetop.compare.threshold import measure_threshold

    res = measure_threshold(args.scene, args.engine, args.which, tuple(args.set or []),
                            rel_tol=args.rel_tol, scheduler=args.scheduler,
                            workers=args.workers, use_cache=not args.no_cache)
    if args.json:
        print_json(res)
    else:
        _print_human({k: v for k, v in res.items() if k != "runs"})
    return 0


# ---------------------------------------------------------------- sweep
def cmd_sweep(args: argparse.Namespace) -> int:
    """``tippetop sweep``: theta_asymp against n0 per mode, optionally written to ``--out``."""
    from pathlib import Path

    from tippetop.compare.io import write_atomic
    from tippetop.compare.sweep import parse_range, run_sweep, sweep_figure
    from tippetop.models.modes import parse_modes

    n0s = parse_range(args.n0)
    modes = parse_modes(args.modes)
    out_dir = None
    if args.out:
        out_dir = Path(args.out)
        files = [out_dir / "sweep.csv", out_dir / "theory.csv", out_dir / "sweep.png"]
        if any(f.exists() for f in files) and not args.force:
            raise TippetopError(f"--out: expected a folder without sweep results (or --force), "
                                f"got {str(out_dir)!r} which has them")
    res = run_sweep(args.scene, n0s, modes, tuple(args.set or []), scheduler=args.scheduler,
                    workers=args.workers, use_cache=not args.no_cache)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(files[0], lambda tmp: res["table"].to_csv(tmp, index=False))
        write_atomic(files[1], lambda tmp: res["theory"].to_csv(tmp, index=False))
        sweep_figure(res, files[2])
    if args.json:
        print_json({"scene": res["scene"], "computed": res["computed"], "cached": res["cached"],
                    "rows": res["table"].to_dict(orient="records")})
    else:
        print(res["table"].to_string(index=False))
        print(f"{res['computed']} computed, {res['cached']} from the cache")
    return 0
