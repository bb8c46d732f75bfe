"""The matrix on a MuJoCo release in a managed environment, against the same plans in process there.

Issue 21's benchmark, in one run, on ``mujoco==--version`` (default 3.3.7; its managed
environment is made first, outside the timing, if it is missing):

* ``in process`` (the baseline): one fresh process of the environment's own Python that loads
  the harness's worker (the folder ``mujoco_runner/worker/``) as a package by path and calls its
  ``run(request)`` for each plan, one after another: the plan's MJCF compiled, stepped sample by
  sample, the contacts recomputed at each sample (the worker's post-pass) and the arrays written
  to an ``.npz``, exactly as a worker does. The requests are the ones the matrix sends
  (:func:`tippetop.mujoco_runner.remote.request`), written to JSON files before any timing.
  Its figure is the process's wall time: Python's start, ``import mujoco, numpy`` once, and the
  plans; the sum of the ``run`` calls alone is printed beside it.
* ``matrix``: ``tippetop matrix SCENES --engines mujoco==X.Y.Z --modes native,paper --set
  run.t_end_s=T --workers W --json`` in a fresh process, with the reference ODE's runs already
  in the result cache and the engine's not: what it includes is the command's start (imports,
  scenes, plans, finding the environment), a worker process per thread (Python's start,
  ``import mujoco``; the harness keeps it for the next plan), per plan the request as JSON, the
  same ``run``, the ``.npz`` read back, the result built from the samples here, the
  analysis, the cache writes and the printing. This is the ratio the target is on (<= 1.2x):
  on the best rounds, and on the median of the rounds with the drift taken out (below).
* ``matrix cached``: the same command again, everything cached: "a second matrix", the
  command's fixed cost. ``matrix`` minus it is the engine runs' own share (printed as a ratio
  too, for reference).
* ``matrix --no-cache`` (once, after the rounds): the same command computing everything, the
  reference ODE once per scene included (it runs alongside the workers): the whole matrix as a
  user first meets it.

Each run gets a results cache of its own (``$TIPPETOP_CACHE`` pointed at a fresh folder seeded
with the reference's entries, with the real cache's ``envs`` and ``numba`` folders linked in, so
the environment and the compiled reference are found where they are). Rounds alternate the
variants; the best round of each counts (the machine is shared), each round's own ratio and
their median are printed beside it. The machine's speed drifts from one minute to the next, so
the matrix's own stepping is read back from its cache entries (each run's ``wall_s``), and the
ratio is also given with the matrix's stepping replaced by the same round's baseline's: what
the matrix adds, free of the drift. With ``--workers W`` above 1 the matrix runs W workers at
once and the baseline W processes, the plans split longest first.

Then where the overhead goes, for one run of each plan in this process
(:func:`tippetop.compare.running.engines.run_plan_on`, the matrix's own call): its wall time
less the worker's own stepping in that same run (from its reply; the machine's speed drifts, so
stepping is never compared across runs), split into the worker's other work inside ``run``
(compile, the post-pass that recomputes the contacts at each sample, the ``.npz``: the
baseline's ``run`` less its stepping, best of its rounds), the worker's process start and
``import mujoco, numpy`` (timed alone; only where the run started a worker, not where a kept
one answered), the model compiled here, ``result_from_samples`` and the
summary here, and the rest (the request's JSON, the pipe, reading the ``.npz``, the exit).

And the second matrix's claim: :func:`tippetop.compare.running.engines.engine_python` of the
existing environment (target < 1 s; in this process and in a fresh one, imports included), and
the environment folder and its ``ready.json`` unchanged (mtimes) across every matrix run of the
benchmark, with no new folder under ``envs/``.

Run: ``python benchmarks/bench_engines.py [--version 3.3.7] [--scenes fig3,fig6]
[--modes native,paper] [--t-end 1.0] [--rounds 3] [--workers 1] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tippetop.compare.cli import command_line
from tippetop.compare.running import engines
from tippetop.compare.running.runner import (
    ResultCache,
    Task,
    code_fingerprint,
    run_tasks,
    task_key,
)
from tippetop.models.engines import EngineSpec, parse_engine
from tippetop.models.modes import run_label
from tippetop.models.resources import user_cache_dir
from tippetop.mujoco_runner import remote
from tippetop.mujoco_runner.envs import READY, env_folder, envs_root
from tippetop.mujoco_runner.settings import build_model

#: The issue's targets: the matrix's wall time over the same plans in process, and the time a
#: second matrix takes to find an environment.
MATRIX_MAX_X = 1.2
FIND_ENV_MAX_S = 1.0

#: Runs in the environment's Python: loads the worker's folder by path as its ``__main__.py``
#: does (its ``load``) and runs each request in turn; its last stdout line is a JSON object of
#: timings. ``numpy.savez`` is wrapped to time the ``.npz`` writing (``run`` looks it up on the
#: module at each call).
BASELINE_CODE = """\
import importlib.util, json, os, sys, time
t0 = time.perf_counter()
spec = importlib.util.spec_from_file_location("tippetop_worker_start",
                                              os.path.join(sys.argv[1], "__main__.py"))
start = importlib.util.module_from_spec(spec)
spec.loader.exec_module(start)
worker = start.load(sys.argv[1])
import mujoco, numpy
import_s = time.perf_counter() - t0
savez, saved = numpy.savez, [0.0]
def timed_savez(*args, **kwargs):
    t = time.perf_counter()
    try:
        return savez(*args, **kwargs)
    finally:
        saved[0] += time.perf_counter() - t
numpy.savez = timed_savez
rows = []
for path in sys.argv[2:]:
    t, s0 = time.perf_counter(), saved[0]
    with open(path) as fh:
        request = json.load(fh)
    reply = worker.run(request)
    if reply.get("status") != "ok":
        raise SystemExit(f"baseline: {path}: {reply}")
    rows.append({"path": path, "run_s": time.perf_counter() - t, "step_s": reply["wall_s"],
                 "savez_s": saved[0] - s0, "samples": reply["samples"]})
print(json.dumps({"import_s": import_s, "rows": rows, "total_s": time.perf_counter() - t0}))
"""
#: Times compiling each request's MJCF as the worker does (``MjSpec``, the harness's userdata).
COMPILE_CODE = """\
import json, sys, time
import mujoco
out = []
for path in sys.argv[1:]:
    with open(path) as fh:
        request = json.load(fh)
    t = time.perf_counter()
    spec = mujoco.MjSpec.from_string(request["mjcf"])
    spec.nuserdata += request.get("userdata", 0)
    spec.compile()
    out.append(time.perf_counter() - t)
print(json.dumps(out))
"""
#: A fresh process that finds the environment: imports, parse, engine_python; prints seconds.
FIND_CODE = """\
import sys, time
t0 = time.perf_counter()
from tippetop.compare.running.engines import engine_python
from tippetop.models.engines import parse_engine
spec = parse_engine(sys.argv[1])
t1 = time.perf_counter()
engine_python(spec)
t2 = time.perf_counter()
print(t2 - t0, t2 - t1)
"""


@dataclass(frozen=True)
class Plan:
    """One engine run of the matrix, as the benchmark prepared it.

    Attributes:
        label: ``scene mode``.
        task: The matrix's task (its cache key is the matrix's).
        request: The JSON file of its worker request.
        n_steps: MuJoCo steps it takes.
    """

    label: str
    task: Task
    request: Path
    n_steps: int


def matrix_command(scenes: Sequence[str], spec: str, modes: Sequence[str], t_end: float,
                   workers: int, *extra: str) -> list[str]:
    """The ``tippetop matrix`` command line timed."""
    return [*command_line(), "matrix", *scenes, "--engines", spec, "--modes",
            ",".join(modes), "--set", f"run.t_end_s={t_end!r}", "--workers", str(workers),
            "--json", *extra]


def matrix_tasks(scenes: Sequence[str], spec: str, modes: Sequence[str],
                 t_end: float) -> tuple[list[Task], list[Task]]:
    """The reference's tasks and the engine's, as ``run_matrix`` makes them for catalogue scenes."""
    over = (f"run.t_end_s={t_end!r}",)
    ode = [Task(s, over, "ode", label=f"{s} [ode]") for s in scenes]
    eng = [Task(s, over, spec, m, label=f"{s} [{run_label(spec, m)}]")
           for s in scenes for m in modes]
    return ode, eng


def split_longest_first(costs: Sequence[float], n: int) -> list[list[int]]:
    """Indices of ``costs`` in ``n`` groups of similar total: longest first to the least loaded.

    Groups left empty are dropped.
    """
    groups: list[list[int]] = [[] for _ in range(max(1, n))]
    loads = [0.0] * len(groups)
    for i in sorted(range(len(costs)), key=lambda i: -costs[i]):
        k = loads.index(min(loads))
        groups[k].append(i)
        loads[k] += costs[i]
    return [g for g in groups if g]


def child_env(cache: Path | None = None) -> dict[str, str]:
    """This process's environment without ``PYTHONPATH`` (as workers get it), and the cache."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if cache is not None:
        env["TIPPETOP_CACHE"] = str(cache)
    return env


def run_timed(cmd: list[str], env: dict[str, str], what: str) -> tuple[float, str, str]:
    """Wall time (s), stdout and stderr of one fresh process; a failure stops the benchmark."""
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"bench_engines: {what} failed (exit {done.returncode}): "
                         f"{done.stderr.strip()[-600:]}")
    return elapsed, done.stdout, done.stderr


class Caches:
    """Fresh results caches, each seeded with the reference's entries, envs and numba linked."""

    def __init__(self, top: Path, real: Path) -> None:
        self.top, self.real, self.n = top, real, 0
        self.seed = top / "seed"
        self.seed.mkdir()

    def reseed(self, tasks: Sequence[Task]) -> list[str]:
        """The seed made again with ``tasks``'s entries (the reference's); their keys."""
        shutil.rmtree(self.seed, ignore_errors=True)
        self.seed.mkdir()
        code_fingerprint.cache_clear()  # the code now, as the next matrix will see it
        run_tasks(tasks, cache_dir=self.seed, workers=1, label="reference")
        return [task_key(t) for t in tasks]

    def new(self) -> Path:
        """A fresh ``$TIPPETOP_CACHE`` holding the seed's entries."""
        self.n += 1
        folder = self.top / f"cache-{self.n}"
        shutil.copytree(self.seed, folder, symlinks=True)
        for name in ("envs", "numba"):
            if (self.real / name).is_dir() and not (folder / name).exists():
                (folder / name).symlink_to(self.real / name, target_is_directory=True)
        return folder


def cache_entries(cache: Path) -> int:
    """Entries in a results cache (its key folders; the linked envs and numba left out)."""
    return sum(len(list(d.glob("*.json"))) for d in cache.iterdir()
               if d.is_dir() and not d.is_symlink() and len(d.name) == 2)


def env_state(root: Path, version: str) -> dict[str, Any]:
    """What a second matrix must leave alone: the envs listing and the folder's mtimes."""
    folder = env_folder(version, root)
    return {"entries": sorted(p.name for p in root.iterdir()),
            "folder_mtime_ns": folder.stat().st_mtime_ns,
            "ready_mtime_ns": (folder / READY).stat().st_mtime_ns,
            "bin_mtime_ns": (folder / "bin").stat().st_mtime_ns}


def find_env_times(spec: EngineSpec, env: dict[str, str], calls: int = 200) -> dict[str, float]:
    """engine_python of the existing environment: first and best call here, a fresh process."""
    t = time.perf_counter()
    engines.engine_python(spec)
    first = time.perf_counter() - t
    best = float("inf")
    for _ in range(calls):
        t = time.perf_counter()
        engines.engine_python(spec)
        best = min(best, time.perf_counter() - t)
    fresh = [run_timed([sys.executable, "-c", FIND_CODE, spec.spec], env, "finding the "
                       "environment in a fresh process")[1].split() for _ in range(3)]
    return {"first_s": first, "best_s": best,
            "fresh_total_s": min(float(a) for a, _ in fresh),
            "fresh_call_s": min(float(b) for _, b in fresh)}


def profile_round_trips(spec: EngineSpec, python: str,
                        plans: Sequence[Plan]) -> list[dict[str, float]]:
    """One run of each plan through :func:`engines.run_plan_on`, its parts timed here.

    The module's own names ``build_model`` and ``result_from_samples`` in
    :mod:`tippetop.mujoco_runner.remote` are wrapped for the call (and put back).
    """
    spent: dict[str, float] = {}

    def timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[name] = spent.get(name, 0.0) + time.perf_counter() - t
        return wrapper

    originals = {name: getattr(remote, name) for name in ("build_model", "result_from_samples",
                                                          "simulate_in")}
    for name, fn in originals.items():
        setattr(remote, name, timed(name, fn))
    out = []
    try:
        for p in plans:
            spent.clear()
            plan = p.task.plan()
            before = set(remote.live_workers())
            t = time.perf_counter()
            run = engines.run_plan_on(spec, plan, python=python)
            total = time.perf_counter() - t
            started = bool(set(remote.live_workers()) - before)  # else a kept worker answered
            if run.summary.get("status") != "ok":
                raise SystemExit(f"bench_engines: {p.label} did not run: {run.summary}")
            sim = spent["simulate_in"]
            # the summary's wall_s: the worker's stepping plus result_from_samples's own time
            out.append({"total_s": total, "worker_step_s": float(run.summary["wall_s"])
                        - spent["result_from_samples"], "build_model_s": spent["build_model"],
                        "result_s": spent["result_from_samples"],
                        "conversation_s": sim - spent["build_model"]
                        - spent["result_from_samples"],
                        "summary_s": total - sim, "started_worker": started})
    finally:
        for name, fn in originals.items():
            setattr(remote, name, fn)
    return out


def best_and_rounds(values: list[float]) -> str:
    """``best (round by round a b c)`` in seconds."""
    return f"{min(values):6.2f} s  (rounds {' '.join(f'{v:.2f}' for v in values)})"


def ratio_line(name: str, num: list[float], den: list[float], target: float | None, *,
               on_median: bool = False) -> str:
    """``num / den`` of the best rounds, each round's own and their median, and the verdict.

    The verdict is on the best rounds' ratio, or with ``on_median`` on the rounds' median.
    """
    best = min(num) / min(den)
    paired = [a / b for a, b in zip(num, den, strict=True)]
    judged = statistics.median(paired) if on_median else best
    verdict = "" if target is None else (
        f" (target <= {target:g}x{', on the median' if on_median else ''}): "
        f"{'met' if judged <= target else 'MISSED'}")
    head = f"median {judged:5.2f}x" if on_median else f"{best:5.2f}x"
    tail = f"best rounds {best:.2f}x" if on_median else f"median {statistics.median(paired):.2f}x"
    return (f"  {name:<46} {head}{verdict}; round by round "
            f"{' '.join(f'{r:.2f}' for r in paired)}, {tail}")


def main(argv: list[str] | None = None) -> int:  # noqa: PLR0915 - one benchmark, in order
    """Prepare, time the variants in alternating rounds, print the ratios and the breakdown."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--version", default="3.3.7", help="the MuJoCo release (default 3.3.7)")
    p.add_argument("--scenes", default="fig3,fig6", help="catalogue scenes (default fig3,fig6)")
    p.add_argument("--modes", default="native,paper", help="default native,paper")
    p.add_argument("--t-end", type=float, default=1.0, help="simulated seconds a run "
                   "(default 1.0: paper mode's Python law steps ~3 s there, native ~0.1 s)")
    p.add_argument("--rounds", type=int, default=3, help="timed rounds (default 3)")
    p.add_argument("--workers", type=int, default=1, help="the matrix's --workers and the "
                   "baseline's processes (default 1)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    spec = parse_engine(f"mujoco=={args.version}")
    say = (lambda line: print(line, file=sys.stderr)) if not args.json else None
    python = engines.engine_python(spec, say=say)  # made now if missing, outside the timing
    real, root = user_cache_dir(), envs_root()
    load_before = os.getloadavg()[0]
    before = env_state(root, args.version)
    top = Path(tempfile.mkdtemp(prefix="tippetop-bench-engines-"))
    try:
        caches = Caches(top, real)
        ode_tasks, eng_tasks = matrix_tasks(scenes, spec.spec, modes, args.t_end)
        # the seed: the reference's entries, which every timed matrix then finds cached
        seed_keys = caches.reseed(ode_tasks)
        plans = []
        (top / "requests").mkdir()
        for i, task in enumerate(eng_tasks):
            plan = task.plan()
            assert plan.mujoco is not None
            path = top / "requests" / f"{i}.json"
            req = remote.request(plan.mujoco, build_model(plan.mujoco), top / "npz" / f"{i}.npz",
                                 {"implementation": spec.implementation,
                                  "precision": spec.precision})
            path.write_text(json.dumps(req))
            plans.append(Plan(task.label, task, path, plan.mujoco.n_steps))
        (top / "npz").mkdir()
        groups = split_longest_first([float(pl.n_steps) for pl in plans], args.workers)
        base_env = child_env()
        script = top / "baseline.py"
        script.write_text(BASELINE_CODE)

        def baseline() -> tuple[float, list[dict[str, Any]]]:
            start = time.perf_counter()
            procs = [subprocess.Popen([python, str(script), str(remote.WORKER),
                                       *(str(plans[i].request) for i in g)],
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                      env=base_env) for g in groups]
            outs = [proc.communicate(timeout=1800) for proc in procs]
            wall = time.perf_counter() - start
            parts = []
            for proc, (out, err) in zip(procs, outs, strict=True):
                if proc.returncode != 0:
                    raise SystemExit(f"bench_engines: the baseline failed: {err.strip()[-600:]}")
                parts.append(json.loads(out.strip().splitlines()[-1]))
            return wall, parts

        cmd = matrix_command(scenes, spec.spec, modes, args.t_end, args.workers)
        # warm: the baseline once (the environment's files, the requests), and the breakdown's
        # one profiled run of each plan through the matrix's own call in this process
        _, warm_parts = baseline()
        all_parts = list(warm_parts)
        # a worker's start alone, timed next to the profiled runs (the machine drifts)
        import_runs = [run_timed([python, "-c", "import mujoco, numpy"], base_env,
                                 "importing mujoco")[0] for _ in range(5)]
        bare_runs = [run_timed([python, "-c", "pass"], base_env, "python")[0]
                     for _ in range(5)]
        profile = profile_round_trips(spec, python, plans)
        times: dict[str, list[float]] = {"baseline": [], "run_calls": [], "matrix": [],
                                         "cached": []}
        stepping: list[float] = []
        matrix_stepping: list[float] = []
        made_env = False
        odd: list[str] = []
        valid: list[bool] = []
        matrix_json: dict[str, Any] = {}
        for _ in range(args.rounds):
            code_fingerprint.cache_clear()
            if [task_key(t) for t in ode_tasks] != seed_keys:  # the code changed meanwhile
                seed_keys = caches.reseed(ode_tasks)
            seeded = cache_entries(caches.seed)
            wall, parts = baseline()
            all_parts += parts
            times["baseline"].append(wall)
            times["run_calls"].append(max(sum(r["run_s"] for r in part["rows"])
                                          for part in parts))
            stepping.append(sum(r["step_s"] for part in parts for r in part["rows"]))
            cache = caches.new()
            wall, out, err = run_timed(cmd, child_env(cache), "the matrix")
            times["matrix"].append(wall)
            matrix_json = json.loads(out)
            made_env |= "making an environment" in err
            valid.append(cache_entries(cache) == seeded + len(plans))
            if not valid[-1]:
                # the reference's entries missed (the code changed since the seed: another
                # key), or the engine's were not written: this round timed something else
                odd.append(f"round {len(times['matrix'])}: {cache_entries(cache)} cache "
                           f"entries after the matrix, expected {seeded} + {len(plans)}")
            # the matrix's own stepping, read back from its cache entries (wall_s: the
            # worker's stepping and result_from_samples here), to tell the machine's speed
            # in that round from the overhead
            hits = [ResultCache(cache).get(task_key(pl.task)) for pl in plans]
            matrix_stepping.append(sum(float(h[0]["wall_s"]) for h in hits if h is not None))
            if any(h is None for h in hits) and valid[-1]:
                valid[-1] = False
                odd.append(f"round {len(times['matrix'])}: the engine's cache entries are "
                           "not under this process's keys (the code changed meanwhile)")
            entries = cache_entries(cache)
            wall, out, err = run_timed(cmd, child_env(cache), "the second matrix")
            times["cached"].append(wall)
            made_env |= "making an environment" in err
            if cache_entries(cache) != entries and valid[-1]:  # it computed: not all cached
                valid[-1] = False
                odd.append(f"round {len(times['matrix'])}: the second matrix wrote "
                           f"{cache_entries(cache) - entries} cache entries (the code changed "
                           "meanwhile)")
        # once, after the rounds: everything computed, the reference included
        nocache, out, err = run_timed([*cmd, "--no-cache"], child_env(caches.new()),
                                      "the matrix --no-cache")
        made_env |= "making an environment" in err
        bad = [r for r in matrix_json.get("runs", []) if r["status"] != "ok"]
        if bad:
            raise SystemExit(f"bench_engines: the matrix's runs did not all end ok: {bad}")
        finding = find_env_times(spec, child_env())
        after = env_state(root, args.version)
        compile_s = json.loads(run_timed([python, "-c", COMPILE_CODE,
                                          *(str(pl.request) for pl in plans)], base_env,
                                         "compiling the requests")[1])
    finally:
        shutil.rmtree(top, ignore_errors=True)
    if not all(valid):  # rounds that timed something else are left out (all, if none is left)
        keep = [i for i, ok in enumerate(valid) if ok] or list(range(len(valid)))
        times = {k: [v[i] for i in keep] for k, v in times.items()}
        stepping = [stepping[i] for i in keep]
        matrix_stepping = [matrix_stepping[i] for i in keep]
        odd.append(f"the figures are from rounds {', '.join(str(i + 1) for i in keep)} only")
    per_plan = []
    for pl in plans:  # the baseline's run of each plan: its best round's, and its own parts
        mine = [r for part in all_parts for r in part["rows"] if r["path"] == str(pl.request)]
        per_plan.append({"run_s": min(r["run_s"] for r in mine),
                         "step_s": min(r["step_s"] for r in mine),
                         "run_not_step_s": min(r["run_s"] - r["step_s"] for r in mine),
                         "savez_s": min(r["savez_s"] for r in mine)})
    engine_only = [m - c for m, c in zip(times["matrix"], times["cached"], strict=True)]
    # each round's matrix as if its workers had stepped as fast as that round's baseline
    same_speed = [m - ms + bs for m, ms, bs in zip(times["matrix"], matrix_stepping, stepping,
                                                   strict=True)]
    same_ready = before["ready_mtime_ns"] == after["ready_mtime_ns"]
    same_folder = all(before[k] == after[k] for k in ("folder_mtime_ns", "bin_mtime_ns"))
    # the verdict is on this release's folder and on what the matrix runs said: other processes
    # (other engineers, other engines' environments) may add folders under envs/ meanwhile
    untouched = same_ready and same_folder and not made_env
    res = {"version": args.version, "python": python, "scenes": scenes, "modes": modes,
           "t_end_s": args.t_end, "rounds": args.rounds, "workers": args.workers,
           "times_s": times, "nocache_s": nocache, "stepping_s": stepping,
           "matrix_stepping_s": matrix_stepping,
           "engine_runs_s": engine_only, "matrix_at_baseline_stepping_s": same_speed,
           "matrix_x_in_process": min(times["matrix"]) / min(times["baseline"]),
           "matrix_target_x": MATRIX_MAX_X,
           "matrix_ok": min(times["matrix"]) / min(times["baseline"]) <= MATRIX_MAX_X,
           "find_env": finding, "find_env_ok": finding["first_s"] < FIND_ENV_MAX_S,
           "env_untouched": untouched, "env_before": before, "env_after": after,
           "plans": [{"label": pl.label, "n_steps": pl.n_steps, **per_plan[i], **profile[i],
                      "compile_s": compile_s[i]} for i, pl in enumerate(plans)],
           "worker_start_import_s": min(import_runs), "python_start_s": min(bare_runs)}
    res["anomalies"] = odd
    # the matrix's cost beyond the in-process one, as a fixed sum: per run what the round trip
    # adds beyond the worker's run() (its start and import, the model, result and summary here,
    # the pipe), once the command's own, less the baseline's own start and import
    per_run = statistics.median(r["total_s"] - r["worker_step_s"] - r["run_not_step_s"]
                                for r in res["plans"])
    n = len(plans)
    added = n * per_run + min(times["cached"]) - (min(times["baseline"])
                                                   - min(times["run_calls"]))
    res["added_s"], res["added_per_run_s"] = added, per_run
    if args.json:
        print(json.dumps(res))
        return 0
    print(f"mujoco=={args.version} in its managed environment ({python}); {len(scenes)} scenes "
          f"({', '.join(scenes)}) x {len(modes)} modes ({', '.join(modes)}), {args.t_end:g} s "
          f"each: {n} engine runs ({', '.join(f'{pl.label} {pl.n_steps} steps' for pl in plans)})"
          f"; --workers {args.workers}, {os.cpu_count()} cores; best of {len(times['matrix'])} "
          f"alternating rounds (of {args.rounds} run); load average before {load_before:.2f}, now "
          f"{os.getloadavg()[0]:.2f}")
    print(f"  {'in process':<19} {best_and_rounds(times['baseline'])}  one process of the "
          f"environment's Python: start, import, worker.run of each plan")
    print(f"  {'  run() calls':<19} {best_and_rounds(times['run_calls'])}  the plans alone "
          f"(compile, step, post-pass, .npz); stepping alone "
          f"{min(stepping):.2f} s")
    print(f"  {'matrix':<19} {best_and_rounds(times['matrix'])}  the command, the reference "
          f"cached, the {n} engine runs computed")
    print(f"  {'  its stepping':<19} {best_and_rounds(matrix_stepping)}  the workers' own "
          f"(and result_from_samples), read back from its cache; the baseline's round by "
          f"round: {' '.join(f'{v:.2f}' for v in stepping)}")
    print(f"  {'matrix cached':<19} {best_and_rounds(times['cached'])}  the same again, all cached "
          f"(the second matrix: the command's fixed cost)")
    print(f"  {'matrix --no-cache':<19} {nocache:6.2f} s  (once, after the rounds)  everything "
          f"computed, the reference ODE once per scene alongside")
    print("ratios (best rounds, unless it says median):")
    print(ratio_line("matrix / in process", times["matrix"], times["baseline"], MATRIX_MAX_X))
    print(ratio_line("(matrix - matrix cached) / in process", engine_only, times["baseline"],
                     None) + "  (the engine runs' own share)")
    print(ratio_line("matrix / in-process run() calls", times["matrix"], times["run_calls"],
                     None))
    print(ratio_line("matrix at the baseline's stepping / in process", same_speed,
                     times["baseline"], MATRIX_MAX_X, on_median=True)
          + "  (the machine's drift taken out)")
    print(f"  {'matrix --no-cache / in process':<46} {nocache / min(times['baseline']):5.2f}x "
          f"(the reference included; against the best baseline)")
    start_import = res["worker_start_import_s"]
    print("where the matrix's time goes, per engine run (one profiled run each through "
          "engines.run_plan_on, against the worker's own stepping in that run):")
    print(f"  {'run':<13} {'steps':>6} {'round trip':>10} {'stepping':>9} {'the rest':>9} | "
          f"{'in run():':>9} {'of it npz':>9} {'compile':>8} | {'start+import':>12} "
          f"{'model here':>10} {'result':>7} {'summary':>7} {'pipe,json,npz,exit':>18}")
    rest_all = 0.0
    for row in res["plans"]:
        rest = row["total_s"] - row["worker_step_s"]
        # a worker kept from the run before pays no start (the harness keeps its workers)
        own_start = start_import if row["started_worker"] else 0.0
        other = (rest - row["run_not_step_s"] - own_start - row["build_model_s"]
                 - row["result_s"] - row["summary_s"])
        rest_all += rest
        print(f"  {row['label']:<13} {row['n_steps']:>6} {row['total_s']:>9.3f}s "
              f"{row['worker_step_s']:>8.3f}s {rest:>8.3f}s | {row['run_not_step_s']:>8.3f}s "
              f"{row['savez_s']:>8.3f}s {row['compile_s']:>7.3f}s | {own_start:>11.3f}s "
              f"{row['build_model_s']:>9.3f}s {row['result_s']:>6.3f}s {row['summary_s']:>6.3f}s "
              f"{other:>17.3f}s")
    starts = sum(bool(r["started_worker"]) for r in res["plans"])
    print(f"  the {n} runs' time beyond their stepping: {rest_all:.2f} s, of it {starts} x the "
          f"worker's start + import mujoco, numpy ({start_import:.3f} s each, best of 5; a bare "
          f"Python starts in {res['python_start_s']:.3f} s; the other runs went to the worker "
          f"kept from the run before): {starts * start_import:.2f} s; the command's fixed cost "
          f"(matrix cached) {min(times['cached']):.2f} s")
    print(f"  so the matrix adds about {added:.2f} s to these {n} runs ({per_run:.2f} s a run, "
          f"median, + the command's {min(times['cached']):.2f} s - the baseline's own start "
          f"{min(times['baseline']) - min(times['run_calls']):.2f} s): <= {MATRIX_MAX_X:g}x "
          f"holds once the same plans take >= {added / (MATRIX_MAX_X - 1):.1f} s in process "
          f"(here {min(times['baseline']):.2f} s), i.e. >= {per_run / (MATRIX_MAX_X - 1):.1f} s "
          f"of stepping a run")
    f = finding
    print(f"second matrix: engine_python({spec.spec}) of the existing environment "
          f"{f['first_s'] * 1e3:.2f} ms first call here, {f['best_s'] * 1e6:.1f} us best of "
          f"200; in a fresh process {f['fresh_call_s'] * 1e3:.2f} ms ({f['fresh_total_s']:.2f} s "
          f"with its imports) (target < {FIND_ENV_MAX_S:g} s): "
          f"{'met' if res['find_env_ok'] else 'MISSED'}")
    new_entries = sorted(set(after["entries"]) - set(before["entries"]))
    print(f"  across the {2 * args.rounds + 1} matrix runs: {env_folder(args.version, root).name}"
          f"/{READY} mtime {'unchanged' if same_ready else 'CHANGED'}, the folder's and its "
          f"bin/'s {'unchanged' if same_folder else 'CHANGED'}, no matrix said 'making an "
          f"environment' {'(none did)' if not made_env else '(ONE DID)'}: "
          f"{'met' if untouched else 'MISSED'}"
          + (f"; meanwhile other processes added to {root}: {', '.join(new_entries)}"
             if new_entries else f"; {root} listing unchanged"))
    for line in odd:
        print(f"WARNING: {line}; rerun when nobody is changing the code")
    print("reproduce: python benchmarks/bench_engines.py " + " ".join(
        f"--{k.replace('_', '-')} {v}" for k, v in (("version", args.version),
                                                     ("scenes", ",".join(scenes)),
                                                     ("modes", ",".join(modes)),
                                                     ("t_end", args.t_end),
                                                     ("rounds", args.rounds),
                                                     ("workers", args.workers))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
