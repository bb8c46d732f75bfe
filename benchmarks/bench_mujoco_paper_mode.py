"""Steps per second: native MuJoCo vs paper-mode friction (compiled callback) vs a Python loop.

All three step the same model (the Fig. 3 top, condim 1, RK4 at dt = 2e-5 s by default) from
the same initial state over the same number of steps:

* native: ``mj_step(model, data, nstep)`` with no callback (frictionless contact);
* paper: the same inside :class:`mujoco_runner.friction_callback.PaperFriction` (the compiled
  ``mjcb_passive`` callback applies the paper's law at every RK4 stage);
* paper, mu = 0: the callback with a zero coefficient (native's trajectory, so the difference
  from native is the callback's own cost);
* python: one ``mj_step`` per Python iteration, the law evaluated in Python once per step and
  applied through ``xfrc_applied`` (force at the centre of mass plus the torque (P - O) x F).

Measurements alternate between the variants for several rounds; the best round counts. A last
line times :func:`mujoco_runner.run.simulate_plan` (paper mode, 1 ms samples, so Python runs
once per 50 steps) over the same horizon. The cost of a step depends on the state (the
frictionless native run follows a different trajectory), so compare ratios from one run.

Run: ``python benchmarks/bench_mujoco_paper_mode.py [--steps 40000] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
from numba.core import registry

from tippetop.models.mjcf import MjcfOption, make_mjcf
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.models.resolve import resolve_plan
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner.friction_callback import PaperFriction, compiled_callback
from tippetop.mujoco_runner.model import TopModel, load_top
from tippetop.mujoco_runner.run import simulate_plan
from tippetop.mujoco_runner.state import initial_qpos_qvel


def _fresh(tm: TopModel, init: InitialState) -> mujoco.MjData:
    data = mujoco.MjData(tm.model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, init)
    mujoco.mj_forward(tm.model, data)
    return data


def native(tm: TopModel, data: mujoco.MjData, steps: int, friction: FrictionParams) -> float:
    start = time.perf_counter()
    mujoco.mj_step(tm.model, data, steps)
    return time.perf_counter() - start


def paper(tm: TopModel, data: mujoco.MjData, steps: int, friction: FrictionParams) -> float:
    with PaperFriction(tm, data, friction):
        start = time.perf_counter()
        mujoco.mj_step(tm.model, data, steps)
        return time.perf_counter() - start


def python_loop(tm: TopModel, data: mujoco.MjData, steps: int, friction: FrictionParams) -> float:
    model, b = tm.model, tm.body_id
    R, a = tm.top.R_m, tm.top.a_m
    mu, lam2 = friction.mu, friction.Lambda_mps**2
    qpos, qvel, qcon, xfrc = data.qpos, data.qvel, data.qfrc_constraint, data.xfrc_applied
    start = time.perf_counter()
    for _ in range(steps):
        w, x, y, z = qpos[3:7].tolist()
        # Body z axis k (third column of the rotation) and world angular velocity.
        kx, ky, kz = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
        bx, by, bz = qvel[3:6].tolist()
        ox = (1 - 2 * (y * y + z * z)) * bx + 2 * (x * y - w * z) * by + kx * bz
        oy = 2 * (x * y + w * z) * bx + (1 - 2 * (x * x + z * z)) * by + ky * bz
        # v_P = v_S + omega x (-R e_z); F = -mu N v_P / sqrt(|v_P|^2 + Lambda^2).
        vx, vy = qvel[0] - oy * R, qvel[1] + ox * R
        N = max(qcon[2], 0.0)
        s = -mu * N / math.sqrt(vx * vx + vy * vy + lam2)
        fx, fy = s * vx, s * vy
        # Arm from the centre of mass O = S - a k to P = S - R e_z: a k - R e_z.
        rx, ry, rz = a * kx, a * ky, a * kz - R
        xfrc[b, 0], xfrc[b, 1], xfrc[b, 2] = fx, fy, 0.0
        xfrc[b, 3], xfrc[b, 4], xfrc[b, 5] = -rz * fy, rz * fx, rx * fy - ry * fx
        mujoco.mj_step(model, data)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=40000, help="steps per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds")
    parser.add_argument("--dt", type=float, default=2e-5, help="timestep (s)")
    parser.add_argument("--integrator", default="RK4")
    args = parser.parse_args()

    top, init, friction = TopParams.from_ratios(1.0, 0.1), InitialState(), FrictionParams()
    tm = load_top(make_mjcf(top, option=MjcfOption(timestep_s=args.dt,
                                                   integrator=args.integrator)))
    registry.cpu_target.target_context.refresh()  # numba's start-up, paid by any jit use
    compile_start = time.perf_counter()
    callback = compiled_callback()
    compile_s = time.perf_counter() - compile_start
    source = "loaded from numba's disk cache" if callback.cache_hits else "compiled"

    def runner(tm: TopModel, data: mujoco.MjData, steps: int, friction: FrictionParams) -> float:
        # The whole runner (1 ms samples) over the same trajectory as the paper variant.
        # (the default scene: the same top, start and law; make_mjcf's default contact)
        scene = load_scene(None, ["mujoco.friction='paper'", f"mujoco.timestep_s={args.dt!r}",
                                  f"mujoco.integrator={args.integrator!r}",
                                  f"run.t_end_s={steps * args.dt!r}", "run.sample_dt_s=1e-3",
                                  "mujoco.solref=[0.02, 1.0]"])
        return simulate_plan(resolve_plan(scene, "mujoco").mujoco).wall_s

    def paper_mu0(tm: TopModel, data: mujoco.MjData, steps: int, friction: FrictionParams) -> float:
        # The callback does all its work but the force is zero: native's trajectory, so this
        # isolates the callback's cost from the state dependence of MuJoCo's own step.
        return paper(tm, data, steps, FrictionParams(mu=0.0))

    variants = {"native": native, "paper_mu0": paper_mu0, "paper": paper, "python": python_loop,
                "runner": runner}
    best = {name: 0.0 for name in variants}
    for _ in range(args.rounds):
        for name, run in variants.items():
            data = _fresh(tm, init)
            best[name] = max(best[name], args.steps / run(tm, data, args.steps, friction))

    print(f"model: Fig. 3 top, condim 1, {args.integrator} at dt = {args.dt:g} s; "
          f"best of {args.rounds} rounds; callback {source} in {compile_s:.3f} s")
    for name, label in (("native", "native MuJoCo (no friction callback)"),
                        ("paper_mu0", "paper mode callback, mu = 0"),
                        ("paper", "paper mode (compiled mjcb_passive)"),
                        ("python", "Python loop + xfrc_applied"),
                        ("runner", "simulate_plan paper, 1 ms samples")):
        ratio = best[name] / best["native"]
        print(f"{label:40s} {best[name]:10.0f} steps/s   {ratio:6.3f}x native")


if __name__ == "__main__":
    main()
