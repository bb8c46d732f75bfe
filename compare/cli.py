"""The ``tippetop`` command line: its parser and ``main``.

Bad input ends in one line on stderr (``tippetop: error: ...``) and exit status 2. The command
bodies are in :mod:`tippetop.compare.commands`, ``nightly``, ``calibrate`` and ``render`` in
their own modules; the options they share in :mod:`tippetop.compare.common_args`.
"""

from __future__ import annotations

import argparse
import sys

from tippetop.compare import commands
from tippetop.compare.calibrate.command import add_calibrate_parser
from tippetop.compare.common_args import (
    Parser,
    add_force_option,
    add_json_option,
    add_parallel_options,
    add_set_option,
    add_workers_option,
    finite_float,
    run_command,
)
from tippetop.compare.nightly.command import add_nightly_parser
from tippetop.compare.render import add_render_parser
from tippetop.compare.validate.command import add_validate_parser


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    p = Parser(prog="tippetop", description="Tippe-top cross-validation harness: the paper's "
               "reference ODE, its theory, and MuJoCo.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)

    t = sub.add_parser("theory", help="the paper's predictions for a top")
    t.add_argument("--A-over-C", dest="A_over_C", type=finite_float)
    t.add_argument("--a-over-R", dest="a_over_R", type=finite_float)
    t.add_argument("--C-factor", dest="C_factor", type=finite_float, default=1.0,
                   help="C = F * (2/5) M R^2 (default 1)")
    t.add_argument("--R-m", dest="R_m", type=finite_float, default=0.015)
    t.add_argument("--M-kg", dest="M_kg", type=finite_float, default=0.015)
    t.add_argument("--g-mps2", dest="g_mps2", type=finite_float, default=9.8)
    t.add_argument("--n0", type=finite_float, help="initial spin near theta = 0 (rad/s)")
    t.add_argument("--mjcf", help="derive the top from an MJCF file")
    add_json_option(t)
    t.set_defaults(func=commands.cmd_theory)

    s = sub.add_parser("simulate", help="run a scene in one engine and print its summary")
    s.add_argument("scene", nargs="?", help="scene .toml file or catalogue name (default: the "
                   "paper's top and Fig. 3 start)")
    s.add_argument("--engine", default="ode", help="ode (default) or mujoco")
    add_set_option(s, help="override a scene key, e.g. init.n0=60 (repeatable)")
    s.add_argument("--mjcf", help="run a loaded MJCF top instead of the scene's: as its file "
                   "says (options, contacts, first keyframe) unless --set says otherwise")
    s.add_argument("--keyframe", metavar="NAME", help="with --mjcf: start from this keyframe "
                   "of the file (default: its first, unless --set init.* sets the state)")
    s.add_argument("--out", help="write the observables table (.csv or .parquet)")
    add_force_option(s)
    add_json_option(s)
    s.set_defaults(func=commands.cmd_simulate)

    cp = sub.add_parser("compare", help="run a scene in several engines/modes and compare")
    cp.add_argument("scene", help="scene file or catalogue name")
    cp.add_argument("--modes", default="ode,mujoco-paper,mujoco-native",
                    help="comma-separated modes (default: ode,mujoco-paper,mujoco-native)")
    add_set_option(cp)
    add_parallel_options(cp)
    add_json_option(cp)
    cp.set_defaults(func=commands.cmd_compare)

    th = sub.add_parser("threshold", help="measure n1 or nc by bisection on n0")
    th.add_argument("scene", nargs="?", help="scene (default: fig11_n060, the Fig. 9 (a) top "
                    "from theta0 = 0.01 over 60 s)")
    th.add_argument("--engine", default="ode", help="ode (default) or mujoco")
    th.add_argument("--which", required=True, help="n1 or nc")
    add_set_option(th)
    th.add_argument("--rel-tol", dest="rel_tol", type=finite_float, default=0.005,
                    help="stop when the bracket is this narrow, relative (default 0.005)")
    add_parallel_options(th)
    add_json_option(th)
    th.set_defaults(func=commands.cmd_threshold)

    sw = sub.add_parser("sweep", help="theta_asymp against n0 per mode, with theta_s(n0)")
    sw.add_argument("scene", help="scene file or catalogue name")
    sw.add_argument("--n0", required=True, help="START:STOP:STEP (rad/s)")
    sw.add_argument("--modes", default="ode", help="comma-separated modes (default: ode)")
    add_set_option(sw)
    sw.add_argument("--out", help="folder for sweep.csv, theory.csv and sweep.png")
    add_force_option(sw, help="overwrite results in --out")
    add_parallel_options(sw)
    add_json_option(sw)
    sw.set_defaults(func=commands.cmd_sweep)

    b = sub.add_parser("bench", help="benchmarks that print ratios against a baseline")
    b.add_argument("what", help="ode: compiled integrator vs scipy solve_ivp(DOP853); "
                   "accuracy: work-precision data and plots")
    b.add_argument("scene", nargs="?", help="accuracy: scene (default fig3 and fig11_n060)")
    b.add_argument("--out", help="accuracy: output folder (default ./accuracy)")
    b.add_argument("--budget-s", dest="budget_s", type=finite_float, default=None,
                   help="accuracy: wall-time budget per point (s; default 20 for the ODE, 30 "
                   "for MuJoCo)")
    b.add_argument("--engines", default="ode,mujoco",
                   help="accuracy: comma-separated engines (default: ode,mujoco)")
    add_workers_option(b, help="accuracy: processes for the MuJoCo series (default: all cores)")
    add_force_option(b, help="accuracy: overwrite results in --out")
    b.add_argument("--n0", type=finite_float, default=60.0)
    b.add_argument("--t-end-s", dest="t_end_s", type=finite_float, default=60.0)
    b.add_argument("--rtol", type=finite_float, default=1e-9)
    b.add_argument("--repeats", type=int, default=3)
    add_json_option(b)
    b.set_defaults(func=commands.cmd_bench)

    add_nightly_parser(sub)
    add_calibrate_parser(sub)
    add_render_parser(sub)
    add_validate_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tippetop`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run_command(args)
    except KeyboardInterrupt:
        sys.stderr.write("tippetop: interrupted\n")
        return 130
    except BrokenPipeError:  # e.g. piped into head
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
