"""The costs the README, the guides and the help quote, measured: writes docs/data/costs.json.

Each cost is measured as a page shows it, in fresh processes on this machine:

* the wall time of a command (or of a page's few commands together) as a newcomer runs it:
  the table :data:`COMMANDS`, each entry with the command the page shows. Unless an entry
  says otherwise the compiled code is warm (the command ran once before, untimed, in a
  throwaway cache, sharing one ``NUMBA_CACHE_DIR``) and no runs are cached (a fresh
  ``$TIPPETOP_CACHE``); each runs in a fresh working folder linking the repository's
  ``examples/``, ``models/`` and ``tests/``, as the docs' tests run them. Some entries also
  read costs from what the command wrote (``bench ode --json``'s speed-up, the accuracy
  study's CSVs);
* ``simulate_first_s``: ``tippetop simulate fig3`` in an empty ``$TIPPETOP_CACHE`` (it
  compiles the reference's integrator); ``simulate_s``: the same again (compiled);
  ``simulate_mujoco_s``: ``--engine mujoco --mode native``, compiled, no runs cached;
* ``validate_no_tune_s``: ``tippetop validate examples/paper_loaded_sphere.xml --no-tune``,
  as the README runs it, compiled code warm, an empty run cache; ``validate_tune_s``: the same
  with the tuning, and ``validate_tune_ratio`` the two's ratio;
* what no command prints, measured by a short Python program of its own (:data:`PROBES`): the
  Python stepping loop against plain ``mj_step``, loading the compiled MuJoCo loops, compiling
  one order's Taylor kernel, the reference's fixed cost of building its tables, a history
  append with two writers, a managed environment's making and size (from the package
  registry, with an empty uv cache);
* read from the stored results under docs/data (:data:`STORED`: the fidelity map's and the
  work-precision sweep's own runs), their ``command`` naming the file;
* ``docs_build_s``: ``properdocs build --strict`` with its pictures (``--docs``; the docs'
  own cache warm, as a second build finds it), and ``docs_build_no_pictures_s`` with
  ``TIPPETOP_DOCS_IMAGES=0``;
* ``tests_fast_s`` and ``tests_slow_s``: read from a ``.ci/run`` log (``--ci-log FILE``:
  pytest's ``N passed ... in S s`` lines, the slow suite first), not run here.

Each command runs ``--repeats`` times (default 1) and keeps the median. Costs not measured in
this run keep their stored value and its date. Run: ``python benchmarks/bench_costs.py
[--repeats N] [--docs] [--ci-log FILE] [--only KEY,...]``; a bad option is one line, exit 2.
``--only`` names keys; an entry that measures several keys runs when any of them is named.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "data"
OUT = DATA / "costs.json"
FORMAT = "tippetop-costs/1"
MODEL = "examples/paper_loaded_sphere.xml"
#: What a command's working folder links from the repository (as tests/test_docs.py does).
INPUTS = ("examples", "models", "tests")
STRANGER = "tests/data/stranger/group2_mu1_implicitfast.xml"

Argv = tuple[str, ...]
#: A cost as stored: ``value``, ``unit``, ``what``, ``command`` (and ``high``, ``measured``).
Entry = dict[str, Any]


def _say(line: str) -> None:
    if sys.stderr.isatty():
        print(f"bench_costs: {line}", file=sys.stderr, flush=True)


def _run(args: list[str], env: dict[str, str], ok: tuple[int, ...] = (0,),
         cwd: Path = ROOT) -> tuple[float, subprocess.CompletedProcess[str]]:
    """(wall seconds, the finished process) of ``args``; a failure ends the benchmark."""
    t0 = time.monotonic()
    proc = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.monotonic() - t0
    if proc.returncode not in ok:
        raise SystemExit(f"bench_costs: {' '.join(args)}: exit {proc.returncode}: "
                         f"{proc.stderr.strip().splitlines()[-1:]}")
    return wall, proc


def _timed(args: list[str], env: dict[str, str], ok: tuple[int, ...] = (0,),
           cwd: Path = ROOT) -> float:
    return _run(args, env, ok, cwd)[0]


def _env(cache: Path, numba: Path | None) -> dict[str, str]:
    # the venv's interpreter first on PATH: mujoco@python names it
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    env = {**os.environ, "TIPPETOP_CACHE": str(cache), "PATH": path}
    env.pop("NUMBA_CACHE_DIR", None)
    if numba is not None:
        env["NUMBA_CACHE_DIR"] = str(numba)
    return env


def _median(fn, repeats: int) -> float:
    return statistics.median(fn() for _ in range(repeats))


def _cost(value: float, unit: str, what: str, command: str,
          high: float | None = None) -> Entry:
    entry: Entry = {"value": round(float(value), 3), "unit": unit, "what": what,
                    "command": command}
    if high is not None:
        entry["high"] = round(float(high), 3)
    return entry


# ----------------------------------------------------------------------- commands as shown
@dataclass(frozen=True)
class Command:
    """A cost a page quotes: the wall time of the commands it shows, and what they print.

    Attributes:
        key: The wall time's key (seconds, the commands' together).
        shown: The commands as the page shows them (the stored ``command``).
        argvs: Each command's arguments after ``tippetop``, run in order in one folder.
        what: What was measured, the conditions included.
        warmup: Run the commands once, untimed, first (in a throwaway cache and folder), so
            that the timed run finds its compiled code; or other commands to run so.
        ok: The exit statuses that count as done.
        reads: Costs read from the timed run: ``(processes, folder) -> {key: entry}``.
        read_keys: The keys ``reads`` gives.
        setup: Run first, untimed, once for each cache (its engines' environments):
            ``(env, folder) -> None``.
        shared_cache: The name of a cache the entries naming it share (their environments
            made once; the commands then say ``--no-cache``), or None for a fresh cache each.
    """

    key: str
    shown: str
    argvs: tuple[Argv, ...]
    what: str
    warmup: bool | tuple[Argv, ...] = True
    ok: tuple[int, ...] = (0,)
    reads: Callable[[list[subprocess.CompletedProcess[str]], Path], dict[str, Entry]] | None = None
    read_keys: tuple[str, ...] = ()
    setup: Callable[[dict[str, str], Path], None] | None = None
    shared_cache: str | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return (self.key, *self.read_keys)


def _bench_ode_reads(procs: list[subprocess.CompletedProcess[str]],
                     _folder: Path) -> dict[str, Entry]:
    res = json.loads(procs[-1].stdout)
    cmd = "tippetop bench ode --json (defaults: Fig. 11 top, 60 s, rtol 1e-9, best of 5 rounds)"
    return {
        "bench_ode_speedup": _cost(res["speedup"], "x", "scipy's solve_ivp(DOP853) CPU time "
                                   "over the whole simulate_ode call's (observables table "
                                   "included), best of the rounds", cmd),
        "bench_ode_scipy_s": _cost(res["scipy_s"], "s", "scipy's solve_ivp(DOP853) run at the "
                                   "defaults (CPU time, best of its rounds)", cmd)}


def _accuracy_reads(_procs: list[subprocess.CompletedProcess[str]],
                    folder: Path) -> dict[str, Entry]:
    import pandas as pd

    from tippetop.compare.studies.accuracy.pareto import pareto_table, series_summary

    out = folder / "accuracy"
    ode, mj = (pd.read_csv(out / f"accuracy_{e}.csv") for e in ("ode", "mujoco"))
    cmd = "tippetop bench accuracy (both scenes, both engines: accuracy_ode.csv, " \
          "accuracy_mujoco.csv)"
    # MuJoCo's cheapest point over the reference's at each accuracy both reach
    rows = pareto_table(pd.concat([ode, mj], ignore_index=True))
    best = {(r["engine"], r["scene"], r["threshold"]): r["wall_per_sim_s"] for r in rows}
    ratios = [best["mujoco", s, x] / best["ode", s, x] for (e, s, x) in best
              if e == "ode" and best[e, s, x] and best.get(("mujoco", s, x))]
    # RK4's cost per step over Euler's and implicitfast's, paper mode, each scene: the study's
    # fit wall = fixed + per_step * n_steps over each series' completed points
    rk4 = []
    for _scene, g in mj[mj["mode"] == "paper"].groupby("scene"):
        fit = series_summary(g).set_index("method")["wall_per_step_s"]
        rk4 += [fit["RK4/paper"] / fit[f"{other}/paper"] for other in ("Euler", "implicitfast")
                if "RK4/paper" in fit and f"{other}/paper" in fit
                and fit["RK4/paper"] and fit[f"{other}/paper"]]
    if not ratios or not rk4:
        raise SystemExit(f"bench_costs: {out}: expected points both engines reach and RK4 "
                         f"beside Euler or implicitfast, got {len(ratios)} and {len(rk4)}")
    return {
        "accuracy_ode_vs_mujoco": _cost(
            min(ratios), "x", "MuJoCo's cheapest point over the reference ODE's (wall time per "
            "simulated second) at each accuracy (1e-2, 1e-4, 1e-6 rad) both reach, each scene",
            cmd, max(ratios)),
        "accuracy_rk4_step_ratio": _cost(
            statistics.median(rk4), "x", "MuJoCo RK4's wall time per step over Euler's and "
            "implicitfast's, paper mode, each scene (each series' fit wall = fixed + per step x "
            "steps; the median)", cmd)}


def _make_envs(releases: tuple[str, ...]) -> Callable[[dict[str, str], Path], None]:
    """A setup making ``releases``' managed environments in the run's cache (untimed; uv's
    cache a temporary one)."""
    def setup(env: dict[str, str], folder: Path) -> None:
        code = ("import sys\nfrom tippetop.mujoco_runner.envs import env_python\n"
                "for v in sys.argv[1:]:\n    env_python(v)\n")
        _run([sys.executable, "-c", code, *releases],
             {**env, "UV_CACHE_DIR": str(Path(env["TIPPETOP_CACHE"]) / "uv-cache")},
             cwd=folder)
    return setup


#: Two releases that differ on a stranger's top (its turn-over and stem times), in its own
#: contact: one scene and mode whose differences the matrix attributes (7 changes x 2 engines).
MATRIX_PAIR = ("matrix", STRANGER, "--engines", "mujoco==3.10.0,mujoco==3.11.0", "--modes",
               "file", "--set", "mujoco.timestep_s=0.001", "--no-cache")

#: The costs the pages quote as a command's wall time (and what the command writes).
COMMANDS: tuple[Command, ...] = (
    Command("nightly_quick_s", "tippetop nightly --profile quick --out DIR",
            (("nightly", "--profile", "quick", "--out", "nightly-report"),),
            "the quick nightly, compiled code warm, no runs cached", warmup=(), ok=(0, 1)),
    Command("validate_stem_tune_s", "tippetop validate examples/capsule_stem_top.xml",
            (("validate", "examples/capsule_stem_top.xml", "--json"),),
            "validate with its tuning on a top with a stem, no runs cached", warmup=(),
            ok=(0, 1)),
    Command("threshold_ode_s", "tippetop threshold fig6 --engine ode --which nc",
            (("threshold", "fig6", "--engine", "ode", "--which", "nc"),),
            "a critical spin in the reference, compiled code warm, no runs cached"),
    Command("threshold_worker_s",
            "tippetop threshold --engine mujoco@python --mode native --which n1",
            (("threshold", "--engine", "mujoco@python", "--mode", "native", "--which", "n1"),),
            "a critical spin on a MuJoCo worker in another Python process, compiled code warm, "
            "no runs cached"),
    Command("atlas_ode_s", "tippetop atlas --engines ode --out atlas",
            (("atlas", "--engines", "ode", "--out", "atlas"),),
            "the group diagram's default grid in the reference, compiled code warm, no runs "
            "cached"),
    Command("simulate_worker_s",
            "tippetop simulate fig3 --engine mujoco@python --mode native --set run.t_end_s=1",
            (("simulate", "fig3", "--engine", "mujoco@python", "--mode", "native", "--set",
              "run.t_end_s=1"),),
            "a 1-s run on a MuJoCo worker in another Python process (its start included), "
            "compiled code warm"),
    Command("simulate_condim4_s",
            "tippetop simulate fig3 --engine mujoco --mode native-condim4 --set run.t_end_s=2",
            (("simulate", "fig3", "--engine", "mujoco", "--mode", "native-condim4", "--set",
              "run.t_end_s=2"),),
            "a 2-s MuJoCo run with torsional friction, compiled code warm"),
    Command("simulate_capsule_ode_s",
            "tippetop simulate --mjcf examples/capsule_stem_top.xml --engine ode",
            (("simulate", "--mjcf", "examples/capsule_stem_top.xml", "--engine", "ode"),),
            "the capsule-stem top in the reference, compiled code warm"),
    Command("plan_three_s",
            "tippetop plan fig3 --engine mujoco --mode native; tippetop plan fig3 --engine "
            "mujoco --mode paper --set run.t_end_s=1 --out fig3-plan.json; tippetop simulate "
            "--plan fig3-plan.json",
            (("plan", "fig3", "--engine", "mujoco", "--mode", "native"),
             ("plan", "fig3", "--engine", "mujoco", "--mode", "paper", "--set", "run.t_end_s=1",
              "--out", "fig3-plan.json"),
             ("simulate", "--plan", "fig3-plan.json")),
            "the three commands together, compiled code warm"),
    Command("render_fig3_s",
            "tippetop render fig3 --engines mujoco,ode --speed 1 --fps 10 --set run.t_end_s=4 "
            "--out fig3.mp4",
            (("render", "fig3", "--engines", "mujoco,ode", "--speed", "1", "--fps", "10",
              "--set", "run.t_end_s=4", "--out", "fig3.mp4"),),
            "a 4-s video of both engines side by side, compiled code warm, no runs cached"),
    Command("nightly_fig3_s", "tippetop nightly --profile quick --cases 'paper/fig3*' --out "
            "fig3-nightly",
            (("nightly", "--profile", "quick", "--cases", "paper/fig3*", "--out",
              "fig3-nightly"),),
            "the quick profile's Fig. 3 cases on every engine and mode, compiled code warm, no "
            "runs cached", ok=(0, 1)),
    Command("compare_fig3_s", "tippetop compare fig3 --engines ode,mujoco --modes paper,native",
            (("compare", "fig3", "--engines", "ode,mujoco", "--modes", "paper,native"),),
            "one scene on every pairing, compiled code warm, no runs cached", ok=(0, 1)),
    Command("matrix_fig3_paper_s", "tippetop matrix fig3 --engines mujoco --modes paper "
            "--no-attribution --history ci-history.sqlite",
            (("matrix", "fig3", "--engines", "mujoco", "--modes", "paper", "--no-attribution",
              "--history", "ci-history.sqlite"),),
            "the matrix of one scene, engine and mode, its history appended, compiled code "
            "warm, no runs cached", ok=(0, 1)),
    Command("nightly_models_capsule_s",
            "tippetop nightly --models examples/capsule_stem_top.xml --cases 'models/*' "
            "--baseline nightly-baselines --update-baseline --cache --out nightly-models",
            (("nightly", "--models", "examples/capsule_stem_top.xml", "--cases", "models/*",
              "--baseline", "nightly-baselines", "--update-baseline", "--cache", "--out",
              "nightly-models"),),
            "the nightly of one MJCF top, its baselines written, compiled code warm, no runs "
            "cached", ok=(0, 1)),
    Command("bench_ode_short_s", "tippetop bench ode --rounds 1 --t-end-s 10",
            (("bench", "ode", "--rounds", "1", "--t-end-s", "10"),),
            "one round of the ODE benchmark over 10 simulated seconds, compiled code warm"),
    Command("bench_ode_s", "tippetop bench ode --json",
            (("bench", "ode", "--json"),),
            "the ODE benchmark at its defaults (Fig. 11 top, 60 s, best of 5 rounds), compiled "
            "code warm", warmup=(("bench", "ode", "--rounds", "1", "--t-end-s", "1"),),
            reads=_bench_ode_reads, read_keys=("bench_ode_speedup", "bench_ode_scipy_s")),
    Command("bench_accuracy_s", "tippetop bench accuracy --out accuracy",
            (("bench", "accuracy", "--out", "accuracy"),),
            "the whole accuracy study (both scenes, both engines), compiled code as a short "
            "run of it (1-s budget a point) left it",
            warmup=(("bench", "accuracy", "--budget-s", "1", "--out", "accuracy"),),
            reads=_accuracy_reads, read_keys=("accuracy_ode_vs_mujoco",
                                              "accuracy_rk4_step_ratio")),
    Command("matrix_attribution_s",
            f"tippetop matrix {STRANGER} --engines mujoco==3.10.0,mujoco==3.11.0 --modes file "
            "--set mujoco.timestep_s=0.001 --no-cache",
            (MATRIX_PAIR,),
            "a matrix of two releases that differ on one scene and mode, with its attribution "
            "reruns, the environments made, no runs cached",
            warmup=((*MATRIX_PAIR, "--no-attribution"),),
            setup=_make_envs(("3.10.0", "3.11.0")), shared_cache="pair"),
    Command("matrix_no_attribution_s",
            f"tippetop matrix {STRANGER} --engines mujoco==3.10.0,mujoco==3.11.0 --modes file "
            "--set mujoco.timestep_s=0.001 --no-cache --no-attribution",
            ((*MATRIX_PAIR, "--no-attribution"),),
            "the same matrix without its attribution reruns, the environments made, no runs "
            "cached", warmup=(), setup=_make_envs(("3.10.0", "3.11.0")),
            shared_cache="pair"),
)


# ------------------------------------------------------------------ what no command prints
@dataclass(frozen=True)
class Probe:
    """Costs measured by a short Python program that prints them as JSON ``{key: value}``.

    A value is a number or ``[low, high]``. The program runs in a fresh process, in a fresh
    cache with the compiled code warm (``numba``: or an empty compile cache), in a fresh folder.
    """

    keys: tuple[str, ...]
    units: tuple[str, ...]
    whats: tuple[str, ...]
    command: str
    code: str
    numba: str = "warm"  # or "fresh"
    warmup: str | None = None  # a program run first, untimed, on the same compile cache
    timeout_s: float = 1800.0
    args: tuple[str, ...] = field(default_factory=tuple)


_STEPPING = textwrap.dedent("""
    import json, time
    import mujoco
    from tippetop.compare.running.engines import plan_for
    from tippetop.models.scene import load_scene
    from tippetop.mujoco_runner.settings import build_model
    from tippetop.mujoco_runner.stepping import start_data, step_top_model
    plan = plan_for(load_scene("fig3", ["run.t_end_s=4"]), "mujoco", "native").mujoco
    tm = build_model(plan)
    def plain():
        data = start_data(tm, plan)
        mujoco.mj_forward(tm.model, data)
        t0 = time.process_time()
        mujoco.mj_step(tm.model, data, plan.n_steps)
        return time.process_time() - t0
    def python():
        t0 = time.process_time()
        step_top_model(tm, plan, compiled=False)
        return time.process_time() - t0
    best = {"plain": [], "python": []}
    for _ in range(3):  # alternated, the best of each
        best["plain"].append(plain())
        best["python"].append(python())
    print(json.dumps({"python_stepping_ratio": min(best["python"]) / min(best["plain"])}))
""")

_LOOPS = textwrap.dedent("""
    import json, time
    import mujoco, numba  # noqa: F401 - imported before the clock
    t0 = time.perf_counter()
    from tippetop.mujoco_runner import friction_callback, stepper
    stepper.load()
    friction_callback.compiled_callback()
    print(json.dumps({"mujoco_loops_load_ms": 1e3 * (time.perf_counter() - t0)}))
""")

_TAYLOR = textwrap.dedent("""
    import json, sys, time
    from tippetop.models.resolve import resolve_plan
    from tippetop.models.scene import load_scene
    from tippetop.reference_ode import taylor
    from tippetop.reference_ode.params_array import pack_params
    pl = resolve_plan(load_scene("fig3"), "ode").ode
    symmetric = taylor.is_symmetric(pack_params(pl.top, pl.friction))
    order = int(sys.argv[1])
    t0 = time.perf_counter()
    taylor.kernel(order, symmetric)
    print(json.dumps({"taylor_compile_s": time.perf_counter() - t0}))
""")

_TABLE = textwrap.dedent("""
    import json, statistics, time
    from tippetop.models.resolve import resolve_plan
    from tippetop.models.scene import load_scene
    from tippetop.reference_ode.solve import simulate_ode
    pl = resolve_plan(load_scene("fig3"), "ode").ode
    def fixed():  # as the work-precision sweep calls it: the table at 0 and t_end only
        t0 = time.process_time()
        res = simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s,
                           sample_dt_s=pl.t_end_s, options=pl.options)
        return time.process_time() - t0 - res.cpu_s
    fixed()  # loads the compiled code
    ms = 1e3 * statistics.median(fixed() for _ in range(9))
    print(json.dumps({"ode_table_ms": ms}))
""")

_HISTORY = textwrap.dedent("""
    import json, statistics, subprocess, sys, time
    WRITER = '''
    import json, sys, time
    from tippetop.compare.nightly import history as h
    path, who, start = sys.argv[1], sys.argv[2], float(sys.argv[3])
    while time.time() < start:
        time.sleep(0.005)
    took = []
    for i in range(200):
        rows = [{"case": f"{who}/case{k}", "engine": "mujoco", "engine_version": "3.3.7",
                 "metric": "t_invert", "value": i + k / 100} for k in range(40)]
        t0 = time.perf_counter()
        h.record_results("bisect", {"format": "tippetop-bisect/1", "rows": rows,
                                     "started": f"2026-11-01T00:{i // 60:02d}:{i % 60:02d}+00:00",
                                     "environment": {"hostname": who}, "who": who, "i": i},
                         path=path)
        took.append(time.perf_counter() - t0)
    print(json.dumps(took))
    '''
    start = time.time() + 3.0  # both processes up before either writes
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, "history.sqlite", who,
                               str(start)], stdout=subprocess.PIPE, text=True)
             for who in ("a", "b")]
    took = [t for p in procs for t in json.loads(p.communicate()[0])]
    assert all(p.returncode == 0 for p in procs) and len(took) == 400
    print(json.dumps({"history_append_ms": 1e3 * statistics.median(took)}))
""")

_ENVS = textwrap.dedent("""
    import json, os, sys, tempfile
    from pathlib import Path
    from tippetop.mujoco_runner.envs import READY, env_folder, env_python
    made, size = [], []
    for version in sys.argv[1:]:
        os.environ["UV_CACHE_DIR"] = tempfile.mkdtemp(prefix="uv-", dir=".")  # empty
        env_python(version, root=Path("envs"))
        ready = json.loads((env_folder(version, Path("envs")) / READY).read_text())
        made.append(ready["made_s"])
        size.append(ready["size_mb"])
    print(json.dumps({"env_make_s": [min(made), max(made)],
                      "env_size_mb": [min(size), max(size)]}))
""")

#: Costs no command prints, each measured by a short program.
PROBES: tuple[Probe, ...] = (
    Probe(("python_stepping_ratio",), ("x",),
          ("MuJoCo stepped one step at a time from Python with each step's window "
           "(stepping.step_python, WindowAccumulator) over a plain mj_step(m, d, n) loop, CPU "
           "time per step, native mode on Fig. 3 (4 s), best of 3 alternated",),
          "a program timing step_top_model(compiled=False) against mujoco.mj_step", _STEPPING),
    Probe(("mujoco_loops_load_ms",), ("ms",),
          ("loading the compiled MuJoCo stepping loop and paper mode's callback in a fresh "
           "process (their modules imported, loaded from the compile cache)",),
          "a program timing stepper.load() and friction_callback.compiled_callback()", _LOOPS),
    Probe(("taylor_compile_s",), ("s",),
          ("compiling one order's Taylor kernel (order 12, Fig. 3's inertia variant) in a "
           "fresh process, the functions it shares with the other orders already compiled "
           "(by order 7's, untimed)",),
          "a program timing reference_ode.taylor.kernel(12, ...) in a new compile cache",
          _TAYLOR, numba="fresh", warmup="7", args=("12",)),
    Probe(("ode_table_ms",), ("ms",),
          ("a simulate_ode call's CPU time besides its integration (OdeResult.cpu_s) with the "
           "table at 0 and t_end only, as the work-precision sweep calls it, Fig. 3 (median "
           "of 9)",),
          "a program timing simulate_ode on Fig. 3", _TABLE),
    Probe(("history_append_ms",), ("ms",),
          ("one append to a history (a run of 40 rows) while another process appends too: "
           "two processes of 200 appends each at once, the median append",),
          "a program of two processes calling compare.nightly.history.record_results", _HISTORY),
    Probe(("env_make_s", "env_size_mb"), ("s", "MB"),
          ("making a managed environment (mujoco==X.Y.Z and numpy) with uv, uv's cache empty "
           "(the wheels downloaded): MuJoCo 3.3.7 and 3.17.0",
           "a managed environment's size on disk: MuJoCo 3.3.7 and 3.17.0"),
          "a program calling mujoco_runner.envs.env_python('3.3.7'), then ('3.17.0')", _ENVS,
          args=("3.3.7", "3.17.0")),
)


# ------------------------------------------------------------------ read from stored results
def _date_of(path: Path) -> str:
    """The day ``path`` was last committed (else its modification day)."""
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cs", "--", str(path)], cwd=ROOT,
                             capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        out = ""
    return out or datetime.date.fromtimestamp(path.stat().st_mtime).isoformat()


def _from_fidelity() -> dict[str, Entry]:
    path = DATA / "fidelity-default.json"
    data = json.loads(path.read_text())
    return {"fidelity_default_s": {
        **_cost(data["wall_s"], "s", f"the default fidelity map ({data['grid']['points']} "
                f"points, {data['points_at_once']} at once, no cache)",
                "docs/data/fidelity-default.json: wall_s (tippetop fidelity --grid default)"),
        "measured": _date_of(path)}}


def _from_work_precision() -> dict[str, Entry]:
    path = DATA / "work-precision.json"
    data = json.loads(path.read_text())
    when = _date_of(path)
    src = "docs/data/work-precision.json (tippetop bench ode --sweep)"

    def rows(top: str) -> list[dict[str, Any]]:
        return data["tops"][top]["levels"]["theta"]["rows"]

    fig3 = [1e3 * r["times"][r["best_reference"]] for r in rows("fig3")]
    stiff = {r["level"]: r for r in rows("stiff")}
    vs_peer = [r["ratio"] for r in stiff.values()]

    def heyoka(level: float) -> float:
        r = stiff[level]
        return r["times"]["heyoka Taylor"] / r["times"][r["best_reference"]]

    out = {
        "bench_ode_sweep_s": _cost(data["elapsed_s"], "s", "the work-precision sweep at its "
                                   "defaults (three tops, every method and peer)",
                                   f"{src}: elapsed_s"),
        "wp_fig3_reference_ms": _cost(min(fig3), "ms", "the reference's fastest method's CPU "
                                      "time on Fig. 3 at the four theta levels",
                                      f"{src}: tops.fig3 theta rows", max(fig3)),
        "wp_stiff_vs_best_peer": _cost(min(vs_peer), "x", "the fastest peer's time over the "
                                       "reference's on the stiff top, theta 1e-4 ... 1e-10 rad",
                                       f"{src}: tops.stiff theta rows' ratio", max(vs_peer)),
        "wp_stiff_vs_heyoka_1e4": _cost(heyoka(1e-4), "x", "heyoka's time over the "
                                        "reference's on the stiff top at theta 1e-4 rad",
                                        f"{src}: tops.stiff, level 1e-4"),
        "wp_stiff_vs_heyoka_1e8": _cost(heyoka(1e-8), "x", "heyoka's time over the "
                                        "reference's on the stiff top at theta 1e-8 rad",
                                        f"{src}: tops.stiff, level 1e-8"),
    }
    return {k: {**v, "measured": when} for k, v in out.items()}


def _attribution_ratio(out: dict[str, Entry]) -> dict[str, Entry]:
    attr, plain = out["matrix_attribution_s"]["value"], out["matrix_no_attribution_s"]["value"]
    return {"matrix_attribution_ratio": _cost(
        (attr - plain) / plain, "x", "the attribution reruns' wall time (the matrix with them "
        "less the matrix without) over the matrix's without them: two releases that differ "
        "on a stranger's top in one scene and mode (14 reruns)",
        "matrix_attribution_s and matrix_no_attribution_s, measured in the same run")}


#: Costs computed from others measured in the same run: (key, the keys it needs, how).
DERIVED: tuple[tuple[str, tuple[str, ...], Callable[[dict[str, Entry]], dict[str, Entry]]],
               ...] = (
    ("matrix_attribution_ratio", ("matrix_attribution_s", "matrix_no_attribution_s"),
     _attribution_ratio),
)


#: Costs read from the stored results of long runs (the keys each reader gives).
STORED: tuple[tuple[tuple[str, ...], Callable[[], dict[str, Entry]]], ...] = (
    (("fidelity_default_s",), _from_fidelity),
    (("bench_ode_sweep_s", "wp_fig3_reference_ms", "wp_stiff_vs_best_peer",
      "wp_stiff_vs_heyoka_1e4", "wp_stiff_vs_heyoka_1e8"), _from_work_precision),
)


# ------------------------------------------------------------------------------ measuring
def _folder(tmp: Path, name: str) -> Path:
    """A fresh working folder linking the repository's inputs."""
    d = Path(tempfile.mkdtemp(prefix=f"{name}-", dir=tmp))
    work = d / "work"
    work.mkdir()
    for name_ in INPUTS:
        (work / name_).symlink_to(ROOT / name_, target_is_directory=True)
    return work


def _command(c: Command, repeats: int, tt: list[str], warm: Path,
             tmp: Path) -> dict[str, Entry]:
    def cache(work: Path) -> Path:
        if c.shared_cache is None:
            return work.parent / "cache"
        shared = tmp / f"shared-cache-{c.shared_cache}"
        shared.mkdir(exist_ok=True)
        return shared

    def ready(work: Path) -> dict[str, str]:
        env = _env(cache(work), warm)
        made = Path(env["TIPPETOP_CACHE"]) / ".bench-setup"
        if c.setup is not None and not made.exists():
            c.setup(env, work)
            if c.shared_cache is not None:
                made.touch()
        return env

    warmup = c.argvs if c.warmup is True else (c.warmup or ())
    if warmup:
        work = _folder(tmp, f"{c.key}-warmup")
        env = ready(work)
        for argv in warmup:
            _run([*tt, *argv], env, c.ok, cwd=work)
    reads: list[dict[str, Entry]] = []

    def once() -> float:
        work = _folder(tmp, c.key)
        env = ready(work)
        done = [_run([*tt, *argv], env, c.ok, cwd=work) for argv in c.argvs]
        if c.reads is not None:
            reads.append(c.reads([p for _, p in done], work))
        return sum(wall for wall, _ in done)

    out = {c.key: _cost(_median(once, repeats), "s", c.what, c.shown)}
    for key in c.read_keys:  # the median run's reading of each
        values = sorted(r[key]["value"] for r in reads)
        out[key] = next(r[key] for r in reads if r[key]["value"] == values[len(values) // 2])
    return out


def _probe(p: Probe, repeats: int, warm: Path, tmp: Path) -> dict[str, Entry]:
    got: dict[str, list[Any]] = {k: [] for k in p.keys}
    for _ in range(repeats):
        work = _folder(tmp, p.keys[0])
        numba = warm if p.numba == "warm" else work.parent / "numba"
        env = _env(work.parent / "cache", numba)
        if p.warmup is not None:
            _run([sys.executable, "-c", p.code, p.warmup], env, cwd=work)
        _, proc = _run([sys.executable, "-c", p.code, *p.args], env, cwd=work)
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        for k in p.keys:
            got[k].append(res[k])
    out: dict[str, Entry] = {}
    for k, unit, what in zip(p.keys, p.units, p.whats, strict=True):
        vals = got[k]
        if isinstance(vals[0], list):  # a range: the medians of its ends
            lo, hi = (statistics.median(v[i] for v in vals) for i in (0, 1))
            out[k] = _cost(lo, unit, what, p.command, hi)
        else:
            out[k] = _cost(statistics.median(vals), unit, what, p.command)
    return out


def measure(keys: set[str], repeats: int, tmp: Path) -> dict[str, Entry]:
    """The costs of ``keys`` (those this run measures), each its value, unit, what and how."""
    tt = [sys.executable, "-m", "tippetop.compare.cli"]
    warm = tmp / "warm-numba"
    out: dict[str, Entry] = {}

    def fresh(name: str) -> Path:
        return Path(tempfile.mkdtemp(prefix=f"{name}-", dir=tmp))

    def cost(key: str, value: float, unit: str, what: str, command: str) -> None:
        out[key] = _cost(value, unit, what, command)
        _say(f"{key}: {value:.3g} {unit}")

    if keys & {"simulate_first_s", "simulate_s", "simulate_mujoco_s"}:
        def first() -> float:
            return _timed([*tt, "simulate", "fig3"], _env(fresh("sim"), None))
        cost("simulate_first_s", _median(first, repeats), "s",
             "the first run in an empty cache, compiling the reference's integrator",
             "tippetop simulate fig3 (empty $TIPPETOP_CACHE)")
        cache = fresh("sim")
        _timed([*tt, "simulate", "fig3"], _env(cache, None))
        cost("simulate_s", _median(lambda: _timed([*tt, "simulate", "fig3"],
                                                  _env(cache, None)), repeats), "s",
             "a run once compiled", "tippetop simulate fig3 (a second time)")
        mj = [*tt, "simulate", "fig3", "--engine", "mujoco", "--mode", "native"]
        _timed(mj, _env(cache, None))
        compiled = next((cache / "numba").iterdir())  # $TIPPETOP_CACHE/numba/<key>
        cost("simulate_mujoco_s", _median(lambda: _timed(mj, _env(fresh("mj"), compiled)),
                                          repeats), "s",
             "a MuJoCo run in its calibrated native mode, compiled, not cached",
             "tippetop simulate fig3 --engine mujoco --mode native")
    # compiled code for the rest (untimed)
    if keys - {"simulate_first_s", "simulate_s", "simulate_mujoco_s"} - STORED_KEYS:
        _timed([*tt, "validate", MODEL, "--no-tune", "--json"], _env(fresh("warm"), warm),
               (0, 1))
    if keys & {"validate_no_tune_s", "validate_tune_s", "validate_tune_ratio"}:
        no_tune = _median(lambda: _timed([*tt, "validate", MODEL, "--no-tune", "--json"],
                                         _env(fresh("vnt"), warm), (0, 1)), repeats)
        tune = _median(lambda: _timed([*tt, "validate", MODEL, "--json"],
                                      _env(fresh("vt"), warm), (0, 1)), repeats)
        cost("validate_no_tune_s", no_tune, "s", "validate without its tuning, no runs cached",
             f"tippetop validate {MODEL} --no-tune")
        cost("validate_tune_s", tune, "s", "validate with its tuning, no runs cached",
             f"tippetop validate {MODEL}")
        cost("validate_tune_ratio", tune / no_tune, "x",
             "validate with its tuning against --no-tune, each with no runs cached",
             f"tippetop validate {MODEL} against --no-tune")
    for c in COMMANDS:
        if keys & set(c.keys):
            got = _command(c, repeats, tt, warm, tmp)
            for key, entry in got.items():
                _say(f"{key}: {entry['value']:.3g} {entry['unit']}")
            out.update(got)
    for p in PROBES:
        if keys & set(p.keys):
            got = _probe(p, repeats, warm, tmp)
            for key, entry in got.items():
                _say(f"{key}: {entry['value']:.3g} {entry['unit']}")
            out.update(got)
    for stored_keys, read in STORED:
        if keys & set(stored_keys):
            out.update(read())
    for key, needs, derive in DERIVED:
        if key in keys and all(k in out for k in needs):
            out.update(derive(out))
    if keys & {"docs_build_s", "docs_build_no_pictures_s"}:
        exe = shutil.which("properdocs") or "properdocs"
        site = tmp / "site"
        env = {**os.environ}
        env.pop("TIPPETOP_DOCS_IMAGES", None)
        _timed([exe, "build", "--strict", "--site-dir", str(site)], env)  # the docs cache warm
        cost("docs_build_s", _median(lambda: _timed(
            [exe, "build", "--strict", "--site-dir", str(site)], env), repeats), "s",
             "the docs build with its pictures, the docs' own cache warm",
             "properdocs build --strict")
        env["TIPPETOP_DOCS_IMAGES"] = "0"
        cost("docs_build_no_pictures_s", _median(lambda: _timed(
            [exe, "build", "--strict", "--site-dir", str(site)], env), repeats), "s",
             "the docs build without its pictures", "TIPPETOP_DOCS_IMAGES=0 properdocs build")
    return out


_SUITE = re.compile(r"^=*\s*(\d+) passed.* in ([0-9.]+)s", re.M)


def from_ci_log(path: Path) -> dict[str, Entry]:
    """The two suites' times from a ``.ci/run`` log: the slow suite's line first."""
    found = [float(m.group(2)) for m in _SUITE.finditer(path.read_text(errors="replace"))]
    if len(found) < 2:
        raise SystemExit(f"bench_costs: {path}: expected two pytest summary lines (the slow "
                         f"suite, then the fast one), got {len(found)}")
    slow, fast = found[-2], found[-1]
    when = datetime.date.fromtimestamp(path.stat().st_mtime).isoformat()
    return {"tests_slow_s": {"value": slow, "unit": "s", "what": "the slow suite",
                             "command": f"pytest -m slow (in .ci/run: {path.name})",
                             "measured": when},
            "tests_fast_s": {"value": fast, "unit": "s", "what": "the default suite",
                             "command": f"pytest -m 'not slow' (in .ci/run: {path.name})",
                             "measured": when}}


STORED_KEYS = frozenset(k for ks, _ in STORED for k in ks)
CI_KEYS = ("tests_fast_s", "tests_slow_s")
DOCS_KEYS = ("docs_build_s", "docs_build_no_pictures_s")
KEYS = ("simulate_first_s", "simulate_s", "simulate_mujoco_s", "validate_no_tune_s",
        "validate_tune_s", "validate_tune_ratio",
        *(k for c in COMMANDS for k in c.keys), *(k for p in PROBES for k in p.keys),
        *(k for ks, _ in STORED for k in ks), *(k for k, _, _ in DERIVED), *DOCS_KEYS)


def _store(new: dict[str, Entry]) -> None:
    """The stored costs with ``new`` (measured today) in place of theirs, written atomically."""
    stored = json.loads(OUT.read_text()) if OUT.is_file() else {"costs": {}}
    today = datetime.date.today().isoformat()
    known = {*KEYS, *CI_KEYS}
    costs = {k: v for k, v in stored.get("costs", {}).items() if k in known}  # none retired
    for key, entry in new.items():
        costs[key] = {**entry, "measured": entry.get("measured", today)}
    data = {"format": FORMAT, "machine": f"{os.cpu_count()} cores", "costs": costs}
    tmp_out = OUT.with_suffix(".json.tmp")
    tmp_out.write_text(json.dumps(data, indent=1) + "\n")
    tmp_out.replace(OUT)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_costs", description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--docs", action="store_true", help="measure the docs build too")
    p.add_argument("--ci-log", type=Path, default=None)
    p.add_argument("--only", default=None, help="comma-separated keys to measure")
    args = p.parse_args(argv)
    if args.repeats < 1:
        p.error(f"--repeats: expected at least 1, got {args.repeats}")
    keys = set(KEYS) if args.only is None else set(args.only.split(","))
    if bad := keys - set(KEYS):
        p.error(f"--only: expected keys among {', '.join(KEYS)}, got {', '.join(sorted(bad))}")
    for key, needs, _ in DERIVED:  # a derived cost measures what it is derived from
        if key in keys:
            keys |= set(needs)
    if not args.docs:
        keys -= set(DOCS_KEYS)
    new: dict[str, Entry] = {}
    if args.ci_log is not None:
        new.update(from_ci_log(args.ci_log))
    docs = set(DOCS_KEYS)
    with tempfile.TemporaryDirectory(prefix="tt-bench-costs-") as tmp:
        try:  # the commands' costs first, stored: the docs build reads them
            new.update(measure(keys - docs, args.repeats, Path(tmp)))
            _store(new)
            if keys & docs:
                # the pages quote the build's own cost: a first measurement needs a value
                # to build with (the one it then replaces)
                stored = json.loads(OUT.read_text())["costs"]
                _store({k: {"value": 1.0, "unit": "s", "what": "not yet measured",
                            "command": "", "measured": "never"}
                        for k in docs if k not in stored and k not in new} | new)
                new.update(measure(keys & docs, args.repeats, Path(tmp)))
                _store(new)
        except KeyboardInterrupt:
            print("bench_costs: interrupted", file=sys.stderr)
            return 130
    for key in sorted(new):
        high = new[key].get("high")
        span = "" if high is None else f" - {high:.3f}"
        print(f"{key:28s} {new[key]['value']:10.3f}{span} {new[key]['unit']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
