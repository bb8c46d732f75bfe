"""``tippetop bisect``: which release moved a metric.

A binary search over the package registry's MuJoCo releases (or an ordered list of
interpreters): :mod:`tippetop.compare.studies.bisect` does the work.
"""

from __future__ import annotations

import argparse
import os
import sys

from tippetop.compare.commands.history import add_history_options
from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_scheduler_option,
    add_set_option,
    add_workers_option,
    finite_float,
    json_text,
    print_json,
    set_overrides,
)

DESCRIPTION = (
    "Find the first release between A and B (both included), in release order over those the "
    "package registry has for this platform and Python (no pre-releases, nothing yanked), at "
    "which a metric of the scene's run moves beyond the nightly's tolerance from A's value "
    "(the matrix's rule): a binary search, about log2(n) releases run in environments made "
    "with uv, not n. It names the pair (the last release like A, the first like B), the "
    "metric's values there and what the move follows (the matrix's attribution at that "
    "pair); it says when the metric moves more than once in the range, and names the other "
    "moves. A release that cannot be installed is skipped and named. --pythons FILE bisects "
    "an ordered list of interpreters instead (own builds in commit order), each run as "
    "mujoco@PYTHON. Exit 0 when the search ends, whatever it found.")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop bisect`` and its options."""
    p = sub.add_parser("bisect", help="which MuJoCo release moved a metric",
                       description=DESCRIPTION)
    p.add_argument("scene", nargs="?", metavar="SCENE|MODEL.xml", help="a catalogue name, a "
                   "scene .toml file or an MJCF top (default: none; required unless --probe)")
    p.add_argument("--probe", metavar="NAME", help="bisect a probe's quantities instead of a "
                   "scene's metrics (tippetop probe; --metric then names its quantities, "
                   "--mode one of its modes; default: none)")
    p.add_argument("--integrator", metavar="NAME", help="with --probe: MuJoCo's integrator "
                   "for every release's run (default: the probe's own)")
    p.add_argument("--timestep", type=finite_float, metavar="S", help="with --probe: the "
                   "step for every release's run (s; default: the probe's own)")
    p.add_argument("--between", nargs=2, metavar=("A", "B"), help="the range's first and last "
                   "releases (3.3.7 3.17.0), A before B; with --pythons, two of its lines "
                   "(default with --pythons: its first and last; required otherwise)")
    p.add_argument("--metric", metavar="METRIC,...", help="comma-separated metrics the matrix "
                   "compares: status, outcome, theta_asymp, t_invert, t_stem, t_left_table, "
                   "J_rel_drift (default: all of them)")
    p.add_argument("--mode", metavar="MODE", help="the mode, how the contact force is made: "
                   "paper, native, file, native-pyramidal ... (default: the scene's own, "
                   "native for a catalogue scene, file for an MJCF top)")
    p.add_argument("--pythons", metavar="FILE", help="bisect the interpreters of FILE, one a "
                   "line in order (# comments; a relative path from the file's folder), "
                   "each running the mujoco it imports, instead of releases (default: none, "
                   "the registry's releases)")
    add_set_option(p)
    p.add_argument("--budget", type=int, metavar="N", help="the most runs in all (one per "
                   "release) when looking for further moves; the first move of every metric "
                   "is found whatever it says (default: twice a binary search's runs, "
                   "2 x (2 + log2 of the range))")
    p.add_argument("--no-attribution", action="store_true", help="skip the matrix's reruns "
                   "that say what each move follows at its pair")
    p.add_argument("--out", metavar="DIR", help="folder for results.json (the --json result) "
                   "and report.html, new or empty, or --force (default: none, printed only)")
    add_force_option(p, help="write into a non-empty --out")
    add_scheduler_option(p)
    add_workers_option(p)
    p.add_argument("--no-cache", action="store_true", help="compute every run again and "
                   "write nothing to the cache; the release list is still kept an hour")
    add_history_options(p, "every release's values, engine versions, commit and machine")
    add_json_option(p)
    p.set_defaults(func=run)


def _check_scene(scene: str, mode: str | None, overrides: tuple[str, ...]) -> str:
    """The mode to run (the scene's own by default), the scene checked to load and plan."""
    from tippetop.compare.running.tasks import Task
    from tippetop.compare.studies.matrix import DEFAULT_FILE_MODES, DEFAULT_MODES
    from tippetop.models.errors import TippetopError
    from tippetop.models.modes import check_pair, parse_mode

    is_file = scene.lower().endswith(".xml")
    if is_file and not os.path.isfile(scene):
        raise TippetopError(f"SCENE: expected a scene or an MJCF file, got {scene!r}")
    chosen = parse_mode(mode) if mode else (DEFAULT_FILE_MODES if is_file else DEFAULT_MODES)[0]
    check_pair("mujoco", chosen)
    over = ((f"top.mjcf={os.path.abspath(scene)!r}",) if is_file else ()) + overrides
    task = Task(None if is_file else scene, over, "mujoco", chosen)
    task.plan()  # a scene that does not load, a bad --set, a mode it cannot run: one line
    return chosen


def _check_probe(args: argparse.Namespace) -> tuple[list[str], str, object]:
    """``--probe``: its metrics, its mode and a maker of its runner; bad input is one line."""
    from tippetop.compare.probes.study import integrator_name, probes_for
    from tippetop.compare.studies import bisect_probe as bp
    from tippetop.models.errors import TippetopError

    probe = probes_for([args.probe], args.set or ())[0]
    mode = args.mode or probe.modes[0]
    if mode not in probe.modes:
        from tippetop.models.errors import did_you_mean

        raise TippetopError(f"--mode: expected one of probe {probe.name}'s modes ("
                            f"{', '.join(probe.modes)}), got {mode!r}"
                            f"{did_you_mean(mode, probe.modes)}")
    integrator = integrator_name(args.integrator) if args.integrator else None
    if args.timestep is not None and not args.timestep > 0:
        raise TippetopError(f"--timestep: expected a positive step in s, got {args.timestep!r}")
    metrics = bp.probe_metrics_of(probe.name, args.metric)

    def runner_for(say):  # noqa: ANN001, ANN202 - made once the range is known
        return bp.ProbeRunner(probe.name, mode, integrator, args.timestep,
                              tuple(args.set or ()), use_cache=not args.no_cache, say=say)

    return metrics, mode, runner_for


def run(args: argparse.Namespace) -> int:
    """``tippetop bisect``."""
    import dataclasses

    from tippetop.compare.results.bisect import BisectContext
    from tippetop.compare.running.io import check_output_dir, hold_output_lock
    from tippetop.compare.studies import bisect as bs
    from tippetop.models.errors import TippetopError

    if args.budget is not None and args.budget < 2:
        raise TippetopError(f"--budget: expected an integer >= 2 (runs), got {args.budget}")
    if args.probe:
        if args.scene:
            raise TippetopError(f"SCENE: expected no scene with --probe {args.probe}, got "
                                f"{args.scene!r}")
        overrides = ()
        metrics, mode, runner_for = _check_probe(args)
    else:
        if not args.scene:
            raise TippetopError("SCENE: expected a scene, an MJCF top or --probe NAME, got "
                                "none")
        for flag in ("integrator", "timestep"):
            if getattr(args, flag) is not None:
                raise TippetopError(f"--{flag}: expected only with --probe (a scene's runs "
                                    f"take it from --set), got {getattr(args, flag)!r}")
        overrides = set_overrides(args)
        metrics = bs.check_metrics(args.metric)
        mode = _check_scene(args.scene, args.mode, overrides)
        runner_for = None
    from tippetop.compare.nightly.history import check_history, timestamp_now

    if not args.no_history:  # before the runs: a file that is not a history is bad input
        check_history(args.history)
    started = timestamp_now()
    out_dir = None
    if args.out:
        out_dir = check_output_dir(args.out, force=args.force)
    if args.pythons:
        cands = bs.python_range(bs.read_pythons(args.pythons), args.between)
        source = f"--pythons {args.pythons}"
    else:
        if not args.between:
            raise TippetopError("--between: expected two releases A B (such as 3.3.7 3.17.0), "
                                "got none")
        releases = bs.registry_releases("mujoco")
        cands = bs.release_range(releases, *args.between, installed=bs.installed_mujoco())
        source = releases.source
    if out_dir is not None:
        hold_output_lock(out_dir)

    def say(line: str) -> None:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()

    if runner_for is not None:
        runner: bs.Runner = runner_for(say)
    else:
        runner = bs.MatrixRunner(args.scene, mode, overrides, workers=args.workers,
                                 use_cache=not args.no_cache, scheduler=args.scheduler,
                                 say=say)
    found = bs.bisect(cands, metrics, runner, budget=args.budget,
                      attribution=not args.no_attribution and runner_for is None, say=say,
                      tty=sys.stderr.isatty())
    scene = f"probe {args.probe}" if args.probe else args.scene
    res = dataclasses.replace(found, context=BisectContext(
        scene, mode, tuple(args.set or []), source, started))
    if not args.no_history:  # a failed append is said in one line; the results are kept
        from tippetop.compare.commands.history import record_command

        res = dataclasses.replace(res, history=record_command("bisect", res.to_json(), args))
    if out_dir is not None:
        from tippetop.compare.presentation.bisect import render_html
        from tippetop.compare.running.io import staged_output_dir

        with staged_output_dir(out_dir) as stage:  # all files or none, even on Ctrl-C
            (stage / "results.json").write_text(json_text(res.to_json(), indent=1) + "\n",
                                                "utf-8")
            (stage / "report.html").write_text(render_html(res), "utf-8")
    if args.json:
        print_json(res.to_json())
    else:
        from tippetop.compare.presentation.bisect import print_bisect

        print_bisect(res)
        if out_dir is not None:
            print(f"wrote {out_dir / 'results.json'} and {out_dir / 'report.html'}")
        if res.history and res.history["run"] is not None:
            print(f"history: appended to {res.history['file']} (run "
                  f"{res.history['run']}; 'tippetop history' shows what moved)")
    return 0
