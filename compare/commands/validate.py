"""``tippetop validate MODEL.xml``: an MJCF top against the theory and the reference."""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

from tippetop.compare.commands.options import (
    add_force_option,
    add_json_option,
    add_parallel_options,
    finite_float,
    print_json,
)
from tippetop.compare.studies.defaults import DEFAULT_T_END_S
from tippetop.compare.tuning import TUNE_BUDGET_RUNS

EXIT_AGREES, EXIT_DEPARTS = 0, 1


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop validate`` and its options."""
    p = sub.add_parser(
        "validate", help="the model-validation report of your own MJCF top",
        description="Run an MJCF top as its file says, in the reference ODE (with the file's "
        "mu and stem), with the paper's law in the same model, and with the calibrated native "
        "settings; check each against the theory and the reference; write report.html, "
        "results.json and the tables into --out. Exit 1 if a check departs.")
    p.add_argument("model", help="the MJCF file of the top (required)")
    p.add_argument("--out", metavar="DIR", help="folder for report.html, results.json and "
                   "tables/ (new or empty, or --force; default: none, printed only)")
    p.add_argument("--t-end-s", dest="t_end_s", type=finite_float, default=DEFAULT_T_END_S,
                   metavar="S", help=f"simulated time of every run (s; default "
                   f"{DEFAULT_T_END_S:g})")
    p.add_argument("--keyframe", metavar="NAME", help="start from this keyframe of the file "
                   "(default: its first)")
    p.add_argument("--engines", default="mujoco", metavar="SPEC,SPEC,...", help="the engines "
                   "the MuJoCo runs run on: mujoco (the installed one), mujoco==X.Y.Z, "
                   "mujoco@PYTHON, mjx, mjx-f32, warp; each runs the file and the paper's "
                   "law, named ENGINE/MODE (mujoco==3.3.7/file); the reference ode/paper "
                   "always runs (default: mujoco)")
    p.add_argument("--no-tune", dest="tune", action="store_false", help="skip the tuning: "
                   "the file's contact settings fitted to the reference at its start and "
                   "verified from held-out starts (the results' 'tuned')")
    p.add_argument("--budget-runs", dest="budget_runs", type=int, default=TUNE_BUDGET_RUNS,
                   metavar="N", help="MuJoCo runs the tuning may use (its seeds, its fits' "
                   "rollouts, its verification runs); where they run out it ends with its best "
                   "so far, verified and labelled budget-limited; one in three is kept for "
                   "the widening where the fits depart (the answer with one choice changed, a "
                   "fit again, then draws about the best so far: docs/guide/tuning.md) (at "
                   f"least 5; default {TUNE_BUDGET_RUNS}: the paper's top takes about 60)")
    add_force_option(p, help="write into a non-empty --out")
    add_parallel_options(p)
    add_json_option(p)
    p.set_defaults(func=run)


def check_budget_runs(n: int) -> None:
    """``--budget-runs`` of the tuning: at least one seed scored and every start verified."""
    from tippetop.compare.tuning.tune import min_budget_runs
    from tippetop.models.errors import expect

    expect(n >= min_budget_runs(), "--budget-runs", f"at least {min_budget_runs()} MuJoCo "
           "runs (one seed scored, then every start verified)", n)


def run(args: argparse.Namespace) -> int:
    """``tippetop validate``: run, write the report folder, print the verdict.

    Exit status 0 when every check agrees, 1 when one departs (2: bad input).
    """
    from tippetop.compare.running.io import check_output_dir, staged_output_dir, write_table
    from tippetop.compare.studies.validate import ValidateConfig, validate
    from tippetop.models.engines import parse_engines

    engines = tuple(e.spec for e in parse_engines(args.engines, mujoco_only=True))
    check_budget_runs(args.budget_runs)

    out = check_output_dir(args.out, force=args.force) if args.out else None
    if out is not None:
        from tippetop.compare.running.io import hold_output_lock

        hold_output_lock(out)
    config = ValidateConfig(model=Path(os.path.abspath(args.model)), t_end_s=args.t_end_s,
                            keyframe=args.keyframe, scheduler=args.scheduler,
                            workers=args.workers, use_cache=not args.no_cache,
                            engines=engines, tune=args.tune, progress=not args.json,
                            budget_runs=args.budget_runs)
    res = validate(config)
    tables = res.pop("tables")
    if out is not None:
        from tippetop.compare.report.validate import render
        from tippetop.compare.running.io import json_ready

        text = json.dumps(json_ready(res), indent=1) + "\n"
        html = render(res, tables)
        with staged_output_dir(out) as stage:  # all files or none, even on Ctrl-C
            (stage / "tables").mkdir()
            for mode, table in tables.items():
                # a run's name holds a "/" (ENGINE/MODE), and an engine may hold a path
                name = re.sub(r"[^A-Za-z0-9._=@+-]", "_", mode)
                write_table(table, stage / "tables" / f"{name}.csv")
            (stage / "results.json").write_text(text, "utf-8")
            (stage / "report.html").write_text(html, "utf-8")
    if args.json:
        print_json(res)
    else:
        _print_summary(res, out)
    sys.stdout.flush()
    return EXIT_AGREES if res["agrees"] else EXIT_DEPARTS


def _print_friction(res: dict[str, Any]) -> None:
    """The law each MuJoCo run realised, and whether the refit reference explains the run."""
    from tippetop.compare.measures.friction_realised import realised_sentence

    lines = []
    for mode, r in res["runs"].items():
        fr = r.get("friction_realised")
        if mode.startswith("ode/") or not fr:
            continue
        lines.append(f"    {realised_sentence(mode, fr)}")
        refit = fr.get("refit")
        if refit:
            lines.append(f"      refit: {refit['sentence']}")
            if refit.get("remains"):
                lines.append("      what else differs: " + ", ".join(refit["remains"]))
    if lines:
        from tippetop.compare.measures.friction_realised import SENTENCE_TERMS
        from tippetop.compare.presentation.terminal import wrapped

        print("  the friction law as each run realises it (the ball's phase):")
        print("\n".join(lines))
        print(wrapped(f"({SENTENCE_TERMS})", indent="    "))


def model_line(m: dict[str, Any]) -> str:
    """The top as read from the file, and the theory's outcome: every number with its unit.

    A/C and a/R are ratios and mu a coefficient (no unit); a value the file does not give says
    so.
    """
    from tippetop.compare.presentation.terminal import fmt

    mu = (fmt(float(m["mu"])) if m.get("mu") is not None
          else "not read (the file's ball geom gives no friction)")
    theta_s = (f"theta_s = {fmt(float(m['theta_s']), 'rad')}" if m.get("theta_s") is not None
               else "no theta_s for this spin")
    return (f"tippetop validate {m['file']}: Group {m['group']}, A/C = {m['A_over_C']:.4g}, "
            f"a/R = {m['a_over_R']:.4g}, mu = {mu}, n0 = {fmt(float(m['n0']), 'rad/s')}: the "
            f"theory says {m['theory_outcome']} ({theta_s})")


def _print_summary(res: dict[str, Any], out: Path | None) -> None:
    from tippetop.compare.presentation.terminal import check_note, check_text

    checks = res["verdict"]
    n_pass = sum(c["passed"] is not False for c in checks)
    print(model_line(res["model"]))
    print(f"verdict: {'AGREES' if res['agrees'] else 'DEPARTS'} ({n_pass} of {len(checks)} "
          f"checks pass, {res['t_end_s']:g} s simulated)")
    width = max(len(c["check"]) for c in checks)
    mwidth = max(len(c["run"]) for c in checks)
    for c in checks:
        if c["passed"] is False:
            shown = check_text(c, res["t_end_s"], res["runs"])
            why = f"; {note}" if (note := check_note(c)) else ""
            print(f"  departs: {c['run']:<{mwidth}} {c['check']:<{width}}  {shown}  "
                  f"(tolerance {c['tolerance']}{why})")
    for mode, r in res["runs"].items():
        if r.get("note"):
            print(f"  note: {mode}: {r['note']}")
    for f in res["findings"]:
        print(f"  the file's own settings: {f}")
    _print_friction(res)
    print_tuned(res.get("tuned") or {}, show_mjcf=False)
    ans = res.get("answer") or {}
    tried = ans.get("candidates") or []
    if tried:
        from tippetop.compare.studies.validate import show_setting

        print("  candidates tried:")
        for c in tried:
            state = "agrees" if c["agrees"] else "departs"
            print(f"    {c['what']}: {state}, {c['passes']} of {c['checks']} checks pass")
            if c.get("note"):
                print(f"      {c['note']}")
            if c.get("changes"):
                print("      changes from the file's: " + "; ".join(
                    f"{ch['setting']} {show_setting(ch['setting'], ch['file'])} -> "
                    f"{show_setting(ch['setting'], ch['calibrated'])}"
                    for ch in c["changes"]))
    lifted = res.get("lift") or {}
    if lifted.get("sentences") or lifted.get("scan"):
        print("  the contact's lift (MuJoCo's soft contact turns friction into normal force):")
        for line in lifted.get("sentences", []):
            print(f"    {line}")
        if lifted.get("scan"):
            print(f"    {lifted['scan']['sentence']}")
    if out is not None:
        print(f"report: {out / 'report.html'}")
    # the last lines: the file's verdict and what to paste
    f = ans.get("file") or {}
    if f:
        print(f"the file: {'AGREES' if f['agrees'] else 'DEPARTS'} ({f['passes']} of "
              f"{f['checks']} of its checks pass)")
    if ans:
        print(ans["label"] + (":" if ans.get("mjcf") else ""))
        for line in (ans.get("mjcf") or "").splitlines():
            print(f"    {line}")


def print_tuned(tuned: dict[str, Any], indent: str = "  ", *, show_mjcf: bool = True) -> None:
    """The tuned settings: the fit, the MJCF (``show_mjcf``), each start's verification."""
    if not tuned:
        return
    if tuned.get("skipped"):
        print(f"{indent}tuned settings: not run ({tuned['skipped']})")
        return
    from tippetop.compare.presentation.terminal import fmt, fmt_duration
    from tippetop.compare.tuning.tune import start_label

    fit = tuned["fit"]
    start = fit["starts"][0]
    limited = " (budget-limited)" if tuned.get("budget_limited") else ""
    print(f"{indent}tuned settings: {'AGREE' if tuned['agrees'] else 'DEPART'}{limited}: "
          f"{tuned['note']}")
    print(f"{indent}  fitted at {start_label(start['n0'], start['theta0'])} over "
          f"{fmt(start['t_end_s'], 's')}: residual "
          f"{fmt(fit['residual'], 'rad')} (theta and J), {fit['runs']} MuJoCo runs"
          f"{' of --budget-runs ' + str(fit['budget_runs']) if fit.get('budget_runs') else ''}, "
          f"{fmt_duration(fit['wall_s'])} (mujoco.sysid"
          f"{'; from the cache' if tuned.get('cached') else ''})")
    if show_mjcf:
        for line in tuned["mjcf"].splitlines():
            print(f"{indent}  {line}")
    base_t_end = min((v.get("t_end_s") for v in tuned["verified"] if v.get("t_end_s")),
                     default=None)
    for v in tuned["verified"]:
        where = f"{start_label(v['n0'], v['theta0'])} ({v['role']})"
        if v.get("t_end_s") and base_t_end and v["t_end_s"] > base_t_end * (1 + 1e-9):
            where += (f" over {fmt(v['t_end_s'], 's')}, its reference still moving at "
                      f"{fmt(base_t_end, 's')}")
        if v["passed"] is None:
            state = v.get("note", "not verified")
        elif v["passed"]:
            state = f"passes all {len(v['checks'])} checks"
        else:
            state = "departs in " + ", ".join(c["check"] for c in v["checks"]
                                              if c["passed"] is False)
        print(f"{indent}  from {where}: {state}")
