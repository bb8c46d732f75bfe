"""What accuracy costs: work-precision data for the reference ODE and for MuJoCo.

Each method integrates a scene over a ladder of tolerances (the ODE) or timesteps (MuJoCo);
every point is scored against one reference run of the same scene (the compiled DOP853 on the
vector formulation at :data:`REFERENCE_RTOL`, the tightest tolerance
:class:`~models.options.OdeOptions` accepts) and costed in wall time and right-hand-side
evaluations (ODE) or steps (MuJoCo).

ODE methods (the names are the ``method`` column):

* ``dop853-compiled/vector`` and ``dop853-compiled/paper``: :func:`reference_ode.solve.simulate_ode`
  on either formulation.
* ``scipy-DOP853``, ``scipy-RK45``, ``scipy-LSODA``, ``scipy-Radau``: ``scipy.integrate.solve_ivp``
  calling the same compiled vector right-hand side (:func:`compare.bench._rhs_alloc`) from its
  Python loop, sampled with ``t_eval`` on the same grid. LSODA and Radau get no Jacobian: they
  build it by finite differences (LSODA internally, Radau with ``scipy``'s ``num_jac``); those
  evaluations are counted in ``n_rhs`` because every call goes through one counting wrapper
  (``solve_ivp``'s own ``nfev`` leaves Radau's out).

MuJoCo methods (:func:`mujoco_work_precision`) are ``<integrator>/<mode>``: the integrators
Euler, implicitfast and RK4 in the ``paper`` friction mode (the paper's law applied by the
harness) and the ``native`` one (MuJoCo's own soft friction, calibrated; not the paper's law,
so its error against the reference floors at the friction-model difference), at timesteps
1e-3 ... 1e-5 s. Their rows have the same columns (``engine = "mujoco"``, ``timestep_s`` set,
``rtol``/``atol``/``n_rhs`` NaN, ``n_steps`` the cost, ``status`` ``ok``, ``diverged: ...``,
``skipped: over budget`` or ``failed: ...``).

Every point is one row of :data:`ACCURACY_COLUMNS`.

Budget: the tolerances of a method run from loose to tight; before each point its wall time
is extrapolated from the previous point (the larger of the observed growth and the method's
nominal ``10^(1/order)`` per decade). A point predicted over ``budget_s`` is recorded as
``skipped: over budget`` together with every tighter one, never silently dropped. A scipy run
that still overruns ``HARD_LIMIT_FACTOR * budget_s`` is stopped and recorded as failed. MuJoCo
series run from the largest timestep down with the same rule, the cost extrapolated in steps
(~ 1/dt) on top of the fixed per-sample work (:func:`_predict_steps_wall`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from tippetop.compare.bench import _rhs_alloc
from tippetop.compare.io import write_atomic
from tippetop.compare.metrics import jellett_drift
from tippetop.models.errors import TippetopError, expect
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams
from tippetop.models.scene import Scene, load_scene
from tippetop.reference_ode import dop853 as _d
from tippetop.reference_ode.friction import LAW_TERMS
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.solve import (
    initial_state_vector,
    observables_table,
    sample_times,
    simulate_ode,
)

#: Columns of the work-precision table, shared by both engines. Errors are against the
#: scene's reference: ``theta_max_err`` max |theta - theta_ref| over the common sample times
#: (rad); ``theta_final_err`` (rad), ``n_final_rel_err`` (relative) and ``Omega_final_err``
#: (rad/s) at t_end; ``final_state_err`` the larger of the first two; ``J_drift`` max
#: |J / J0 - 1|. ``n_steps`` is NaN where ``solve_ivp`` does not report it; errors are NaN for
#: points that did not complete (``status`` says why).
ACCURACY_COLUMNS: tuple[str, ...] = (
    "engine", "scene", "method", "formulation", "rtol", "atol", "timestep_s", "t_end_s",
    "wall_s", "wall_per_sim_s", "n_rhs", "n_steps", "theta_max_err", "theta_final_err",
    "n_final_rel_err", "Omega_final_err", "final_state_err", "J_drift", "status",
)

DEFAULT_TOLERANCES: tuple[float, ...] = tuple(10.0**-k for k in range(3, 13))  # 1e-3 ... 1e-12
DEFAULT_METHODS: tuple[str, ...] = (
    "dop853-compiled/vector", "dop853-compiled/paper", "scipy-DOP853", "scipy-RK45",
    "scipy-LSODA", "scipy-Radau",
)
COMPILED_METHODS = {"dop853-compiled/vector": "vector", "dop853-compiled/paper": "paper"}
SCIPY_METHODS = {"scipy-DOP853": "DOP853", "scipy-RK45": "RK45", "scipy-LSODA": "LSODA",
                 "scipy-Radau": "Radau"}

#: atol = ATOL_PER_RTOL * rtol for every point (the package default pair is 1e-9 / 1e-12).
ATOL_PER_RTOL = 1e-3
#: The reference: compiled DOP853, vector formulation, at the tightest rtol OdeOptions accepts.
REFERENCE_RTOL = 1e-14
#: A second reference run at this many times the reference rtol; the two differ by about the
#: looser one's error, an upper estimate of the reference's own error (the "floor").
REFERENCE_CHECK_FACTOR = 10.0
#: Default per-point wall-time budget (s).
DEFAULT_BUDGET_S = 20.0
#: A scipy run is stopped once its wall time exceeds this many budgets.
HARD_LIMIT_FACTOR = 3.0
#: A point whose runs took less than this in total (s) is run again, up to REPEATS times, and
#: its best wall time kept: sub-second timings on a shared machine are noisy.
REPEAT_BELOW_S = 0.5
REPEATS = 3
#: Nominal convergence order of each method: cost grows as rtol^(-1/order).
NOMINAL_ORDER = {"dop853-compiled/vector": 8, "dop853-compiled/paper": 8, "scipy-DOP853": 8,
                 "scipy-RK45": 5, "scipy-LSODA": 5, "scipy-Radau": 4}
#: Pareto thresholds on max |theta error| (rad).
DEFAULT_THRESHOLDS: tuple[float, ...] = (1e-2, 1e-4, 1e-6)
#: Floor for plotting errors on a log axis (a point equal to the reference).
PLOT_ERR_FLOOR = 1e-16

STATUS_OK = "ok"
STATUS_SKIPPED = "skipped: over budget"


class _OverBudget(Exception):
    """Raised from inside a scipy run that exceeded its hard wall-time limit."""


@dataclass(frozen=True)
class Reference:
    """The reference run of a scene.

    Attributes:
        method: The method name (always the compiled DOP853 on the vector formulation).
        rtol: Its relative tolerance.
        atol: Its absolute tolerance.
        t: Sample times (s), the common grid of every point.
        theta: theta at ``t`` (rad).
        theta_final: theta at t_end (rad).
        n_final: Spin at t_end (rad/s).
        Omega_final: Precession rate at t_end (rad/s).
        floor: max |theta| difference from a run one decade looser: the reference's error is
            well below this.
        wall_s: Wall time of the reference run (s).
        n_rhs: Its right-hand-side evaluations.
    """

    method: str
    rtol: float
    atol: float
    t: np.ndarray
    theta: np.ndarray
    theta_final: float
    n_final: float
    Omega_final: float
    floor: float
    wall_s: float
    n_rhs: int


def _scene(scene: Scene | str, t_end_s: float | None) -> Scene:
    s = load_scene(scene) if isinstance(scene, str) else scene
    if t_end_s is not None:
        expect(math.isfinite(t_end_s) and t_end_s > 0, "t_end_s", "a finite number > 0",
               t_end_s)
        s = replace(s, run=replace(s.run, t_end_s=float(t_end_s)))
    return s


def _friction(scene: Scene) -> FrictionParams:
    """The scene's friction, or none when its sliding effect is off (as ``run_ode`` does)."""
    if scene.effects.sliding:
        return scene.friction
    return replace(scene.friction, law="none")


def reference_run(scene: Scene | str, *, t_end_s: float | None = None,
                  rtol: float = REFERENCE_RTOL) -> Reference:
    """Integrate ``scene`` with the most accurate method and tolerance available.

    Args:
        scene: A :class:`~models.scene.Scene` or a catalogue name.
        t_end_s: Cut the scene's run to this time (s); None keeps it.
        rtol: The reference tolerance (atol = ``ATOL_PER_RTOL * rtol``).

    Returns:
        The reference samples and its error floor (distance from a run at
        ``REFERENCE_CHECK_FACTOR * rtol``).

    Raises:
        TippetopError: if the reference run does not complete.
    """
    s = _scene(scene, t_end_s)
    T = s.run.t_end_s
    runs = []
    for r in (rtol, REFERENCE_CHECK_FACTOR * rtol):
        opts = OdeOptions(formulation="vector", rtol=r, atol=ATOL_PER_RTOL * r)
        res = simulate_ode(s.top, _friction(s), s.init, t_end_s=T,
                           sample_dt_s=s.run.sample_dt_s, options=opts)
        if res.status != "ok":
            raise TippetopError(f"accuracy: expected the reference run of {s.name!r} (compiled "
                                f"DOP853, vector, rtol {r:g}) to complete, got {res.status}: "
                                f"{res.message}")
        runs.append(res)
    ref, check = runs
    last = ref.table.iloc[-1]
    return Reference(
        method="dop853-compiled/vector", rtol=rtol, atol=ATOL_PER_RTOL * rtol,
        t=ref.table["t"].to_numpy(), theta=ref.table["theta"].to_numpy(),
        theta_final=float(last["theta"]), n_final=float(last["n"]),
        Omega_final=float(last["Omega"]),
        floor=float(np.max(np.abs(ref.table["theta"].to_numpy()
                                  - check.table["theta"].to_numpy()))),
        wall_s=ref.wall_s, n_rhs=ref.n_rhs)


def _score(table: pd.DataFrame, ref: Reference) -> dict[str, float]:
    """Errors of a complete run's table (sampled on ``ref.t``) against the reference."""
    theta = table["theta"].to_numpy()
    last = table.iloc[-1]
    th_f = abs(float(last["theta"]) - ref.theta_final)
    n_f = abs(float(last["n"]) - ref.n_final) / max(abs(ref.n_final), 1e-300)
    om_f = abs(float(last["Omega"]) - ref.Omega_final)
    return {
        "theta_max_err": float(np.max(np.abs(theta - ref.theta))),
        "theta_final_err": th_f,
        "n_final_rel_err": n_f,
        "Omega_final_err": om_f,
        "final_state_err": max(th_f, n_f),
        "J_drift": jellett_drift(table),
    }


def _nan_scores() -> dict[str, float]:
    keys = ("theta_max_err", "theta_final_err", "n_final_rel_err", "Omega_final_err",
            "final_state_err", "J_drift")
    return dict.fromkeys(keys, math.nan)


def _run_compiled(scene: Scene, formulation: str, rtol: float, atol: float,
                  ref: Reference) -> dict[str, Any]:
    opts = OdeOptions(formulation=formulation, rtol=rtol, atol=atol)
    try:
        res = simulate_ode(scene.top, _friction(scene), scene.init, t_end_s=scene.run.t_end_s,
                           sample_dt_s=scene.run.sample_dt_s, options=opts)
    except TippetopError as exc:  # e.g. the paper form refusing theta0 = 0
        return {"wall_s": math.nan, "n_rhs": 0, "n_steps": 0, **_nan_scores(),
                "status": f"failed: {exc}"}
    row: dict[str, Any] = {"wall_s": res.wall_s, "n_rhs": res.n_rhs, "n_steps": res.n_steps}
    if res.status != "ok":
        return {**row, **_nan_scores(), "status": f"failed: {res.status}: {res.message}"}
    return {**row, **_score(res.table, ref), "status": STATUS_OK}


def _run_scipy(scene: Scene, method: str, rtol: float, atol: float, ref: Reference,
               hard_limit_s: float) -> dict[str, Any]:
    friction = _friction(scene)
    ck, visc = LAW_TERMS[friction.law]
    visc = int(visc)
    p = pack_params(scene.top, friction)
    y0 = initial_state_vector(scene.top, scene.init)
    _rhs_alloc(_d.FORM_VECTOR, ck, visc, y0, p)  # compiled before the clock starts
    count = [0]
    t_start = [0.0]

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        if count[0] % 1000 == 0 and time.perf_counter() - t_start[0] > hard_limit_s:
            raise _OverBudget
        return _rhs_alloc(_d.FORM_VECTOR, ck, visc, y, p)

    T = scene.run.t_end_s
    t_start[0] = time.perf_counter()
    try:
        # Radau's num_jac grows its difference step without bound for the columns the
        # right-hand side does not depend on (x, y) and overflows to inf there; harmless (the
        # step is then never used), but numpy would warn.
        with np.errstate(over="ignore", invalid="ignore"):
            sol = solve_ivp(fun, (0.0, T), y0, method=SCIPY_METHODS[method], t_eval=ref.t,
                            rtol=rtol, atol=atol)
    except _OverBudget:
        wall = time.perf_counter() - t_start[0]
        return {"wall_s": wall, "n_rhs": count[0], "n_steps": math.nan, **_nan_scores(),
                "status": f"failed: stopped after {wall:.3g} s, over the hard limit "
                          f"{hard_limit_s:.3g} s"}
    wall = time.perf_counter() - t_start[0]
    row: dict[str, Any] = {"wall_s": wall, "n_rhs": count[0], "n_steps": math.nan}
    if sol.status != 0 or sol.y.shape[1] != ref.t.size:
        return {**row, **_nan_scores(), "status": f"failed: {sol.message}"}
    Y = np.ascontiguousarray(sol.y.T)
    if not np.isfinite(Y).all():
        return {**row, **_nan_scores(), "status": "failed: non-finite state"}
    table = observables_table("vector", friction, p, ref.t, Y)
    return {**row, **_score(table, ref), "status": STATUS_OK}


def _timed_point(s: Scene, method: str, rtol: float, atol: float, ref: Reference,
                 budget_s: float) -> dict[str, Any]:
    """Run one point; a fast one is repeated and its best wall time kept (timing noise)."""
    out: dict[str, Any] | None = None
    spent = 0.0
    for _ in range(REPEATS):
        if method in COMPILED_METHODS:
            o = _run_compiled(s, COMPILED_METHODS[method], rtol, atol, ref)
        else:
            o = _run_scipy(s, method, rtol, atol, ref, HARD_LIMIT_FACTOR * budget_s)
        if out is None:
            out = o
        elif math.isfinite(o["wall_s"]):
            out["wall_s"] = min(out["wall_s"], o["wall_s"])
        if out["status"] != STATUS_OK or not math.isfinite(o["wall_s"]):
            break
        spent += o["wall_s"]
        if spent > REPEAT_BELOW_S:
            break
    assert out is not None
    return out


def _predict_wall(walls: list[tuple[float, float]], rtol: float, method: str) -> float | None:
    """Wall time predicted at ``rtol`` from the points run so far [(rtol, wall_s)]."""
    if not walls:
        return None
    r_last, w_last = walls[-1]
    decades = math.log10(r_last / rtol)
    growth = 10.0 ** (1.0 / NOMINAL_ORDER[method])
    if len(walls) >= 2:
        r_prev, w_prev = walls[-2]
        d_prev = math.log10(r_prev / r_last)
        if w_prev > 0 and d_prev > 0:
            growth = max(growth, (w_last / w_prev) ** (1.0 / d_prev))
    return w_last * growth**decades


def ode_work_precision(
    scene: Scene | str,
    *,
    tolerances: Sequence[float] = DEFAULT_TOLERANCES,
    methods: Sequence[str] = DEFAULT_METHODS,
    budget_s: float = DEFAULT_BUDGET_S,
    t_end_s: float | None = None,
    reference: Reference | None = None,
    log: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Work-precision points of the reference ODE on one scene.

    Args:
        scene: A :class:`~models.scene.Scene` or a catalogue name.
        tolerances: rtol values (atol = ``ATOL_PER_RTOL * rtol``), run from loose to tight.
        methods: Names from :data:`DEFAULT_METHODS`.
        budget_s: Per-point wall-time budget (s); see the module docstring.
        t_end_s: Cut the scene's run to this time (s); None keeps the scene's.
        reference: A precomputed :func:`reference_run` of the same scene and horizon.
        log: Called with one line per finished point.

    Returns:
        One row per (method, tolerance) with :data:`ACCURACY_COLUMNS`; ``df.attrs["reference"]``
        describes the reference (method, rtol, atol, floor, wall_s, n_rhs).
    """
    s = _scene(scene, t_end_s)
    for m in methods:
        expect(m in NOMINAL_ORDER, "accuracy.methods", "|".join(DEFAULT_METHODS), m)
    tols = sorted({float(t) for t in tolerances}, reverse=True)
    for t in tols:
        expect(math.isfinite(t) and 1e-14 <= t < 1, "accuracy.tolerances",
               "numbers in [1e-14, 1)", t)
    expect(math.isfinite(budget_s) and budget_s > 0, "accuracy.budget_s", "a finite number > 0",
           budget_s)
    ref = reference if reference is not None else reference_run(s)
    expect(ref.t.size == sample_times(s.run.t_end_s, s.run.sample_dt_s).size,
           "accuracy.reference", "a reference run of the same scene and horizon", ref.t.size)
    T = s.run.t_end_s
    rows: list[dict[str, Any]] = []
    for method in methods:
        walls: list[tuple[float, float]] = []
        over = False
        for rtol in tols:
            atol = ATOL_PER_RTOL * rtol
            base = {"engine": "ode", "scene": s.name, "method": method,
                    "formulation": COMPILED_METHODS.get(method, "vector"), "rtol": rtol,
                    "atol": atol, "timestep_s": math.nan, "t_end_s": T}
            pred = _predict_wall(walls, rtol, method)
            if over or (pred is not None and pred > budget_s):
                over = True
                rows.append({**base, "wall_s": math.nan, "n_rhs": 0, "n_steps": 0,
                             **_nan_scores(), "status": STATUS_SKIPPED})
                if log is not None:
                    log(f"{s.name} {method} rtol {rtol:g}: {STATUS_SKIPPED} ({budget_s:g} s)")
                continue
            out = _timed_point(s, method, rtol, atol, ref, budget_s)
            if math.isfinite(out["wall_s"]):
                walls.append((rtol, out["wall_s"]))
            row = {**base, **out}
            row["wall_per_sim_s"] = row["wall_s"] / T
            rows.append(row)
            if log is not None:
                log(f"{s.name} {method} rtol {rtol:g}: {row['status']}, "
                    f"{row['wall_s']:.3g} s, n_rhs {row['n_rhs']}, "
                    f"theta err {row['theta_max_err']:.2e}")
    df = pd.DataFrame(rows).reindex(columns=list(ACCURACY_COLUMNS))
    df["wall_per_sim_s"] = df["wall_s"] / df["t_end_s"]
    df.attrs["reference"] = {"method": ref.method, "rtol": ref.rtol, "atol": ref.atol,
                             "floor": ref.floor, "wall_s": ref.wall_s, "n_rhs": ref.n_rhs}
    return df


# ------------------------------------------------------------------ MuJoCo half
#: MuJoCo integrators, timesteps (s) and friction modes of the default study.
DEFAULT_INTEGRATORS: tuple[str, ...] = ("Euler", "implicitfast", "RK4")
DEFAULT_TIMESTEPS: tuple[float, ...] = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5)
DEFAULT_MODES: tuple[str, ...] = ("paper", "native")
#: Default per-point wall-time budget of a MuJoCo point (s). See :func:`mujoco_work_precision`.
DEFAULT_MUJOCO_BUDGET_S = 30.0
#: Dynamics evaluations per step, for ordering the work (largest series first).
_EVALS_PER_STEP = {"Euler": 1, "implicit": 1, "implicitfast": 1, "RK4": 4}
STATUS_DIVERGED = "diverged"
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


def _mujoco_scene(s: Scene, integrator: str, mode: str, dt: float, sample_dt_s: float) -> Scene:
    """``s`` with the MuJoCo integrator, timestep, friction mode and row spacing set.

    They are written into ``raw["mujoco"]`` too, so native mode takes them as the scene's own
    settings rather than the calibrated defaults (which include a 2e-4 s RK4 timestep).
    """
    raw = {k: dict(v) for k, v in s.raw.items()}
    raw.setdefault("mujoco", {}).update(friction=mode, integrator=integrator, timestep_s=dt)
    raw.setdefault("run", {}).update(t_end_s=s.run.t_end_s, sample_dt_s=sample_dt_s)
    return replace(s, mujoco=replace(s.mujoco, friction=mode, integrator=integrator,
                                     timestep_s=dt),
                   run=replace(s.run, sample_dt_s=sample_dt_s), raw=raw)


def _run_mujoco_point(s: Scene, ref: Reference, hard_limit_s: float) -> dict[str, Any]:
    """One MuJoCo run scored against the reference; stopped past ``hard_limit_s`` of stepping."""
    from tippetop.mujoco_runner.engine import run_mujoco

    start: list[float] = []
    t_done = s.run.t_end_s - 0.5 * float(ref.t[1] - ref.t[0])

    def watchdog(t: float) -> None:
        # The runner calls this at t = 0, then every 0.2 s of wall time, and once more after
        # its loop (with the last sample's time): a run that got to the end is kept.
        now = time.perf_counter()
        if not start:
            start.append(now)
        elif now - start[0] > hard_limit_s and t < t_done:
            raise _OverBudget

    try:
        run = run_mujoco(s, watchdog)
    except _OverBudget:
        wall = time.perf_counter() - start[0]
        return {"wall_s": wall, "n_steps": math.nan, **_nan_scores(),
                "status": f"failed: stopped after {wall:.3g} s, over the hard limit "
                          f"{hard_limit_s:.3g} s"}
    except TippetopError as exc:  # a setting the runner refuses (nothing was simulated)
        return {"wall_s": math.nan, "n_steps": 0, **_nan_scores(), "status": f"failed: {exc}"}
    row: dict[str, Any] = {"wall_s": float(run.summary["wall_s"]),
                           "n_steps": int(run.summary["n_steps"])}
    if run.status != "ok":
        msg = run.message.removeprefix("diverged ")
        return {**row, **_nan_scores(), "status": f"{STATUS_DIVERGED}: {msg}"}
    if len(run.table) != ref.t.size:
        return {**row, **_nan_scores(),
                "status": f"failed: {len(run.table)} rows against the reference's {ref.t.size} "
                          "(the sample grid is not a whole number of timesteps)"}
    return {**row, **_score(run.table, ref), "status": STATUS_OK}


def _predict_steps_wall(runs: list[tuple[int, float, bool]], n_steps: int) -> float | None:
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
        base = {"engine": "mujoco", "scene": s.name, "method": method, "formulation": mode,
                "rtol": math.nan, "atol": math.nan, "timestep_s": dt, "t_end_s": T,
                "n_rhs": math.nan}
        pred = _predict_steps_wall(runs, n_needed)
        if over or (pred is not None and pred > budget_s):
            over = True
            rows.append({**base, "wall_s": math.nan, "n_steps": 0, **_nan_scores(),
                         "status": STATUS_SKIPPED, "_predicted_wall_s": pred})
            continue
        out = _run_mujoco_point(_mujoco_scene(s, integrator, mode, dt, sample_dt), ref,
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


def _mujoco_rows(jobs: Sequence[tuple[Scene, Reference]], integrators: Sequence[str],
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


def _mujoco_frame(rows: list[dict[str, Any]], ref: Reference) -> pd.DataFrame:
    df = pd.DataFrame(rows).reindex(columns=list(ACCURACY_COLUMNS))
    df["wall_per_sim_s"] = df["wall_s"] / df["t_end_s"]
    df.attrs["reference"] = {"method": ref.method, "rtol": ref.rtol, "atol": ref.atol,
                             "floor": ref.floor, "wall_s": ref.wall_s, "n_rhs": ref.n_rhs}
    return df


def _check_mujoco_scene(s: Scene) -> None:
    expect(s.top_mjcf is None, "top.mjcf", "a scene whose top is given by its parameters for "
           "the MuJoCo work-precision study (an MJCF top sets its own integrator and timestep)",
           str(s.top_mjcf))


def _check_mujoco_args(integrators: Sequence[str], modes: Sequence[str],
                       timesteps: Sequence[float], budget_s: float) -> list[float]:
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
    one proportional to the steps, ~ 1/dt: :func:`_predict_steps_wall`); a point predicted
    over ``budget_s`` is recorded as ``skipped: over budget`` with every smaller timestep of
    the series. A run that still exceeds ``HARD_LIMIT_FACTOR * budget_s`` is stopped and
    recorded as ``failed: stopped ...``. A run that diverges (the runner's checks: NaN,
    MuJoCo's instability warnings, an energy rise, the ball sinking into the table, lost
    contact) is recorded as ``diverged: <its message>`` and the series goes on to the smaller
    timesteps. Nothing is dropped.

    The runs use the scene's MuJoCo settings (:func:`mujoco_runner.engine.mujoco_settings`)
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
    s = _scene(scene, t_end_s)
    _check_mujoco_scene(s)
    dts = _check_mujoco_args(integrators, modes, timesteps, budget_s)
    ref = reference if reference is not None else reference_run(s)
    expect(ref.t.size == sample_times(s.run.t_end_s, s.run.sample_dt_s).size,
           "accuracy.reference", "a reference run of the same scene and horizon", ref.t.size)
    (rows,) = _mujoco_rows([(s, ref)], integrators, modes, dts, budget_s, workers, log)
    return _mujoco_frame(rows, ref)


# ------------------------------------------------------------------ Pareto frontier
def pareto_front(df: pd.DataFrame) -> pd.DataFrame:
    """The completed points not beaten by any other in both wall time and theta error.

    Args:
        df: Rows of one scene and engine (:data:`ACCURACY_COLUMNS`).

    Returns:
        The frontier rows, sorted by wall time.
    """
    ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
    ok = ok.sort_values(["wall_s", "theta_max_err"])
    keep = []
    best = math.inf
    for idx, row in ok.iterrows():
        if row["theta_max_err"] < best:
            keep.append(idx)
            best = row["theta_max_err"]
    return ok.loc[keep]


def _setting(row: pd.Series) -> str:
    if row["engine"] == "ode":
        return f"rtol {row['rtol']:g}"
    return f"dt = {row['timestep_s']:g} s in {row['formulation']} mode"


def _num_or_none(v: Any) -> float | None:
    return None if v is None or math.isnan(float(v)) else float(v)


def _mujoco_use(row: pd.Series) -> str:
    """``RK4 at dt = 0.0001 s in paper mode`` for a MuJoCo row."""
    integrator = str(row["method"]).split("/")[0]
    return f"{integrator} at {_setting(row)}"


def pareto_table(df: pd.DataFrame,
                 thresholds: Iterable[float] = DEFAULT_THRESHOLDS) -> list[dict[str, Any]]:
    """For each scene, engine and threshold: the cheapest point whose theta error meets it.

    Args:
        df: Work-precision rows (:data:`ACCURACY_COLUMNS`), any number of scenes and engines.
        thresholds: Bounds on max |theta error| (rad).

    Returns:
        One dictionary per (engine, scene, threshold): ``engine``, ``scene``, ``threshold``,
        ``method``, ``setting``, ``rtol``, ``timestep_s``, ``wall_s``, ``wall_per_sim_s``,
        ``n_rhs_per_sim_s``, ``n_steps_per_sim_s``, ``theta_max_err`` (None where no point
        qualifies), ``best_theta_max_err`` and ``best_method``/``best_setting`` (the smallest
        error of any completed point, None if none completed) and ``text``. ODE: "to get theta
        right to X rad, use METHOD at SETTING; it costs Y s per simulated second", or "...
        none reached". MuJoCo: "to get theta right to X rad, use INTEGRATOR at dt = D s in
        MODE mode; it costs Y s per simulated second", or "... not reached (best error E rad,
        INTEGRATOR at dt = D s in MODE mode)".
    """
    out: list[dict[str, Any]] = []
    for (engine, scene), g in df.groupby(["engine", "scene"], sort=False):
        ok = g[(g["status"] == STATUS_OK) & g["theta_max_err"].notna()]
        best = ok.loc[ok["theta_max_err"].idxmin()] if not ok.empty else None
        for x in thresholds:
            q = ok[ok["theta_max_err"] <= x]
            entry: dict[str, Any] = {"engine": engine, "scene": scene, "threshold": float(x)}
            if q.empty:
                if engine == "ode":
                    text = f"to get theta right to {x:g} rad: none reached"
                elif best is None:
                    text = f"to get theta right to {x:g} rad: not reached (no point completed)"
                else:
                    text = (f"to get theta right to {x:g} rad: not reached (best error "
                            f"{best['theta_max_err']:.1e} rad, {_mujoco_use(best)})")
                entry.update(method=None, setting=None, rtol=None, timestep_s=None,
                             wall_s=None, wall_per_sim_s=None, n_rhs_per_sim_s=None,
                             n_steps_per_sim_s=None, theta_max_err=None, text=text)
            else:
                row = q.loc[q["wall_s"].idxmin()]
                setting = _setting(row)
                use = (f"{row['method']} at {setting}" if engine == "ode"
                       else _mujoco_use(row))
                entry.update(
                    method=row["method"], setting=setting,
                    rtol=_num_or_none(row["rtol"]), timestep_s=_num_or_none(row["timestep_s"]),
                    wall_s=float(row["wall_s"]), wall_per_sim_s=float(row["wall_per_sim_s"]),
                    n_rhs_per_sim_s=_num_or_none(row["n_rhs"] / row["t_end_s"]),
                    n_steps_per_sim_s=_num_or_none(row["n_steps"] / row["t_end_s"]),
                    theta_max_err=float(row["theta_max_err"]),
                    text=(f"to get theta right to {x:g} rad, use {use}; "
                          f"it costs {row['wall_per_sim_s']:.3g} s per simulated second "
                          f"(theta error {row['theta_max_err']:.1e} rad)"))
            entry.update(
                best_theta_max_err=None if best is None else float(best["theta_max_err"]),
                best_method=None if best is None else best["method"],
                best_setting=None if best is None else _setting(best))
            out.append(entry)
    return out


# ------------------------------------------------------------------ figure and report
def work_precision_figure(df: pd.DataFrame, path: str | Path, *, title: str | None = None) -> None:
    """Plot max |theta error| against wall time on log axes, one line per method.

    Written atomically as PNG. ``df`` should hold one scene of one engine; the frontier is
    drawn as a grey step line. A second panel plots the same errors against the
    deterministic cost (``n_rhs``; ``n_steps`` for MuJoCo), which does not depend on the
    machine's load.

    Args:
        df: Work-precision rows.
        path: The PNG file.
        title: The figure title; by default the scene, the engine and the reference.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(12.0, 5.0), sharey=True)
    try:
        ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
        cost = "n_steps" if (df["engine"] == "mujoco").all() else "n_rhs"
        for method, g in ok.groupby("method", sort=False):
            g = g.sort_values("wall_s")
            err = np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR)
            line = ax.loglog(g["wall_s"], err, "o-", ms=4, label=str(method))[0]
            g = g.sort_values(cost)
            ax_n.loglog(g[cost], np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR), "o-", ms=4,
                        color=line.get_color())
        front = pareto_front(df)
        if not front.empty:
            ax.step(front["wall_s"], np.maximum(front["theta_max_err"], PLOT_ERR_FLOOR),
                    where="post", color="0.6", lw=3, alpha=0.4, zorder=0, label="frontier")
        ref = df.attrs.get("reference")
        if ref and ref.get("floor"):
            for a in (ax, ax_n):
                a.axhline(ref["floor"], color="0.3", ls=":", lw=1,
                          label=f"reference floor ({ref['floor']:.0e} rad)")
        ax.set_xlabel("wall time (s)")
        ax_n.set_xlabel("right-hand-side evaluations" if cost == "n_rhs" else "steps")
        ax.set_ylabel("max |theta - theta_ref| (rad)")
        if title is None:
            scenes = ", ".join(sorted(df["scene"].unique()))
            engines = ", ".join(sorted(df["engine"].unique()))
            title = f"{scenes} [{engines}]: work-precision"
            if ref:
                title += f"; reference: {ref['method']} at rtol {ref['rtol']:g}"
        fig.suptitle(title, fontsize=10)
        ax.set_title("error against wall time (this machine)", fontsize=9)
        ax_n.set_title("error against evaluations (deterministic)", fontsize=9)
        for a in (ax, ax_n):
            a.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def mujoco_work_precision_figure(df: pd.DataFrame, path: str | Path, *,
                                 title: str | None = None) -> None:
    """Plot MuJoCo's max |theta error| against wall time and against steps, on log axes.

    One colour per integrator, solid for paper mode and dashed for native mode; the frontier
    as a grey step line. The steps panel carries the timestep on its top axis and marks the
    diverged (x) and skipped (|) points along its top edge, so that every point of the table
    shows. The notes under the panels (:data:`MUJOCO_NOTES`) say what limits each mode's
    error. Written atomically as PNG; ``df`` should hold one scene of the MuJoCo engine.

    Args:
        df: MuJoCo work-precision rows of one scene.
        path: The PNG file.
        title: The figure title; by default the scene, the engine and the reference.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(13.0, 6.2), sharey=True)
    try:
        colours = {i: f"C{k}" for k, i in enumerate(
            dict.fromkeys([*DEFAULT_INTEGRATORS, *(m.split("/")[0] for m in df["method"])]))}
        styles = {"paper": ("-", "o"), "native": ("--", "s")}
        ok = df[(df["status"] == STATUS_OK) & df["theta_max_err"].notna()]
        for method, g in ok.groupby("method", sort=False):
            integrator, mode = str(method).split("/")
            ls, marker = styles.get(mode, (":", "^"))
            kw = {"color": colours[integrator], "ls": ls, "marker": marker, "ms": 4}
            g = g.sort_values("n_steps")
            err = np.maximum(g["theta_max_err"], PLOT_ERR_FLOOR)
            ax.loglog(g["wall_s"], err, label=str(method), **kw)
            ax_n.loglog(g["n_steps"], err, **kw)
        front = pareto_front(df)
        if not front.empty:
            ax.step(front["wall_s"], np.maximum(front["theta_max_err"], PLOT_ERR_FLOOR),
                    where="post", color="0.6", lw=3, alpha=0.4, zorder=0, label="frontier")
        if not ok.empty:
            lo = float(np.maximum(ok["theta_max_err"], PLOT_ERR_FLOOR).min())
            hi = float(ok["theta_max_err"].max())
            ax.set_ylim(lo / 3, hi * 8)
        for x in DEFAULT_THRESHOLDS:
            lo_y, hi_y = ax.get_ylim()
            if lo_y < x < hi_y:
                for a in (ax, ax_n):
                    a.axhline(x, color="0.75", ls=":", lw=1, zorder=0)
        # every point that has no error: diverged (x) and skipped (|) along the top edge
        T = float(df["t_end_s"].iloc[0]) if len(df) else 1.0
        # one row per method along the top edge, in the legend's order
        rows_y = {m: ax.get_ylim()[1] / 1.5 / 1.4**k
                  for k, m in enumerate(dict.fromkeys(df["method"]))}
        for kind, marker in ((STATUS_DIVERGED, "x"), ("skipped", "|"), ("failed", "+")):
            bad = df[df["status"].str.startswith(kind)]
            for method, g in bad.groupby("method", sort=False):
                integrator, mode = str(method).split("/")
                ax_n.plot(T / g["timestep_s"], np.full(len(g), rows_y[method]), ls="none",
                          marker=marker, ms=7, mew=1.5, color=colours[integrator],
                          alpha=1.0 if mode == "paper" else 0.55)
        for kind, marker in ((STATUS_DIVERGED, "x"), ("skipped: over budget", "|"),
                             ("failed", "+")):
            n = int(df["status"].str.startswith(kind.split(":")[0]).sum())
            if n:
                ax_n.plot([], [], ls="none", marker=marker, color="0.3", label=f"{kind} ({n})")
        if T > 0:
            top = ax_n.secondary_xaxis("top", functions=(lambda n: T / np.maximum(n, 1e-300),
                                                         lambda d: T / np.maximum(d, 1e-300)))
            top.set_xlabel("timestep dt (s)", fontsize=8)
        from matplotlib.ticker import FuncFormatter

        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(FuncFormatter(
            lambda v, _: f"{v:g}" if f"{v:.1e}"[0] in "25" else ""))
        ax.set_xlabel("wall time (s)")
        ax_n.set_xlabel("steps")
        ax.set_ylabel("max |theta - theta_ref| (rad)")
        ref = df.attrs.get("reference")
        if title is None:
            scenes = ", ".join(sorted(df["scene"].unique()))
            title = (f"{scenes} [mujoco, {T:g} s simulated]: work-precision against the reference "
                     "ODE")
            if ref:
                title += f" ({ref['method']} at rtol {ref['rtol']:g})"
            title += ("\nnative mode is MuJoCo's soft friction, not the paper's law: its error "
                      "floors at the friction-model difference")
        fig.suptitle(title, fontsize=10)
        ax.set_title("error against wall time (this machine)", fontsize=9)
        ax_n.set_title("error against steps (deterministic)", fontsize=9)
        for a in (ax, ax_n):
            a.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        if ax_n.get_legend_handles_labels()[0]:
            ax_n.legend(fontsize=7, loc="lower left")
        notes = "\n".join(f"- {n}" for n in MUJOCO_NOTES)
        fig.text(0.01, 0.01, notes, fontsize=7, va="bottom", ha="left", wrap=True)
        fig.tight_layout(rect=(0, 0.1, 1, 1))
        write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def pareto_markdown(entries: list[dict[str, Any]], references: dict[str, dict]) -> str:
    """The Pareto table as Markdown, one section per scene."""
    lines = ["# Reference ODE: accuracy against cost", ""]
    for scene in dict.fromkeys(e["scene"] for e in entries):
        ref = references.get(scene, {})
        lines += [f"## {scene}", ""]
        if ref:
            lines += [f"Errors are max |theta - theta_ref| over the run, the reference being "
                      f"{ref['method']} at rtol {ref['rtol']:g}, atol {ref['atol']:g} (its "
                      f"distance from a run at 10x the tolerance: {ref['floor']:.1e} rad).", ""]
        lines += ["| theta right to (rad) | method | setting | s per simulated s "
                  "| rhs evaluations per simulated s | theta error reached (rad) |",
                  "|---|---|---|---|---|---|"]
        for e in entries:
            if e["scene"] != scene:
                continue
            if e["method"] is None:
                lines.append(f"| {e['threshold']:g} | none reached | | | | |")
            else:
                lines.append(f"| {e['threshold']:g} | {e['method']} | {e['setting']} | "
                             f"{e['wall_per_sim_s']:.3g} | {e['n_rhs_per_sim_s']:.3g} | "
                             f"{e['theta_max_err']:.1e} |")
        lines += [""] + [f"- {e['text']}" for e in entries if e["scene"] == scene] + [""]
    return "\n".join(lines)


def series_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per method of one scene and engine: its best point and what did not complete.

    Args:
        df: Work-precision rows of one scene (:data:`ACCURACY_COLUMNS`).

    Returns:
        One row per method: ``method``, ``best_theta_max_err``, ``best_setting``,
        ``best_timestep_s``,
        ``best_wall_per_sim_s``, ``n_ok``, ``n_diverged`` (with ``diverged_at``, the settings,
        and ``diverged_dt``, the timesteps),
        ``n_skipped``, ``n_failed``, and ``wall_per_step_s`` and ``wall_fixed_s``, a
        least-squares fit wall = fixed + per_step * n_steps over the completed points (None
        with fewer than two).
    """
    out = []
    for method, g in df.groupby("method", sort=False):
        ok = g[(g["status"] == STATUS_OK) & g["theta_max_err"].notna()]
        div = g[g["status"].str.startswith(STATUS_DIVERGED)]
        best = ok.loc[ok["theta_max_err"].idxmin()] if not ok.empty else None
        n_skip = int((g["status"] == STATUS_SKIPPED).sum())
        per_step = fixed = None
        fit = ok[(ok["n_steps"] > 0) & ok["wall_s"].notna()]
        if fit["n_steps"].nunique() >= 2:
            b, a = np.polyfit(fit["n_steps"].astype(float), fit["wall_s"], 1)
            per_step, fixed = float(b), float(a)
        out.append({
            "method": method,
            "best_theta_max_err": None if best is None else float(best["theta_max_err"]),
            "best_setting": None if best is None else _setting(best),
            "best_timestep_s": None if best is None else _num_or_none(best["timestep_s"]),
            "best_wall_per_sim_s": None if best is None else float(best["wall_per_sim_s"]),
            "n_ok": len(ok), "n_diverged": len(div),
            "diverged_at": [_setting(r) for _, r in div.iterrows()],
            "diverged_dt": [float(t) for t in div["timestep_s"]],
            "n_skipped": n_skip, "n_failed": len(g) - len(ok) - len(div) - n_skip,
            "wall_per_step_s": per_step, "wall_fixed_s": fixed})
    return pd.DataFrame(out)


def mujoco_pareto_markdown(entries: list[dict[str, Any]], references: dict[str, dict],
                           df: pd.DataFrame | None = None) -> str:
    """The MuJoCo Pareto table as Markdown, one section per scene.

    Args:
        entries: :func:`pareto_table` entries of the MuJoCo engine.
        references: The reference of each scene (``df.attrs["reference"]``).
        df: The MuJoCo rows, for the per-series summary (optional).

    Returns:
        The Markdown text.
    """
    lines = ["# MuJoCo: accuracy against cost", "",
             *[f"- {n}" for n in MUJOCO_NOTES], ""]
    for scene in dict.fromkeys(e["scene"] for e in entries):
        ref = references.get(scene, {})
        g = df[df["scene"] == scene] if df is not None else None
        T = f" ({g['t_end_s'].iloc[0]:g} s simulated)" if g is not None and len(g) else ""
        lines += [f"## {scene}{T}", ""]
        if ref:
            lines += [f"Errors are max |theta - theta_ref| over the run, the reference being the "
                      f"ODE's {ref['method']} at rtol {ref['rtol']:g} (its own error is below "
                      f"{ref['floor']:.1e} rad).", ""]
        lines += ["| theta right to (rad) | integrator | friction mode | dt (s) "
                  "| s per simulated s | steps per simulated s | theta error reached (rad) |",
                  "|---|---|---|---|---|---|---|"]
        for e in entries:
            if e["scene"] != scene:
                continue
            if e["method"] is None:
                best = ("no point completed" if e["best_theta_max_err"] is None else
                        f"best {e['best_theta_max_err']:.1e} "
                        f"({str(e['best_method']).split('/')[0]} at {e['best_setting']})")
                lines.append(f"| {e['threshold']:g} | not reached | | | | | {best} |")
            else:
                integrator, mode = str(e["method"]).split("/")
                lines.append(f"| {e['threshold']:g} | {integrator} | {mode} | "
                             f"{e['timestep_s']:g} | {e['wall_per_sim_s']:.3g} | "
                             f"{e['n_steps_per_sim_s']:,.0f} | {e['theta_max_err']:.1e} |")
        lines += [""] + [f"- {e['text']}" for e in entries if e["scene"] == scene] + [""]
        if g is not None and len(g):
            lines += ["Best point of each integrator and mode:", "",
                      "| integrator/mode | best theta error (rad) | at dt (s) | s per simulated s "
                      "| ok | diverged | skipped (over budget) | failed | us per step (fit) "
                      "| fixed s per run (fit) |",
                      "|---|---|---|---|---|---|---|---|---|---|"]
            for _, r in series_summary(g).iterrows():
                best = ("-" if r["best_theta_max_err"] is None
                        else f"{r['best_theta_max_err']:.1e}")
                cost = ("-" if r["best_wall_per_sim_s"] is None
                        else f"{r['best_wall_per_sim_s']:.3g}")
                div = (f"{r['n_diverged']} (dt = "
                       f"{', '.join(f'{t:g}' for t in r['diverged_dt'])} s)"
                       if r["n_diverged"] else "0")
                dt = "-" if r["best_timestep_s"] is None else f"{r['best_timestep_s']:g}"
                us = ("-" if r["wall_per_step_s"] is None
                      else f"{1e6 * r['wall_per_step_s']:.3g}")
                fixed = "-" if r["wall_fixed_s"] is None else f"{r['wall_fixed_s']:.3g}"
                lines.append(f"| {r['method']} | {best} | {dt} | {cost} "
                             f"| {r['n_ok']} | {div} | {r['n_skipped']} | {r['n_failed']} "
                             f"| {us} | {fixed} |")
            lines.append("")
    return "\n".join(lines)


ENGINES: tuple[str, ...] = ("ode", "mujoco")


def run_accuracy(
    scene_names: Sequence[str] = ("fig3", "fig11_n060"),
    out_dir: str | Path = ".",
    *,
    tolerances: Sequence[float] = DEFAULT_TOLERANCES,
    methods: Sequence[str] = DEFAULT_METHODS,
    budget_s: float = DEFAULT_BUDGET_S,
    thresholds: Sequence[float] = DEFAULT_THRESHOLDS,
    t_end_s: float | None = None,
    force: bool = False,
    log: Callable[[str], None] | None = None,
    engines: Sequence[str] = ("ode",),
    integrators: Sequence[str] = DEFAULT_INTEGRATORS,
    timesteps: Sequence[float] = DEFAULT_TIMESTEPS,
    modes: Sequence[str] = DEFAULT_MODES,
    mujoco_budget_s: float = DEFAULT_MUJOCO_BUDGET_S,
    workers: int | None = None,
) -> dict[str, Any]:
    """Work-precision study; writes the CSV, the figures and the table of each engine.

    Files (each written atomically into ``out_dir``), per engine in ``engines``: ODE
    ``accuracy_ode.csv`` (every point), ``accuracy_ode_<scene>.png`` (one per scene) and
    ``pareto_ode.md``; MuJoCo ``accuracy_mujoco.csv``, ``accuracy_mujoco_<scene>.png`` and
    ``pareto_mujoco.md``. Both engines are scored against one :func:`reference_run` per scene.
    The ODE points run in this process, one at a time (their timings are sub-second); then the
    MuJoCo series run on ``workers`` processes.

    Args:
        scene_names: Scene files or catalogue names.
        out_dir: An existing folder (created if missing).
        tolerances: ODE rtol ladder.
        methods: ODE methods to run.
        budget_s: Per-point wall-time budget of the ODE (s).
        thresholds: Pareto thresholds on max |theta error| (rad).
        t_end_s: Cut every scene's run to this time (s); None keeps each scene's.
        force: Overwrite existing output files.
        log: Called with one line per finished point.
        engines: ``ode`` and/or ``mujoco`` (default: the ODE only, as before the MuJoCo half;
            the command line runs both).
        integrators: MuJoCo integrators.
        timesteps: MuJoCo timesteps (s).
        modes: MuJoCo friction modes.
        mujoco_budget_s: Per-point wall-time budget of MuJoCo (s).
        workers: Processes for the MuJoCo series (None: all cores).

    Returns:
        ``csv``, ``pareto_md`` (the ODE's when it ran, else MuJoCo's), ``figures`` (all),
        ``references`` (per scene), ``pareto`` (the :func:`pareto_table` entries of every
        engine), ``n_points``, ``n_ok``, ``n_skipped``, ``n_failed`` (totals; diverged MuJoCo
        points count as failed), ``engines`` (per engine: ``csv``, ``figures``,
        ``pareto_md``, ``n_points``, ``n_ok``, ``n_skipped``, ``n_diverged``, ``n_failed``)
        and a printable ``report``.

    Raises:
        TippetopError: bad scene or engine, an existing output without ``force``, or a
            reference run that does not complete.
    """
    if isinstance(scene_names, str):
        scene_names = (scene_names,)
    if isinstance(engines, str):
        engines = tuple(e.strip() for e in engines.split(","))
    engines = tuple(dict.fromkeys(engines))
    expect(len(engines) > 0, "--engines", "ode and/or mujoco", list(engines))
    for e in engines:
        expect(e in ENGINES, "--engines", "a comma-separated list of ode, mujoco", e)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(out_dir)!r}")
    scenes = [_scene(name, t_end_s) for name in scene_names]
    expect(len(scenes) > 0, "scene", "at least one scene", list(scene_names))
    if "mujoco" in engines:
        for s in scenes:
            _check_mujoco_scene(s)
        dts = _check_mujoco_args(integrators, modes, timesteps, mujoco_budget_s)
    files = {e: (out / f"accuracy_{e}.csv", out / f"pareto_{e}.md",
                 [out / f"accuracy_{e}_{s.name}.png" for s in scenes]) for e in engines}
    for csv_p, md_p, figs in files.values():
        for p in [csv_p, md_p, *figs]:
            if p.exists() and not force:
                raise TippetopError(f"--out: expected a folder without {p.name} (or --force to "
                                    f"overwrite), got existing {str(p)!r}")
    out.mkdir(parents=True, exist_ok=True)
    refs = [reference_run(s) for s in scenes]
    references: dict[str, dict] = {}
    per_engine: dict[str, dict[str, Any]] = {}
    all_entries: list[dict[str, Any]] = []
    report: list[str] = []
    frames: list[pd.DataFrame] = []

    def finish(engine: str, dfs: list[pd.DataFrame]) -> None:
        csv_path, md_path, fig_paths = files[engine]
        for df, fig_path in zip(dfs, fig_paths, strict=True):
            references[str(df["scene"].iloc[0])] = df.attrs["reference"]
            if engine == "ode":
                work_precision_figure(df, fig_path)
            else:
                mujoco_work_precision_figure(df, fig_path)
        all_df = pd.concat(dfs, ignore_index=True)
        all_df.attrs = {}
        entries = pareto_table(all_df, thresholds)
        write_atomic(csv_path, lambda tmp: all_df.to_csv(tmp, index=False, float_format="%.6g"))
        md = (pareto_markdown(entries, references) if engine == "ode"
              else mujoco_pareto_markdown(entries, references, all_df))
        write_atomic(md_path, lambda tmp: tmp.write_text(md + "\n"))
        status = all_df["status"]
        n_ok = int((status == STATUS_OK).sum())
        n_skipped = int((status == STATUS_SKIPPED).sum())
        n_div = int(status.str.startswith(STATUS_DIVERGED).sum())
        per_engine[engine] = {
            "csv": str(csv_path), "figures": [str(p) for p in fig_paths],
            "pareto_md": str(md_path), "n_points": len(all_df), "n_ok": n_ok,
            "n_skipped": n_skipped, "n_diverged": n_div,
            "n_failed": len(all_df) - n_ok - n_skipped - n_div}
        all_entries.extend(entries)
        frames.append(all_df)
        report.append(f"wrote {csv_path}, {md_path} and {len(fig_paths)} figure(s)")
        tag = "" if engine == "ode" else f" [{engine}]"
        report.extend(f"{e['scene']}{tag}: {e['text']}" for e in entries)

    if "ode" in engines:
        finish("ode", [ode_work_precision(s, tolerances=tolerances, methods=methods,
                                          budget_s=budget_s, reference=ref, log=log)
                       for s, ref in zip(scenes, refs, strict=True)])
    if "mujoco" in engines:
        rows = _mujoco_rows(list(zip(scenes, refs, strict=True)), integrators, modes, dts,
                            mujoco_budget_s, workers, log)
        finish("mujoco", [_mujoco_frame(r, ref) for r, ref in zip(rows, refs, strict=True)])
    first = per_engine[engines[0]]
    status = pd.concat(frames, ignore_index=True)["status"]
    n_ok = int((status == STATUS_OK).sum())
    n_skipped = int((status == STATUS_SKIPPED).sum())
    return {
        "csv": first["csv"], "figures": [f for e in engines for f in per_engine[e]["figures"]],
        "pareto_md": first["pareto_md"], "references": references, "pareto": all_entries,
        "n_points": len(status), "n_ok": n_ok, "n_skipped": n_skipped,
        "n_failed": len(status) - n_ok - n_skipped, "engines": per_engine,
        "report": "\n".join(report),
    }
