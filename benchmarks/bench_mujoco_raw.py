"""A MuJoCo run against raw ``mj_step`` on the same compiled model: what the harness costs.

For paper mode and native mode (the calibrated settings, ``mujoco.friction=native`` as the
harness runs it) of one scene (Fig. 3 by default), in one process:

* raw: ``mj_step(model, data, nstep)`` over the run's whole horizon, one call, on the model
  the harness compiled (``settings.build_model`` of the plan), from the run's initial state,
  with paper mode's compiled callback armed (the baseline: what anyone stepping that model
  without tippetop pays);
* run: :func:`tippetop.mujoco_runner.run.run_compiled` on the same model over the same
  horizon, everything included: ``mj_step`` taken apart at every step and each step's
  forward pass added to its sample's window (the contacts, N, the friction force and power,
  the gaps; :mod:`tippetop.mujoco_runner.worker.windows`), the state recorded at each
  sample and checked, and the post-processing
  (:func:`~tippetop.mujoco_runner.results.result_from_samples`: the windows' means, the
  energy, sink and flight checks, the observables table).

The variants alternate over ``--rounds`` rounds; the best time of each counts (the machine is
shared). Each is timed by this process's CPU time (``time.process_time``: what the work
costs, not the time other processes took the core) and by wall time. Printed per mode: both
times, the ratios raw / run (the run's speed as a fraction of raw mj_step's; target >= 0.9x,
judged on CPU time) and the post-processing's share of the run's CPU time.

Run: ``python benchmarks/bench_mujoco_raw.py [--scene fig3] [--t-end 4] [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import contextlib
import time

import mujoco

from tippetop.compare.running.engines import plan_for
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner import run as mj_run
from tippetop.mujoco_runner.friction_callback import PaperFriction, compiled_callback
from tippetop.mujoco_runner.results import MujocoResult
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.stepping import start_data

#: The run's speed against raw mj_step that the harness must reach (issue 14).
TARGET = 0.9
#: The modes timed, each run on engine ``mujoco``.
MODES = ("paper", "native")


def _raw(tm, plan, nstep: int) -> tuple[float, float]:
    """(CPU, wall) seconds of one ``mj_step(model, data, nstep)`` from the run's start."""
    model = tm.model
    data = start_data(tm, plan)
    armed = (PaperFriction(tm, data, plan.law, stem=plan.stem) if plan.law is not None
             else contextlib.nullcontext())
    with armed:
        mujoco.mj_forward(model, data)
        cpu, wall = time.process_time(), time.perf_counter()
        mujoco.mj_step(model, data, nstep)
        return time.process_time() - cpu, time.perf_counter() - wall


def _run(tm, plan) -> tuple[float, float, MujocoResult]:
    """(CPU, wall) seconds of the harness's run, and the run."""
    cpu, wall = time.process_time(), time.perf_counter()
    result = mj_run.run_compiled(tm, plan)
    return time.process_time() - cpu, time.perf_counter() - wall, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="fig3", help="scene name or file (default fig3)")
    parser.add_argument("--t-end", type=float, default=4.0, help="simulated time (s)")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds")
    args = parser.parse_args()

    compiled_callback()  # loaded or compiled once, before any clock
    setups = {}
    for mode in MODES:
        scene = load_scene(args.scene, [f"run.t_end_s={args.t_end:g}"])
        plan = plan_for(scene, "mujoco", mode).mujoco
        setups[mode] = (build_model(plan), plan, plan.sample_dt_s, plan.n_steps)

    # time the post-processing inside the run: run_compiled calls it by module global
    post_s: list[float] = []
    original = mj_run.result_from_samples

    def timed(*a, **k):
        t0 = time.process_time()
        try:
            return original(*a, **k)
        finally:
            post_s.append(time.process_time() - t0)

    inf = float("inf")
    best = {(mode, v): [inf, inf] for mode in MODES for v in ("raw", "run")}
    post_best = dict.fromkeys(MODES, 0.0)
    results = {}
    mj_run.result_from_samples = timed
    try:
        for _ in range(args.rounds):
            for mode, (tm, plan, _sample_dt, nstep) in setups.items():
                cpu, wall = _raw(tm, plan, nstep)
                raw = best[mode, "raw"]
                raw[:] = min(raw[0], cpu), min(raw[1], wall)
                post_s.clear()
                cpu, wall, result = _run(tm, plan)
                run = best[mode, "run"]
                if cpu < run[0]:
                    post_best[mode] = post_s[-1]
                run[:] = min(run[0], cpu), min(run[1], wall)
                results[mode] = result
    finally:
        mj_run.result_from_samples = original

    print(f"scene {args.scene}, {args.t_end:g} s simulated, best of {args.rounds} alternating "
          f"rounds; ratio = raw mj_step time / run time (target >= {TARGET}x on CPU time)")
    for mode, (tm, _plan, sample_dt, nstep) in setups.items():
        (raw_cpu, raw_wall), (run_cpu, run_wall) = best[mode, "raw"], best[mode, "run"]
        res = results[mode]
        ratio = raw_cpu / run_cpu
        verdict = "meets" if ratio >= TARGET else "BELOW"
        print(f"{mode:6s}: {nstep} steps of {res.ran.get('integrator')} at dt = "
              f"{tm.model.opt.timestep:g} s, a sample every {sample_dt:g} s, status {res.status}"
              f"\n        CPU: raw mj_step {raw_cpu:.3f} s, run {run_cpu:.3f} s -> {ratio:.3f}x "
              "raw "
              f"({verdict} the target); post-processing {100 * post_best[mode] / run_cpu:.1f} % "
              f"of the run\n        wall: raw mj_step {raw_wall:.3f} s, run {run_wall:.3f} s "
              f"-> {raw_wall / run_wall:.3f}x raw")


if __name__ == "__main__":
    main()
