"""Runs per second of a MuJoCo sweep: one process's loop of single runs vs the thread pool.

The sweep is the Fig. 3 top at ``--runs`` initial spins n0 spread over 40-160 rad/s, each run
``--t-end`` seconds of simulated time, on engine ``mujoco`` in paper mode (the compiled
friction callback, RK4 at dt = 2e-5 s) and in native mode (the calibrated native contact,
dt = 2e-4 s). Variants, every one giving the same results (tests/mujoco_runner/test_batch.py
checks ==):

* single: a loop of :func:`mujoco_runner.run.simulate_plan` in this process (the baseline;
  what a sweep costs on one core);
* threads: :func:`mujoco_runner.batch.simulate_plans` on ``--threads`` threads (what ``tippetop
  sweep`` and the other many-run commands do): each run is stepped whole on a worker thread in
  the compiled stepper, which releases the GIL, every step's forward pass added to its
  sample's window, as the single run steps it; the main thread turns finished records into
  results (``batch._run_threads``). Paper mode's callback is installed once, on the main
  thread, for as long as the runs go;
* pool (``--pool``): the old path for reference, :func:`compare.running.runner.execute` of each
  run on a pool of ``--threads`` worker processes, already started and warm (its start-up is left
  out, which favours it); cold: the same on a pool started for the sweep, as a command paid
  it (spawned workers import numpy, pandas, MuJoCo and load the compiled code).

Each round times every variant once, in turn; the best round of each counts (the machine is
shared). Everything is compiled and loaded before the first round. The ratio printed is the
thread pool's runs per second over the single loop's (best rounds); the target is >= 1.8 on 2
cores. Beside it, each round's own ratio and their median (a shared machine's speed drifts
from one minute to the next, by up to 1.6x here, for both variants), and what the machine gives
MuJoCo itself at that moment: plain ``mj_step`` on ``--threads`` threads against one thread,
in every round (:func:`ceiling`; 2.0 on a machine that gives every core its full speed,
1.3-2.2 here): the pool cannot beat it, so a ratio below 1.8 beside a ceiling below 1.8 is the
machine's, not the pool's; each round's ratio over that round's plain ``mj_step`` ratio says
how near the pool comes to it (1.0: all of it). The CPU time the variant took over the single
loop's (least of the rounds each; the pool's workers' is not this process's, NaN) says what
the threads cost in work, whatever cores the machine gives. Beside each, the cores the
process got (its CPU time over the wall time): on a machine other processes keep busy the pool
cannot get two, and the ratio says so rather than the pool's own speed; a line also says how
many cores two threads of plain C work (sha256) get at that moment.

Run: ``python benchmarks/bench_mujoco_batch.py [--runs 64] [--t-end 0.2] [--rounds 3]
[--threads 2] [--modes paper,native] [--pool]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from tippetop.compare.running.engines import plan_for
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner.batch import simulate_plans
from tippetop.mujoco_runner.friction_callback import compiled_callback
from tippetop.mujoco_runner.run import simulate_plan


def cores_free(threads: int) -> float:
    """Cores ``threads`` threads of plain C work (sha256, GIL released) get now, CPU / wall."""
    import hashlib
    import threading

    data = b"x" * (64 * 2**20)

    def work() -> None:
        for _ in range(4):
            hashlib.sha256(data).digest()

    workers = [threading.Thread(target=work) for _ in range(threads)]
    start, cpu = time.perf_counter(), time.process_time()
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    return (time.process_time() - cpu) / (time.perf_counter() - start)


def ceiling(plan, threads: int, steps: int = 80_000) -> float:
    """How much faster ``threads`` threads step MuJoCo now than one, with no tippetop code.

    ``threads`` plain ``mj_step(model, data, steps)`` calls (the bindings release the GIL) on
    their own mjData of ``plan``'s model, one after another and then on as many threads: the
    serial time over the threaded. On a machine that gives two cores their full speed this
    is 2.0; a shared one gives less, and what it gives moves from minute to minute (the
    pool's rounds move with it; a round of the pool can beat the reference taken after it).
    """
    import threading

    import mujoco

    from tippetop.mujoco_runner.settings import build_model
    from tippetop.mujoco_runner.state import initial_qpos_qvel

    top_model = build_model(plan)

    def data() -> mujoco.MjData:
        d = mujoco.MjData(top_model.model)
        d.qpos[:7], d.qvel[:6] = initial_qpos_qvel(top_model, plan.init)
        return d

    def step(d: mujoco.MjData) -> None:
        mujoco.mj_step(top_model.model, d, steps)

    start = time.perf_counter()
    for d in [data() for _ in range(threads)]:
        step(d)
    serial = time.perf_counter() - start
    workers = [threading.Thread(target=step, args=(data(),)) for _ in range(threads)]
    start = time.perf_counter()
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    return serial / (time.perf_counter() - start)


def _overrides(n0: float, t_end: float) -> list[str]:
    return [f"init.n0={n0!r}", f"run.t_end_s={t_end!r}"]


def _plans(mode: str, runs: int, t_end: float) -> list:
    return [plan_for(load_scene("fig3", _overrides(float(n0), t_end)), "mujoco", mode).mujoco
            for n0 in np.linspace(40.0, 160.0, runs)]


def single(plans: list, threads: int) -> tuple[float, float]:
    start, cpu = time.perf_counter(), time.process_time()
    for plan in plans:
        simulate_plan(plan)
    return time.perf_counter() - start, time.process_time() - cpu


def on_threads(plans: list, threads: int) -> tuple[float, float]:
    start, cpu = time.perf_counter(), time.process_time()
    simulate_plans(plans, nthread=threads)
    return time.perf_counter() - start, time.process_time() - cpu


def _pool_variant(mode: str, runs: int, t_end: float):
    from tippetop.compare.running.runner import Task, execute, local_pool

    tasks = [Task("fig3", tuple(_overrides(float(n0), t_end)), "mujoco", mode)
             for n0 in np.linspace(40.0, 160.0, runs)]

    def pool(plans: list, threads: int) -> tuple[float, float]:
        executor, _queue = local_pool(threads)
        start = time.perf_counter()
        for fut in [executor.submit(execute, task) for task in tasks]:
            fut.result()
        return time.perf_counter() - start, math.nan  # the workers' CPU is not this process's

    def pool_cold(plans: list, threads: int) -> tuple[float, float]:
        from concurrent.futures import ProcessPoolExecutor
        from multiprocessing import get_context

        start = time.perf_counter()
        with ProcessPoolExecutor(threads, mp_context=get_context("spawn")) as executor:
            for fut in [executor.submit(execute, task) for task in tasks]:
                fut.result()
        return time.perf_counter() - start, math.nan

    return pool, pool_cold


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=64)
    parser.add_argument("--t-end", type=float, default=0.2, help="simulated seconds a run")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--modes", default="paper,native")
    parser.add_argument("--pool", action="store_true", help="also the old process pool")
    args = parser.parse_args()
    compiled_callback()
    print(f"{args.runs} runs of fig3 (n0 40-160 rad/s, {args.t_end:g} s each), "
          f"{args.threads} threads, {os.cpu_count()} cores, best of {args.rounds} rounds; "
          f"load average before {os.getloadavg()[0]:.2f} (other processes take cores too)")
    for mode in args.modes.split(","):
        plans = _plans(mode, args.runs, args.t_end)
        variants = {"single": single, "threads": on_threads}
        if args.pool:
            variants["pool"], variants["cold"] = _pool_variant(mode, args.runs, args.t_end)
            variants["pool"](plans[:args.threads], args.threads)  # start and warm the workers
        simulate_plans(plans[:2], nthread=args.threads)  # warm: imports, the compiled loop
        best = dict.fromkeys(variants, (math.inf, math.nan))
        rounds: dict[str, list[float]] = {name: [] for name in variants}
        cpus: dict[str, list[float]] = {name: [] for name in variants}
        ceilings = []
        for _ in range(args.rounds):
            for name, run in variants.items():
                took = run(plans, args.threads)
                rounds[name].append(took[0])
                cpus[name].append(took[1])
                best[name] = min(best[name], took)
            ceilings.append(ceiling(plans[0], args.threads))
        base = args.runs / best["single"][0]
        print(f"  (load average now {os.getloadavg()[0]:.2f}; {args.threads} threads of plain "
              f"C work get {cores_free(args.threads):.2f} cores now; plain mj_step on "
              f"{args.threads} threads against one, what this machine gives MuJoCo, round by "
              f"round: "
              f"{' '.join(f'{c:.2f}' for c in ceilings)}, median "
              f"{float(np.median(ceilings)):.2f}x)")
        for name, (seconds, cpu) in best.items():
            rate = args.runs / seconds
            # the machine's speed drifts between rounds: each round's ratio against the single
            # loop timed just before it, and their median, say how steady the best one is
            paired = [one / other for one, other in zip(rounds["single"], rounds[name],
                                                          strict=True)]
            # against what the machine gave plain mj_step in the same round
            of_ceiling = [r / c for r, c in zip(paired, ceilings, strict=True)]
            # the CPU time the runs took, over the single loop's (least of the rounds each):
            # 1.00, the threads add no work; the cores the machine gives are not in it
            work = min(cpus[name]) / min(cpus["single"])
            against = "" if name == "single" else (
                f"; over that round's plain mj_step ratio "
                f"{' '.join(f'{r:.2f}' for r in of_ceiling)}, median "
                f"{float(np.median(of_ceiling)):.2f}; CPU time {work:.3f}x the single loop's")
            print(f"  {mode:6s} {name:7s} {rate:8.2f} runs/s  ({seconds:.2f} s; cores this "
                  f"process got: {cpu / seconds:.2f})  {rate / base:.2f}x single (best "
                  f"rounds); round by round {' '.join(f'{r:.2f}' for r in paired)}, median "
                  f"{float(np.median(paired)):.2f}x{against}")


if __name__ == "__main__":
    main()
