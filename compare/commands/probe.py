"""``tippetop probe``: each part of an engine on a motion with a closed-form answer."""

from __future__ import annotations

import argparse
import sys

from tippetop.compare.commands.options import (
    EXIT_RUN_FAILED,
    add_force_option,
    add_json_option,
    add_set_option,
    finite_float,
    json_text,
    print_json,
)

DESCRIPTION = (
    "Run small motions whose answers are known on paper - a ball that slides then rolls, "
    "bodies on a slope, a spinning ball, a rolling ball with rolling friction, a ball sliding "
    "fast enough to leave the table, a free body tumbling in zero gravity - on each engine, "
    "and print each quantity against its exact value, with the error and the tolerance. "
    "Every step of each run is measured. Exit 1 when a quantity is outside its tolerance or "
    "a run failed (the reasons are printed), 2 for bad input. The closed forms: "
    "docs/physics/probes.md; the quantities: 'tippetop metrics probe.*'.")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop probe`` and its options."""
    from tippetop.compare.probes import probe_names

    names = ", ".join(probe_names())
    p = sub.add_parser("probe", help="each part of an engine on a motion with a closed-form "
                       "answer", description=DESCRIPTION)
    p.add_argument("probes", nargs="*", metavar="NAME",
                   help=f"the probes to run: {names} (default: all)")
    p.add_argument("--engines", default="mujoco", metavar="ENGINE,...",
                   help="comma-separated MuJoCo engines: mujoco, mujoco==X.Y.Z, mujoco@PYTHON, "
                   "mjx, mjx-f32, warp (default: mujoco, the one installed)")
    p.add_argument("--modes", metavar="MODE,...", help="only these of the probes' modes: "
                   "each probe's own settings (pyramidal, elliptic, condim4, ...), not a run's "
                   "paper or native mode (default: every mode of each probe)")
    p.add_argument("--integrator", metavar="NAME", help="MuJoCo's integrator for every run: "
                   "Euler, RK4, implicit, implicitfast (default: each probe's own)")
    p.add_argument("--timestep", type=finite_float, metavar="S", help="the step for every "
                   "run (s; default: each probe's own)")
    add_set_option(p, help="a probe parameter, SI: KEY=VALUE for every probe that has it, or "
                   "PROBE.KEY=VALUE (mu=0.5, slide-to-roll.v0=2); repeatable (default: each "
                   "probe's own values, listed in --json's params)")
    p.add_argument("--out", metavar="DIR", help="folder for results.json, a figure per probe "
                   "and report.html, new or empty, or --force (default: none)")
    add_force_option(p, help="write into a non-empty --out")
    p.add_argument("--no-cache", action="store_true", help="run every probe again and write "
                   "nothing to the cache")
    add_json_option(p, help="print the result as one JSON object (format tippetop-probe/1: "
                    "results with probe, engine, version, mode, integrator, timestep_s, "
                    "quantity, value, exact, error, unit, tolerance, passed)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop probe``: exit 1 when a quantity is outside its tolerance or a run failed."""
    from tippetop.compare.probes.study import (
        check_modes,
        integrator_name,
        probes_for,
        run_probes,
    )
    from tippetop.compare.running.io import check_output_dir, hold_output_lock
    from tippetop.models.engines import parse_engines
    from tippetop.models.errors import TippetopError

    engines = parse_engines(args.engines, mujoco_only=True)
    modes = [m.strip() for m in args.modes.split(",") if m.strip()] if args.modes else None
    if args.modes is not None and not modes:
        raise TippetopError(f"--modes: expected at least one mode, got {args.modes!r}")
    # bad input first, before any run or output folder
    check_modes(probes_for(args.probes, args.set or ()), modes)
    if args.integrator:
        integrator_name(args.integrator)
    if args.timestep is not None and not args.timestep > 0:
        raise TippetopError(f"--timestep: expected a positive step in s, got {args.timestep!r}")
    out_dir = None
    if args.out:
        out_dir = check_output_dir(args.out, force=args.force)
        hold_output_lock(out_dir)
    res = run_probes(args.probes, engines, modes=modes, integrator=args.integrator,
                     timestep_s=args.timestep, sets=args.set or (),
                     use_cache=not args.no_cache, progress=not args.json)
    if out_dir is not None:
        from tippetop.compare.report.probes import write_outputs
        from tippetop.compare.running.io import staged_output_dir

        with staged_output_dir(out_dir) as stage:  # all files or none, even on Ctrl-C
            (stage / "results.json").write_text(json_text(res.to_json(), indent=1) + "\n",
                                                "utf-8")
            write_outputs(res, stage)
    if args.json:
        print_json(res.to_json())
    else:
        from tippetop.compare.presentation.probes import print_probes

        print_probes(res)
        if out_dir is not None:
            print(f"wrote {out_dir / 'results.json'}, the figures and "
                  f"{out_dir / 'report.html'}")
    failed = res.failed()
    if failed:
        sys.stderr.write(f"tippetop: {len(failed)} of {len(res.rows)} probe quantities not "
                         "within tolerance or not measured; see the rows marked FAIL\n")
        return EXIT_RUN_FAILED
    return 0
