"""The ``tippetop`` command line: its parser and ``main``.

Bad input ends in one line on stderr (``tippetop: error: ...``) and exit status 2; every exit
status is in :data:`tippetop.compare.common_args.EXIT_STATUSES`. The command bodies are in
:mod:`tippetop.compare.commands`, ``nightly``, ``calibrate``, ``render`` and ``validate`` in
their own modules; the options they share in :mod:`tippetop.compare.common_args`.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from tippetop.compare import commands
from tippetop.compare.analysis.calibrate.command import add_calibrate_parser
from tippetop.compare.atlas_command import add_atlas_parser
from tippetop.compare.common_args import (
    EXIT_OK,
    EXIT_STATUSES,
    Parser,
    add_force_option,
    add_json_option,
    add_parallel_options,
    add_set_option,
    add_workers_option,
    finite_float,
    run_main,
    worker_count,
)
from tippetop.compare.mjcf_command import add_mjcf_parser
from tippetop.compare.nightly.command import add_nightly_parser
from tippetop.compare.presentation.video import add_render_parser
from tippetop.compare.validate.command import add_validate_parser

#: The environment variables ``tippetop`` reads, with what they do (``tippetop --help``).
ENVIRONMENT: dict[str, str] = {
    "TIPPETOP_CACHE": "folder of the run cache and the compiled code (default "
                      "~/.cache/tippetop); delete it to start afresh",
    "MUJOCO_GL": "offscreen OpenGL for render: egl or osmesa (default: EGL if it opens, else "
                 "OSMesa)",
    "NUMBA_CACHE_DIR": "where numba caches the compiled code instead (default: "
                       "$TIPPETOP_CACHE/numba/<key>)",
    "TIPPETOP_MAX_SAMPLES_GIB": "the most memory a run's table of samples may take, in GiB "
                                "(default 4); a larger run is refused before it starts",
}


def version_text() -> str:
    """``tippetop 0.1.0 (MuJoCo 3.2.7, Python 3.11.7)``: the installed versions."""
    from importlib import metadata

    def ver(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "not installed"

    py = ".".join(str(v) for v in sys.version_info[:3])
    return f"tippetop {ver('tippetop')} (MuJoCo {ver('mujoco')}, Python {py})"


class _VersionAction(argparse.Action):
    """``--version``: print :func:`version_text` and exit 0 (read only when asked)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS,
                 default: Any = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(version_text())
        parser.exit(EXIT_OK)


def _natural(name: str) -> tuple[Any, ...]:
    """``fig3`` before ``fig11_n030``: digits compare as numbers."""
    import re

    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def scene_catalogue() -> list[tuple[str, str]]:
    """The catalogue's scenes (``models/scenes/*.toml``): name and description, in order."""
    import tomllib

    from tippetop.models.scene import SCENES_DIR, catalogue_names

    out = []
    for name in sorted(catalogue_names(), key=_natural):
        try:
            with open(SCENES_DIR / f"{name}.toml", "rb") as f:
                desc = str(tomllib.load(f).get("scene", {}).get("description", ""))
        except (OSError, tomllib.TOMLDecodeError):
            desc = ""
        out.append((name, desc))
    return out


def _help_width() -> int:
    """The width argparse wraps help at (the terminal's, at most 100)."""
    import shutil

    return max(60, min(100, shutil.get_terminal_size((100, 24)).columns) - 2)


def top_epilog() -> str:
    """The end of ``tippetop --help``: scenes, modes, environment and exit statuses."""
    import textwrap

    from tippetop.models.modes import MODES

    width = _help_width()

    def wrap(text: str, first: str = "", rest: str = "  ") -> list[str]:
        return textwrap.wrap(text, width=width, initial_indent=first, subsequent_indent=rest,
                             break_on_hyphens=False, break_long_words=False)

    def block(title: str, rows: list[tuple[str, str]]) -> list[str]:
        w = max(len(k) for k, _ in rows) + 2
        lines = wrap(title)
        for k, text in rows:
            lines += wrap(text or "-", f"  {k:<{w}}", " " * (w + 2))
        return lines

    lines = block("scenes (SCENE is one of these or a scene .toml file; without one, simulate "
                  "and render run the paper's eq. 3.10 top from the Fig. 3 start):",
                  scene_catalogue())
    lines += [""] + wrap("modes (--modes; --engine takes ode, mujoco or a mode): "
                         + ", ".join(MODES))
    lines += [""] + block("environment:", list(ENVIRONMENT.items()))
    lines += [""] + block("exit status:", [(str(k), v) for k, v in EXIT_STATUSES.items()])
    lines += [""] + wrap("'tippetop COMMAND --help' lists a command's options, each with its "
                         "unit and default.")
    return "\n".join(lines)


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """The epilog as written; the command names and their help on one line each.

    argparse measures the subcommands' names without their extra indent, so the longest of
    them (``threshold``) would go on a line of its own.
    """

    def __init__(self, prog: str) -> None:
        super().__init__(prog, max_help_position=30, width=_help_width())

    def add_argument(self, action: argparse.Action) -> None:
        """Measure a subcommand's name with the indent it is printed at."""
        super().add_argument(action)
        if isinstance(action, argparse._SubParsersAction) and action.help is not \
                argparse.SUPPRESS:
            longest = max((len(a.metavar or a.dest) for a in action._get_subactions()),
                          default=0)
            self._action_max_length = max(self._action_max_length,
                                          longest + self._current_indent + 2 * 2)


class _TopParser(Parser):
    """The top-level parser: its epilog (the catalogue, read from disk) is built when shown."""

    def format_help(self) -> str:
        """The help, with :func:`top_epilog` at its end."""
        if self.epilog is None:
            self.epilog = top_epilog()
        return super().format_help()


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and docs)."""
    p = _TopParser(prog="tippetop", description="Tippe-top cross-validation harness: the "
                   "paper's reference ODE, its theory, and MuJoCo.",
                   formatter_class=_Formatter)
    p.add_argument("--version", action=_VersionAction,
                   help="print the installed versions of tippetop, MuJoCo and Python, and exit")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser,
                           metavar="COMMAND")

    t = sub.add_parser("theory", help="the paper's predictions for a top",
                       description="The paper's group, critical spins n1...n4 and nc, the "
                       "angles theta_c/f/d and (with --n0) theta_s, for a top given by its "
                       "ratios or an MJCF file.")
    t.add_argument("--A-over-C", dest="A_over_C", type=finite_float, metavar="X",
                   help="A/C, the transverse over the axial moment of inertia (no default: "
                   "required unless --mjcf)")
    t.add_argument("--a-over-R", dest="a_over_R", type=finite_float, metavar="Y",
                   help="a/R, the centre of mass's offset from the ball's centre over the "
                   "radius (no default: required unless --mjcf)")
    t.add_argument("--C-factor", dest="C_factor", type=finite_float, default=1.0, metavar="F",
                   help="C = F (2/5) M R^2, the axial moment over a uniform ball's (default 1)")
    t.add_argument("--R-m", dest="R_m", type=finite_float, default=0.015, metavar="M",
                   help="ball radius (m; default 0.015)")
    t.add_argument("--M-kg", dest="M_kg", type=finite_float, default=0.015, metavar="KG",
                   help="mass (kg; default 0.015)")
    t.add_argument("--g-mps2", dest="g_mps2", type=finite_float, default=9.8, metavar="G",
                   help="gravity (m/s^2; default 9.8)")
    t.add_argument("--n0", type=finite_float, metavar="RAD_S",
                   help="initial spin near theta = 0 (rad/s); adds theta_s (default: none)")
    t.add_argument("--mjcf", metavar="FILE", help="derive the top from an MJCF file instead "
                   "of the ratios (default: none)")
    add_json_option(t)
    t.set_defaults(func=commands.cmd_theory)

    s = sub.add_parser("simulate", help="run a scene in one engine and print its summary",
                       description="Run a scene in one engine and print its summary: the "
                       "results (theta, the inversion time, Jellett's drift, the energy), what "
                       "ran (read back from the engine) and the --set keys it did not read. "
                       "Exit 1 if the run failed.")
    s.add_argument("scene", nargs="?", help="scene .toml file or catalogue name (default: the "
                   "paper's top and Fig. 3 start)")
    s.add_argument("--engine", default="ode", help="ode (the reference), mujoco, or a mode "
                   "such as mujoco-native (see 'tippetop --help'; default ode)")
    add_set_option(s)
    s.add_argument("--mjcf", metavar="FILE", help="run a loaded MJCF top instead of the "
                   "scene's: as its file says (options, contacts, first keyframe) unless --set "
                   "says otherwise (default: the scene's top)")
    s.add_argument("--keyframe", metavar="NAME", help="with --mjcf: start from this keyframe "
                   "of the file (default: its first, unless --set init.* sets the state)")
    s.add_argument("--out", metavar="FILE", help="write the observables table, one row per "
                   "sample, to this .csv or .parquet file (default: the scene's outputs.table, "
                   "else none)")
    add_force_option(s)
    add_json_option(s)
    s.set_defaults(func=commands.cmd_simulate)

    cp = sub.add_parser("compare", help="run a scene in several engines/modes and compare",
                        description="Run a scene in each mode and the reference ODE; print one "
                        "line per mode (outcome, agreement with the theory, inversion time, "
                        "theta_asymp, Jellett's drift, energy) and every metric that departs "
                        "from the reference, naming the tolerance it broke.")
    cp.add_argument("scene", help="scene .toml file or catalogue name (required)")
    cp.add_argument("--modes", default="ode,mujoco-paper,mujoco-native",
                    help="comma-separated modes, listed in 'tippetop --help' (default: "
                    "ode,mujoco-paper,mujoco-native)")
    add_set_option(cp)
    add_parallel_options(cp)
    add_json_option(cp)
    cp.set_defaults(func=commands.cmd_compare)

    th = sub.add_parser("threshold", help="measure n1, n4 or nc in an engine, against the "
                        "theory",
                        description="Measure a critical spin in an engine's own dynamics and "
                        "compare it with the theory: by default from growth rates (short runs "
                        "started 0.01 rad from the upright or inverted state; the spin where "
                        "the tilt stops decaying), or by bisection on n0 over full runs (their "
                        "final states; the bracket's ends are rerun over twice the horizon).")
    th.add_argument("scene", nargs="?", help="scene (default: fig11_n060, the Fig. 9 (a) top "
                    "from theta0 = 0.01 over 60 s)")
    th.add_argument("--engine", default="ode", help="ode (the reference), mujoco, or a mode "
                    "(default ode)")
    th.add_argument("--which", required=True, choices=("n1", "n4", "nc"),
                    help="n1: the spin above which theta = 0 is unstable; n4: the spin at "
                    "theta = 0 that keeps the inverted state stable; nc: the spin above which "
                    "a Group II top inverts fully, max(n1, n4) (no default: required)")
    th.add_argument("--method", choices=("growth", "bisect"), default=None,
                    help="growth: the zero of the steady state's growth rate, from 2-s runs "
                    "(any of n1, n4, nc); bisect: the outcome of runs over the scene's "
                    "run.t_end_s (n1 or nc) (default growth)")
    add_set_option(th)
    th.add_argument("--rel-tol", dest="rel_tol", type=finite_float, default=None,
                    metavar="REL", help="stop when the spin is known to this, relative "
                    "(default 1e-5 for growth, 0.005, i.e. 0.5 %%, for bisect)")
    th.add_argument("--out", metavar="DIR", help="folder for threshold.json (the --json "
                    "result) and runs.csv (every n0 run), new or empty, or --force (default: "
                    "none, printed only)")
    add_force_option(th, help="write into a non-empty --out")
    add_parallel_options(th)
    add_json_option(th)
    th.set_defaults(func=commands.cmd_threshold)

    sw = sub.add_parser("sweep", help="theta_asymp against n0 per mode, with theta_s(n0)",
                        description="theta_asymp against the initial spin n0 in each mode, "
                        "with the theory's theta_s(n0) (the paper's Figs. 9, 10).")
    sw.add_argument("scene", help="scene .toml file or catalogue name (required)")
    sw.add_argument("--n0", required=True, metavar="START:STOP:STEP",
                    help="initial spins, rad/s; STOP is included when it falls on the grid, "
                    "at most 2000 points (no default: required)")
    sw.add_argument("--modes", default="ode", help="comma-separated modes, listed in "
                    "'tippetop --help' (default: ode)")
    add_set_option(sw)
    sw.add_argument("--out", metavar="DIR", help="folder for sweep.csv, theory.csv and "
                    "sweep.png (default: none, printed only)")
    add_force_option(sw, help="overwrite results in --out")
    add_parallel_options(sw)
    add_json_option(sw)
    sw.set_defaults(func=commands.cmd_sweep)

    b = sub.add_parser("bench", help="benchmarks that print ratios against a baseline",
                       description="bench ode: the compiled integrator against its peers "
                       "(numbalsoda's DOP853 and LSODA, if installed: pip install -e "
                       "'.[peers]') and scipy's solve_ivp(DOP853) on the same right-hand side. "
                       "bench accuracy: "
                       "work-precision of both engines against the reference (CSVs, figures, "
                       "Pareto tables), and with the ODE the stiff case (fig3 at Lambda = 1e-6 "
                       "m/s, rolling phases against the law) on its own frontier.")
    b.add_argument("what", choices=("ode", "accuracy"), help="ode: compiled integrator vs "
                   "numbalsoda and scipy solve_ivp(DOP853); accuracy: work-precision data and "
                   "plots")
    b.add_argument("scene", nargs="?", help="accuracy: scene (default: fig3 and fig11_n060)")
    b.add_argument("--out", metavar="DIR", help="accuracy: output folder (default ./accuracy)")
    b.add_argument("--budget-s", dest="budget_s", type=finite_float, default=None,
                   metavar="S", help="accuracy: wall-time budget per point (s; default 20 for "
                   "the ODE, 30 for MuJoCo)")
    b.add_argument("--engines", default="ode,mujoco",
                   help="accuracy: comma-separated engines (default: ode,mujoco)")
    add_workers_option(b, help="accuracy: processes for the MuJoCo series (default: all cores)")
    add_force_option(b, help="accuracy: overwrite results in --out")
    b.add_argument("--n0", type=finite_float, default=60.0, metavar="RAD_S",
                   help="ode: initial spin of the Fig. 11 top (rad/s; default 60)")
    b.add_argument("--t-end-s", dest="t_end_s", type=finite_float, default=60.0, metavar="S",
                   help="ode: simulated time (s; default 60)")
    b.add_argument("--rtol", type=finite_float, default=1e-9, metavar="REL",
                   help="ode: relative tolerance of both integrators (default 1e-9)")
    b.add_argument("--rounds", "--repeats", dest="rounds", type=worker_count, default=5,
                   metavar="N", help="ode: rounds in which the solvers take turns (runs of "
                   "each), each keeping its best time (default 5)")
    b.add_argument("--scipy-rounds", dest="scipy_rounds", type=worker_count, default=1,
                   metavar="N", help="ode: of those, the rounds scipy runs in (~6 s each at the "
                   "defaults; default 1)")
    add_json_option(b)
    b.set_defaults(func=commands.cmd_bench)

    add_nightly_parser(sub)
    add_calibrate_parser(sub)
    add_render_parser(sub)
    add_validate_parser(sub)
    add_atlas_parser(sub)
    add_mjcf_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tippetop`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_main(args)


if __name__ == "__main__":
    raise SystemExit(main())
