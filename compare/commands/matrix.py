"""``tippetop matrix``: scenes on several engines side by side.

Against the theory and each other: :mod:`tippetop.compare.studies.matrix` does the work.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from tippetop.compare.commands.history import add_history_options
from tippetop.compare.commands.options import (
    EXIT_RUN_FAILED,
    add_force_option,
    add_json_option,
    add_scheduler_option,
    add_set_option,
    add_workers_option,
    json_text,
    print_json,
    set_overrides,
)

if TYPE_CHECKING:
    from tippetop.compare.results.matrix import MatrixResult

DESCRIPTION = (
    "Run every scene on every engine in every mode, and the reference ODE once per scene: "
    "whether each run agrees with the theory (the nightly's rule), and every metric on which "
    "two engines differ beyond the nightly's tolerance. Engines: mujoco (the MuJoCo installed "
    "with tippetop), mujoco==X.Y.Z (a release, in an environment made with uv on first use "
    "under $TIPPETOP_CACHE/envs), mujoco@PYTHON (the mujoco that interpreter imports: a build "
    "of your own; it needs only mujoco and numpy, and is never cached), mjx and mjx-f32 (MuJoCo "
    "MJX on JAX in float64 and float32) and warp (MuJoCo Warp, float32), each in an "
    "environment of its own, on the CPU here. Each difference is attributed: the pair is run "
    "again with one subsystem changed at a time (--no-attribution skips it). Exit 1 if a run "
    "failed.")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop matrix`` and its options."""
    p = sub.add_parser("matrix", help="scenes on several engines side by side",
                       description=DESCRIPTION)
    p.add_argument("scenes", nargs="*", metavar="SCENE|MODEL.xml",
                   help="catalogue names, scene .toml files or MJCF tops (default: the "
                   "--profile's scenes)")
    p.add_argument("--profile", choices=("quick", "full"), default="quick",
                   help="the scenes when none are named: quick (fig3, fig6, fig8a, fig11_n060) "
                   "or full (the whole catalogue) (default quick)")
    p.add_argument("--engines", required=True, metavar="ENGINE,...",
                   help="comma-separated MuJoCo engines: mujoco, mujoco==X.Y.Z, mujoco@PYTHON, "
                   "mjx, mjx-f32, warp; the reference ODE runs once per scene anyway (no "
                   "default: required)")
    p.add_argument("--modes", metavar="MODE,...", help="comma-separated MuJoCo modes: paper "
                   "(the paper's law at the contact point), native (MuJoCo's own contact, "
                   "calibrated), file (the model's own contact settings), native-pyramidal, "
                   "native-elliptic, native-condim4, native-condim6 (default: native,paper for "
                   "a catalogue scene, file,paper for an MJCF top)")
    add_set_option(p)
    p.add_argument("--out", metavar="DIR", help="folder for results.json (the --json result) "
                   "and report.html, new or empty, or --force (default: none, printed only)")
    add_force_option(p, help="write into a non-empty --out")
    add_workers_option(p)
    add_scheduler_option(p)
    p.add_argument("--no-attribution", action="store_true", help="skip the reruns that say "
                   "what each difference follows (the integrator, contacts, friction, the cone, "
                   "the solver, the timestep) and which engine is nearer the reference and its "
                   "own converged answer")
    p.add_argument("--probes", nargs="?", const="all", metavar="NAME,...", help="also run "
                   "the probes (tippetop probe: each part of the engine against an exact "
                   "answer) on the same engines and say which probe quantities moved between "
                   "them: all of them, or those named (default: none)")
    p.add_argument("--no-cache", action="store_true", help="compute every run again and "
                   "write nothing to the cache")
    add_history_options(p, "this matrix's values, engine versions, commit and machine")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop matrix``: exit 1 when a run failed."""
    import dataclasses

    from tippetop.compare.running.io import check_output_dir, hold_output_lock
    from tippetop.compare.studies.matrix import profile_scenes, run_matrix
    from tippetop.models.engines import parse_engines
    from tippetop.models.modes import parse_modes

    engines = parse_engines(args.engines)
    modes = parse_modes(args.modes) if args.modes else None
    probe_names: list[str] | None = None
    if args.probes is not None:
        from tippetop.compare.probes import probe_class

        probe_names = [] if args.probes == "all" else \
            [n.strip() for n in args.probes.split(",") if n.strip()]
        for n in probe_names:
            probe_class(n)  # an unknown probe: one line, before any run
    scenes = list(args.scenes) or list(profile_scenes(args.profile))
    from tippetop.compare.nightly.history import check_history, timestamp_now

    if not args.no_history:  # before the runs: a file that is not a history is bad input
        check_history(args.history)
    started = timestamp_now()
    out_dir = None
    if args.out:
        out_dir = check_output_dir(args.out, force=args.force)
        hold_output_lock(out_dir)
    tables: dict[str, Any] = {}
    res = run_matrix(scenes, engines, modes, set_overrides(args), workers=args.workers,
                     use_cache=not args.no_cache, attribution=not args.no_attribution,
                     tables=tables, scheduler=args.scheduler)
    if res.started is None:
        res = dataclasses.replace(res, started=started)
    probes = None
    if probe_names is not None:
        from tippetop.compare.probes.study import probe_moves, run_probes

        probe_res = run_probes(probe_names, engines, use_cache=not args.no_cache,
                               progress=not args.json)
        probes = {**probe_res.to_json(),
                  "moved": [m.to_json() for m in probe_moves(probe_res)]}
    if not args.no_history:  # a failed append is said in one line; the results are kept
        res = dataclasses.replace(res, history=record_matrix(res, args))
    if out_dir is not None:
        from tippetop.compare.report.matrix import render
        from tippetop.compare.running.io import staged_output_dir

        text = json_text(_with_probes(res.to_json(), probes), indent=1) + "\n"
        html = render(res, tables)
        if probes is not None:
            from tippetop.compare.report.probes import moves_section

            html = html.replace("</body>", moves_section(probes) + "</body>", 1)
        with staged_output_dir(out_dir) as stage:  # all files or none, even on Ctrl-C
            (stage / "results.json").write_text(text, "utf-8")
            (stage / "report.html").write_text(html, "utf-8")
    if args.json:
        print_json(_with_probes(res.to_json(), probes))
    else:
        from tippetop.compare.presentation.matrix import print_matrix

        print_matrix(res)
        if probes is not None:
            from tippetop.compare.presentation.probes import print_moves

            print_moves(probes)
        if out_dir is not None:
            print(f"wrote {out_dir / 'results.json'} and {out_dir / 'report.html'}")
        if res.history and res.history["run"] is not None:
            print(f"history: appended to {res.history['file']} (run "
                  f"{res.history['run']}; 'tippetop history' shows what moved)")
    failed = res.failed_runs()
    if failed:
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(res.runs)} runs "
                         "failed; the reasons are in the output\n")
        return EXIT_RUN_FAILED
    return 0


def _with_probes(data: dict[str, Any], probes: dict[str, Any] | None) -> dict[str, Any]:
    """The matrix's JSON with its ``probes`` (``--probes``: the probes' result and ``moved``)."""
    return data if probes is None else {**data, "probes": probes}


def record_matrix(res: MatrixResult, args: argparse.Namespace) -> dict[str, Any]:
    """Append the matrix to the history: ``{file, run, error}`` (never raises)."""
    from tippetop.compare.commands.history import record_command

    return record_command("matrix", res.to_json(), args,
                          profile=None if args.scenes else args.profile)
