"""``tippetop plan``: what a run would run, without running it; ``--json``: the plan itself."""

from __future__ import annotations

import argparse
from typing import Any

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


def print_plan(plan: Any) -> None:
    """A plan for a person: what will run and where, in the lines a run's summary says."""
    from tippetop.compare.presentation.terminal import fmt, fmt_value, ran_lines

    said = plan.what_runs()
    rows: list[tuple[str, str]] = [("start", _start(plan))]
    mj = plan.mujoco
    if mj is None:
        print(f"{plan.scene} on engine {plan.engine} (the reference ODE) in mode {plan.mode}: "
              f"{fmt(plan.t_end_s, 's')} simulated, a sample every "
              f"{fmt(plan.ode.sample_dt_s, 's')}")
    else:
        print(f"{plan.scene} on engine {plan.engine} in mode {plan.mode}: "
              f"{fmt(mj.t_end_s, 's')} "
              f"simulated, {fmt(mj.n_steps)} steps of {fmt(mj.timestep_s, 's')}, a sample "
              f"every {fmt(mj.steps_per_sample)} steps ({fmt(mj.n_intervals + 1)} rows)")
        rows.append(("model", "generated from the scene's top" if mj.source is None else
                     f"{mj.source}, with the values here written into its document"))
        for c in mj.contacts:
            rows.append(("contact", f"{c.element} {c.name} ({c.role}): condim {c.condim}, "
                         f"friction {fmt_value('', list(c.friction))}, solref "
                         f"{fmt_value('solref', list(c.solref))}, solimp "
                         f"{fmt_value('solimp', list(c.solimp))}"
                         + (", solreffriction "
                            + fmt_value("solreffriction", list(c.solreffriction))
                            if c.solreffriction else "")
                         + ("" if c.collides else ", collides with nothing")))
        if mj.paper_max_timestep_s is not None:
            rows.append(("law's step", f"at most {fmt(mj.paper_max_timestep_s, 's')} (the "
                         "paper's law relaxes the slip in that time)"))
        rows += [("note", note) for note in mj.notes]
    width = max(max(len(k) for k in [*(k for k, _ in rows), "unused"]),
                max(len(k) + 2 for k in said))
    print("what will run:")
    print("\n".join(ran_lines(said, width)))
    for key, text in rows:
        print(f"{key:<{width}}  {text}")
    print(f"{'unused':<{width}}  {', '.join(plan.unused) or 'none'} (--set keys the engine "
          "would not read)")


def _start(plan: Any) -> str:
    from tippetop.compare.presentation.terminal import fmt

    mj = plan.mujoco
    if mj is not None and mj.keyframe is not None:
        return f"keyframe '{mj.keyframe_name}' of the file (index {mj.keyframe})"
    ini = plan.init
    return (f"theta0 {fmt(ini.theta0, 'rad')}, n0 {fmt(ini.n0, 'rad/s')}, thetadot0 "
            f"{fmt(ini.thetadot0, 'rad/s')}, Omega0 {fmt(ini.Omega0, 'rad/s')}, uOX "
            f"{fmt(ini.uOX, 'm/s')}, uOY {fmt(ini.uOY, 'm/s')}")
