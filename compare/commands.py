"""The bodies of the ``tippetop`` commands theory, simulate, compare, threshold, sweep, bench.

Each ``cmd_x(args)`` reads its parsed arguments, calls the function that does the work with
plain values, prints the result (text, or one JSON object with ``--json``) and returns the exit
status. Their parsers are in :mod:`tippetop.compare.cli`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from typing import Any

from tippetop.compare.common_args import EXIT_RUN_FAILED, comma_list, print_json
from tippetop.compare.presentation.terminal import (
    MISSING,
    fmt,
    fmt_percent,
    fmt_value,
    key_values,
    labelled,
    table,
)
from tippetop.models.errors import TippetopError


def _print_human(d: dict[str, Any]) -> None:
    """``key  value unit`` lines (:func:`tippetop.compare.presentation.terminal.key_values`)."""
    print(key_values(d))


def _cache_line(computed: int | None, cached: int | None, use_cache: bool) -> str:
    """Where the runs went: ``runs: 6 computed, 2 from the cache in /root/.cache/tippetop``."""
    from tippetop.models.resources import user_cache_dir

    counts = f"{computed} computed, {cached} from the cache" if computed is not None else ""
    if not use_cache:
        return f"runs: {counts or 'computed'}; the cache was not used (--no-cache)"
    where = f"{user_cache_dir()} ($TIPPETOP_CACHE)"
    return f"runs: {counts} in {where}" if counts else f"runs: cached in {where}"


# ---------------------------------------------------------------- theory
def cmd_theory(args: argparse.Namespace) -> int:
    """``tippetop theory``: the paper's predictions for a top."""
    from tippetop.compare.analysis import theory
    from tippetop.models.params import TopParams

    extra: dict[str, Any] = {}
    if args.mjcf:
        from tippetop.mujoco_runner.model import top_from_mjcf_file

        top = top_from_mjcf_file(args.mjcf)
        extra = {"R_m": top.R_m, "a_m": top.a_m, "A": top.A_kgm2, "C": top.C_kgm2,
                 "M_kg": top.M_kg, "A_over_C": top.A_over_C, "a_over_R": top.a_over_R}
    else:
        if args.A_over_C is None or args.a_over_R is None:
            raise TippetopError("theory: expected --A-over-C and --a-over-R (or --mjcf FILE), "
                                "got neither")
        top = TopParams.from_ratios(args.A_over_C, args.a_over_R, args.C_factor,
                                    R_m=args.R_m, M_kg=args.M_kg, g_mps2=args.g_mps2)
    out = theory.summary(top, n0=args.n0)
    out.update(extra)
    if args.json:
        print_json(out)
    else:
        _print_theory(out, top, args.n0)
    return 0


#: What each number of ``tippetop theory`` is (the paper's names in brackets).
THEORY_MEANINGS: dict[str, str] = {
    "group": "the paper's classification by A/C and a/R (Sec. 4)",
    "n1": "spin above which the vertical state theta = 0 is unstable (eq. 4.13)",
    "n2": "spin below which no precession exists at theta = pi",
    "n3": "spin at theta = pi above which the inverted state is stable",
    "n4": "spin at theta = 0 that leaves n3 after inversion",
    "nc": "spin above which a Group II top inverts fully (Sec. 4.3)",
    "rc": "A/C at which F(-1) = F(1) (depends on a/R only)",
    "theta_c": "Group I: critical angle (below it theta falls back to 0)",
    "theta_f": "Group III: the fixed point theta settles at",
    "theta_d": "Group II (rc < A/C < 1): the jump angle",
    "theta_s": "asymptotic angle predicted for the start near theta = 0",
}


def _print_theory(out: dict[str, Any], top: Any, n0: float | None) -> None:
    """The theory's numbers with units and what each one is; ``-`` where it does not exist."""
    print(f"Group {out['group']} top: A/C = {fmt(top.A_over_C)}, a/R = {fmt(top.a_over_R)}, "
          f"R = {fmt(top.R_m, 'm')}, M = {fmt(top.M_kg, 'kg')}")
    rows = []
    for k, v in out.items():
        meaning = THEORY_MEANINGS.get(k, "")
        if k == "theta_s" and n0 is not None:
            meaning = f"{meaning} at n0 = {fmt(n0, 'rad/s')}"
        if v is None:
            meaning = f"{meaning}; none for this top" if meaning else "none for this top"
        rows.append((k, fmt_value(k, v), meaning))
    print(table(("quantity", "value", "meaning"), rows))


# ---------------------------------------------------------------- simulate
def _load(args: argparse.Namespace):
    from tippetop.models.scene import load_scene

    overrides = list(args.set or [])
    if getattr(args, "mjcf", None):
        # relative to the working folder, not to the scene file
        overrides.append(f"top.mjcf={json.dumps(os.path.abspath(args.mjcf))}")
    if getattr(args, "keyframe", None):
        overrides.append(f"init.keyframe={json.dumps(args.keyframe)}")
    return load_scene(args.scene, overrides)


def cmd_simulate(args: argparse.Namespace) -> int:
    """``tippetop simulate``: one scene in one engine; exit 1 when the run failed."""
    from tippetop.compare.running.engines import run_engine, run_failed
    from tippetop.compare.running.io import TABLE_SUFFIXES, check_output_path, write_table

    scene = _load(args)
    out_path = None
    target = args.out or scene.outputs.table
    if target:
        if not args.out and scene.path is not None:
            target = str(scene.path.parent / target)
        out_path = check_output_path(target, force=args.force, suffixes=TABLE_SUFFIXES)
    run = run_engine(scene, args.engine)
    failed = run_failed(run.summary)
    if out_path is not None and not failed:
        write_table(run.table, out_path)
    if args.json:
        print_json(run.summary)
    else:
        _print_summary(scene.name, run.summary, out_path if not failed else None)
    if failed:
        sys.stderr.write(f"tippetop: run failed: {run.message}\n")
        return EXIT_RUN_FAILED
    return 0


#: Summary keys that say what ran (settings read back from the engine), listed apart.
RAN_KEYS = ("mode", "friction_law", "formulation", "rtol", "atol", "law_mu", "timestep_s",
            "integrator", "cone", "impratio", "noslip_iterations", "condim", "mu", "torsional",
            "rolling", "solref", "solimp", "gravity_mps2", "sample_dt_s", "keyframe")


def _print_summary(scene: str, summary: dict[str, Any], table_path: Any = None) -> None:
    """A run's summary: the results, then what ran, then the unused ``--set`` keys."""
    ran = [(k, summary[k]) for k in RAN_KEYS if k in summary]
    rest = [(k, v) for k, v in summary.items() if k not in RAN_KEYS and k != "unused"]
    pairs = [("scene", scene), *rest]
    width = max(len(k) for k, _ in [*pairs, *ran, ("unused", 0)])
    print("\n".join(f"{k:<{width}}  {fmt_value(k, v)}" for k, v in pairs))
    if ran:
        print("what ran:")
        print("\n".join(f"  {k:<{width - 2}}  {fmt_value(k, v)}" for k, v in ran))
    unused = summary.get("unused")
    if unused is not None:
        print(f"{'unused':<{width}}  {', '.join(unused) if unused else 'none'} (--set keys "
              "the engine did not read)")
    if table_path is not None:
        print(f"wrote {table_path}")


# ---------------------------------------------------------------- bench
def cmd_bench(args: argparse.Namespace) -> int:
    """``tippetop bench ode`` or ``tippetop bench accuracy``."""
    if args.what == "accuracy":
        from tippetop.compare.analysis.accuracy import (
            DEFAULT_BUDGET_S,
            DEFAULT_MUJOCO_BUDGET_S,
            run_accuracy,
        )

        engines = list(comma_list(args.engines))
        if args.budget_s is not None and args.budget_s <= 0:
            raise TippetopError(f"--budget-s: expected a number > 0, got {args.budget_s}")
        res = run_accuracy([args.scene] if args.scene else ["fig3", "fig11_n060"],
                           args.out or "accuracy", force=args.force, engines=engines,
                           budget_s=args.budget_s or DEFAULT_BUDGET_S,
                           mujoco_budget_s=args.budget_s or DEFAULT_MUJOCO_BUDGET_S,
                           workers=args.workers,
                           log=None if args.json else (lambda m: print(m, file=sys.stderr)))
        if args.json:
            print_json({k: v for k, v in res.items() if k != "report"})
        else:
            print(res["report"])
        return 0
    from tippetop.compare.analysis.bench import bench_ode

    if args.what != "ode":
        raise TippetopError(f"bench: expected 'ode' or 'accuracy', got {args.what!r}")
    res = bench_ode(n0=args.n0, t_end_s=args.t_end_s, rtol=args.rtol, rounds=args.rounds,
                    scipy_rounds=args.scipy_rounds)
    if args.json:
        print_json(res)
    else:
        print(res.pop("report"))
    return 0


# ---------------------------------------------------------------- compare
def cmd_compare(args: argparse.Namespace) -> int:
    """``tippetop compare``: one scene in several engines/modes, against the theory."""
    from tippetop.compare.analysis.crossval import compare_scene
    from tippetop.models.modes import parse_modes

    res = compare_scene(args.scene, parse_modes(args.modes), tuple(args.set or []),
                        scheduler=args.scheduler, workers=args.workers,
                        use_cache=not args.no_cache)
    if args.json:
        print_json(res)
    else:
        print_compare(res)
    # a failed run is reported in its row (the others kept), and the command exits 1
    failed = [m for m, s in res["modes"].items() if s.get("outcome") == "failed"]
    if failed:
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(res['modes'])} runs "
                         f"failed ({', '.join(failed)}); the reasons are in the output\n")
        return EXIT_RUN_FAILED
    return 0


#: Unit of each metric ``compare`` checks against the reference.
METRIC_UNITS = {"theta_asymp": "rad", "theta_rms": "rad", "t_invert": "s",
                "J_rel_drift": "relative", "d_theta_asymp": "rad"}


def _tolerance_why(metric: str, d: dict[str, Any]) -> str:
    """Why a tolerance is what it is: the difference's own ``why``, else crossval's table."""
    why = d.get("why")
    if not why:
        try:
            from tippetop.compare.analysis.crossval import TOLERANCES

            why = TOLERANCES.get(metric, (None, ""))[1]
        except ImportError:  # pragma: no cover - crossval is part of the package
            why = ""
    # the table's reasons start with the unit ("s; 1 ms sampling ..."): the unit is shown
    head, sep, tail = str(why or "").partition("; ")
    return tail if sep and len(head) <= 12 else str(why or "")


def difference_text(d: dict[str, Any]) -> str:
    """One difference from the reference in words, naming the tolerance it broke.

    Example: ``t_invert 2.496 s against the reference's 2.329 s: 0.167 s apart, over the
    t_invert tolerance of 0.1 s (1 ms sampling plus ...)``.
    """
    metric = str(d.get("metric", "?"))
    unit = METRIC_UNITS.get(metric, "")
    value, ref, tol = d.get("value"), d.get("reference"), d.get("tolerance")
    if metric == "status":
        note = d.get("note") or value
        return f"the run failed ({note}); the reference's status is {fmt(ref)}"
    if metric == "outcome":
        return f"ends {fmt(value)} where the reference ends {fmt(ref)} (a different outcome)"
    if metric == "t_invert" and (value is None) != (ref is None):
        if value is None:
            return f"never turns over; the reference does at {fmt(ref, 's')}"
        return f"turns over at {fmt(value, 's')}; the reference never does"
    text = f"{metric} {fmt(value, unit)}"
    if metric == "theta_rms":
        text = f"theta(t) departs from the reference's by {fmt(value, 'rad')} RMS"
    elif ref is not None:
        text += f" against the reference's {fmt(ref, unit)}"
    if tol is None:
        return text
    if isinstance(value, (int, float)) and isinstance(ref, (int, float)) and metric not in (
            "J_rel_drift", "theta_rms"):
        text += f": {fmt(abs(value - ref), unit)} apart"
    why = _tolerance_why(metric, d)
    limit = "limit" if metric == "J_rel_drift" else "tolerance"
    return f"{text}, over the {metric} {limit} of {fmt(tol, unit)}" + (
        f" ({why})" if why else "")


def print_compare(res: dict[str, Any]) -> None:
    """``tippetop compare`` for a person: the theory, one line per mode, what differs and why.

    Robust to the keys a result has: a missing value is ``-``.
    """
    th = res.get("theory") or {}
    theta_s = th.get("theta_s")
    tol_s = th.get("theta_s_tol")
    head = f"{res.get('scene', '?')} (Group {res.get('group', '?')}): "
    if "outcome" in th and th["outcome"] is None:  # needs a run's Jellett constant at t = 0
        print(head + "no prediction from the theory: every run failed")
    else:
        print(head + f"the theory predicts {th.get('outcome', '?')}, theta_s = "
              f"{fmt(theta_s, 'rad')}")
    modes: dict[str, dict[str, Any]] = res.get("modes") or {}
    rows = []
    for m, s in modes.items():
        matches = s.get("matches_theory")
        if s.get("outcome") == "failed":
            rows.append((m, "failed", "DIFFERS" if matches is False else MISSING,
                         *[MISSING] * 5))
            continue
        rows.append((
            m + (" (reference)" if m == "ode" else ""),
            fmt(s.get("outcome")),
            {True: "agrees", False: "DIFFERS", None: MISSING}.get(matches, fmt(matches)),
            fmt_value("t_invert", s.get("t_invert")).split(" (")[0],
            fmt(s.get("theta_asymp"), "rad"),
            fmt(s.get("J_rel_drift"), "relative"),
            fmt(s.get("energy_dissipated_J"), "J"),
            MISSING if m == "ode" else fmt(s.get("theta_rms_vs_ref"), "rad"),
        ))
    if rows:
        print()
        print(table(("mode", "outcome", "theory", "t_invert", "theta_asymp", "J drift",
                     "energy lost", "theta RMS vs ref"), rows))
    agree_rule = (f"agrees: the theory's outcome, and theta_asymp within "
                  f"{fmt(tol_s, 'rad')} of theta_s" if tol_s is not None else
                  "agrees: the theory's outcome")
    print(f"  ({agree_rule}; J drift: Jellett's constant, relative)")
    against = [(str(r.get("mode")), r.get("reasons") or []) for r in res.get("crossval") or []
               if not r.get("agrees", True)]
    if against:
        print("\nagainst the theory:")
        width = max(len(m) for m, _ in against)
        for m, reasons in against:
            print(labelled(m, "; ".join(reasons) if reasons else "does not agree", width))
    diffs = res.get("differences") or []
    print()
    if not diffs:
        print("differences from the reference beyond their tolerances: none")
    else:
        print("differences from the reference beyond their tolerances:")
        width = max(len(str(d.get("mode", ""))) for d in diffs)
        for d in diffs:
            print(labelled(str(d.get("mode", "?")), difference_text(d), width))
    ran = []
    for m, s in modes.items():
        if "engine" not in s:
            continue
        try:
            from tippetop.compare.running.engines import describe_ran

            text = describe_ran(s)
        except (KeyError, TypeError, ValueError):
            text = MISSING
        ran.append((m, re.sub(r"\b(None|nan)\b", MISSING, text)))
    if ran:
        print("\nwhat ran:")
        width = max(len(m) for m, _ in ran)
        for m, text in ran:
            print(labelled(m, text, width))
    notes = [(m, str(s.get("note"))) for m, s in modes.items() if s.get("note") and m != "ode"]
    if notes:
        print("\nwhy a mode may depart from the paper's law:")
        width = max(len(m) for m, _ in notes)
        for m, note in notes:
            print(labelled(m, note, width))


# ---------------------------------------------------------------- threshold
def cmd_threshold(args: argparse.Namespace) -> int:
    """``tippetop threshold``: n1 or nc by bisection on n0; ``--out`` writes the runs."""
    from tippetop.compare.analysis.threshold import measure_threshold

    out_dir = None
    if getattr(args, "out", None):
        from tippetop.compare.running.io import check_output_dir, hold_output_lock

        out_dir = check_output_dir(args.out, force=args.force)
        hold_output_lock(out_dir)  # a second run into it is refused now, not mixed in later
    method = {"method": args.method} if getattr(args, "method", None) else {}
    res = measure_threshold(args.scene, args.engine, args.which, tuple(args.set or []),
                            rel_tol=args.rel_tol, scheduler=args.scheduler,
                            workers=args.workers, use_cache=not args.no_cache, **method)
    files = _write_threshold(res, out_dir) if out_dir is not None else []
    if args.json:
        print_json(res)
    else:
        print_threshold(res)
        print(_cache_line(None, None, not args.no_cache))
        if files:
            print("wrote " + ", ".join(str(f) for f in files))
    if res.get("failed_runs"):  # every run is reported above; the failure in one line
        sys.stderr.write(f"tippetop: run failed: {res['warning']}\n")
        return EXIT_RUN_FAILED
    return 0


def _write_threshold(res: dict[str, Any], out: Any) -> list[Any]:
    """``threshold.json`` (the ``--json`` result) and ``runs.csv`` (every run) into ``out``."""
    import csv

    from tippetop.compare.common_args import json_text
    from tippetop.compare.running.io import staged_output_dir

    names = ["threshold.json", "runs.csv"]
    with staged_output_dir(out) as stage:  # all files or none
        (stage / names[0]).write_text(json_text(res, indent=1) + "\n", "utf-8")
        runs = [{k: v for k, v in r.items() if not isinstance(v, (list, dict))}
                for r in res.get("runs") or []]  # nested values stay in threshold.json
        cols = list(dict.fromkeys(k for r in runs for k in r)) or ["n0"]
        with open(stage / names[1], "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            w.writeheader()
            w.writerows(runs)
    return [out / n for n in names]


#: Where the theory's value of each threshold comes from.
THRESHOLD_THEORY = {"n1": "eq. 4.13", "n4": "n3 (1 + a/R) / (1 - a/R)",
                    "nc": "Sec. 4.3: n4, or n1 for A/C <= rc"}


def print_threshold(res: dict[str, Any]) -> None:
    """A measured critical spin for a person.

    The measured spin against the theory's, how it was measured (growth rates or a
    bisection), the check at twice the horizon (bisection), and a warning when the answer is
    not to be trusted.
    """
    which = res.get("which", "?")
    horizon = res.get("horizon_s")
    method = res.get("method", "bisect")
    runs = res.get("runs") or []
    n_runs = res.get("n_runs", len(runs))
    if method == "growth":
        how = f"from growth rates of {n_runs} runs of {fmt(horizon, 's')} near the steady state"
    else:
        how = f"by bisection on n0 over {n_runs} runs of {fmt(horizon, 's')}"
    print(f"{which} of {res.get('scene', '?')} in {res.get('engine', '?')}, {how}:")
    bracket = res.get("bracket") or [None, None]
    rows = [
        ("measured", fmt(res.get("measured"), "rad/s"),
         f"bracket {fmt(bracket[0])} to {fmt(bracket[-1], 'rad/s')}"),
        ("theory", fmt(res.get("theory"), "rad/s"), THRESHOLD_THEORY.get(which, "")),
        ("difference", fmt_percent(res.get("rel_diff")), "measured / theory - 1"),
    ]
    if which == "nc" and method == "growth":
        rows += [(k, fmt(res.get(k), "rad/s"), "measured") for k in ("n1", "n4")
                 if k in res]
    print(table(("", "value", ""), rows, indent="  ", header=False))
    check = res.get("horizon_check")
    if isinstance(check, dict):
        h2 = fmt(check.get("horizon_s"), "s")
        if check.get("depends_on_horizon"):
            print(f"  horizon check: over {h2} the bracket's ends change side")
        else:
            print(f"  horizon check: over {h2} the bracket's ends keep their side")
    if method == "growth" and "settled" in res:
        print("  fits: " + ("every run is two modes, cleanly" if res["settled"] else
                            "some runs are not two clean modes (see runs in --json)"))
    elif res.get("unsettled_n0"):
        print("  still moving at the end of their runs: n0 = "
              + ", ".join(fmt(n) for n in res["unsettled_n0"]) + " rad/s")
    conv = res.get("converged")
    if conv is not None:
        why = []
        if res.get("bracket_converged") is False:
            why.append("the bracket is wider than --rel-tol after the rounds allowed")
        if res.get("depends_on_horizon"):
            why.append("the answer depends on the run length")
        if method == "growth" and res.get("settled") is False:
            why.append("a fit is not clean")
        print(f"  converged: {fmt(conv)}" + (f" ({'; '.join(why)})" if why and not conv
                                              else ""))
    if res.get("warning"):
        print(f"  warning: {res['warning']}")


# ---------------------------------------------------------------- sweep
def cmd_sweep(args: argparse.Namespace) -> int:
    """``tippetop sweep``: theta_asymp against n0 per mode, optionally written to ``--out``."""
    from pathlib import Path

    from tippetop.compare.analysis.sweep import parse_range, run_sweep
    from tippetop.compare.presentation.figures import sweep_figure
    from tippetop.compare.running.io import check_writable, hold_output_lock, write_atomic
    from tippetop.models.modes import parse_modes

    n0s = parse_range(args.n0)
    modes = parse_modes(args.modes)
    out_dir = None
    if args.out:
        out_dir = Path(args.out)
        files = [out_dir / "sweep.csv", out_dir / "theory.csv", out_dir / "sweep.png"]
        if out_dir.exists() and not out_dir.is_dir():
            raise TippetopError(f"--out: expected a folder, got the file {str(out_dir)!r}")
        if any(f.exists() for f in files) and not args.force:
            raise TippetopError(f"--out: expected a folder without sweep results (or --force), "
                                f"got {str(out_dir)!r} which has them")
        base = out_dir if out_dir.is_dir() else out_dir.parent
        if not base.is_dir():
            raise TippetopError(f"--out: expected an existing parent folder, got {str(base)!r}")
        check_writable(base)  # before the runs, not after them
        hold_output_lock(out_dir)  # a second sweep into it is refused now
    res = run_sweep(args.scene, n0s, modes, tuple(args.set or []), scheduler=args.scheduler,
                    workers=args.workers, use_cache=not args.no_cache)
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(files[0], lambda tmp: res["table"].to_csv(tmp, index=False))
        write_atomic(files[1], lambda tmp: res["theory"].to_csv(tmp, index=False))
        sweep_figure(res, files[2])
    if args.json:
        print_json({"scene": res["scene"], "computed": res["computed"], "cached": res["cached"],
                    "rows": res["table"].to_dict(orient="records")})
    else:
        print_sweep(res)
        print(_cache_line(res.get("computed"), res.get("cached"), not args.no_cache))
        if out_dir is not None:
            print("wrote " + ", ".join(str(f) for f in files))
        else:
            print("not written: --out DIR writes sweep.csv, theory.csv and sweep.png")
    # a failed run is a row with its status (the others kept), and the command exits 1
    table = res["table"]
    failed = table[table["outcome"] == "failed"] if len(table) else table
    if len(failed):
        sys.stderr.write(f"tippetop: run failed: {len(failed)} of {len(table)} runs failed "
                         f"({', '.join(sorted(set(failed['status'])))}); each is a row with "
                         "its status\n")
        return EXIT_RUN_FAILED
    return 0


def print_sweep(res: dict[str, Any]) -> None:
    """A sweep for a person: per mode and n0, theta_asymp against the theory's theta_s(n0)."""
    import numpy as np

    rows_in = res["table"].to_dict(orient="records")
    th = res.get("theory")
    print(f"{res.get('scene', '?')}: theta_asymp against n0, with the theory's theta_s(n0)")
    rows = []
    for r in rows_in:
        t_inv = r.get("t_invert")
        if isinstance(t_inv, float) and math.isnan(t_inv):
            r["t_invert"] = None  # pandas holds "never turned over" as NaN
        theta_s = None
        if th is not None and len(th):
            theta_s = float(np.interp(r["n0"], th["n0"], th["theta_s"]))
        rows.append((r.get("mode"), fmt(r.get("n0"), "rad/s"), fmt(r.get("theta_asymp"), "rad"),
                     fmt(theta_s, "rad"), fmt(r.get("outcome")),
                     fmt_value("t_invert", r.get("t_invert")).split(" (")[0],
                     fmt(r.get("J_rel_drift"), "relative"), fmt(r.get("status")),
                     "cache" if r.get("cached") else "run"))
    print(table(("mode", "n0", "theta_asymp", "theta_s", "outcome", "t_invert", "J drift",
                 "status", "from"), rows))
