"""The fidelity map's cost: the grid tuned point by point, several at once, against one at a time.

Issue 41's target: the default map (18 points) in at most 20 minutes on 2 cores. Every run
here neither reads nor writes the run cache nor the tunings' (``use_cache=False``: every
reference run, fit and verification is computed). In one run of this script:

1. **the baseline, on a subset** (``--baseline-points``, default 4, spread over the grid from
   its cheapest corner, mu = 0.1, to its dearest, mu = 1): those points one at a time in this
   process, the map's way before issue 41 (``points_at_once=1``: each point's runs on every
   core), then the same points as the map tunes them now (several at once, each in a process
   of its own); their ratio, and whether both gave the same points (they must);
2. **the map**: the whole grid as ``tippetop fidelity`` tunes it, its wall time, each point's
   own time (the points overlap: their sum is more than the wall time) and the target met or
   not; and the map one at a time estimated from it and the subset's ratio (an estimate: the
   whole grid is tuned once only).

The load average is sampled throughout and printed with each timing, with the process CPU time
(this process and the points' processes): on a shared machine a timing is only as good as
the load it ran under.

Run: ``python benchmarks/bench_fidelity.py [--grid default] [--baseline-points 4] [--t-end-s 8]
[--budget-runs 200] [--workers N] [--json] [--out DIR]`` (``--a-over-c``, ``--a-over-r``,
``--mu`` replace the grid's lists, as the command's do). ``--out DIR`` writes the map as
``tippetop fidelity --out`` does (docs/data/fidelity-default.json is such a run's
results.json). Measured: docs/guide/fidelity.md, "Cost".
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tippetop.compare.results.fidelity import FidelityPoint, FidelityResult

#: Issue 41: the default map within 20 minutes on 2 cores.
TARGET_S = 20 * 60.0
#: The keys that say what a point is, compared between the two ways of tuning it.
SAME_KEYS_SKIPPED = ("wall_s", "cached")


class LoadSampler:
    """The 1-minute load average, sampled every few seconds while a block runs."""

    def __init__(self, every_s: float = 5.0) -> None:
        self.every_s = every_s
        self.samples: list[float] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> LoadSampler:
        self.samples = [os.getloadavg()[0]]
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            self.samples.append(os.getloadavg()[0])

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.samples.append(os.getloadavg()[0])

    def text(self) -> str:
        """``load 2.1-3.4 (mean 2.8)``."""
        s = self.samples or [float("nan")]
        return f"load {min(s):.1f}-{max(s):.1f} (mean {sum(s) / len(s):.1f})"

    def to_json(self) -> dict[str, float]:
        """``{min, mean, max}`` of the samples."""
        s = self.samples or [float("nan")]
        return {"min": min(s), "mean": sum(s) / len(s), "max": max(s)}


def cpu_s() -> float:
    """CPU time of this process and of its children, ended and running (s).

    The running ones (the reference's worker processes, kept from one batch to the next)
    through psutil where it is installed.
    """
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    try:
        import psutil
    except ImportError:  # pragma: no cover - the ended children only
        return total
    for child in psutil.Process().children(recursive=True):
        try:
            t = child.cpu_times()
        except psutil.Error:  # gone meanwhile: counted in RUSAGE_CHILDREN once reaped
            continue
        total += t.user + t.system
    return total


def timed(fn: Any, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
    """``fn(**kwargs)`` and ``{wall_s, cpu_s, load}`` of it."""
    cpu0 = cpu_s()
    with LoadSampler() as load:
        t0 = time.perf_counter()
        res = fn(**kwargs)
        wall = time.perf_counter() - t0
    return res, {"wall_s": wall, "cpu_s": cpu_s() - cpu0, "load": load.to_json(),
                 "load_text": load.text()}


def same_points(a: list[FidelityPoint], b: list[FidelityPoint]) -> bool:
    """Whether two maps' points are the same but for their timing and cache flags."""
    def strip(points: list[FidelityPoint]) -> str:
        return json.dumps([{k: v for k, v in p.to_json().items() if k not in SAME_KEYS_SKIPPED}
                           for p in points], sort_keys=True, default=str)
    return strip(a) == strip(b)


def subset(points: list[tuple[float, float, float]], n: int) -> list[tuple[float, float, float]]:
    """``n`` points spread evenly over the grid's order (its first and its last among them)."""
    if n >= len(points):
        return list(points)
    if n == 1:
        return [points[-1]]
    return [points[round(k * (len(points) - 1) / (n - 1))] for k in range(n)]


def main() -> int:
    """Run the baseline and the map; print the times, the ratio and the target."""
    from pathlib import Path

    from tippetop.compare.commands.fidelity import DEFAULT_BUDGET_RUNS, write_fidelity
    from tippetop.compare.presentation.fidelity import table_lines
    from tippetop.compare.running.io import check_output_dir
    from tippetop.compare.studies.defaults import Grid
    from tippetop.compare.studies.fidelity import (
        DEFAULT_GRID,
        DEFAULT_T_END_S,
        machine_cores,
        make_grid,
        run_fidelity,
    )

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default=DEFAULT_GRID)
    ap.add_argument("--a-over-c", dest="A_over_C", default=None)
    ap.add_argument("--a-over-r", dest="a_over_R", default=None)
    ap.add_argument("--mu", default=None)
    ap.add_argument("--t-end-s", dest="t_end_s", type=float, default=DEFAULT_T_END_S)
    ap.add_argument("--budget-runs", dest="budget_runs", type=int, default=DEFAULT_BUDGET_RUNS)
    ap.add_argument("--workers", type=int, default=None,
                    help="points tuned at once (default: the command's, every core)")
    ap.add_argument("--baseline-points", dest="baseline_points", type=int, default=4,
                    help="points of the grid tuned both ways for the ratio (0: none)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", metavar="DIR", default=None,
                    help="also write the map (results.json, fidelity.png, report.html) here, "
                         "as `tippetop fidelity --out DIR` does (new or empty folder)")
    args = ap.parse_args()
    grid = make_grid(args.grid, args.A_over_C, args.a_over_R, args.mu)
    out_dir = check_output_dir(args.out, force=False) if args.out else None
    common = {"t_end_s": args.t_end_s, "budget_runs": args.budget_runs, "use_cache": False,
              "progress": True}
    cores = machine_cores()
    say = print if not args.json else (lambda *a, **k: None)
    say(f"grid {grid.name} ({len(grid.points())} points), t_end {args.t_end_s:g} s, "
        f"--budget-runs {args.budget_runs}, {cores} cores, no cache; "
        f"load now {os.getloadavg()[0]:.1f}", flush=True)

    # 1. the baseline: a subset one at a time (before issue 41), then at once (now)
    base: dict[str, Any] | None = None
    if args.baseline_points > 0:
        pts = subset(grid.points(), args.baseline_points)
        say(f"baseline: {len(pts)} points " + ", ".join(f"({r:g}, {e:g}, {m:g})"
                                                       for r, e, m in pts)
            + " (A/C, a/R, mu)", flush=True)
        sub_grids = [Grid("custom", (r,), (e,), (m,)) for r, e, m in pts]

        def one_at_a_time() -> list[FidelityPoint]:
            parts = [run_fidelity(g, points_at_once=1, **common) for g in sub_grids]
            return [p for part in parts for p in part.points]

        def at_once() -> FidelityResult:
            # the subset as one grid would hold other points: the map's own path on these
            return _run_points(run_fidelity, pts, workers=args.workers, **common)

        serial, serial_t = timed(one_at_a_time)
        say(f"  one at a time: {serial_t['wall_s']:.0f} s ({serial_t['load_text']}, CPU "
            f"{serial_t['cpu_s']:.0f} s)", flush=True)
        paral, paral_t = timed(at_once)
        say(f"  at once ({paral.points_at_once} points at once): "
            f"{paral_t['wall_s']:.0f} s ({paral_t['load_text']}, CPU {paral_t['cpu_s']:.0f} s)",
            flush=True)
        same = same_points(serial, list(paral.points))
        ratio = serial_t["wall_s"] / paral_t["wall_s"]
        say(f"  ratio one at a time / at once: {ratio:.2f}x; the same points: "
            f"{'yes' if same else 'NO'}", flush=True)
        base = {"points": [list(p) for p in pts], "one_at_a_time": serial_t,
                "at_once": {**paral_t, "points_at_once": paral.points_at_once},
                "ratio": ratio, "same_points": same,
                "per_point_one_at_a_time_s": [p.wall_s for p in serial]}

    # 2. the map, once
    res, map_t = timed(run_fidelity, grid=grid, workers=args.workers, **common)
    if out_dir is not None:
        write_fidelity(res, Path(out_dir))
    pts_res = res.points
    wall = map_t["wall_s"]
    applies = grid.name == DEFAULT_GRID and args.t_end_s == DEFAULT_T_END_S and \
        args.budget_runs == DEFAULT_BUDGET_RUNS
    met = wall <= TARGET_S
    estimate = wall * base["ratio"] if base else None
    out = {"grid": res.grid.to_json(), "cores": cores, "t_end_s": args.t_end_s,
           "budget_runs": args.budget_runs, "points_at_once": res.points_at_once,
           "wall_s": wall, "cpu_s": map_t["cpu_s"], "load": map_t["load"],
           "target_s": TARGET_S, "target_applies": applies, "target_met": met,
           "one_at_a_time_estimate_s": estimate, "baseline": base,
           "points": [{k: getattr(p, k) for k in ("A_over_C", "a_over_R", "mu", "group",
                                                   "agrees", "residual", "runs", "wall_s",
                                                   "cause")}
                      for p in pts_res]}
    if args.json:
        print(json.dumps(out, indent=1, default=str))
        return 0
    print(f"the map: {len(pts_res)} points, {res.points_at_once} at once")
    print(f"{'A/C':>5} {'a/R':>5} {'mu':>4} {'group':>5} {'agrees':>6} {'runs':>5} "
          f"{'own s':>6}")
    for p in pts_res:
        print(f"{p.A_over_C:>5.3g} {p.a_over_R:>5.3g} {p.mu:>4.3g} "
              f"{p.group or '-':>5} {'yes' if p.agrees else 'no':>6} {p.runs or 0:>5} "
              f"{p.wall_s:>6.0f}")
    own = [p.wall_s for p in pts_res]
    print(f"points' own times: {min(own):.0f}-{max(own):.0f} s, sum {sum(own):.0f} s "
          f"(they overlap)")
    print("the command's table (tippetop fidelity --grid " + grid.name + "):")
    for line in table_lines(res):
        print(line)
    print(f"map wall time {wall:.0f} s ({wall / 60:.1f} min), {map_t['load_text']}, CPU "
          f"{map_t['cpu_s']:.0f} s")
    if base is not None:
        print(f"baseline ({len(base['points'])} points, this run): one at a time "
              f"{base['one_at_a_time']['wall_s']:.0f} s, at once "
              f"{base['at_once']['wall_s']:.0f} s: ratio {base['ratio']:.2f}x, the same points: "
              f"{'yes' if base['same_points'] else 'NO'}")
        print(f"the map one at a time, estimated (map x ratio): {estimate:.0f} s "
              f"({estimate / 60:.1f} min)")
    print(f"target: the default map within {TARGET_S / 60:.0f} min on 2 cores: "
          + (("met" if met else "NOT met") + f" ({wall / 60:.1f} min on {cores} cores)"
             if applies else "not measured (not the default grid, horizon and budget)"))
    return 0 if base is None or base["same_points"] else 1


def _run_points(run_fidelity: Any, pts: list[tuple[float, float, float]],
                **kwargs: Any) -> FidelityResult:
    """The map's path on the given points only (a grid of their lists holds others)."""
    class Points:
        """A grid made of given points (what :func:`run_fidelity` reads of a grid)."""

        name = "subset"

        def points(self) -> list[tuple[float, float, float]]:
            return list(pts)

        def to_json(self) -> dict[str, Any]:
            return {"name": self.name, "points": len(pts)}

    return run_fidelity(Points(), **kwargs)


if __name__ == "__main__":
    sys.exit(main())
