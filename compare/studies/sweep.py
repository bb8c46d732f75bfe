"""theta_asymp against the initial spin n0 in each mode, with the theory's theta_s(n0).

This is the paper's Figs. 9 and 10, measured in any engine.
"""

from __future__ import annotations

import math

import pandas as pd

from tippetop.compare.measures.series import classify_outcome
from tippetop.compare.measures.summary import run_failed
from tippetop.compare.results.sweep import SweepResult, theory_curve
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.models.errors import TippetopError
from tippetop.models.modes import run_label
from tippetop.models.scene import Override

#: A run of a study: (engine, mode or None for the scene's, more scene keys).
Run = tuple[str, str | None, tuple[str, ...]]


def parse_range(text: str) -> list[float]:
    """``START:STOP:STEP`` (STOP included when it falls on the grid) -> the n0 values."""
    parts = text.split(":")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        raise TippetopError(f"--n0: expected START:STOP:STEP numbers, got {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(stop) and math.isfinite(step)) or step <= 0 \
            or stop < start:
        raise TippetopError(f"--n0: expected START <= STOP and STEP > 0, got {text!r}")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    if n > 2000:
        raise TippetopError(f"--n0: expected at most 2000 points, got {n} from {text!r}")
    return [round(start + i * step, 12) for i in range(n)]


def run_sweep(scene: str | None, n0_values: list[float], runs: list[Run],
              overrides: tuple[Override, ...] = (), *, scheduler: str | None = None,
              workers: int | None = None, use_cache: bool = True) -> SweepResult:
    """Run every (engine, mode, n0) and return the table, the theory curve and the cache hits.

    Args:
        scene: A scene name or file.
        n0_values: The initial spins (rad/s).
        runs: (engine, mode, more scene keys) of each curve (:data:`Run`).
        overrides: Scene overrides for every run.
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes.
        use_cache: Read and write the run cache.

    Returns:
        The rows, the theory's curve and the cache's share (:class:`SweepResult`).
    """
    tasks = []
    for engine, mode, extra in runs:
        for n0 in n0_values:
            tasks.append(Task(scene, (*overrides, *extra, Override.of("init.n0", n0)), engine,
                              mode))
    results = run_tasks(tasks, scheduler=scheduler, workers=workers, use_cache=use_cache,
                        label="sweep")
    rows = []
    n0s = [n0 for _ in runs for n0 in n0_values]
    for n0, res in zip(n0s, results, strict=True):
        if res.error:
            raise TippetopError(res.error)
        s = res.summary
        failed = run_failed(s)
        rows.append({"engine": s["engine"], "mode": s["mode"],
                     "run": run_label(s["engine"], s["mode"]), "n0": n0,
                     "theta_asymp": s["theta_asymp"],
                     "outcome": "failed" if failed else classify_outcome(res.table),
                     "t_invert": s["t_invert"],
                     "J_rel_drift": s["J_rel_drift"], "status": s.get("status", "ok"),
                     "cached": res.cached})
    top = tasks[0].plan().top
    return SweepResult(table=pd.DataFrame(rows), theory=theory_curve(top, n0_values), top=top,
                       scene=tasks[0].load().name,
                       computed=sum(not r.cached for r in results),
                       cached=sum(r.cached for r in results))
