"""The reference ODE's work-precision points: methods x tolerances, scored and costed.

The methods and the budget are in docs/design.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from tippetop.compare.studies.accuracy.common import (
    ACCURACY_COLUMNS,
    ATOL_PER_RTOL,
    HARD_LIMIT_FACTOR,
    STATUS_OK,
    STATUS_SKIPPED,
    OverBudget,
    Reference,
    cut_scene,
    nan_scores,
    ode_plan,
    reference_run,
    score,
)
from tippetop.models.errors import TippetopError, expect
from tippetop.models.scene import Override, Scene
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.peers import numbalsoda_missing, numbalsoda_solve
from tippetop.reference_ode.solve import (
    initial_state_vector,
    observables_table,
    sample_times,
    scipy_rhs,
    simulate_ode,
)

DEFAULT_TOLERANCES: tuple[float, ...] = tuple(10.0**-k for k in range(3, 13))  # 1e-3 ... 1e-12
DEFAULT_METHODS: tuple[str, ...] = (
    "dop853-compiled/vector", "dop853-compiled/paper", "scipy-DOP853", "scipy-RK45",
    "scipy-LSODA", "scipy-Radau",
)
COMPILED_METHODS = {"dop853-compiled/vector": "vector", "dop853-compiled/paper": "paper",
                    "dop853-compiled/vector-law": "vector"}
#: The compiled methods' ``stiff`` argument of ``simulate_ode`` (default ``auto``).
COMPILED_STIFF = {"dop853-compiled/vector-law": "off"}
SCIPY_METHODS = {"scipy-DOP853": "DOP853", "scipy-RK45": "RK45", "scipy-LSODA": "LSODA",
                 "scipy-Radau": "Radau"}
#: The peers a user would pick (:mod:`reference_ode.peers`: numbalsoda's C++ DOP853 and
#: ODEPACK's LSODA on the same compiled right-hand side), in the default methods when
#: numbalsoda is installed (the optional extra ``.[peers]``): :func:`default_methods`.
PEER_METHODS = {"numbalsoda-DOP853": "numbalsoda DOP853", "numbalsoda-LSODA": "numbalsoda LSODA"}
#: Default per-point wall-time budget (s).
DEFAULT_BUDGET_S = 20.0
#: A point whose runs took less than this in total (s) is run again, up to REPEATS times, and
#: its best wall time kept: sub-second timings on a shared machine are noisy.
REPEAT_BELOW_S = 0.5
REPEATS = 3
#: Nominal convergence order of each method: cost grows as rtol^(-1/order).
NOMINAL_ORDER = {"dop853-compiled/vector": 8, "dop853-compiled/paper": 8,
                 "dop853-compiled/vector-law": 8, "scipy-DOP853": 8, "scipy-RK45": 5,
                 "scipy-LSODA": 5, "scipy-Radau": 4, "numbalsoda-DOP853": 8,
                 "numbalsoda-LSODA": 5}


def default_methods() -> tuple[str, ...]:
    """:data:`DEFAULT_METHODS`, and the numbalsoda peers when numbalsoda is installed."""
    return DEFAULT_METHODS + (() if numbalsoda_missing() else tuple(PEER_METHODS))


#: The stiff case (:func:`stiff_work_precision`): the scene, its Lambda (m/s), the methods.
STIFF_SCENE = "fig3"
STIFF_LAMBDA_MPS = 1e-6
#: (scipy's stiff solvers are left out by default: on 1 s of it LSODA took 7 s at rtol 1e-3
#: and Radau over 15 s, both calling the compiled right-hand side from Python.)
STIFF_METHODS: tuple[str, ...] = ("dop853-compiled/vector", "dop853-compiled/vector-law")
#: The stiff case's reference: the law throughout (``stiff="off"``) at this rtol, and its
#: floor from a run at 10x it. The law at its stability limit costs about as much at any
#: tolerance (46M evaluations at rtol 1e-9, 52M at 1e-11 on fig3), so 1e-11 is affordable;
#: 1e-9 and 1e-11 differ by 3e-11 rad in theta.
STIFF_REFERENCE_RTOL = 1e-11


def _run_compiled(scene: Scene, formulation: str, rtol: float, atol: float,
                  ref: Reference, stiff: str = "auto") -> dict[str, Any]:
    try:
        p = ode_plan(scene, formulation=formulation, rtol=rtol, atol=atol, method="dop853")
        res = simulate_ode(p.top, p.friction, p.init, t_end_s=p.t_end_s,
                           sample_dt_s=p.sample_dt_s, options=p.options, stiff=stiff)
    except TippetopError as exc:  # e.g. the paper form refusing theta0 = 0
        return {"wall_s": math.nan, "n_rhs": 0, "n_steps": 0, **nan_scores(),
                "status": f"failed: {exc}"}
    row: dict[str, Any] = {"wall_s": res.wall_s, "n_rhs": res.n_rhs, "n_steps": res.n_steps}
    if res.status != "ok":
        return {**row, **nan_scores(), "status": f"failed: {res.status}: {res.message}"}
    return {**row, **score(res.table, ref), "status": STATUS_OK}


def _run_scipy(scene: Scene, method: str, rtol: float, atol: float, ref: Reference,
               hard_limit_s: float) -> dict[str, Any]:
    plan = ode_plan(scene)
    friction = plan.friction
    p = pack_params(plan.top, friction)
    y0 = initial_state_vector(plan.top, plan.init)
    rhs = scipy_rhs(plan.top, friction, "vector")  # compiled before the clock starts
    count = [0]
    t_start = [0.0]

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        if count[0] % 1000 == 0 and time.perf_counter() - t_start[0] > hard_limit_s:
            raise OverBudget
        return rhs(t, y)

    T = plan.t_end_s
    t_start[0] = time.perf_counter()
    try:
        # Radau's num_jac grows its difference step without bound for the columns the
        # right-hand side does not depend on (x, y) and overflows to inf there; harmless (the
        # step is then never used), but numpy would warn.
        with np.errstate(over="ignore", invalid="ignore"):
            sol = solve_ivp(fun, (0.0, T), y0, method=SCIPY_METHODS[method], t_eval=ref.t,
                            rtol=rtol, atol=atol)
    except OverBudget:
        wall = time.perf_counter() - t_start[0]
        return {"wall_s": wall, "n_rhs": count[0], "n_steps": math.nan, **nan_scores(),
                "status": f"failed: stopped after {wall:.3g} s, over the hard limit "
                          f"{hard_limit_s:.3g} s"}
    wall = time.perf_counter() - t_start[0]
    row: dict[str, Any] = {"wall_s": wall, "n_rhs": count[0], "n_steps": math.nan}
    if sol.status != 0 or sol.y.shape[1] != ref.t.size:
        return {**row, **nan_scores(), "status": f"failed: {sol.message}"}
    Y = np.ascontiguousarray(sol.y.T)
    if not np.isfinite(Y).all():
        return {**row, **nan_scores(), "status": "failed: non-finite state"}
    table = observables_table("vector", friction, p, ref.t, Y)
    return {**row, **score(table, ref), "status": STATUS_OK}


def _run_peer(scene: Scene, method: str, rtol: float, atol: float, ref: Reference
              ) -> dict[str, Any]:
    """A numbalsoda point, sampled at the reference's times (wall time of the solve)."""
    missing = numbalsoda_missing()
    if missing:
        return {"wall_s": math.nan, "n_rhs": 0, "n_steps": math.nan, **nan_scores(),
                "status": f"failed: {missing}"}
    plan = ode_plan(scene)
    p = pack_params(plan.top, plan.friction)
    y0 = initial_state_vector(plan.top, plan.init)
    numbalsoda_solve(PEER_METHODS[method], y0, p, ref.t[:2], rtol, atol)  # compiled off the clock
    t0 = time.perf_counter()
    Y, n_rhs, _cpu, ok = numbalsoda_solve(PEER_METHODS[method], y0, p, ref.t, rtol, atol)
    row: dict[str, Any] = {"wall_s": time.perf_counter() - t0, "n_rhs": n_rhs,
                           "n_steps": math.nan}
    if not ok or Y.shape[0] != ref.t.size or not np.isfinite(Y).all():
        return {**row, **nan_scores(), "status": "failed: numbalsoda did not complete"}
    table = observables_table("vector", plan.friction, p, ref.t, np.ascontiguousarray(Y))
    return {**row, **score(table, ref), "status": STATUS_OK}


def _timed_point(s: Scene, method: str, rtol: float, atol: float, ref: Reference,
                 budget_s: float) -> dict[str, Any]:
    """Run one point; a fast one is repeated and its best wall time kept (timing noise)."""
    out: dict[str, Any] | None = None
    spent = 0.0
    for _ in range(REPEATS):
        if method in COMPILED_METHODS:
            o = _run_compiled(s, COMPILED_METHODS[method], rtol, atol, ref,
                              COMPILED_STIFF.get(method, "auto"))
        elif method in PEER_METHODS:
            o = _run_peer(s, method, rtol, atol, ref)
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
    methods: Sequence[str] | None = None,
    budget_s: float = DEFAULT_BUDGET_S,
    t_end_s: float | None = None,
    reference: Reference | None = None,
    log: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Work-precision points of the reference ODE on one scene.

    Args:
        scene: A :class:`~models.scene.Scene` or a catalogue name.
        tolerances: rtol values (atol = ``ATOL_PER_RTOL * rtol``), run from loose to tight.
        methods: Names from :data:`NOMINAL_ORDER`; None: :func:`default_methods`.
        budget_s: Per-point wall-time budget (s); see the module docstring.
        t_end_s: Cut the scene's run to this time (s); None keeps the scene's.
        reference: A precomputed :func:`reference_run` of the same scene and horizon.
        log: Called with one line per finished point.

    Returns:
        One row per (method, tolerance) with :data:`ACCURACY_COLUMNS`; ``df.attrs["reference"]``
        describes the reference (method, rtol, atol, floor, wall_s, n_rhs).
    """
    s = cut_scene(scene, t_end_s)
    methods = default_methods() if methods is None else methods
    for m in methods:
        expect(m in NOMINAL_ORDER, "accuracy.methods", "|".join(NOMINAL_ORDER), m)
    tols = sorted({float(t) for t in tolerances}, reverse=True)
    for t in tols:
        expect(math.isfinite(t) and 1e-14 <= t < 1, "accuracy.tolerances",
               "numbers in [1e-14, 1)", t)
    expect(math.isfinite(budget_s) and budget_s > 0, "accuracy.budget_s", "a finite number > 0",
           budget_s)
    ref = reference if reference is not None else reference_run(s)
    expect(ref.t.size == sample_times(s.run.t_end_s, ode_plan(s).sample_dt_s).size,
           "accuracy.reference", "a reference run of the same scene and horizon", ref.t.size)
    T = s.run.t_end_s
    rows: list[dict[str, Any]] = []
    for method in methods:
        walls: list[tuple[float, float]] = []
        over = False
        for rtol in tols:
            atol = ATOL_PER_RTOL * rtol
            base = {"engine": "ode", "mode": "paper", "scene": s.name, "method": method,
                    "formulation": COMPILED_METHODS.get(method, "vector"), "rtol": rtol,
                    "atol": atol, "timestep_s": math.nan, "t_end_s": T}
            pred = _predict_wall(walls, rtol, method)
            if over or (pred is not None and pred > budget_s):
                over = True
                rows.append({**base, "wall_s": math.nan, "n_rhs": 0, "n_steps": 0,
                             **nan_scores(), "status": STATUS_SKIPPED})
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


def stiff_scene(scene: Scene | str = STIFF_SCENE, Lambda_mps: float = STIFF_LAMBDA_MPS,
                t_end_s: float | None = None) -> Scene:
    """``scene`` with the law's Lambda set (and its run cut), named ``<scene>_Lambda<L>``."""
    s = cut_scene(scene, t_end_s).with_overrides([Override.of("friction.Lambda_mps",
                                                               float(Lambda_mps))])
    return replace(s, name=f"{s.name}_Lambda{Lambda_mps:g}")


def law_reference(scene: Scene, rtol: float = STIFF_REFERENCE_RTOL) -> Reference:
    """The reference of a stiff scene: the friction law throughout (``stiff="off"``).

    :func:`~tippetop.compare.studies.accuracy.common.reference_run` integrates the scene as a run
    does, with rolling phases where the law is stiff; scored against it, the rolling phases'
    own departure from the law would not show. Here the law itself, at ``rtol`` (its floor:
    the distance from a run at ``REFERENCE_CHECK_FACTOR`` x ``rtol``).

    Raises:
        TippetopError: if either run does not complete.
    """
    return reference_run(scene, rtol=rtol, stiff="off")


def stiff_work_precision(
    scene: Scene | str = STIFF_SCENE,
    *,
    Lambda_mps: float = STIFF_LAMBDA_MPS,
    tolerances: Sequence[float] = DEFAULT_TOLERANCES,
    methods: Sequence[str] = STIFF_METHODS,
    budget_s: float = DEFAULT_BUDGET_S,
    t_end_s: float | None = None,
    log: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """The stiff case's work-precision points: ``scene`` at a small Lambda, its own frontier.

    The methods (by default the compiled DOP853 with rolling phases and the same on the law
    throughout; any of :data:`NOMINAL_ORDER`'s) are scored against the law at
    :data:`STIFF_REFERENCE_RTOL` (:func:`law_reference`), so the rolling phases' departure
    from the law is part of their error. Rows as :func:`ode_work_precision`; the scene is
    named ``<scene>_Lambda<L>``.
    """
    s = stiff_scene(scene, Lambda_mps, t_end_s)
    return ode_work_precision(s, tolerances=tolerances, methods=methods, budget_s=budget_s,
                              reference=law_reference(s), log=log)
