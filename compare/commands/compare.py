"""``tippetop compare``: one scene in several modes, against the theory and the reference."""

from __future__ import annotations

import argparse
import sys

from tippetop.compare.commands.options import (
    ENGINE_HELP,
    EXIT_RUN_FAILED,
    MODE_HELP,
    add_json_option,
    add_parallel_options,
    add_set_option,
    print_json,
    set_overrides,
)
from tippetop.compare.presentation.crossval import print_compare


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop compare`` and its options."""
    p = sub.add_parser("compare", help="run a scene on several engines and modes, and compare",
                       description="Run a scene on every pairing of --engines and --modes that "
                       "can run, and the reference ODE; print one line per run (outcome, "
                       "agreement with the theory, inversion time, theta_asymp, Jellett's "
                       "drift, energy) and every metric that departs from the reference, "
                       "naming the tolerance it broke.")
    p.add_argument("scene", help="scene .toml file or catalogue name (required)")
    p.add_argument("--engines", metavar="ENGINE,...", help="comma-separated engines: "
                   + ENGINE_HELP.removeprefix("the engine that integrates the run: ")
                   + " (default: ode,mujoco)")
    p.add_argument("--modes", metavar="MODE,...", help="comma-separated modes: "
                   + MODE_HELP.removeprefix("the mode, how the contact force is made: ")
                   + " (default: paper,native)")
    add_set_option(p)
    add_parallel_options(p)
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop compare``: one scene in several engines/modes, against the theory."""
    from tippetop.compare.commands.options import engines_and_modes
    from tippetop.compare.studies.crossval import compare_scene

    runs = engines_and_modes(args, engines="ode,mujoco", modes="paper,native")
    res = compare_scene(args.scene, runs, set_overrides(args), scheduler=args.scheduler,
                        workers=args.workers, use_cache=not args.no_cache)
    if args.json:
        print_json(res.to_json())
    else:
        print_compare(res)
    # a failed run is reported in its row (the others kept), and the command exits 1
    failed = res.failed()
    if failed:
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(res.runs)} runs "
                         f"failed ({', '.join(failed)}); the reasons are in the output\n")
        return EXIT_RUN_FAILED
    return 0
