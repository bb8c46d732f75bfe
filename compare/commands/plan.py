"""``tippetop plan``: what a run would run, without running it; ``--json``: the plan itself."""

from __future__ import annotations

import argparse

from tippetop.compare.commands.options import (
    add_engine_option,
    add_force_option,
    add_json_option,
    add_mode_option,
    add_scene_options,
    add_set_option,
    engine_and_mode,
    load_scene,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop plan`` and its options."""
    p = sub.add_parser("plan", help="print what a run would run, without running it",
                       description="Resolve a scene for one engine in one mode exactly as "
                       "'tippetop simulate' does and print what would run and where, without "
                       "running it: the same 'what ran' lines a run's summary prints, the "
                       "start, the model, every contact's settings and the --set keys the "
                       "engine would not read. --json prints the plan itself (the engine it "
                       "runs on, its mode, every value resolved, the MJCF text that would be "
                       "compiled), which 'tippetop simulate --plan FILE.json' runs on that "
                       "engine in any process.")
    add_scene_options(p)
    add_engine_option(p)
    add_mode_option(p)
    add_set_option(p)
    p.add_argument("--out", metavar="FILE.json", help="also write the plan's JSON to this file "
                   "(default: none)")
    add_force_option(p, help="overwrite an existing --out file")
    add_json_option(p, help="print the plan as JSON (format tippetop-plan/2) instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop plan``: print the plan (and write it with ``--out``); exit 2 for bad input."""
    from tippetop.compare.presentation.plan import print_plan
    from tippetop.compare.running.engines import plan_for
    from tippetop.compare.running.io import check_output_path, write_atomic

    out = check_output_path(args.out, force=args.force, suffixes=(".json",)) if args.out \
        else None
    spec, mode, extra = engine_and_mode(args)
    scene = load_scene(args)
    if extra:
        scene = scene.with_overrides(list(extra))
    plan = plan_for(scene, spec, mode)
    text = plan.to_json()
    if out is not None:
        write_atomic(out, lambda tmp: tmp.write_text(text + "\n", encoding="utf-8"))
    if args.json:
        print(text)
    else:
        print_plan(plan)
        if out is not None:
            print(f"wrote {out}: run it with 'tippetop simulate --plan {out}'")
    return 0
