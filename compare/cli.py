"""The ``tippetop`` command line.

Bad input ends in one line on stderr (``tippetop: error: ...``) and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any, NoReturn

from tippetop.models.errors import TippetopError

EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 1  # a run that diverged or stopped short: reported, never as numbers


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"tippetop: error: {message} (see '{self.prog} --help')\n")
        raise SystemExit(EXIT_BAD_INPUT)


def _finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def _json_default(o: Any) -> Any:
    if hasattr(o, "item"):
        return o.item()
    raise TypeError(type(o).__name__)


def _clean(obj: Any) -> Any:
    """NaN/inf -> None so the JSON stays standard."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    return obj


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout."""
    print(json.dumps(_clean(obj), default=_json_default))


def _print_human(d: dict[str, Any]) -> None:
    width = max(len(k) for k in d)
    for k, v in d.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        print(f"{k:<{width}}  {v}")


# ---------------------------------------------------------------- theory
def _cmd_theory(args: argparse.Namespace) -> int:
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
        overrides.append(f"top.mjcf={json.dumps(args.mjcf)}")
    return load_scene(args.scene, overrides)


def _cmd_simulate(args: argparse.Namespace) -> int:
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
    failed = run.status not in ("ok", "contact_lost")
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
def _cmd_bench(args: argparse.Namespace) -> int:
    if args.what == "accuracy":
        from tippetop.compare.accuracy import (
            DEFAULT_BUDGET_S,
            DEFAULT_MUJOCO_BUDGET_S,
            run_accuracy,
        )

        engines = [e.strip() for e in args.engines.split(",") if e.strip()]
        if args.workers is not None and args.workers < 1:
            raise TippetopError(f"--workers: expected an integer >= 1, got {args.workers}")
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
def _cmd_compare(args: argparse.Namespace) -> int:
    from tippetop.compare.crossval import compare_scene, friction_law_table
    from tippetop.compare.modes import parse_modes

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
def _cmd_threshold(args: argparse.Namespace) -> int:
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
def _cmd_sweep(args: argparse.Namespace) -> int:
    from pathlib import Path

    from tippetop.compare.io import write_atomic
    from tippetop.compare.modes import parse_modes
    from tippetop.compare.sweep import parse_range, run_sweep, sweep_figure

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


def _add_parallel_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", help="tcp://HOST:PORT of a Dask scheduler (default: local "
                   "processes)")
    p.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    p = _Parser(prog="tippetop", description="Tippe-top cross-validation harness: the paper's "
                "reference ODE, its theory, and MuJoCo.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    t = sub.add_parser("theory", help="the paper's predictions for a top")
    t.add_argument("--A-over-C", dest="A_over_C", type=_finite_float)
    t.add_argument("--a-over-R", dest="a_over_R", type=_finite_float)
    t.add_argument("--C-factor", dest="C_factor", type=_finite_float, default=1.0,
                   help="C = F * (2/5) M R^2 (default 1)")
    t.add_argument("--R-m", dest="R_m", type=_finite_float, default=0.015)
    t.add_argument("--M-kg", dest="M_kg", type=_finite_float, default=0.015)
    t.add_argument("--g-mps2", dest="g_mps2", type=_finite_float, default=9.8)
    t.add_argument("--n0", type=_finite_float, help="initial spin near theta = 0 (rad/s)")
    t.add_argument("--mjcf", help="derive the top from an MJCF file")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=_cmd_theory)

    s = sub.add_parser("simulate", help="run a scene in one engine and print its summary")
    s.add_argument("scene", nargs="?", help="scene .toml file or catalogue name (default: the "
                   "paper's top and Fig. 3 start)")
    s.add_argument("--engine", default="ode", help="ode (default) or mujoco")
    s.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override a scene key, e.g. init.n0=60 (repeatable)")
    s.add_argument("--mjcf", help="run a loaded MJCF top instead of the scene's")
    s.add_argument("--out", help="write the observables table (.csv or .parquet)")
    s.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=_cmd_simulate)

    cp = sub.add_parser("compare", help="run a scene in several engines/modes and compare")
    cp.add_argument("scene", help="scene file or catalogue name")
    cp.add_argument("--modes", default="ode,mujoco-paper,mujoco-native",
                    help="comma-separated modes (default: ode,mujoco-paper,mujoco-native)")
    cp.add_argument("--set", action="append", metavar="KEY=VALUE")
    _add_parallel_options(cp)
    cp.add_argument("--json", action="store_true")
    cp.set_defaults(func=_cmd_compare)

    th = sub.add_parser("threshold", help="measure n1 or nc by bisection on n0")
    th.add_argument("scene", nargs="?", help="scene (default: fig11_n060, the Fig. 9 (a) top "
                    "from theta0 = 0.01 over 60 s)")
    th.add_argument("--engine", default="ode", help="ode (default) or mujoco")
    th.add_argument("--which", required=True, help="n1 or nc")
    th.add_argument("--set", action="append", metavar="KEY=VALUE")
    th.add_argument("--rel-tol", dest="rel_tol", type=_finite_float, default=0.005,
                    help="stop when the bracket is this narrow, relative (default 0.005)")
    _add_parallel_options(th)
    th.add_argument("--json", action="store_true")
    th.set_defaults(func=_cmd_threshold)

    sw = sub.add_parser("sweep", help="theta_asymp against n0 per mode, with theta_s(n0)")
    sw.add_argument("scene", help="scene file or catalogue name")
    sw.add_argument("--n0", required=True, help="START:STOP:STEP (rad/s)")
    sw.add_argument("--modes", default="ode", help="comma-separated modes (default: ode)")
    sw.add_argument("--set", action="append", metavar="KEY=VALUE")
    sw.add_argument("--out", help="folder for sweep.csv, theory.csv and sweep.png")
    sw.add_argument("--force", action="store_true", help="overwrite results in --out")
    _add_parallel_options(sw)
    sw.add_argument("--json", action="store_true")
    sw.set_defaults(func=_cmd_sweep)

    b = sub.add_parser("bench", help="benchmarks that print ratios against a baseline")
    b.add_argument("what", help="ode: compiled integrator vs scipy solve_ivp(DOP853); "
                   "accuracy: work-precision data and plots")
    b.add_argument("scene", nargs="?", help="accuracy: scene (default fig3 and fig11_n060)")
    b.add_argument("--out", help="accuracy: output folder (default ./accuracy)")
    b.add_argument("--budget-s", dest="budget_s", type=_finite_float, default=None,
                   help="accuracy: wall-time budget per point (s; default 20 for the ODE, 30 "
                   "for MuJoCo)")
    b.add_argument("--engines", default="ode,mujoco",
                   help="accuracy: comma-separated engines (default: ode,mujoco)")
    b.add_argument("--workers", type=int, help="accuracy: processes for the MuJoCo series "
                   "(default: all cores)")
    b.add_argument("--force", action="store_true", help="accuracy: overwrite results in --out")
    b.add_argument("--n0", type=_finite_float, default=60.0)
    b.add_argument("--t-end-s", dest="t_end_s", type=_finite_float, default=60.0)
    b.add_argument("--rtol", type=_finite_float, default=1e-9)
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=_cmd_bench)

    from tippetop.compare.calibrate import add_calibrate_parser
    from tippetop.compare.nightly import add_nightly_parser
    from tippetop.mujoco_runner.render import add_render_parser

    add_nightly_parser(sub)
    add_calibrate_parser(sub)
    add_render_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tippetop`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except TippetopError as exc:
        sys.stderr.write(f"tippetop: error: {exc}\n")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        sys.stderr.write("tippetop: interrupted\n")
        return 130
    except BrokenPipeError:  # e.g. piped into head
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
