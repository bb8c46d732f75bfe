"""What the work-precision study shares: the table's columns, the reference run, scoring."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from tippetop.compare.measures.series import jellett_drift
from tippetop.compare.running.engines import plan_for
from tippetop.models.errors import TippetopError, expect
from tippetop.models.plan import OdePlan
from tippetop.models.scene import Override, Scene, load_scene
from tippetop.reference_ode.solve import simulate_ode

#: Columns of the work-precision table, shared by both engines. Errors are against the
#: scene's reference: ``theta_max_err`` max |theta - theta_ref| over the common sample times
#: (rad); ``theta_final_err`` (rad), ``n_final_rel_err`` (relative) and ``Omega_final_err``
#: (rad/s) at t_end; ``final_state_err`` the larger of the first two; ``J_drift`` max
#: |J / J0 - 1|. ``n_steps`` is NaN where ``solve_ivp`` does not report it; errors are NaN for
#: points that did not complete (``status`` says why). ``mode``: how the contact force is made
#: (:mod:`tippetop.models.modes`); ``formulation``: the reference's equations (``vector`` or
#: ``paper``), and for MuJoCo its mode again (the column's meaning before ``mode`` existed).
ACCURACY_COLUMNS: tuple[str, ...] = (
    "engine", "mode", "scene", "method", "formulation", "rtol", "atol", "timestep_s", "t_end_s",
    "wall_s", "wall_per_sim_s", "n_rhs", "n_steps", "theta_max_err", "theta_final_err",
    "n_final_rel_err", "Omega_final_err", "final_state_err", "J_drift", "status",
)

#: atol = ATOL_PER_RTOL * rtol for every point (the package default pair is 1e-9 / 1e-12).
ATOL_PER_RTOL = 1e-3
#: The reference: compiled DOP853, vector formulation, at the tightest rtol OdeOptions accepts.
REFERENCE_RTOL = 1e-14
#: A second reference run at this many times the reference rtol; the two differ by about the
#: looser one's error, an upper estimate of the reference's own error (the "floor").
REFERENCE_CHECK_FACTOR = 10.0
#: A run is stopped once its wall time exceeds this many budgets.
HARD_LIMIT_FACTOR = 3.0
#: Pareto thresholds on max |theta error| (rad).
DEFAULT_THRESHOLDS: tuple[float, ...] = (1e-2, 1e-4, 1e-6)
#: Floor for plotting errors on a log axis (a point equal to the reference).
PLOT_ERR_FLOOR = 1e-16

STATUS_OK = "ok"
STATUS_SKIPPED = "skipped: over budget"
STATUS_DIVERGED = "diverged"


class OverBudget(Exception):
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


def cut_scene(scene: Scene | str, t_end_s: float | None = None) -> Scene:
    """A scene (or catalogue name), its run cut to ``t_end_s`` when one is given."""
    s = load_scene(scene) if isinstance(scene, str) else scene
    if t_end_s is not None:
        expect(math.isfinite(t_end_s) and t_end_s > 0, "t_end_s", "a finite number > 0",
               t_end_s)
        s = s.with_overrides([Override.of("run.t_end_s", float(t_end_s))])
    return s


def ode_plan(scene: Scene, **options: object) -> OdePlan:
    """The scene's plan in the reference ODE, with these integrator ``options`` replaced."""
    plan = plan_for(scene, "ode").ode
    assert plan is not None
    return replace(plan, options=replace(plan.options, **options)) if options else plan


def reference_run(scene: Scene | str, *, t_end_s: float | None = None,
                  rtol: float = REFERENCE_RTOL, stiff: str = "auto") -> Reference:
    """Integrate ``scene`` with the most accurate method and tolerance available.

    Args:
        scene: A :class:`~models.scene.Scene` or a catalogue name.
        t_end_s: Cut the scene's run to this time (s); None keeps it.
        rtol: The reference tolerance (atol = ``ATOL_PER_RTOL * rtol``).
        stiff: ``simulate_ode``'s ``stiff``: ``auto`` integrates the scene as a run does (with
            rolling phases where the law is stiff); ``off``, the law throughout (method
            ``dop853-compiled/vector-law``).

    Returns:
        The reference samples and its error floor (distance from a run at
        ``REFERENCE_CHECK_FACTOR * rtol``).

    Raises:
        TippetopError: if the reference run does not complete.
    """
    s = cut_scene(scene, t_end_s)
    T = s.run.t_end_s
    runs = []
    for r in (rtol, REFERENCE_CHECK_FACTOR * rtol):
        p = ode_plan(s, formulation="vector", rtol=r, atol=ATOL_PER_RTOL * r, method="dop853")
        res = simulate_ode(p.top, p.friction, p.init, t_end_s=T, sample_dt_s=p.sample_dt_s,
                           options=p.options, stiff=stiff)
        if res.status != "ok":
            law = "" if stiff == "auto" else f", stiff {stiff}"
            raise TippetopError(f"accuracy: expected the reference run of {s.name!r} (compiled "
                                f"DOP853, vector, rtol {r:g}{law}) to complete, got "
                                f"{res.status}: {res.message}")
        runs.append(res)
    ref, check = runs
    last = ref.table.iloc[-1]
    return Reference(
        method="dop853-compiled/vector" + ("" if stiff == "auto" else "-law"), rtol=rtol,
        atol=ATOL_PER_RTOL * rtol,
        t=ref.table["t"].to_numpy(), theta=ref.table["theta"].to_numpy(),
        theta_final=float(last["theta"]), n_final=float(last["n"]),
        Omega_final=float(last["Omega"]),
        floor=float(np.max(np.abs(ref.table["theta"].to_numpy()
                                  - check.table["theta"].to_numpy()))),
        wall_s=ref.wall_s, n_rhs=ref.n_rhs)


def score(table: pd.DataFrame, ref: Reference) -> dict[str, float]:
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


def nan_scores() -> dict[str, float]:
    """The scores of a point that did not complete: NaN."""
    keys = ("theta_max_err", "theta_final_err", "n_final_rel_err", "Omega_final_err",
            "final_state_err", "J_drift")
    return dict.fromkeys(keys, math.nan)
