"""Steps per second of MJX and MuJoCo Warp on this machine's CPU, against MuJoCo C in one run.

The model is the catalogue's default scene in native mode (the paper's top on the calibrated
native contact: RK4 at dt = 2e-4 s, a pyramidal sphere-plane contact), started at ``--starts``
spins n0 spread over 40-160 rad/s, each stepped ``--steps`` steps. Small scripts run inside
the managed environments (``tippetop.mujoco_runner.envs``), made on first use:

* MJX (``mjx-3.17.0``, JAX on the CPU, float64): the sweep as one vmapped call,
  ``jit(vmap(fori_loop(step)))`` over the batch of starts; its throughput (steps/s, every
  start's steps counted) against MuJoCo C's threaded batch of the same release in the same
  environment, ``mujoco.rollout.rollout`` on ``--threads`` threads over the same starts and
  steps. Compile time is reported apart and left out of the throughput (the second call is
  timed).
* Warp (``warp-4.0.0``, float32): steps per second of one world (``--graph-steps`` steps
  captured as a Warp graph, launched until ``--steps``) and of ``--starts`` worlds in one
  graph, against MuJoCo C 4.0's ``mj_step`` in a loop in the same process (the ``mujoco``
  that environment holds, the release Warp follows), one start on one thread.

Each variant is timed ``--rounds`` times; the best counts (the machine is shared). The ratios
are accelerated over C (>1: faster than C).

Run: ``python benchmarks/bench_accel.py [--starts 32] [--steps 500] [--threads 2]
[--rounds 2] [--graph-steps 25]``. MJX's compiled sweep is kept in JAX's persistent cache
(``$TIPPETOP_CACHE/jax``): a second run skips most of its compile.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

MJX_SCRIPT = r'''
import contextlib, json, sys, time
import numpy as np
import mujoco
req = json.loads(sys.stdin.read())
with contextlib.redirect_stdout(sys.stderr):
    import jax
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_compilation_cache_dir", req["jax_cache"])
    from mujoco import mjx
    from mujoco import rollout
spec = mujoco.MjSpec.from_string(req["mjcf"]); spec.nuserdata += req["userdata"]
m = spec.compile()
qpos, qvel = np.array(req["qpos"]), np.array(req["qvel"])
N, S, R = len(qpos), req["steps"], req["rounds"]
out = {"mujoco": mujoco.__version__, "jax": jax.__version__,
       "device": jax.devices()[0].platform}
# MuJoCo C's threaded batch: mujoco.rollout over the same starts
d = mujoco.MjData(m)
spec_full = mujoco.mjtState.mjSTATE_FULLPHYSICS
states = []
for i in range(N):
    mujoco.mj_resetData(m, d)
    d.qpos[:], d.qvel[:] = qpos[i], qvel[i]
    mujoco.mj_forward(m, d)
    s = np.empty(mujoco.mj_stateSize(m, spec_full))
    mujoco.mj_getState(m, d, s, spec_full)
    states.append(s)
states = np.array(states)
datas = [mujoco.MjData(m) for _ in range(req["threads"])]
best = float("inf")
for _ in range(R):
    t0 = time.perf_counter()
    st, _ = rollout.rollout(m, datas, states, nstep=S)
    best = min(best, time.perf_counter() - t0)
out["c_batch_s"] = best
out["c_final_qpos"] = st[:, -1, 1:1 + m.nq].tolist()
# MJX: one vmapped, jitted call over the starts
d0 = mujoco.MjData(m); mujoco.mj_forward(m, d0)
mx = mjx.put_model(m, impl="jax"); dx = mjx.put_data(m, d0, impl="jax")
shapes = jax.eval_shape(lambda d: mjx.step(mx, d), dx)
dx = jax.tree_util.tree_map(lambda x, o: x.astype(o.dtype) if x.dtype != o.dtype else x,
                            dx, shapes)
batch = jax.jit(jax.vmap(lambda q, v: mjx.forward(mx, dx.replace(qpos=q, qvel=v))))(
    jax.numpy.asarray(qpos), jax.numpy.asarray(qvel))
run = jax.jit(jax.vmap(lambda d: jax.lax.fori_loop(0, S, lambda i, d: mjx.step(mx, d), d)))
t0 = time.perf_counter()
res = run(batch); res.qpos.block_until_ready()
out["mjx_compile_s"] = time.perf_counter() - t0
best = float("inf")
for _ in range(R):
    t0 = time.perf_counter()
    res = run(batch); res.qpos.block_until_ready()
    best = min(best, time.perf_counter() - t0)
out["mjx_batch_s"] = best
out["mjx_precision"] = str(res.qpos.dtype)
out["mjx_final_qpos"] = np.asarray(res.qpos).tolist()
print(json.dumps(out))
'''

WARP_SCRIPT = r'''
import contextlib, json, sys, time
import numpy as np
import mujoco
req = json.loads(sys.stdin.read())
with contextlib.redirect_stdout(sys.stderr):
    import warp as wp
    wp.config.quiet = True
    import mujoco_warp as mjw
    wp.init()
spec = mujoco.MjSpec.from_string(req["mjcf"]); spec.nuserdata += req["userdata"]
m = spec.compile()
qpos, qvel = np.array(req["qpos"]), np.array(req["qvel"])
N, S, R = len(qpos), req["steps"], req["rounds"]
K = req["graph_steps"]
S = S // K * K
dev = wp.get_device()
out = {"mujoco": mujoco.__version__, "warp": wp.__version__, "device": str(dev.alias)}
d = mujoco.MjData(m)
def start(i):
    mujoco.mj_resetData(m, d); d.qpos[:], d.qvel[:] = qpos[i], qvel[i]; mujoco.mj_forward(m, d)
best = float("inf")
for _ in range(R):
    start(0)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, S)
    best = min(best, time.perf_counter() - t0)
out["c_single_s"] = best
start(0)
with wp.ScopedDevice(dev):
    mx = mjw.put_model(m)
    for nworld, key in ((1, "warp_single_s"), (N, "warp_batch_s")):
        dx = mjw.put_data(m, d, nworld=nworld)
        mjw.step(mx, dx)  # kernels compiled (or loaded) before the capture
        t0 = time.perf_counter()
        with wp.ScopedCapture() as cap:  # K steps a graph, launched S / K times
            for _ in range(K):
                mjw.step(mx, dx)
        out[key[:-2] + "_capture_s"] = time.perf_counter() - t0
        best = float("inf")
        for _ in range(R):
            dx.qpos.assign(qpos[:nworld].astype(np.float32))
            dx.qvel.assign(qvel[:nworld].astype(np.float32))
            mjw.forward(mx, dx)
            t0 = time.perf_counter()
            for _ in range(S // K):
                wp.capture_launch(cap.graph)
            wp.synchronize()
            best = min(best, time.perf_counter() - t0)
        out[key] = best
        out["warp_precision"] = str(dx.qpos.numpy().dtype)
        if nworld == N:
            out["warp_final_qpos"] = dx.qpos.numpy().tolist()
print(json.dumps(out))
'''


def starts(n: int) -> dict:
    """The native default scene's MJCF and ``n`` starts at n0 spread over 40-160 rad/s."""
    from tippetop.compare.running.engines import plan_for
    from tippetop.models.mjcf import HARNESS_USERDATA
    from tippetop.models.scene import load_scene

    mjcf, qpos, qvel = None, [], []
    for n0 in np.linspace(40.0, 160.0, n):
        plan = plan_for(load_scene(None, ["mujoco.friction=native", f"init.n0={n0}"]),
                        "mujoco").mujoco
        assert plan is not None and plan.keyframe is None
        if mjcf is None:
            mjcf = plan.mjcf
        elif plan.mjcf != mjcf:
            raise SystemExit("bench_accel: expected one MJCF for every start, got several")
        qpos.append(list(plan.start_qpos))
        qvel.append(list(plan.start_qvel))
    return {"mjcf": mjcf, "userdata": HARNESS_USERDATA, "qpos": qpos, "qvel": qvel}


def run_script(python: str, script: str, req: dict) -> tuple[dict, float]:
    """Run ``script`` in ``python`` with ``req`` on stdin; its last stdout line, and the wall."""
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as fh:
        fh.write(script)
    t0 = time.perf_counter()
    done = subprocess.run([python, fh.name], input=json.dumps(req), capture_output=True,
                          text=True, timeout=900)
    wall = time.perf_counter() - t0
    Path(fh.name).unlink()
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"bench_accel: expected the script to run in {python}, got: {tail}")
    return json.loads(done.stdout.strip().splitlines()[-1]), wall


def main() -> None:
    """Measure and print."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--starts", type=int, default=32, help="starts in the batch (default 32)")
    ap.add_argument("--steps", type=int, default=500, help="steps from each (default 500)")
    ap.add_argument("--threads", type=int, default=2,
                    help="mujoco.rollout's threads (default 2)")
    ap.add_argument("--rounds", type=int, default=2, help="timed rounds, best counts")
    ap.add_argument("--graph-steps", type=int, default=25,
                    help="Warp steps captured in one graph, launched steps / this times "
                         "(capture runs the host code: ~20 ms a step here; default 25)")
    args = ap.parse_args()
    from tippetop.models.resources import user_cache_dir
    from tippetop.mujoco_runner import envs

    t_all = time.perf_counter()
    print("command: python benchmarks/bench_accel.py " + " ".join(sys.argv[1:]))
    t0 = time.perf_counter()
    mjx_py = str(envs.accelerated_env_python("mjx", say=print))
    warp_py = str(envs.accelerated_env_python("warp", say=print))
    print(f"environments found or made in {time.perf_counter() - t0:.2f} s")
    req = {**starts(args.starts), "steps": args.steps, "threads": args.threads,
           "rounds": args.rounds, "graph_steps": args.graph_steps,
           "jax_cache": str(user_cache_dir() / "jax")}
    N, S = args.starts, args.steps
    total = N * S
    print(f"model: default scene, native mode (RK4, dt = 2e-4 s); {N} starts at n0 40-160 "
          f"rad/s, {S} steps each")

    out, wall = run_script(mjx_py, MJX_SCRIPT, req)
    c_rate, mjx_rate = total / out["c_batch_s"], total / out["mjx_batch_s"]
    gap = np.max(np.abs(np.array(out["mjx_final_qpos"]) - np.array(out["c_final_qpos"])))
    print(f"\nMJX {envs.MJX_VERSION} (JAX {out['jax']}, {out['device']}, "
          f"{out['mjx_precision']}) vs MuJoCo C {out['mujoco']} mujoco.rollout on "
          f"{args.threads} threads  [script {wall:.1f} s]")
    print(f"  MuJoCo C rollout : {out['c_batch_s'] * 1e3:9.1f} ms  {c_rate:12.0f} steps/s")
    print(f"  MJX jit(vmap)    : {out['mjx_batch_s'] * 1e3:9.1f} ms  {mjx_rate:12.0f} steps/s"
          f"  (compile + first call {out['mjx_compile_s']:.1f} s)")
    print(f"  ratio MJX / C batch: {mjx_rate / c_rate:.3g}x   (final qpos apart by at most "
          f"{gap:.2g})")

    out, wall = run_script(warp_py, WARP_SCRIPT, req)
    c1 = S / out["c_single_s"]
    w1 = S / out["warp_single_s"]
    wn = total / out["warp_batch_s"]
    print(f"\nWarp {envs.WARP_VERSION} (warp-lang {out['warp']}, {out['device']}, "
          f"{out['warp_precision']}) vs MuJoCo C {out['mujoco']} mj_step in process, one "
          f"thread  [script {wall:.1f} s]")
    print(f"  MuJoCo C mj_step : {out['c_single_s'] * 1e3:9.1f} ms  {c1:12.0f} steps/s "
          f"(1 start)")
    print(f"  Warp 1 world     : {out['warp_single_s'] * 1e3:9.1f} ms  {w1:12.0f} steps/s  "
          f"ratio {w1 / c1:.3g}x  (capture of {args.graph_steps} steps "
          f"{out['warp_single_capture_s']:.1f} s)")
    print(f"  Warp {N} worlds   : {out['warp_batch_s'] * 1e3:9.1f} ms  {wn:12.0f} steps/s  "
          f"ratio {wn / c1:.3g}x  (capture {out['warp_batch_capture_s']:.1f} s; every "
          f"world's steps counted)")
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
