"""``tippetop matrix``: scenes on several engines side by side.

Against the theory and each other: :mod:`tippetop.compare.studies.matrix` does the work.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

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
    p.add_argument("--no-cache", action="store_true", help="compute every run again and "
                   "write nothing to the cache")
    add_history_options(p, "this matrix's values, engine versions, commit and machine")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop matrix``: exit 1 when a run failed."""
    from tippetop.compare.running.io import check_output_dir, hold_output_lock
    from tippetop.compare.studies.matrix import profile_scenes, run_matrix
    from tippetop.models.engines import parse_engines
    from tippetop.models.modes import parse_modes

    engines = parse_engines(args.engines)
    modes = parse_modes(args.modes) if args.modes else None
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
    res.setdefault("started", started)
    if not args.no_history:  # a failed append is said in one line; the results are kept
        res["history"] = record_matrix(res, args)
    if out_dir is not None:
        from tippetop.compare.report.matrix import render
        from tippetop.compare.running.io import staged_output_dir

        text = json_text(res, indent=1) + "\n"
        html = render(res, tables)
        with staged_output_dir(out_dir) as stage:  # all files or none, even on Ctrl-C
            (stage / "results.json").write_text(text, "utf-8")
            (stage / "report.html").write_text(html, "utf-8")
    if args.json:
        print_json(res)
    else:
        print_matrix(res)
        if out_dir is not None:
            print(f"wrote {out_dir / 'results.json'} and {out_dir / 'report.html'}")
        if res.get("history") and res["history"]["run"] is not None:
            print(f"history: appended to {res['history']['file']} (run "
                  f"{res['history']['run']}; 'tippetop history' shows what moved)")
    failed = [r for r in res["runs"] if r["status"] not in ("ok", "contact_lost", "hop")]
    if failed:
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(res['runs'])} runs "
                         "failed; the reasons are in the output\n")
        return EXIT_RUN_FAILED
    return 0


def record_matrix(res: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    """Append the matrix to the history: ``{file, run, error}`` (never raises)."""
    from tippetop.compare.commands.history import record_command

    return record_command("matrix", res, args, profile=None if args.scenes else args.profile)


def closer_text(d: dict[str, Any], near: dict[str, Any]) -> str:
    """Which engine is nearer the reference, and its own converged answer, in words."""
    from tippetop.compare.measures.metrics import metric
    from tippetop.compare.presentation.terminal import fmt

    unit = metric(d["metric"]).table_unit
    ref, conv = near.get("reference"), near.get("converged_nearer")
    parts = []
    if ref is None:
        parts.append("to the reference: n/a (a value is missing)")
    elif ref == "tie":
        parts.append("to the reference: a tie")
    else:
        parts.append(f"to the reference ({fmt(near['reference_value'], unit)}): {ref}")
    if conv is None:
        parts.append("to its own answer at dt/4: n/a")
    elif conv == "tie":
        parts.append("to its own answer at dt/4: a tie")
    else:
        gaps = ", ".join(f"{k} {fmt(v, unit)} off" for k, v in near["converged"].items()
                         if v is not None)
        parts.append(f"to its own answer at dt/4: {conv} ({gaps})")
    return "; ".join(parts)


def print_matrix(res: dict[str, Any]) -> None:
    """The matrix for a person: the verdict against the theory first.

    Then what changes between engines, then which engines ran.
    """
    from tippetop.compare.measures.metrics import metric
    from tippetop.compare.presentation.terminal import fmt, labelled, table

    engines = res["engines"]
    print(f"matrix: {len(res['scenes'])} scenes x {len(engines)} engines x "
          f"{len(res['modes'])} modes, against the theory and each other")
    stem = sum(r.get("against") == "reference" for r in res["runs"])
    print("\nagainst the theory and the reference (the verdict's checks, 'tippetop metrics'"
          + (f"; {stem} run(s) on a stem judged against the reference" if stem else "")
          + "):")
    rows = []
    for e in engines:
        for mode in res["modes"]:
            mine = [r for r in res["runs"] if r["engine"] == e["engine"] and r["mode"] == mode]
            if not mine:
                continue
            agree = sum(r["agrees"] for r in mine)
            failed = sum(r["status"] not in ("ok", "contact_lost", "hop") for r in mine)
            why = [f"{r['scene']}: {'; '.join(r['reasons']) or 'departs'}" for r in mine
                   if not r["agrees"]]
            rows.append((e["engine"], mode, f"{agree} of {len(mine)}", str(failed),
                         why[0] + (f" (and {len(why) - 1} more)" if len(why) > 1 else "")
                         if why else ""))
    print(table(("engine", "mode", "agree", "failed", "first departure"), rows, indent="  "))
    diffs = res["differences"]
    print("\nwhat changes between engines (beyond the nightly's tolerances):"
          + ("" if diffs else " nothing"))
    width = max([len(f"{d['scene']} {d['mode']}") for d in diffs] or [0])
    for d in diffs:
        (a, b), (va, vb) = d["engines"], d["values"]
        unit = metric(d["metric"]).table_unit
        text = (f"{d['metric']} {fmt(va, unit)} ({a}) against {fmt(vb, unit)} ({b})"
                + (f", over {fmt(d['tolerance'], unit)}" if d["tolerance"] is not None
                   else ""))
        print(labelled(f"{d['scene']} {d['mode']}", text, width))
        att, near = d.get("attribution"), d.get("closer")
        if att:
            print(labelled("", f"follows: {att['follows']}", width))
        if near:
            print(labelled("", f"closer: {closer_text(d, near)}", width))
    realised = [r for r in res["runs"] if r["mode"] != "paper" and r["engine"] != "ode"
                and (r.get("friction_realised") or {}).get("samples")]
    if realised:
        from tippetop.compare.measures.friction_realised import realised_sentence

        print("\nthe friction law as each engine realises it (the ball's phase):")
        for r in realised:
            name = f"{r['scene']} {r['mode']} {r['engine']}"
            print(f"  {realised_sentence(name, r['friction_realised'])}")
    print("\nengines (read back from their runs):")
    print(table(("engine", "implementation", "version", "precision", "device"),
                [(e["engine"], e["implementation"], fmt(e["version"]), e["precision"],
                  e["device"]) for e in engines], indent="  "))
