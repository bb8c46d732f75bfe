"""Is it a limit of MuJoCo? Search MuJoCo's whole contact space at one point of the fidelity map.

Issue 41, item 4: a point may be called a limit of MuJoCo only after a search over MuJoCo's
whole contact space (cone, impratio, solref, solreffriction, solimp, noslip, condim,
integrator, step) fails there, and the search is reported. Stage 1 draws candidates
space-filling over that space (:mod:`tippetop.compare.studies.contact_search`); stage 2 keeps
the cells stage 1's evidence does not rule out and searches them densely (a Sobol draw, sysid
fits, local rounds: :mod:`tippetop.compare.studies.contact_search_refine`). Every candidate is
verified from the point's four starts exactly as the tuning verifies. It prints each stage
(its candidates, runs, time, the cells kept and why), the statement (``limit: ...``), the
best ten, and where in stage 1's even draw each check fails.

Run: ``python scripts/contact_search.py --point A_OVER_C,A_OVER_R,MU [--n0 RAD_S]
[--theta0 RAD] [--candidates 112] [--budget-runs 1000] [--stages 2] [--no-fit] [--t-end-s 8]
[--seed 0] [--tuned FILE|none] [--no-neighbours] [--json] [--out FILE] [--workers N]
[--scheduler ADDRESS] [--no-cache]``. ``--budget-runs`` caps the MuJoCo runs of the whole
search (four per candidate, cached or not; one per fit rollout): the default takes about
10 min on 2 cores at 8-s runs.
The point's tuned settings are a baseline, from ``--tuned`` (a fidelity map's results.json;
default: the docs' map, docs/data/fidelity-default.json, where it holds the point), and so is
the first baseline with each choice (cone, condim, integrator, step, noslip) changed alone,
unless ``--no-neighbours``. Exit status: 0 done (whether or not a candidate agrees), 1 a run
or a write failed, 2 bad input (one line), 130 Ctrl-C.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, NoReturn

ROOT = Path(__file__).resolve().parents[1]
DOCS_MAP = ROOT / "docs" / "data" / "fidelity-default.json"
PROG = "contact_search"


class BadInput(Exception):
    """Bad input: one line on stderr, exit 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise BadInput(message)


def _point(text: str) -> tuple[float, float, float]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) and v > 0 for v in vals):
        raise argparse.ArgumentTypeError(f"expected A/C,a/R,mu (three numbers > 0), got "
                                         f"{text!r}")
    if not vals[1] < 1.0:
        raise argparse.ArgumentTypeError(f"expected a/R in (0, 1), got {vals[1]:g}")
    return vals  # type: ignore[return-value]


def parser() -> argparse.ArgumentParser:
    """The command line (bad input raises :class:`BadInput`, one line)."""
    from tippetop.compare.commands.options import (
        NO_CACHE_HELP,
        SCHEDULER_HELP,
        WORKERS_HELP,
        HelpFormatter,
        finite_float,
        worker_count,
    )
    from tippetop.compare.studies.contact_search import DEFAULT_CANDIDATES, DEFAULT_T_END_S
    from tippetop.compare.studies.contact_search_refine import DEFAULT_BUDGET_RUNS

    p = _Parser(prog=PROG, formatter_class=HelpFormatter,
                description="Search MuJoCo's whole contact space at one point: does any "
                            "contact agree with the reference from every start?")
    p.add_argument("--point", type=_point, required=True, metavar="A/C,a/R,MU",
                   help="the point: the top's A/C and a/R and the law's mu, e.g. 1.0,0.1,0.3")
    p.add_argument("--n0", type=finite_float, default=None, metavar="RAD_S",
                   help="the fit's start spin (default: the fidelity map's, 100 rad/s or "
                        "1.25 x the top's thresholds)")
    p.add_argument("--theta0", type=finite_float, default=0.1, metavar="RAD",
                   help="the fit's start tilt (default 0.1 rad)")
    p.add_argument("--candidates", type=int, default=DEFAULT_CANDIDATES, metavar="N",
                   help=f"candidates stage 1 draws besides the baselines (default "
                        f"{DEFAULT_CANDIDATES}; fewer where half the budget is less)")
    p.add_argument("--budget-runs", type=int, default=DEFAULT_BUDGET_RUNS, metavar="N",
                   help=f"MuJoCo runs the whole search may use, four per candidate and one "
                        f"per fit rollout (default {DEFAULT_BUDGET_RUNS}: about 10 min on 2 "
                        f"cores at 8-s runs)")
    p.add_argument("--stages", type=int, choices=(1, 2), default=2,
                   help="1: the even draw alone; 2: then the dense stage (default)")
    p.add_argument("--no-fit", action="store_true",
                   help="leave out stage 2's sysid fits")
    p.add_argument("--t-end-s", type=finite_float, default=DEFAULT_T_END_S, metavar="S",
                   help=f"horizon of every run (default {DEFAULT_T_END_S:g} s)")
    p.add_argument("--seed", type=int, default=0, help="the draw's seed (default 0)")
    p.add_argument("--tuned", default=None, metavar="FILE|none",
                   help="a fidelity map's results.json holding the point's tuned settings "
                        "(a baseline; default: the docs' map where it holds the point)")
    p.add_argument("--no-neighbours", action="store_true",
                   help="leave out the first baseline with each choice changed alone")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="also write the result's JSON to FILE")
    p.add_argument("--workers", type=worker_count, default=None, help=WORKERS_HELP)
    p.add_argument("--scheduler", default=None, help=SCHEDULER_HELP)
    p.add_argument("--no-cache", action="store_true", help=NO_CACHE_HELP)
    return p


def _tuned(arg: str | None, point: tuple[float, float, float]) -> tuple[dict[str, Any] | None,
                                                                       str]:
    """The point's tuned settings and where they came from (``none`` where there are none)."""
    from tippetop.compare.studies.contact_search import tuned_settings_from

    if arg is not None and arg.lower() == "none":
        return None, "none (--tuned none)"
    path = DOCS_MAP if arg is None else Path(arg)
    try:
        res = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(res, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as exc:
        if arg is None:
            return None, f"none ({path} unreadable)"
        raise BadInput(f"--tuned: expected a fidelity map's results.json, got {arg} "
                       f"({exc.__class__.__name__}: {exc})") from None
    settings = tuned_settings_from(res, *point)
    if settings is None:
        if arg is not None:
            raise BadInput(f"--tuned: {arg} holds no tuned settings for A/C = {point[0]:g}, "
                           f"a/R = {point[1]:g}, mu = {point[2]:g}")
        return None, f"none (the point is not in {path.relative_to(ROOT)})"
    return settings, str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)


def summary(result: dict[str, Any], tuned_from: str) -> list[str]:
    """The readable summary: the point, the cost, the stages, the statement, the top ten."""
    pt = result["point"]
    n = result["candidates_evaluated"]
    wall = result["wall_s"]
    runs = result["runs"]
    lines = [f"contact search at A/C = {pt['A_over_C']:g}, a/R = {pt['a_over_R']:g}, mu = "
             f"{pt['mu']:g} (Group {pt['group']}), n0 = {pt['n0']:.4g} rad/s, theta0 = "
             f"{pt['theta0']:g} rad: {len(result['starts'])} starts, {result['t_end_s']:g} s "
             f"each, MuJoCo {result['mujoco_version']}",
             f"{n} candidates in {len(result['stages'])} stage(s) (seed {result['seed']}; "
             + ", ".join(f"{v} {k}" for k, v in result["origins"].items())
             + f"; tuned from {tuned_from}), "
             f"{runs['mujoco']} MuJoCo runs of --budget-runs {result['budget_runs']} "
             f"({runs['cached']} cached, {runs['fit_rollouts']} fit rollouts), {wall:.0f} s"
             + (f", {60.0 * n / wall:.1f} candidates/min" if wall > 0 else ""),
             *stage_lines(result), "",
             f"{'#':>3} {'agrees':>6} {'passes':>7} {'theta rms':>9}  {'origin stage':<12} "
             "first departing check | settings"]
    for k, r in enumerate(result["top"], 1):
        first = r["first_departing"]
        rms = r["theta_rms_rad"]
        lines.append(f"{k:>3} {'yes' if r['agrees'] else 'no':>6} "
                     f"{r['passes']:>3}/{r['checks']:<3} "
                     f"{'-' if rms is None else f'{rms:.3g}':>9}  "
                     f"{r['settings']['origin'] + ' ' + str(r.get('stage', 1)):<12} "
                     f"{'-' if first is None else first['check'] + ' (' + first['role'] + ')'}"
                     f" | {r['label']}")
    lines += ["", "where it departs (stage 1's drawn candidates by each dimension's value: "
                  "how many agree, and the share passing each check from every start):"]
    lines += [f"  {line}" for line in attribution_lines(result)]
    return lines


#: The checks' short names in :func:`attribution_lines`' table.
SHORT = {"completed": "runs", "stays_on_table": "table", "outcome": "outcome",
         "t_invert": "t_inv", "t_stem": "t_stem", "jellett_before_stem": "J",
         "energy_never_rises": "E"}


def attribution_lines(result: dict[str, Any]) -> list[str]:
    """A table: per dimension and value, agreeing / n and each check's share passing."""
    from tippetop.compare.studies.fidelity import CAUSE_ORDER

    att = result["attribution"]
    used = [c for c in CAUSE_ORDER
            if any(c in cell["checks"] for vals in att.values() for cell in vals.values())]
    lines = [f"{'dimension':<18} {'value':<24} {'agree':>6} "
             + " ".join(f"{SHORT.get(c, c):>7}" for c in used)]
    for dim, vals in att.items():
        for k, (val, cell) in enumerate(vals.items()):
            shares = [cell["checks"].get(c) for c in used]
            lines.append(f"{dim if k == 0 else '':<18} {val:<24} "
                         f"{str(cell['agree']) + '/' + str(cell['n']):>6} "
                         + " ".join(f"{'-' if v is None else f'{v:.0%}':>7}" for v in shares))
    return lines


def stage_lines(result: dict[str, Any]) -> list[str]:
    """Each stage in a few lines: its candidates, runs and time, its cells and why, its best."""
    lines = []
    for s in result.get("stages") or []:
        if s.get("skipped"):
            lines.append(f"stage {s['stage']} ({s['name']}): not run: {s['skipped']}")
            continue
        b = s["best"]
        best = ("-" if b is None else f"{b['passes']}/{b['checks']} "
                f"{'agrees' if b['agrees'] else 'departs'} ({b['origin']}): {b['label']}")
        if s["stage"] == 1:
            lines.append(f"stage 1 ({s['name']}, all {s['cells']['of']} cells): "
                         f"{s['candidates']} candidates ({s['drawn']} drawn of "
                         f"{s['drawn_asked']} asked; baselines: "
                         + (", ".join(f"{v} {k}" for k, v in s["baselines"].items()) or "none")
                         + f"), {s['runs']} runs, {s['wall_s']:.0f} s; best {best}")
            continue
        rule = s["cells"]
        parts = "; ".join(
            f"{p['part']} {p['candidates']}" + (f" ({p['rollouts']} rollouts)" if "rollouts"
                                                in p else "") for p in s["parts"])
        lines += [f"stage 2 ({s['name']}, {rule['cells_kept']} of {rule['cells_total']} "
                  f"cells kept): {s['candidates']} candidates ({parts}), {s['runs']} runs, "
                  f"{s['wall_s']:.0f} s; best {best}", f"  the rule: {rule['rule']}",
                  "  kept: " + "; ".join(f"{d} " + ", ".join(str(v) for v in vals)
                                         for d, vals in rule["kept_values"].items())
                  + "".join(f"; and {_cell_text(c)} ({c['why']})" for c in rule["cells"]
                            if not c["why"].startswith("no choice"))]
        for c in rule["choices"]:
            lines.append(f"  {c['dimension'] + ' = ' + str(c['value']):<26} "
                         f"{c['ran']:>3}/{c['candidates']:<3} ran  {c['why']}")
        for f in next((p["fits"] for p in s["parts"] if p["part"] == "fit"), []):
            lines.append(f"  fit: RMS {_num(f['rms_from_rad'])} -> {_num(f['rms_rad'])} rad in "
                         f"{f['rollouts']} rollouts ({f['stop']}), "
                         + ("a candidate already verified" if f["duplicate"] else
                            f"verified {f['passes']}/{f['checks']}") + f": {f['to']}")
    return lines + [f"limit: {result['limit']}"]


def _num(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.3g}"


def _cell_text(c: dict[str, Any]) -> str:
    return (f"{c['cone']} condim {c['condim']} noslip {c['noslip_iterations']} "
            f"{c['integrator']} dt {c['timestep_s']:g}")


def main(argv: list[str] | None = None) -> int:
    """Run the search and print its summary (or its JSON)."""
    from tippetop.models.errors import RunFailedError, TippetopError

    try:
        from tippetop.compare.running.interrupt import install_sigterm_handler

        install_sigterm_handler()  # SIGTERM stops the runs as Ctrl-C does
        args = parser().parse_args(argv)
        if args.out is not None and not args.out.parent.is_dir():
            raise BadInput(f"--out: expected a file in an existing folder, got {args.out}")
        tuned, tuned_from = _tuned(args.tuned, args.point)
        from tippetop.compare.studies.contact_search_refine import (
            SearchOptions,
            search_two_stage,
        )

        options = SearchOptions(candidates=args.candidates, seed=args.seed,
                                with_neighbours=not args.no_neighbours,
                                budget_runs=args.budget_runs, stages=args.stages,
                                fit=not args.no_fit)
        result = search_two_stage(*args.point, n0=args.n0, theta0=args.theta0,
                                  t_end_s=args.t_end_s, tuned=tuned, options=options,
                                  progress=True,
                                  run_options={"scheduler": args.scheduler,
                                               "workers": args.workers,
                                               "use_cache": not args.no_cache})
        result["tuned_from"] = tuned_from
    except BadInput as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    except RunFailedError as exc:
        print(f"{PROG}: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except TippetopError as exc:
        print(f"{PROG}: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    from tippetop.compare.running.io import json_ready, write_atomic

    text = json.dumps(json_ready(result), indent=1)
    if args.out is not None:
        try:
            write_atomic(args.out, lambda tmp: tmp.write_text(text + "\n", "utf-8"))
        except OSError as exc:
            print(f"{PROG}: could not write {args.out}: {exc}", file=sys.stderr)
            return 1
    print(text if args.json else "\n".join(summary(result, tuned_from)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
