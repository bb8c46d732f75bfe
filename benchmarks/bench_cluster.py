"""A matrix on a loopback Dask cluster of 2 single-threaded workers, against one local worker.

Issue 31's benchmark (target: at least 1.6x), in one run:

* ``local``: :func:`tippetop.compare.studies.matrix.run_matrix` in this process with
  ``workers=1`` (``tippetop matrix ... --workers 1``): the reference's runs one after another,
  then the MuJoCo runs on one thread; a managed release's runs through one engine worker.
* ``dask``: the same matrix with ``scheduler=`` a ``distributed.LocalCluster(n_workers=2,
  threads_per_worker=1, processes=True)`` on loopback (``tippetop matrix ... --scheduler``):
  each Dask worker a process of its own, with its own ``TIPPETOP_CACHE`` (whose ``envs`` and
  compiled code are linked to this process's, so nothing is made or compiled in the timing).

Both compute every run (``use_cache=False``) with no attribution reruns. Before the rounds one
warm-up matrix runs each way (imports, the workers' first runs, the engine workers started:
both sides keep theirs from then on). The rounds alternate the two; the machine is shared, so
the best round of each counts and each round's own ratio is printed beside it. The results of
the two are checked equal (every metric to 1e-9 relative) so the ratio compares the same work.

Matrices (``--matrices``): ``release`` (``mujoco==3.17.0``: a managed environment, run by
engine workers: the target is on this one) and ``installed`` (engine ``mujoco``: this process's
MuJoCo, run in process; printed for reference). Locally the installed MuJoCo's runs step on
threads of one process (once, in paper mode, in one ``mujoco.batch.Batch``: 4 runs batched in
0.6x the time of the 4 alone, and this ratio then 1.1x; not measured since the windows, which
retired the Batch), which a Dask worker running one run per task does not; a release's runs go
through one engine worker each either way.

Run: ``python benchmarks/bench_cluster.py [--scenes fig3,fig6,fig8a,fig11_n060]
[--modes native,paper] [--t-end 2.0] [--rounds 2] [--matrices installed,release] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

#: The target: the cluster's matrix at least this many times faster than one local worker.
TARGET = 1.6
MATRICES = {"installed": "mujoco", "release": "mujoco==3.17.0"}
METRICS = ("status", "t_invert", "t_stem", "theta_final", "theta_asymp", "J_rel_drift")


def _worker_env(folder: Path) -> dict[str, str]:
    """A Dask worker's environment: its own TIPPETOP_CACHE, this process's envs and numba."""
    from tippetop.models.resources import user_cache_dir
    from tippetop.reference_ode._jit import cache_key

    real = user_cache_dir()
    (real / "envs").mkdir(parents=True, exist_ok=True)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "envs").symlink_to(real / "envs", target_is_directory=True)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR") or str(real / "numba" / cache_key())
    return {"TIPPETOP_CACHE": str(folder), "NUMBA_CACHE_DIR": numba_dir,
            "MUJOCO_GL": "disable"}


def _rows(res: dict[str, Any]) -> dict[tuple[str, str, str], dict[str, Any]]:
    rows = {(r["scene"], r["engine"], r["mode"]): r for r in res["runs"]}
    rows.update({(s, "ode", "ode"): r for s, r in res["reference"].items()})
    return rows


def _same(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """The runs whose metrics differ between two matrices (beyond 1e-9 relative)."""
    bad = []
    ra, rb = _rows(a), _rows(b)
    if ra.keys() != rb.keys():
        return [f"runs differ: {sorted(set(ra) ^ set(rb))}"]
    for key, x in ra.items():
        for m in METRICS:
            u, v = x.get(m), rb[key].get(m)
            if isinstance(u, float) and isinstance(v, float):
                if abs(u - v) > 1e-9 * max(abs(u), abs(v), 1e-12):
                    bad.append(f"{key} {m}: {u!r} vs {v!r}")
            elif u != v:
                bad.append(f"{key} {m}: {u!r} vs {v!r}")
    return bad


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print the ratios (``--json``: one object)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--scenes", default="fig3,fig6,fig8a,fig11_n060")
    ap.add_argument("--modes", default="native,paper")
    ap.add_argument("--t-end", type=float, default=2.0, help="simulated seconds of each run")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--matrices", default="release,installed",
                    help=f"comma-separated, of {', '.join(MATRICES)}")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    from distributed import LocalCluster

    from tippetop.compare.studies.matrix import run_matrix
    from tippetop.models.engines import parse_engines

    scenes = args.scenes.split(",")
    modes = args.modes.split(",")
    over = (f"run.t_end_s={args.t_end!r}",)
    names = args.matrices.split(",")

    def say(text: str) -> None:
        if not args.json:
            print(text, flush=True)

    out: dict[str, Any] = {"scenes": scenes, "modes": modes, "t_end_s": args.t_end,
                           "rounds": args.rounds, "target": TARGET, "matrices": {}}
    with tempfile.TemporaryDirectory(prefix="bench-cluster-") as tmp, \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         dashboard_address=None,
                         env=_worker_env(Path(tmp) / "worker-cache")) as cluster:
        address = cluster.scheduler_address
        say(f"loopback cluster {address}: 2 workers x 1 thread; "
            f"{len(scenes)} scenes x {len(modes)} modes, {args.t_end:g} s each, no cache")
        for name in names:
            engines = parse_engines(MATRICES[name])

            def local() -> dict[str, Any]:
                return run_matrix(scenes, engines, modes, over, workers=1, use_cache=False,  # noqa: B023
                                  attribution=False).to_json()

            def on_dask() -> dict[str, Any]:
                return run_matrix(scenes, engines, modes, over, use_cache=False,  # noqa: B023
                                  attribution=False, scheduler=address).to_json()

            t0 = time.perf_counter()
            local()
            on_dask()
            say(f"{name} ({MATRICES[name]}): warm-up {time.perf_counter() - t0:.1f} s")
            times: dict[str, list[float]] = {"local": [], "dask": []}
            diffs: list[str] = []
            for r in range(args.rounds):
                results = {}
                for side, fn in (("local", local), ("dask", on_dask)):
                    t0 = time.perf_counter()
                    results[side] = fn()
                    times[side].append(time.perf_counter() - t0)
                diffs += _same(results["local"], results["dask"])
                say(f"  round {r + 1}: local {times['local'][-1]:.2f} s, dask "
                    f"{times['dask'][-1]:.2f} s, ratio "
                    f"{times['local'][-1] / times['dask'][-1]:.2f}x")
            n_runs = len(_rows(results["local"]))
            best = min(times["local"]) / min(times["dask"])
            out["matrices"][name] = {
                "engine": MATRICES[name], "runs": n_runs, "local_s": times["local"],
                "dask_s": times["dask"], "ratio_best": best,
                "ratios": [a / b for a, b in zip(times["local"], times["dask"], strict=True)],
                "meets_target": best >= TARGET if name == "release" else None,
                "equal": not diffs, "differences": diffs[:5]}
            target = (f" (target >= {TARGET}x: {'met' if best >= TARGET else 'NOT met'})"
                      if name == "release" else " (for reference: no target)")
            say(f"{name}: {n_runs} runs; best local {min(times['local']):.2f} s, best dask "
                f"{min(times['dask']):.2f} s: {best:.2f}x{target}; results "
                f"{'equal' if not diffs else 'DIFFER: ' + '; '.join(diffs[:3])}")
    if args.json:
        print(json.dumps(out, indent=1))
    ok = all(m["equal"] for m in out["matrices"].values())
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
