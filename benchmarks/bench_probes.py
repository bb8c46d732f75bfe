"""The whole probe set on one engine, against a plain ``mj_step`` loop of the same models.

Issue 44's target: every probe in every mode on one engine in under 10 s on 2 cores. Three
times, each the best of ``--rounds``:

* ``plain``: the probes' own models (each probe's setup, in each mode) compiled and stepped
  from their starts with a bare ``mj_step`` loop for their durations, nothing recorded: what
  MuJoCo alone costs;
* ``harness``: :func:`tippetop.compare.probes.study.run_probes` on the installed MuJoCo, no
  cache: every step recorded (state, contacts, normal force, warnings), each quantity
  measured against its exact value;
* ``command``: ``tippetop probe --no-cache --json`` in a fresh process (its start-up, the
  imports and the probes' modules included).

It prints each time and the ratios harness / plain and command / plain, and whether the command
meets the 10 s target. Run: ``python benchmarks/bench_probes.py [--rounds 3] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

#: The issue's bound on the whole set on one engine (s).
TARGET_S = 10.0


def plain_loop() -> float:
    """Step every probe's models with a bare mj_step loop; the wall time (s)."""
    import mujoco

    from tippetop.compare.probes import probe_class, probe_names

    setups = [probe_class(n)().setup(m) for n in probe_names() for m in probe_class(n).modes]
    t0 = time.perf_counter()
    for s in setups:
        model = mujoco.MjModel.from_xml_string(s.mjcf)
        model.opt.timestep = s.timestep_s
        model.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + s.integrator.upper())
        data = mujoco.MjData(model)
        data.qpos[:], data.qvel[:] = s.qpos, s.qvel
        if model.nu:
            data.ctrl[:] = s.ctrl
        for _ in range(int(round(s.duration_s / s.timestep_s))):
            mujoco.mj_step(model, data)
    return time.perf_counter() - t0


def harness() -> float:
    """run_probes on the installed MuJoCo, no cache; the wall time (s)."""
    from tippetop.compare.probes.study import run_probes
    from tippetop.models.engines import parse_engine

    t0 = time.perf_counter()
    run_probes([], [parse_engine("mujoco")], use_cache=False)
    return time.perf_counter() - t0


def command() -> float:
    """``tippetop probe --no-cache --json`` in a fresh process; the wall time (s)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "probe", "--no-cache",
                    "--json"], capture_output=True, check=False)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench_probes", description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    if args.rounds < 1:
        p.error(f"--rounds: expected at least 1, got {args.rounds}")
    harness()  # warm: imports, the file-system cache
    best = {"plain": [], "harness": [], "command": []}
    for _ in range(args.rounds):
        best["plain"].append(plain_loop())
        best["harness"].append(harness())
        best["command"].append(command())
    t = {k: min(v) for k, v in best.items()}
    out = {"plain_s": t["plain"], "harness_s": t["harness"], "command_s": t["command"],
           "harness_over_plain": t["harness"] / t["plain"],
           "command_over_plain": t["command"] / t["plain"], "target_s": TARGET_S,
           "meets_target": t["command"] < TARGET_S}
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"plain mj_step loop of the probes' models: {t['plain']:.2f} s (baseline)")
        print(f"run_probes, every step recorded:         {t['harness']:.2f} s "
              f"({out['harness_over_plain']:.2f}x the baseline)")
        print(f"tippetop probe in a fresh process:       {t['command']:.2f} s "
              f"({out['command_over_plain']:.2f}x the baseline; target < {TARGET_S:g} s: "
              f"{'met' if out['meets_target'] else 'NOT met'})")
    return 0 if out["meets_target"] else 1


if __name__ == "__main__":
    sys.exit(main())
