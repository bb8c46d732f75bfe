"""``tippetop bench``: the reference integrator against its peers, or accuracy against cost."""

from __future__ import annotations

import argparse
import sys

from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_workers_option,
    comma_list,
    finite_float,
    print_json,
    worker_count,
)
from tippetop.models.errors import TippetopError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop bench`` and its options."""
    p = sub.add_parser("bench", help="benchmarks that print ratios against a baseline",
                       description="bench ode: the compiled integrator against its peers "
                       "(numbalsoda's DOP853 and LSODA, if installed: pip install -e "
                       "'.[peers]') and scipy's solve_ivp(DOP853) on the same right-hand side. "
                       "bench accuracy: "
                       "work-precision of both engines against the reference (CSVs, figures, "
                       "Pareto tables), and with the ODE the stiff case (fig3 at Lambda = 1e-6 "
                       "m/s, rolling phases against the law) on its own frontier.")
    p.add_argument("what", choices=("ode", "accuracy"), help="ode: compiled integrator vs "
                   "numbalsoda and scipy solve_ivp(DOP853); accuracy: work-precision data and "
                   "plots")
    p.add_argument("scene", nargs="?", help="accuracy: scene (default: fig3 and fig11_n060)")
    p.add_argument("--out", metavar="DIR", help="accuracy: output folder (default ./accuracy); "
                   "ode --sweep: (default ./work-precision)")
    p.add_argument("--sweep", action="store_true", help="ode: the work-precision benchmark: "
                   "every solver's error against a converged truth over a sweep of "
                   "tolerances, compared at equal achieved error (tables, a figure per top, "
                   "--json)")
    p.add_argument("--tops", default="fig3,fig11,stiff", metavar="TOP,...",
                   help="ode --sweep: comma-separated tops, of fig3, fig11, stiff (default: "
                   "fig3,fig11,stiff)")
    p.add_argument("--budget-s", dest="budget_s", type=finite_float, default=None,
                   metavar="S", help="accuracy: wall-time budget per point (s; default 20 for "
                   "the ODE, 30 for MuJoCo)")
    p.add_argument("--engines", default="ode,mujoco", metavar="ENGINE,...",
                   help="accuracy: comma-separated engines, ode (the reference's methods and "
                   "tolerances) and/or mujoco (the installed MuJoCo's integrators and "
                   "timesteps, in modes paper and native) (default: ode,mujoco)")
    add_workers_option(p, help="accuracy: processes for the MuJoCo series (default: all cores)")
    add_force_option(p, help="accuracy: overwrite results in --out")
    p.add_argument("--n0", type=finite_float, default=60.0, metavar="RAD_S",
                   help="ode: initial spin of the Fig. 11 top (rad/s; default 60)")
    p.add_argument("--t-end-s", dest="t_end_s", type=finite_float, default=None, metavar="S",
                   help="ode: simulated time (s; default 60)")
    p.add_argument("--rtol", type=finite_float, default=1e-9, metavar="REL",
                   help="ode: relative tolerance of both integrators (default 1e-9)")
    p.add_argument("--rounds", "--repeats", dest="rounds", type=worker_count, default=None,
                   metavar="N", help="ode: rounds in which the solvers take turns (runs of "
                   "each), each keeping its best time (default 5; --sweep: 3)")
    p.add_argument("--scipy-rounds", dest="scipy_rounds", type=worker_count, default=1,
                   metavar="N", help="ode: of those, the rounds scipy runs in (about 4 s each at "
                   "the defaults; default 1)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop bench ode`` or ``tippetop bench accuracy``."""
    if args.what == "accuracy" and args.sweep:
        raise TippetopError("--sweep: expected with 'bench ode', got 'bench accuracy'")
    if args.what == "accuracy":
        from tippetop.compare.presentation.accuracy import accuracy_json, print_accuracy
        from tippetop.compare.running.options import RunOptions
        from tippetop.compare.studies.accuracy import (
            DEFAULT_BUDGET_S,
            DEFAULT_MUJOCO_BUDGET_S,
            MujocoGrid,
            OdeGrid,
            run_accuracy,
        )

        engines = list(comma_list(args.engines))
        if args.budget_s is not None and args.budget_s <= 0:
            raise TippetopError(f"--budget-s: expected a number > 0, got {args.budget_s}")
        res = run_accuracy([args.scene] if args.scene else ["fig3", "fig11_n060"],
                           args.out or "accuracy", force=args.force, engines=engines,
                           ode=OdeGrid(budget_s=args.budget_s or DEFAULT_BUDGET_S),
                           mujoco=MujocoGrid(
                               budget_s=args.budget_s or DEFAULT_MUJOCO_BUDGET_S),
                           run=RunOptions(workers=args.workers),
                           log=None if args.json else (lambda m: print(m, file=sys.stderr)))
        if args.json:
            print_json(accuracy_json(res))
        else:
            print_accuracy(res)
        return 0
    if args.what != "ode":
        raise TippetopError(f"bench: expected 'ode' or 'accuracy', got {args.what!r}")
    if args.sweep:
        return _sweep(args)
    from tippetop.compare.presentation.bench import print_bench_ode
    from tippetop.compare.studies.bench import bench_ode

    res = bench_ode(n0=args.n0, t_end_s=60.0 if args.t_end_s is None else args.t_end_s,
                    rtol=args.rtol, rounds=args.rounds or 5, scipy_rounds=args.scipy_rounds)
    if args.json:
        print_json(res.to_json())
    else:
        print_bench_ode(res)
    return 0


def _sweep(args: argparse.Namespace) -> int:
    """``tippetop bench ode --sweep``."""
    from tippetop.compare.presentation.bench import print_work_precision
    from tippetop.compare.studies.work_precision_report import (
        DEFAULT_OUT,
        parse_tops,
        run_work_precision,
        slow_peers,
    )

    if args.scene:
        raise TippetopError(f"bench ode --sweep: expected no scene (use --tops), got "
                            f"{args.scene!r}")
    tops = parse_tops(args.tops)
    t_end = args.t_end_s
    if t_end is not None and not t_end > 0:
        raise TippetopError(f"--t-end-s: expected a number > 0, got {args.t_end_s}")
    res = run_work_precision(tops, args.out or DEFAULT_OUT, rounds=args.rounds or 3,
                             force=args.force, t_end_s=t_end)
    if args.json:
        print_json(res.to_json())
    else:
        print_work_precision(res, slow_peers())
    return 0
