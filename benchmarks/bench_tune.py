"""What the tuning costs: ``validate`` with it against ``validate --no-tune``, in one run.

The target (issue 30, item 3): ``tippetop validate MODEL.xml`` with its tuning at most 4x
``validate --no-tune`` on the paper's top (``examples/paper_loaded_sphere.xml``), both without
a cache. Timed, as fresh processes (``subprocess``), the wall time of:

* ``no-tune``: ``validate FILE --no-tune --json`` with an empty ``$TIPPETOP_CACHE``;
* ``tune``: ``validate FILE --json`` (the tuning at its default ``--budget-runs``) with
  another empty one;
* ``cached``: ``validate FILE --json`` again in the ``tune`` run's cache: the runs and the
  tuning come from it.

Paired and interleaved: each pair runs no-tune, tune, cached, in that order, and gives the
ratios tune/no-tune and cached/no-tune; the table shows each command's median and the median,
min and max of the pair ratios (the machine is shared: a pair's runs see about the same load,
which the ratio cancels). The CPU time (user + system) of each process and its workers is
printed beside, which the machine's load moves less.

Caches. Every run gets a fresh temporary ``$TIPPETOP_CACHE`` (removed after, Ctrl-C
included) whose ``numba`` is a link to a warm folder, ``<tmp>/tt-bench-tune/numba``, so no
run compiles: a warm-up ``validate --no-tune`` fills it first (untimed).

Same work: every tuning must say its settings agree from every start (``tuned.agrees``; the
test of issue 22) and the cached run must say ``cached``; else the exit status is 1.

Run: ``python benchmarks/bench_tune.py [--pairs 3] [--model FILE] [--json]``. A bad option
is one line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from tippetop.compare.cli import command_line

ROOT = Path(__file__).resolve().parents[1]
#: The paper's top as a user would write it.
DEFAULT_MODEL = ROOT / "examples" / "paper_loaded_sphere.xml"
#: The issue's target: validate with its tuning at most this many times --no-tune.
MAX_RATIO = 4.0
#: The warm folder of numba's compiled code, shared by every run (never a run's cache).
WARM = Path(tempfile.gettempdir()) / "tt-bench-tune"


def _say(line: str) -> None:
    if sys.stderr.isatty():
        print(f"bench_tune: {line}", file=sys.stderr, flush=True)


def fresh_cache() -> Path:
    """An empty ``$TIPPETOP_CACHE`` whose ``numba`` is the warm folder's."""
    cache = Path(tempfile.mkdtemp(prefix="tt-bench-tune-"))
    (WARM / "numba").mkdir(parents=True, exist_ok=True)
    (cache / "numba").symlink_to(WARM / "numba", target_is_directory=True)
    return cache


def run(args: list[str], cache: Path) -> tuple[float, float, dict[str, Any]]:
    """Wall and CPU time (s) of one fresh ``tippetop`` process, and its ``--json`` output."""
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    env.pop("NUMBA_CACHE_DIR", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([*command_line(), *args], capture_output=True, text=True,
                          timeout=1800, env=env, cwd=cache)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode not in (0, 1):  # 1: the file's own settings depart (its verdict)
        raise SystemExit(f"bench_tune: tippetop {' '.join(args[:3])} ... failed "
                         f"({proc.returncode}): {proc.stderr.strip()[-300:]}")
    return wall, cpu, json.loads(proc.stdout)


def spread(values: list[float]) -> dict[str, float]:
    """Median, min and max."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def main(argv: list[str] | None = None) -> int:
    """Time the pairs and print the medians and ratios against the target."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--pairs", type=int, default=3, help="timed pairs (default 3)")
    p.add_argument("--model", default=str(DEFAULT_MODEL),
                   help="the MJCF top (default examples/paper_loaded_sphere.xml)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    a = p.parse_args(argv)
    if a.pairs < 1:
        p.exit(2, f"bench_tune: --pairs: expected at least 1, got {a.pairs}\n")
    model = Path(a.model).resolve()
    if not model.is_file():
        p.exit(2, f"bench_tune: --model: expected an existing MJCF file, got {a.model}\n")
    no_tune = ["validate", str(model), "--no-tune", "--json"]
    tune = ["validate", str(model), "--json"]
    caches: list[Path] = []
    times: dict[str, list[float]] = {"no-tune": [], "tune": [], "cached": []}
    cpus: dict[str, list[float]] = {"no-tune": [], "tune": [], "cached": []}
    problems: list[str] = []
    runs_used: list[int] = []
    try:
        caches.append(fresh_cache())
        _say("warm-up (compiles into the warm folder, untimed)")
        run(no_tune, caches[-1])
        for i in range(a.pairs):
            for name in ("no-tune", "tune", "cached"):
                if name != "cached":
                    caches.append(fresh_cache())
                _say(f"pair {i + 1}/{a.pairs}: {name}")
                wall, cpu, res = run(no_tune if name == "no-tune" else tune, caches[-1])
                times[name].append(wall)
                cpus[name].append(cpu)
                t = res["tuned"]
                if name != "no-tune" and not t.get("agrees"):
                    problems.append(f"pair {i + 1} {name}: the tuned settings do not agree "
                                    f"({t.get('note') or t.get('skipped')})")
                if name == "tune":
                    runs_used.append(int(t.get("fit", {}).get("runs", 0)))
                if name == "cached" and not t.get("cached"):
                    problems.append(f"pair {i + 1}: the second validate did not take the "
                                    "tuning from the cache")
    finally:
        for c in caches:
            shutil.rmtree(c, ignore_errors=True)
    ratio = [t / n for t, n in zip(times["tune"], times["no-tune"], strict=True)]
    cached = [t / n for t, n in zip(times["cached"], times["no-tune"], strict=True)]
    cpu_ratio = [t / n for t, n in zip(cpus["tune"], cpus["no-tune"], strict=True)]
    res = {"model": str(model), "pairs": a.pairs,
           "wall_s": {k: spread(v) for k, v in times.items()},
           "cpu_s": {k: spread(v) for k, v in cpus.items()},
           "tune_x_no_tune": spread(ratio), "cached_x_no_tune": spread(cached),
           "tune_cpu_x_no_tune": spread(cpu_ratio), "target_x": MAX_RATIO,
           "ok": statistics.median(ratio) <= MAX_RATIO and not problems,
           "tuning_runs": runs_used, "problems": problems}
    if a.json:
        print(json.dumps(res))
        return 0 if not problems else 1
    print(f"validate {model.name}, {a.pairs} pairs (no-tune, tune, cached), fresh processes, "
          f"each with an empty cache but warm compiled code:")
    for name in times:
        w, c = res["wall_s"][name], res["cpu_s"][name]
        print(f"  {name:<8} wall median {w['median']:6.1f} s (min {w['min']:.1f}, max "
              f"{w['max']:.1f})   cpu median {c['median']:6.1f} s")
    r = res["tune_x_no_tune"]
    print(f"tune / no-tune   = {r['median']:.2f}x median (pairs {r['min']:.2f}x-{r['max']:.2f}x;"
          f" target <= {MAX_RATIO:g}x): {'met' if r['median'] <= MAX_RATIO else 'MISSED'}")
    c = res["cached_x_no_tune"]
    print(f"cached / no-tune = {c['median']:.2f}x median (pairs {c['min']:.2f}x-{c['max']:.2f}x)"
          f"; cpu tune / no-tune = {res['tune_cpu_x_no_tune']['median']:.2f}x")
    print(f"the tuning's MuJoCo runs: {', '.join(map(str, runs_used))}")
    for line in problems:
        print(f"PROBLEM: {line}")
    return 0 if not problems else 1


if __name__ == "__main__":
    raise SystemExit(main())
