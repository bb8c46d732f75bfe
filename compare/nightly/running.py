"""Running the cases: runs and sweep points in parallel batches per engine, then bisections."""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.measures.series import classify_outcome, theta_trend
from tippetop.compare.nightly.catalogue import Case
from tippetop.compare.running.runner import SchedulerLost, Task, TaskResult, run_tasks
from tippetop.compare.studies.threshold import measure_threshold
from tippetop.models.engines import FAMILIES
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Override, Scene, load_scene


@dataclass
class CaseRun:
    """What one case produced: metric values, details for the report, tables, or an error."""

    case: Case
    values: dict[str, Any] = field(default_factory=dict)
    detail: dict[str, Any] = field(default_factory=dict)
    table: pd.DataFrame | None = None
    error: str | None = None
    wall_s: float = 0.0


#: ``set`` overrides in these sections leave the physics, and so the scene's [expect], as is.
_NEUTRAL_SECTIONS = ("run", "ode", "mujoco", "outputs")


def expectation(case: Case, scene: Scene) -> dict[str, Any]:
    """The scene's [expect] table, or {} when the case's ``set`` leaves it behind.

    A ``set`` that changes the top, the friction or the start makes the scene file's
    expectation about another run; one that changes only the horizon or the solver does not.
    """
    if all(o.split(".", 1)[0] in _NEUTRAL_SECTIONS for o in case.set):
        return dict(scene.expect)
    return {}


def run_metrics(scene: Scene, summary: dict[str, Any], table: pd.DataFrame,
                expect: Mapping[str, Any]) -> dict[str, Any]:
    """Every run metric from a run's summary and observables.

    Args:
        scene: The scene that ran.
        summary: The engine's run summary.
        table: The run's observables.
        expect: The expectation that applies (:func:`expectation`).
    """
    outcome = classify_outcome(table)
    exp = expect.get("outcome")
    E = table["E"].to_numpy()
    return {
        "outcome": outcome,
        "matches_expect": None if exp is None else outcome == exp,
        "theta_asymp": summary["theta_asymp"],
        "t_invert": summary["t_invert"],
        "t_stem": summary.get("t_stem"),
        "J_rel_drift": summary["J_rel_drift"],
        "energy_monotone": summary["energy_monotone"],
        "energy_lost": float(E[0] - E[-1]),
        "contact_lost": summary["contact_lost"],
        "t_left_table": summary.get("t_left_table"),
        "status": summary.get("status", "ok"),
    }


def error_text(exc: BaseException) -> str:
    """``Type: message`` of an exception, as results.json records it."""
    return f"{type(exc).__name__}: {exc}".strip()


def _run_engine_group(tasks: list[Task], *, scheduler: str | None, workers: int | None,
                      cache_dir: Path, log: Callable[[str], None]) -> list[TaskResult | str]:
    """Run tasks; if the batch raises (e.g. an engine that cannot start), rerun one by one.

    Finished tasks of a failed batch are in ``cache_dir`` already, so the retry recomputes
    only what had not finished. Returns a TaskResult or an error message per task.
    """
    try:
        return list(run_tasks(tasks, scheduler=scheduler, workers=workers, cache_dir=cache_dir,
                              use_cache=True, label="nightly"))
    except TippetopError:
        raise
    except Exception as exc:  # noqa: BLE001 - one broken engine must not hide the others
        log(f"  batch failed ({error_text(exc)}); retrying its runs one by one")
    out: list[TaskResult | str] = []
    for task in tasks:
        try:
            out.append(run_tasks([task], workers=1, cache_dir=cache_dir, use_cache=True)[0])
        except TippetopError:
            raise
        except Exception as exc:  # noqa: BLE001
            out.append(error_text(exc))
    return out



def run_cases(cases: Sequence[Case], *, scheduler: str | None = None,
              workers: int | None = None, cache_dir: Path | None = None,
              shared_cache: bool = False,
              log: Callable[[str], None] = lambda s: None) -> list[CaseRun]:
    """Run every case: runs and sweep points in parallel batches per engine, then thresholds.

    Args:
        cases: The selected cases.
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes (default: all cores).
        cache_dir: The run cache used for this nightly (duplicates and retries).
        shared_cache: Thresholds also read and write the shared cache (``--cache``).
        log: Where progress lines go.

    Returns:
        One :class:`CaseRun` per case, in order.
    """
    out = {c.id: CaseRun(c) for c in cases}
    scenes: dict[str, Scene] = {}
    for c in cases:  # validate every scene before any work
        if c.kind == "probe":
            continue
        try:
            scenes[c.id] = load_scene(c.scene_arg, list(c.overrides))
        except TippetopError as exc:
            raise TippetopError(f"case {c.id}: {exc}") from None
    with tempfile.TemporaryDirectory(prefix="tippetop-nightly-") as tmp:
        cache = cache_dir or Path(tmp)
        for engine in FAMILIES:
            jobs: list[tuple[Case, float | None, Task]] = []
            for c in cases:
                if c.family != engine:
                    continue
                if c.kind == "run":
                    jobs.append((c, None, Task(c.scene_arg, c.overrides, c.engine, c.mode)))
                elif c.kind == "sweep":
                    jobs += [(c, n0, Task(c.scene_arg, (*c.overrides, Override.of("init.n0", n0)),
                                          c.engine, c.mode)) for n0 in c.n0]
            if not jobs:
                continue
            log(f"nightly: {len(jobs)} {engine} runs")
            t0 = time.perf_counter()
            results = _run_engine_group([j[2] for j in jobs], scheduler=scheduler,
                                        workers=workers, cache_dir=cache, log=log)
            log(f"  done in {time.perf_counter() - t0:.1f} s")
            for (c, n0, _task), res in zip(jobs, results, strict=True):
                _collect(out[c.id], scenes[c.id], n0, res)
        for c in cases:
            if c.kind == "threshold":
                _run_threshold(out[c.id], scheduler=scheduler, workers=workers,
                               use_cache=shared_cache, log=log)
        for c in cases:
            if c.kind == "atlas":
                _run_atlas(out[c.id], scheduler=scheduler, workers=workers,
                           use_cache=shared_cache, log=log)
        probes = [c for c in cases if c.kind == "probe"]
        if probes:
            log(f"nightly: {len(probes)} probe runs")
            for c in probes:
                _run_probe(out[c.id], use_cache=shared_cache)
    for c in cases:
        if c.model:  # results.json says which file, and which content, ran
            out[c.id].detail["model"] = model_detail(c)
        if c.kind == "sweep" and out[c.id].error is None:
            pts = sorted(out[c.id].detail.get("points", []), key=lambda p: p["n0"])
            out[c.id].detail["points"] = pts
            out[c.id].values = {
                "theta_asymp_vs_n0": {f"{p['n0']:g}": p["theta_asymp"] for p in pts},
                "outcomes_vs_n0": {f"{p['n0']:g}": p["outcome"] for p in pts},
            }
    return [out[c.id] for c in cases]


def _run_probe(cr: CaseRun, *, use_cache: bool) -> None:
    """A probe case: its probe in its mode on its engine, each quantity a metric value.

    The detail holds the rows (value, exact, error, tolerance, passed) and what ran; a run
    that failed (diverged, warned, an engine that did not answer) is the case's error.
    """
    from tippetop.compare.probes.study import probes_for, run_one
    from tippetop.models.engines import parse_engine

    c = cr.case
    t0 = time.perf_counter()
    try:
        probe = probes_for([c.scene], c.set)[0]
        run = run_one(probe, c.mode, parse_engine(c.engine), integrator=None, timestep_s=None,
                      cache=_probe_cache() if use_cache else None)
    except TippetopError as exc:
        cr.error = error_text(exc)
        return
    finally:
        cr.wall_s = time.perf_counter() - t0
    rows = [r.to_json() for r in run.rows]
    cr.values = {r.metric: (r.value if math.isfinite(r.value) else None) for r in run.rows}
    reasons = [r.reason for r in run.rows if r.reason]
    if reasons:
        cr.error = reasons[0]
    cr.detail = {"probe": {"rows": rows, "ran": run.ran, "engine": run.engine_ran,
                           "params": {k: probe.p(k) for k in probe.params}},
                 "summary": {"version": run.engine_ran.get("version"),
                             "integrator": rows[0]["integrator"] if rows else None,
                             "timestep_s": rows[0]["timestep_s"] if rows else None}}


def _probe_cache() -> Any:
    from tippetop.compare.probes.study import ProbeCache
    from tippetop.compare.running.cache import default_cache_dir

    return ProbeCache(default_cache_dir() / "probes")


def model_detail(case: Case) -> dict[str, Any]:
    """A model case's ``model`` entry in results.json.

    Its file (absolute and as given), the content hash it ran with, the files the hash covers,
    and where it came from (``catalogue`` or ``--models``).
    """
    from tippetop.compare.nightly.catalogue import model_files

    folder = Path(case.model).parent
    return {"file": case.model, "given": case.scene, "sha256": case.model_sha256,
            "files": [str(f.relative_to(folder)) if f.is_relative_to(folder) else str(f)
                      for f in model_files(Path(case.model))],
            "origin": case.model_origin}


def _collect(cr: CaseRun, scene: Scene, n0: float | None, res: TaskResult | str) -> None:
    err = res if isinstance(res, str) else res.error
    if err is not None:
        msg = err if n0 is None else f"n0 = {n0:g}: {err}"
        cr.error = msg if cr.error is None else cr.error
        return
    assert not isinstance(res, str) and res.summary is not None and res.table is not None
    s = res.summary
    cr.wall_s += float(s.get("wall_s", 0.0))
    if n0 is None:
        cr.values = run_metrics(scene, s, res.table, expectation(cr.case, scene))
        slip = (res.table["vPX"] ** 2 + res.table["vPY"] ** 2) ** 0.5
        small = slip[slip.notna()] < 0.1 * scene.friction.Lambda_mps
        cr.detail = {"summary": s, "cached": res.cached,
                     "E0": float(res.table["E"].iloc[0]),
                     "J0": float(res.table["J"].iloc[0]),
                     "theta_trend_rad_s": theta_trend(res.table),
                     "slip_small_frac": float(small.mean()) if len(small) else None}
        cr.table = res.table
        return
    cr.detail.setdefault("points", []).append({
        "n0": n0, "theta_asymp": s["theta_asymp"], "outcome": classify_outcome(res.table),
        "t_invert": s["t_invert"], "J_rel_drift": s["J_rel_drift"],
        "status": s.get("status", "ok"), "wall_s": s.get("wall_s")})


def _run_threshold(cr: CaseRun, *, scheduler: str | None, workers: int | None,
                   use_cache: bool, log: Callable[[str], None]) -> None:
    c = cr.case
    t0 = time.perf_counter()
    log(f"nightly: threshold {c.id} ({c.method}"
        + (f", rel_tol {c.rel_tol:g})" if c.rel_tol else ")"))
    try:
        options: dict[str, Any] = ({"max_rounds": c.max_rounds,
                                    "points_per_round": c.points_per_round}
                                   if c.method == "bisect" else {})
        res = measure_threshold(c.scene, c.engine, c.which or "n1", c.overrides,
                                method=c.method, rel_tol=c.rel_tol, scheduler=scheduler,
                                workers=workers, use_cache=use_cache, mode=c.mode, **options)
    except SchedulerLost:  # the cluster went: the whole nightly stops (one line)
        raise
    except Exception as exc:  # noqa: BLE001 - a failed bisection is that case's error
        cr.error = error_text(exc)
        cr.wall_s = time.perf_counter() - t0
        log(f"  failed: {cr.error}")
        return
    cr.wall_s = time.perf_counter() - t0
    if res.failed_runs:
        cr.error = f"RunFailedError: {res.warning}"
        log(f"  failed: {cr.error}")
        return
    cr.values = {"measured": res.measured, "converged": bool(res.converged)}
    cr.detail = {"threshold": {**res.to_json(), "rel_tol": c.rel_tol}}
    log(f"  {res.measured:.4g} rad/s (theory {res.theory:.4g}), {res.n_runs} runs, "
        f"{cr.wall_s:.1f} s")



def point_key(p: Mapping[str, Any]) -> str:
    """An atlas point's key in the metric dictionaries: ``A/C=0.8,a/R=0.05``."""
    return f"A/C={p['A_over_C']:.4g},a/R={p['a_over_R']:.4g}"


def _run_atlas(cr: CaseRun, *, scheduler: str | None, workers: int | None,
               use_cache: bool, log: Callable[[str], None]) -> None:
    from tippetop.compare.studies.atlas import parse_grid, run_atlas

    c = cr.case
    t0 = time.perf_counter()
    log(f"nightly: atlas {c.id} (A/C {c.A_over_C}, a/R {c.a_over_R})")
    try:
        res = run_atlas(parse_grid(c.A_over_C, "A_over_C"), parse_grid(c.a_over_R, "a_over_R"),
                        [(c.engine, c.mode, c.extra)], tuple(c.set), scheduler=scheduler,
                        workers=workers,
                        use_cache=use_cache)
    except SchedulerLost:
        raise
    except Exception as exc:  # noqa: BLE001 - a failed atlas is that case's error
        cr.error = error_text(exc)
        cr.wall_s = time.perf_counter() - t0
        log(f"  failed: {cr.error}")
        return
    cr.wall_s = time.perf_counter() - t0
    pts = [p.to_json() for p in res.points]
    cr.values = {
        "groups_measured": {point_key(p): p["group_measured"] for p in pts},
        "agreement": res.agreement[c.run],
        "n1_measured": {point_key(p): p["n1_measured"] for p in pts},
        "n4_measured": {point_key(p): p["n4_measured"] for p in pts},
    }
    cr.detail = {"atlas": res.to_json()}
    log(f"  groups agree at {100 * res.agreement[c.run]:.0f} % of {len(pts)} points, "
        f"{res.n_runs} runs, {cr.wall_s:.1f} s")
