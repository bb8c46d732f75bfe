"""What accuracy costs: work-precision data for the reference ODE.

Each method integrates a scene over a ladder of tolerances; every point is scored against one
reference run of the same scene (the compiled DOP853 on the vector formulation at
:data:`REFERENCE_RTOL`, the tightest tolerance :class:`~models.options.OdeOptions` accepts) and
costed in wall time and right-hand-side evaluations.

Methods (the names are the ``method`` column):

* ``dop853-compiled/vector`` and ``dop853-compiled/paper``: :func:`reference_ode.solve.simulate_ode`
  on either formulation.
* ``scipy-DOP853``, ``scipy-RK45``, ``scipy-LSODA``, ``scipy-Radau``: ``scipy.integrate.solve_ivp``
  calling the same compiled vector right-hand side (:func:`compare.bench._rhs_alloc`) from its
  Python loop, sampled with ``t_eval`` on the same grid. LSODA and Radau get no Jacobian: they
  build it by finite differences (LSODA internally, Radau with ``scipy``'s ``num_jac``); those
  evaluations are counted in ``n_rhs`` because every call goes through one counting wrapper
  (``solve_ivp``'s own ``nfev`` leaves Radau's out).

Every point is one row of :data:`ACCURACY_COLUMNS`. A MuJoCo half can append rows with the same
columns (``engine = "mujoco"``, ``timestep_s`` set, ``rtol``/``atol`` NaN, ``n_steps`` its cost).

Budget: the tolerances of a method run from loose to tight; before each point its wall time
is extrapolated from the previous point (the larger of the observed growth and the method's
nominal ``10^(1/order)`` per decade). A point predicted over ``budget_s`` is recorded as
``skipped: over budget`` together with every tighter one, never silently dropped. A scipy run
that still overruns ``HARD_LIMIT_FACTOR * budget_s`` is stopped and recorded as failed.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from compare.bench import _rhs_alloc
from compare.io import write_atomic
from compare.metrics import jellett_drift
from models.errors import TippetopError, expect
from models.options import OdeOptions
from models.params import FrictionParams
from models.scene import Scene, load_scene
from reference_ode import dop853 as _d
from reference_ode.friction import LAW_TERMS
from reference_ode.params_array import pack_params
from reference_ode.solve import (
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
    return f"timestep {row['timestep_s']:g} s"


def pareto_table(df: pd.DataFrame,
                 thresholds: Iterable[float] = DEFAULT_THRESHOLDS) -> list[dict[str, Any]]:
    """For each scene, engine and threshold: the cheapest point whose theta error meets it.

    Args:
        df: Work-precision rows (:data:`ACCURACY_COLUMNS`), any number of scenes and engines.
        thresholds: Bounds on max |theta error| (rad).

    Returns:
        One dictionary per (engine, scene, threshold): ``engine``, ``scene``, ``threshold``,
        ``method``, ``setting``, ``rtol``, ``timestep_s``, ``wall_s``, ``wall_per_sim_s``,
        ``n_rhs_per_sim_s``, ``theta_max_err`` (None where no point qualifies) and ``text``,
        "to get theta right to X rad, use METHOD at SETTING; it costs Y s per simulated
        second", or "... none reached".
    """
    out: list[dict[str, Any]] = []
    for (engine, scene), g in df.groupby(["engine", "scene"], sort=False):
        ok = g[(g["status"] == STATUS_OK) & g["theta_max_err"].notna()]
        for x in thresholds:
            q = ok[ok["theta_max_err"] <= x]
            entry: dict[str, Any] = {"engine": engine, "scene": scene, "threshold": float(x)}
            if q.empty:
                entry.update(method=None, setting=None, rtol=None, timestep_s=None,
                             wall_s=None, wall_per_sim_s=None, n_rhs_per_sim_s=None,
                             theta_max_err=None,
                             text=f"to get theta right to {x:g} rad: none reached")
            else:
                row = q.loc[q["wall_s"].idxmin()]
                setting = _setting(row)
                entry.update(
                    method=row["method"], setting=setting,
                    rtol=None if math.isnan(row["rtol"]) else float(row["rtol"]),
                    timestep_s=(None if math.isnan(row["timestep_s"])
                                else float(row["timestep_s"])),
                    wall_s=float(row["wall_s"]), wall_per_sim_s=float(row["wall_per_sim_s"]),
                    n_rhs_per_sim_s=float(row["n_rhs"] / row["t_end_s"]),
                    theta_max_err=float(row["theta_max_err"]),
                    text=(f"to get theta right to {x:g} rad, use {row['method']} at {setting}; "
                          f"it costs {row['wall_per_sim_s']:.3g} s per simulated second "
                          f"(theta error {row['theta_max_err']:.1e} rad)"))
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
) -> dict[str, Any]:
    """Work-precision study of the reference ODE; writes the CSV, the figures and the table.

    Files (each written atomically into ``out_dir``): ``accuracy_ode.csv`` (every point),
    ``accuracy_ode_<scene>.png`` (one per scene) and ``pareto_ode.md``.

    Args:
        scene_names: Scene files or catalogue names.
        out_dir: An existing folder (created if missing).
        tolerances: rtol ladder.
        methods: Methods to run.
        budget_s: Per-point wall-time budget (s).
        thresholds: Pareto thresholds on max |theta error| (rad).
        t_end_s: Cut every scene's run to this time (s); None keeps each scene's.
        force: Overwrite existing output files.
        log: Called with one line per finished point.

    Returns:
        ``csv``, ``figures``, ``pareto_md`` (paths), ``references`` (per scene), ``pareto``
        (the :func:`pareto_table` entries), ``n_points``, ``n_ok``, ``n_skipped``,
        ``n_failed`` and a printable ``report``.

    Raises:
        TippetopError: bad scene, an existing output without ``force``, or a reference run
            that does not complete.
    """
    if isinstance(scene_names, str):
        scene_names = (scene_names,)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(out_dir)!r}")
    scenes = [_scene(name, t_end_s) for name in scene_names]
    expect(len(scenes) > 0, "scene", "at least one scene", list(scene_names))
    csv_path = out / "accuracy_ode.csv"
    md_path = out / "pareto_ode.md"
    fig_paths = [out / f"accuracy_ode_{s.name}.png" for s in scenes]
    for p in [csv_path, md_path, *fig_paths]:
        if p.exists() and not force:
            raise TippetopError(f"--out: expected a folder without {p.name} (or --force to "
                                f"overwrite), got existing {str(p)!r}")
    out.mkdir(parents=True, exist_ok=True)
    frames = []
    references: dict[str, dict] = {}
    for s, fig_path in zip(scenes, fig_paths, strict=True):
        df = ode_work_precision(s, tolerances=tolerances, methods=methods, budget_s=budget_s,
                                log=log)
        references[s.name] = df.attrs["reference"]
        work_precision_figure(df, fig_path)
        frames.append(df)
    all_df = pd.concat(frames, ignore_index=True)
    all_df.attrs = {}
    entries = pareto_table(all_df, thresholds)
    write_atomic(csv_path, lambda tmp: all_df.to_csv(tmp, index=False, float_format="%.6g"))
    md = pareto_markdown(entries, references)
    write_atomic(md_path, lambda tmp: tmp.write_text(md + "\n"))
    status = all_df["status"]
    n_skipped = int((status == STATUS_SKIPPED).sum())
    n_ok = int((status == STATUS_OK).sum())
    report = "\n".join([f"wrote {csv_path}, {md_path} and {len(fig_paths)} figure(s)",
                        *[f"{e['scene']}: {e['text']}" for e in entries]])
    return {
        "csv": str(csv_path), "figures": [str(p) for p in fig_paths], "pareto_md": str(md_path),
        "references": references, "pareto": entries, "n_points": len(all_df), "n_ok": n_ok,
        "n_skipped": n_skipped, "n_failed": len(all_df) - n_ok - n_skipped, "report": report,
    }
