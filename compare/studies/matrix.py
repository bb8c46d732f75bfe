"""Engines side by side: every scene on every engine and mode, against the theory and each other.

:func:`run_matrix` runs the scenes (catalogue names, scene files or MJCF tops) on each engine
(:mod:`tippetop.models.engines`) in each mode (:mod:`tippetop.models.modes`: by default the
scene's own contact, ``native`` for a catalogue scene and ``file`` for an MJCF top, and the
paper's law, ``paper``), and the reference ODE once per scene; it says per run whether it
agrees with the theory (the nightly's rule), and lists every metric on which two engines
differ beyond the nightly's tolerance for it.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Sequence
from typing import Any

from tippetop.compare.measures.metrics import TOLERANCES as METRIC_TOLERANCES
from tippetop.compare.measures.summary import run_failed
from tippetop.compare.measures.verdict import crossval_row, predicted_outcome, run_facts
from tippetop.compare.results.matrix import (
    FORMAT,
    Evidence,
    MatrixDifference,
    MatrixEngine,
    MatrixResult,
    MatrixRun,
)
from tippetop.compare.running.runner import Task, TaskResult, run_tasks
from tippetop.models.engines import EngineSpec, parse_engine
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.modes import check_pair, run_label
from tippetop.models.scene import Override, catalogue_names

#: The modes run when ``--modes`` is not given: the scene's own contact (the calibrated
#: settings of a catalogue scene, ``native``; an MJCF top's own, ``file``), then the paper's law.
DEFAULT_MODES = ("native", "paper")
DEFAULT_FILE_MODES = ("file", "paper")
#: ``--profile``: the scenes run when none are named.
PROFILES: dict[str, tuple[str, ...]] = {"quick": ("fig3", "fig6", "fig8a", "fig11_n060")}
#: The metrics two engines are compared on, each within its declared tolerance
#: (:mod:`tippetop.compare.measures.metrics`: the nightly's against its baseline). A growth
#: tolerance (Jellett's drift) is symmetric here: neither engine is the baseline, so the larger
#: value may be at most that factor times the smaller (or under the floor).
COMPARED: tuple[str, ...] = ("status", "outcome", "theta_asymp", "t_invert", "t_stem",
                             "t_left_table", "J_rel_drift")


def table_key(scene: str, mode: str, engine: str) -> str:
    """The key of a run's table in ``run_matrix``'s ``tables``."""
    return f"{scene}|{mode}|{engine}"


def profile_scenes(profile: str) -> tuple[str, ...]:
    """The scenes of ``--profile`` (``full``: the whole catalogue)."""
    if profile == "full":
        return tuple(catalogue_names())
    if profile not in PROFILES:
        raise TippetopError(f"--profile: expected quick or full, got {profile!r}"
                            f"{did_you_mean(profile, ('quick', 'full'))}")
    return PROFILES[profile]


def _scene_task_args(scene: str) -> tuple[str | None, tuple[Override, ...], bool]:
    """(scene for Task, overrides, is an MJCF top) of a scene name, scene file or MJCF file."""
    if scene.lower().endswith(".xml"):
        if not os.path.isfile(scene):
            raise TippetopError(f"SCENE: expected a scene or an MJCF file, got {scene!r}")
        return None, (Override.of("top.mjcf", os.path.abspath(scene)),), True
    return scene, (), False


def metric_tolerance(metric: str) -> Any:
    """A metric's tolerance against a baseline: a run metric's, or a probe quantity's.

    A probe quantity is ``probe.<probe>.<quantity>``
    (:func:`tippetop.compare.probes.probe_metrics`).

    Raises:
        KeyError: Not a metric with a tolerance.
    """
    if metric in METRIC_TOLERANCES:
        return METRIC_TOLERANCES[metric]
    if metric.startswith("probe."):
        from tippetop.compare.probes import probe_metric

        tol = probe_metric(metric).tolerance
        if tol is not None:
            return tol
    raise KeyError(metric)


def _differ(metric: str, a: Any, b: Any) -> bool:
    tol = metric_tolerance(metric)
    if a is None or b is None:
        return (a is None) != (b is None)
    if tol.kind == "exact":
        return a != b
    a, b = float(a), float(b)
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.isfinite(a) != math.isfinite(b)
    if tol.kind == "abs":
        return abs(a - b) > tol.value
    if tol.kind == "rel":
        return abs(a - b) > max(tol.value * max(abs(a), abs(b)), tol.floor)
    lo, hi = sorted((abs(a), abs(b)))
    return hi > max(tol.value * lo, tol.floor)


def differs(metric: str, a: Any, b: Any) -> bool:
    """Whether two values of a metric differ beyond the nightly's tolerance for it.

    The matrix's rule (:data:`COMPARED` metrics; a growth tolerance is symmetric here), shared
    with ``tippetop bisect``. A missing value differs from a present one.
    """
    return _differ(metric, a, b)


def run_matrix(scenes: Sequence[str], engines: Sequence[EngineSpec],
               modes: Sequence[str] | None = None, overrides: tuple[Override, ...] = (), *,
               workers: int | None = None, use_cache: bool = True, attribution: bool = True,
               tables: dict[str, Any] | None = None,
               scheduler: str | None = None) -> MatrixResult:
    """Every scene on every MuJoCo engine in every mode, the reference once per scene.

    Args:
        scenes: Catalogue names, scene files or MJCF tops.
        engines: MuJoCo engines (the reference runs once per scene anyway).
        modes: MuJoCo modes (:mod:`tippetop.models.modes`); None: :data:`DEFAULT_MODES` for a
            scene, :data:`DEFAULT_FILE_MODES` for an MJCF top.
        overrides: Scene overrides for every run.
        workers: Local worker processes.
        use_cache: Read and write the run cache.
        attribution: Rerun each difference with one subsystem changed at a time.
        tables: Receives each run's table under :func:`table_key`.
        scheduler: ``tcp://HOST:PORT`` of a Dask scheduler to run on (the attribution's
            reruns too), or None for local processes.

    Returns:
        The engines (the version read back from the runs), the runs, the differences (each
        attributed, see :mod:`.attribution`; not with ``attribution`` False) and the
        reference's run per scene. ``tables``, when given, receives each run's table under
        :func:`table_key` (the reference's: mode and engine ``ode``).
    """
    for spec in engines:
        if spec.is_reference:
            raise TippetopError("--engines: expected MuJoCo engines (the reference runs once "
                                "per scene anyway), got 'ode'")
    for m in modes or ():
        check_pair("mujoco", m)
    jobs: list[tuple[str, str | None, Task]] = []  # (scene, mode or None, task)
    scene_modes: dict[str, tuple[str, ...]] = {}
    for scene in scenes:
        name, base, is_file = _scene_task_args(scene)
        over = (*base, *overrides)
        jobs.append((scene, None, Task(name, over, "ode", label=f"{scene} [ode]")))
        scene_modes[scene] = tuple(modes) if modes else (
            DEFAULT_FILE_MODES if is_file else DEFAULT_MODES)
        for mode, spec in itertools.product(scene_modes[scene], engines):
            fit = ((Override.of("mujoco.fit_paper_timestep", True),) if is_file and mode == "paper"
                   else ())
            jobs.append((scene, mode, Task(name, (*over, *fit), spec.spec, mode,
                                           label=f"{scene} [{run_label(spec.spec, mode)}]")))
    results = run_tasks([t for _, _, t in jobs], workers=workers, use_cache=use_cache,
                        label="matrix", scheduler=scheduler)
    runs: list[MatrixRun] = []
    reference: dict[str, MatrixRun] = {}
    done: dict[tuple[str, str, str], tuple[Task, TaskResult]] = {}
    predictions: dict[str, tuple[float | None, str | None]] = {}
    for scene in scenes:
        mine = [(m, t, r) for (s, m, t), r in zip(jobs, results, strict=True) if s == scene]
        ref = mine[0][2]
        th_s, th_out = _prediction(mine[0][1], [r for _, _, r in mine])
        predictions[scene] = th_s, th_out
        ref_mode = (ref.summary or {}).get("mode") or "paper"
        try:
            A_over_C: float | None = mine[0][1].plan().top.A_over_C
        except TippetopError:
            A_over_C = None
        ref_facts = run_facts(ref.summary, ref.table, error=ref.error)
        reference[scene] = _run_row(scene, "ode", ref_mode, ref, th_s, th_out, None, A_over_C)
        if tables is not None and ref.table is not None:
            tables[table_key(scene, "ode", "ode")] = ref.table
        for mode, task, res in mine[1:]:
            runs.append(_run_row(scene, task.engine, str(mode), res, th_s, th_out, ref_facts,
                                 A_over_C))
            done[scene, str(mode), task.engine] = task, res
            if tables is not None and res.table is not None and res.error is None:
                tables[table_key(scene, str(mode), task.engine)] = res.table
    differences = _differences(runs, engines, scene_modes, scenes)
    if attribution:
        differences = _attribute(differences, done, reference, predictions, workers=workers,
                                 use_cache=use_cache, scheduler=scheduler)
    return MatrixResult(tuple(_engines(engines, runs)), tuple(runs), tuple(differences),
                        attribution, reference,
                        tuple(dict.fromkeys(m for ms in scene_modes.values() for m in ms)),
                        tuple(scenes),
                        {k: METRIC_TOLERANCES[k].to_json() for k in COMPARED})


def _attribute(differences: list[MatrixDifference],
               done: dict[tuple[str, str, str], tuple[Task, TaskResult]],
               reference: dict[str, MatrixRun],
               predictions: dict[str, tuple[float | None, str | None]], *,
               workers: int | None, use_cache: bool,
               scheduler: str | None = None) -> list[MatrixDifference]:
    """The differences with their ``attribution`` and ``closer`` (one batch of reruns)."""
    from tippetop.compare.studies import attribution as attr

    groups: dict[tuple[str, str], set[str]] = {}
    for d in differences:
        groups.setdefault((d.scene, d.mode), set()).update(d.engines)
    jobs: list[tuple[str, str, str, attr.Change, Task]] = []
    changes: dict[tuple[str, str], list[attr.Change]] = {}
    integrators: dict[tuple[str, str], str] = {}
    for (scene, mode), specs in groups.items():
        first = next(iter(sorted(specs)))
        task0 = done[scene, mode, first][0]
        try:
            plan = task0.plan().mujoco
        except TippetopError:
            plan = None
        if plan is None:
            changes[scene, mode] = []
            continue
        changes[scene, mode] = attr.changes_for(plan)
        integrators[scene, mode] = plan.integrator
        for spec in sorted(specs):
            task = done[scene, mode, spec][0]
            for ch in changes[scene, mode]:
                if ch.overrides is None:
                    continue
                jobs.append((scene, mode, spec, ch, Task(
                    task.scene, (*task.overrides, *ch.overrides), spec, mode,
                    label=f"{scene} [{run_label(spec, mode)}, {ch.name}]")))
    if jobs:
        import sys

        n = len(differences)
        sys.stderr.write(f"matrix: {n} difference{'s' if n != 1 else ''} between engines: "
                         f"{len(jobs)} more runs to attribute {'them' if n != 1 else 'it'} "
                         "(each engine with one subsystem changed at a time; "
                         "--no-attribution skips them)\n")
        sys.stderr.flush()
    results = run_tasks([j[4] for j in jobs], workers=workers, use_cache=use_cache,
                        label="attribution", scheduler=scheduler) if jobs else []
    rerun: dict[tuple[str, str, str, str], MatrixRun] = {}
    tables: dict[tuple[str, str, str, str], Any] = {}
    for (scene, mode, spec, ch, _t), res in zip(jobs, results, strict=True):
        th_s, th_out = predictions[scene]
        rerun[scene, mode, spec, ch.name] = _run_row(scene, spec, mode, res, th_s, th_out,
                                                     None, None)
        tables[scene, mode, spec, ch.name] = res.table if res.error is None else None
    out = []
    for d in differences:
        scene, mode, metric = d.scene, d.mode, d.metric
        a, b = d.engines
        ta, tb = done[scene, mode, a][1].table, done[scene, mode, b][1].table
        base_gap = attr.theta_gap(ta, tb)
        evidence: list[Evidence] = []
        for ch in changes[scene, mode]:
            if ch.overrides is None:
                evidence.append(Evidence(ch.name, applies=False, why=ch.why_not))
                continue
            ra, rb = rerun[scene, mode, a, ch.name], rerun[scene, mode, b, ch.name]
            va, vb = ra.value(metric), rb.value(metric)
            bad = [r for r in (ra, rb) if r.status == "failed"]
            evidence.append(Evidence(
                ch.name, a=va, b=vb, difference=attr.value_gap(va, vb),
                theta_gap_rad=attr.theta_gap(tables[scene, mode, a, ch.name],
                                             tables[scene, mode, b, ch.name]),
                agree=not _differ(metric, va, vb), failed=bad[0].message if bad else None))
        att = attr.attribute(metric, a, b, base_gap, evidence,
                             ran_integrator=integrators.get((scene, mode)),
                             precisions=(parse_engine(a).precision, parse_engine(b).precision))
        quarter = next((c.name for c in changes[scene, mode] if c.name == "quarter timestep"),
                       None)
        conv = ((rerun[scene, mode, a, quarter].value(metric),
                 rerun[scene, mode, b, quarter].value(metric)) if quarter else (None, None))
        near = attr.closer(metric, d.values, reference[scene].value(metric), conv, (a, b))
        out.append(dataclasses.replace(d, attribution=att, closer=near))
    return out


def _prediction(task: Task, results: list[TaskResult]) -> tuple[float | None, str | None]:
    """The theory's theta_s and outcome for the scene's Jellett constant at t = 0."""
    tables = [r.table for r in results if r.error is None and not run_failed(r.summary)
              and r.table is not None and len(r.table)]
    if not tables:
        return None, None
    top = task.plan().top
    th, out = predicted_outcome(top, float(tables[0]["J"].iloc[0]))
    return th, out


def _run_row(scene: str, engine: str, mode: str, res: TaskResult, theta_s: float | None,
             theory_outcome: str | None, ref: dict[str, Any] | None,
             A_over_C: float | None) -> MatrixRun:
    """One run's row: what it measured, and its verdict.

    The verdict is :func:`crossval_row`'s, the rule every command judges a run by (against
    the reference where the top reaches its stem).
    """
    s = res.summary or {}
    facts = run_facts(res.summary, res.table, error=res.error)
    failed = facts["outcome"] == "failed"
    label = run_label(engine, mode)
    row = crossval_row(scene, label, facts, ref, theta_s=theta_s,
                       theory_outcome=theory_outcome, A_over_C=A_over_C,
                       is_reference=ref is None)
    return MatrixRun(
        scene, engine, mode, label, "failed" if res.error else s.get("status"),
        message=res.error or s.get("message"), t_invert=s.get("t_invert"),
        t_stem=s.get("t_stem"), t_left_table=s.get("t_left_table"),
        theta_final=s.get("theta_final"),
        theta_asymp=None if failed else s.get("theta_asymp"), J_rel_drift=s.get("J_rel_drift"),
        agrees=row["agrees"], against=row["against"], outcome=row["outcome"],
        theta_s=theta_s, theory_outcome=theory_outcome, reasons=tuple(row["reasons"]),
        checks=tuple(row["checks"]), version=s.get("version"), path=s.get("path"),
        friction_realised=s.get("friction_realised"))


def _engines(engines: Sequence[EngineSpec], runs: list[MatrixRun]) -> list[MatrixEngine]:
    out = []
    for spec in engines:
        ran = [r for r in runs if r.engine == spec.spec and r.version]
        out.append(MatrixEngine(spec.spec, spec.implementation,
                                ran[0].version if ran else spec.version, spec.precision, "cpu"))
    return out


def _differences(runs: list[MatrixRun], engines: Sequence[EngineSpec],
                 scene_modes: dict[str, tuple[str, ...]],
                 scenes: Sequence[str]) -> list[MatrixDifference]:
    by = {(r.scene, r.mode, r.engine): r for r in runs}
    out = []
    for scene, mode in ((sc, m) for sc in scenes for m in scene_modes[sc]):
        for a, b in itertools.combinations([e.spec for e in engines], 2):
            ra, rb = by[scene, mode, a], by[scene, mode, b]
            metrics = COMPARED if ra.status == rb.status == "ok" else ("status",)
            for metric in metrics:
                va, vb = ra.value(metric), rb.value(metric)
                if _differ(metric, va, vb):
                    tol = METRIC_TOLERANCES[metric]
                    out.append(MatrixDifference(
                        scene, mode, (a, b), metric, (va, vb),
                        None if tol.kind == "exact" else tol.value, tol.why))
    return out


__all__ = ["DEFAULT_FILE_MODES", "DEFAULT_MODES", "COMPARED", "FORMAT", "PROFILES",
           "differs", "metric_tolerance", "profile_scenes", "run_matrix", "table_key"]
