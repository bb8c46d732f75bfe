"""``tippetop simulate``: one scene in one engine, its summary and what ran."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from tippetop.compare.commands.options import (
    EXIT_RUN_FAILED,
    add_engine_option,
    add_force_option,
    add_json_option,
    add_mode_option,
    add_scene_options,
    add_set_option,
    engine_and_mode,
    load_scene,
    print_json,
)
from tippetop.models.errors import TippetopError

if TYPE_CHECKING:
    from tippetop.models.plan import RunPlan


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop simulate`` and its options."""
    p = sub.add_parser("simulate", help="run a scene on one engine in one mode and print its "
                       "summary",
                       description="Run a scene on one engine in one mode and print its "
                       "summary: the results (theta, the inversion time, Jellett's drift, the "
                       "energy), what ran (read back from the engine) and the --set keys it did "
                       "not read. Exit 1 if the run failed.")
    add_scene_options(p)
    add_engine_option(p)
    add_mode_option(p)
    add_set_option(p)
    p.add_argument("--plan", metavar="FILE.json", help="run this plan (written by 'tippetop "
                   "plan --json', or by another program) exactly as it says, on the engine it "
                   "names, instead of a scene: not with SCENE, --engine, --mode, --set, --mjcf "
                   "or --keyframe (default: none)")
    p.add_argument("--out", metavar="FILE", help="write the observables table, one row per "
                   "sample, to this .csv or .parquet file (default: the scene's outputs.table, "
                   "else none)")
    add_force_option(p)
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop simulate``: one scene in one engine; exit 1 when the run failed."""
    from tippetop.compare.measures.summary import measured_steps, run_failed
    from tippetop.compare.running.cost import record_mujoco_runs
    from tippetop.compare.running.engines import plan_for, run_plan
    from tippetop.compare.running.io import TABLE_SUFFIXES, check_output_path, write_table
    from tippetop.models.engines import parse_engine

    target = args.out
    if args.plan:
        plan = read_plan(args)
    else:
        spec, mode, extra = engine_and_mode(args)
        scene = load_scene(args)
        if extra:
            scene = scene.with_overrides(list(extra))
        plan = plan_for(scene, spec, mode)
        if not target and scene.outputs.table:
            target = scene.outputs.table
            if scene.path is not None:
                target = str(scene.path.parent / target)
    out_path = None
    if target:
        out_path = check_output_path(target, force=args.force, suffixes=TABLE_SUFFIXES)
    python = None
    engine = parse_engine(plan.engine)  # the plan says where it runs
    if not engine.in_process:
        from tippetop.compare.running.engines import engine_python

        python = engine_python(engine, say=_say)  # a managed environment is made on first use
    run = run_plan(plan, python=python)
    # for the next run's estimate
    record_mujoco_runs(measured_steps([run.summary], plan.engine), plan.engine)
    failed = run_failed(run.summary)
    if out_path is not None and not failed:
        write_table(run.table, out_path)
    if args.json:
        print_json(run.summary)
    else:
        from tippetop.compare.presentation.simulate import print_summary

        print_summary(plan.scene, run.summary, out_path if not failed else None)
    if failed:
        sys.stderr.write(f"tippetop: run failed: {run.message}\n")
        return EXIT_RUN_FAILED
    return 0


def _say(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def read_plan(args: argparse.Namespace) -> RunPlan:
    """The plan of ``--plan FILE.json``; the options a plan replaces must not be given.

    Raises:
        TippetopError: A scene option beside the plan, a missing file, or JSON that is not a
            plan (one line each).
    """
    from tippetop.models.plan import RunPlan

    given = [name for name, value in (("SCENE", args.scene), ("--engine", args.engine),
                                      ("--on", args.on), ("--mode", args.mode),
                                      ("--set", args.set), ("--mjcf", args.mjcf),
                                      ("--keyframe", args.keyframe)) if value]
    if given:
        raise TippetopError(f"--plan: expected the plan alone (it says what runs), got "
                            f"{', '.join(given)} beside it")
    path = Path(args.plan)
    if not path.is_file():
        raise TippetopError(f"--plan: expected an existing plan file (tippetop plan --json), "
                            f"got {args.plan!r}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TippetopError(f"--plan: expected a readable UTF-8 JSON file, got {args.plan!r} "
                            f"({type(exc).__name__})") from None
    return RunPlan.from_json(text)
