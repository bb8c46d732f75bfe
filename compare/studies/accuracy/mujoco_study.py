"""MuJoCo's work-precision points: integrators x friction modes x timesteps.

The methods and the budget are in docs/design.md.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from typing import Any

import pandas as pd

from tippetop.compare.running.engines import plan_for, run_plan
from tippetop.compare.studies.accuracy.common import (
    ACCURACY_COLUMNS,
    HARD_LIMIT_FACTOR,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_SKIPPED,
    OverBudget,
    Reference,
    cut_scene,
    nan_scores,
    reference_run,
    score,
)
from tippetop.models.errors import TippetopError, expect
from tippetop.models.scene import Override, Scene
from tippetop.reference_ode.solve import sample_times

#: MuJoCo integrators, timesteps (s) and friction modes of the default study.
DEFAULT_INTEGRATORS: tuple[str, ...] = ("Euler", "implicitfast", "RK4")
DEFAULT_TIMESTEPS: tuple[float, ...] = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
DEFAULT_MODES: tuple[str, ...] = ("paper", "native")
#: Default per-point wall-time budget of a MuJoCo point (s). See :func:`mujoco_work_precision`.
DEFAULT_MUJOCO_BUDGET_S = 30.0
#: Dynamics evaluations per step, for ordering the work (largest series first).
_EVALS_PER_STEP = {"Euler": 1, "implicit": 1, "implicitfast": 1, "RK4": 4}
#: What the MuJoCo figure and Pareto table say about the floors of the two friction modes.
MUJOCO_NOTES: tuple[str, ...] = (
    "paper mode: the paper's friction law applied by the harness's callback on a frictionless "
    "contact; its error is first order in dt (the callback uses the normal force of the "
    "previous evaluation) down to a floor from MuJoCo's stiff but still soft contact (solref "
    "0.5 ms, the ball sinks < 1 um; about 2e-4 rad on Fig. 3, reached at dt <= 2e-5 s). Near "
    "the floor the two errors partly cancel, so a point a little below it (Fig. 3: 1.1e-4 rad "
    "at 5e-5 s) is not a converged value.",
    "native mode: MuJoCo's own soft contact friction with the calibrated settings "
    "(models/calibrated_native.toml), which is not the paper's law: its error against the "
    "reference includes that friction-model difference and floors out there, whatever dt.",
    "wall time: the runner's stepping loop including its per-sample work (one forward pass "
    "and the checks per row of the table, the same rows as the reference), which dominates at "
    "large dt; the per-series fit in pareto_mujoco.md separates it from the cost per step.",
)


def _mujoco_point_scene(s: Scene, integrator: str, mode: str, dt: float,
                        sample_dt_s: float) -> Scene:
    """``s`` with the MuJoCo integrator, timestep, friction mode and row spacing set.

    They are the scene's own settings then, so native mode takes them rather than the
    calibrated defaults (which include a 2e-4 s RK4 timestep).
    """
    return s.with_overrides([Override.of("mujoco.friction", mode),
                             Override.of("mujoco.integrator", integrator),
                             Override.of("mujoco.timestep_s", dt),
                             Override.of("run.t_end_s", s.run.t_end_s),
                             Override.of("run.sample_dt_s", sample_dt_s)])


def _run_mujoco_point(s: Scene, ref: Reference, hard_limit_s: float) -> dict[str, Any]:
    """One MuJoCo run scored against the reference; stopped past ``hard_limit_s`` of stepping."""
    start: list[float] = []
    t_done = s.run.t_end_s - 0.5 * float(ref.t[1] - ref.t[0])

    def watchdog(t: float) -> None:
        # The runner calls this at t = 0, then every 0.2 s of wall time, and once more after
        # its loop (with the last sample's time): a run that got to the end is kept.
        now = time.perf_counter()
        if not start:
            start.append(now)
        elif now - start[0] > hard_limit_s and t < t_done:
            raise OverBudget

    try:
        run = run_plan(plan_for(s, "mujoco"), progress=watchdog)
    except OverBudget:
        wall = time.perf_counter() - start[0]
        return {"wall_s": wall, "n_steps": math.nan, **nan_scores(),
                "status": f"failed: stopped after {wall:.3g} s, over the hard limit "
                          f"{hard_limit_s:.3g} s"}
    except TippetopError as exc:  # a setting the runner refuses (nothing was simulated)
        return {"wall_s": math.nan, "n_steps": 0, **nan_scores(), "status": f"failed: {exc}"}
    # what ran, read back from the compiled model (the series asked for the same)
    row: dict[str, Any] = {"wall_s": float(run.summary["wall_s"]),
                           "n_steps": int(run.summary["n_steps"]),
                           "timestep_s": float(run.summary["timestep_s"])}
    if run.status != "ok":
        msg = run.message.removeprefix("diverged ")
        return {**row, **nan_scores(), "status": f"{STATUS_DIVERGED}: {msg}"}
    if len(run.table) != ref.t.size:
        return {**row, **nan_scores(),
                "status": f"failed: {len(run.table)} rows against the reference's {ref.t.size} "
                          "(the sample grid is not a whole number of timesteps)"}
    return {**row, **score(run.table, ref), "status": STATUS_OK}


def predict_steps_wall(runs: list[tuple[int, float, bool]], n_steps: int) -> float | None:
    """Wall time predicted for a run of ``n_steps`` from the runs of the same series so far.

    ``runs`` holds (steps taken, wall s, completed). The cost of a MuJoCo run is a fixed part
    (the per-sample work, the same for every timestep of a scene) plus a part proportional to
    the steps (~ 1/dt): with two completed runs both are fitted from the last two; with one,
    the whole wall time is scaled by the steps (an overestimate, as the fixed part does not
    grow); with only diverged runs, their wall time per step taken is scaled the same way.
    """
    done = [(k, w) for k, w, ok in runs if ok and k > 0 and w > 0]
    if not done:
        part = [(k, w) for k, w, ok in runs if not ok and k > 0 and w > 0]
        if not part:
            return None
        k, w = part[-1]
        return w * n_steps / k
    k1, w1 = done[-1]
    if len(done) >= 2:
        k0, w0 = done[-2]
        if k1 != k0:
            per_step = (w1 - w0) / (k1 - k0)
            if per_step > 0:
                return max(w1, w1 + per_step * (n_steps - k1))
    return w1 * n_steps / k1


def _mujoco_series(s: Scene, integrator: str, mode: str, timesteps: Sequence[float],
                   budget_s: float, ref: Reference) -> list[dict[str, Any]]:
    """The points of one (integrator, mode) series, from the largest timestep down.

    Module level so that it can run in a worker process.
    """
    T = s.run.t_end_s
    sample_dt = float(ref.t[1] - ref.t[0])
    method = f"{integrator}/{mode}"
    rows: list[dict[str, Any]] = []
    runs: list[tuple[int, float, bool]] = []
    over = False
    for dt in timesteps:
        n_needed = round(T / dt)
        base = {"engine": "mujoco", "mode": mode, "scene": s.name, "method": method,
                "formulation": mode,
                "rtol": math.nan, "atol": math.nan, "timestep_s": dt, "t_end_s": T,
                "n_rhs": math.nan}
        pred = predict_steps_wall(runs, n_needed)
        if over or (pred is not None and pred > budget_s):
            over = True
            rows.append({**base, "wall_s": math.nan, "n_steps": 0, **nan_scores(),
                         "status": STATUS_SKIPPED, "_predicted_wall_s": pred})
            continue
        out = _run_mujoco_point(_mujoco_point_scene(s, integrator, mode, dt, sample_dt), ref,
                                HARD_LIMIT_FACTOR * budget_s)
        if out["status"].startswith("failed: stopped"):
            over = True  # a smaller timestep would cost even more
        elif math.isfinite(out["wall_s"]):
            runs.append((int(out["n_steps"]), out["wall_s"], out["status"] == STATUS_OK))
        rows.append({**base, **out, "_predicted_wall_s": pred})
    return rows


def _log_mujoco_row(log: Callable[[str], None], row: dict[str, Any], budget_s: float) -> None:
    head = f"{row['scene']} mujoco {row['method']} dt {row['timestep_s']:g} s"
    if row["status"] == STATUS_SKIPPED:
        pred = row.get("_predicted_wall_s")
        why = f"predicted {pred:.3g} s > " if pred is not None else "after a point over "
        log(f"{head}: {STATUS_SKIPPED} ({why}{budget_s:g} s)")
    elif row["status"] == STATUS_OK:
        log(f"{head}: ok, {row['wall_s']:.3g} s, {row['n_steps']} steps, "
            f"theta err {row['theta_max_err']:.2e}")
    else:
        log(f"{head}: {row['status']}")


def mujoco_rows(jobs: Sequence[tuple[Scene, Reference]], integrators: Sequence[str],
                 modes: Sequence[str], timesteps: Sequence[float], budget_s: float,
                 workers: int | None, log: Callable[[str], None] | None
                 ) -> list[list[dict[str, Any]]]:
    """Run every (integrator, mode) series of every scene; one list of rows per scene.

    Each series runs in order (its budget logic needs the points before it); the series run
    in parallel on ``workers`` processes, the most expensive first.
    """
    series = [(j, integ, mode) for j in range(len(jobs)) for integ in integrators
              for mode in modes]
    results: dict[tuple[int, str, str], list[dict[str, Any]]] = {}
    n = min(workers or os.cpu_count() or 1, len(series))

    def done(key: tuple[int, str, str], rows: list[dict[str, Any]]) -> None:
        results[key] = rows
        if log is not None:
            for row in rows:
                _log_mujoco_row(log, row, budget_s)

    if n <= 1:
        for key in series:
            j, integ, mode = key
            done(key, _mujoco_series(jobs[j][0], integ, mode, timesteps, budget_s, jobs[j][1]))
    else:
        order = sorted(series, key=lambda k: -jobs[k[0]][0].run.t_end_s
                       * _EVALS_PER_STEP.get(k[1], 1))
        if log is not None:
            log(f"mujoco: {len(series)} series (integrator x mode x scene) on {n} processes")
        with ProcessPoolExecutor(max_workers=n, mp_context=get_context("spawn")) as pool:
            futures = {pool.submit(_mujoco_series, jobs[k[0]][0], k[1], k[2], timesteps,
                                   budget_s, jobs[k[0]][1]): k for k in order}
            try:
                for fut in as_completed(futures):
                    done(futures[fut], fut.result())
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
    out: list[list[dict[str, Any]]] = []
    for j in range(len(jobs)):
        rows = [r for key in series if key[0] == j for r in results[key]]
        out.append(rows)
    return out


def mujoco_frame(rows: list[dict[str, Any]], ref: Reference) -> pd.DataFrame:
    """The rows of a MuJoCo study as a table, with its reference in ``attrs``."""
    df = pd.DataFrame(rows).reindex(columns=list(ACCURACY_COLUMNS))
    df["wall_per_sim_s"] = df["wall_s"] / df["t_end_s"]
    df.attrs["reference"] = {"method": ref.method, "rtol": ref.rtol, "atol": ref.atol,
                             "floor": ref.floor, "wall_s": ref.wall_s, "n_rhs": ref.n_rhs}
    return df


def check_mujoco_args(integrators: Sequence[str], modes: Sequence[str],
                      timesteps: Sequence[float], budget_s: float) -> list[float]:
    """Validate the MuJoCo study's settings; return its timesteps, largest first."""
    from tippetop.models.options import MUJOCO_FRICTION_MODES, MUJOCO_INTEGRATORS

    for i in integrators:
        expect(i in MUJOCO_INTEGRATORS, "accuracy.integrators", "|".join(MUJOCO_INTEGRATORS), i)
    for m in modes:
        expect(m in MUJOCO_FRICTION_MODES, "accuracy.modes", "|".join(MUJOCO_FRICTION_MODES), m)
    dts = sorted({float(t) for t in timesteps}, reverse=True)
    expect(len(dts) > 0, "accuracy.timesteps", "at least one timestep", list(timesteps))
    for t in dts:
        expect(math.isfinite(t) and 0 < t <= 0.1, "accuracy.timesteps",
               "numbers in (0, 0.1] (s)", t)
    expect(math.isfinite(budget_s) and budget_s > 0, "accuracy.budget_s", "a finite number > 0",
           budget_s)
    return dts


def mujoco_work_precision(
    scene: Scene | str,
    *,
    integrators: Sequence[str] = DEFAULT_INTEGRATORS,
    timesteps: Sequence[float] = DEFAULT_TIMESTEPS,
    modes: Sequence[str] = DEFAULT_MODES,
    budget_s: float = DEFAULT_MUJOCO_BUDGET_S,
    t_end_s: float | None = None,
    reference: Reference | None = None,
    workers: int | None = 1,
    log: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Work-precision points of MuJoCo on one scene, scored against the reference ODE.

    Every (integrator, mode) series runs from the largest timestep to the smallest. Before
    each point its wall time is predicted from the series' earlier points (a fixed part plus
    one proportional to the steps, ~ 1/dt: :func:`predict_steps_wall`); a point predicted
    over ``budget_s`` is recorded as ``skipped: over budget`` with every smaller timestep of
    the series. A run that still exceeds ``HARD_LIMIT_FACTOR * budget_s`` is stopped and
    recorded as ``failed: stopped ...``. A run that diverges (the runner's checks: NaN,
    MuJoCo's instability warnings, an energy rise, the ball sinking into the table, lost
    contact) is recorded as ``diverged: <its message>`` and the series goes on to the smaller
    timesteps. Nothing is dropped.

    The runs use the scene's plan (:func:`tippetop.models.resolve.resolve_plan`)
    with ``mujoco.friction``, ``mujoco.integrator`` and ``mujoco.timestep_s`` set per point
    (so native mode keeps its calibrated contact but not the calibrated 2e-4 s timestep), and
    the reference's sample grid (``run.sample_dt_s``), which every timestep must divide.

    Args:
        scene: A :class:`~models.scene.Scene` or a catalogue name.
        integrators: MuJoCo integrators (``Euler``, ``implicitfast``, ``implicit``, ``RK4``).
        timesteps: Timesteps (s).
        modes: Friction modes, ``paper`` and/or ``native``.
        budget_s: Per-point wall-time budget (s).
        t_end_s: Cut the scene's run to this time (s); None keeps the scene's.
        reference: A precomputed :func:`reference_run` of the same scene and horizon.
        workers: Processes running series in parallel (None: all cores; 1: this process).
        log: Called with one line per point (as each series finishes).

    Returns:
        One row per (integrator, mode, timestep) with :data:`ACCURACY_COLUMNS`: ``engine``
        ``"mujoco"``, ``method`` ``"<integrator>/<mode>"``, ``formulation`` the mode,
        ``rtol``/``atol``/``n_rhs`` NaN, ``n_steps`` the steps taken (0 when skipped);
        ``df.attrs["reference"]`` describes the reference.
    """
    s = cut_scene(scene, t_end_s)
    dts = check_mujoco_args(integrators, modes, timesteps, budget_s)
    ref = reference if reference is not None else reference_run(s)
    expect(ref.t.size == sample_times(s.run.t_end_s, s.run.sample_dt_s).size,
           "accuracy.reference", "a reference run of the same scene and horizon", ref.t.size)
    (rows,) = mujoco_rows([(s, ref)], integrators, modes, dts, budget_s, workers, log)
    return mujoco_frame(rows, ref)
