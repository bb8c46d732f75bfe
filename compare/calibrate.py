"""``tippetop calibrate``: fit MuJoCo's native contact settings to the reference ODE.

MuJoCo's own friction is a soft constraint: below saturation it acts like a steep viscous law
whose slope depends on the friction cone, ``impratio``, ``solref``, ``solimp`` and the timestep,
and with MuJoCo's defaults the paper's Fig. 3 top settles into rolling instead of turning over.
This module picks the native settings (``mu``, ``cone``, ``impratio``, ``solref``, ``solimp``
at a fixed integrator and timestep) that make native runs follow the reference ODE (the paper's
modified Coulomb law) on a *calibration* set of scenes, and then measures how well the chosen
settings do on *held-out* scenes that the fit never saw.

Objective (rad), minimised over the calibration set::

    objective = mean_s [ rms_s + W_T * dt_inv_s ] + W_J * max(0, log10(J_drift / J_MAX))

* ``rms_s``: RMS over the run of theta_mujoco(t) - theta_ode(t), both interpolated on a
  uniform grid of :data:`GRID_DT_S` (rad). This is the whole trajectory: the rise, the
  inversion and the relaxation towards the final angle.
* ``dt_inv_s``: inversion-time error (s), |t_inv_mujoco - t_inv_ode|; when only one engine
  turns over (theta > pi/2) within the horizon T, ``T - t_inv`` of the one that did (a lower
  bound of the error); 0 when neither does. Weighted by :data:`W_T` = 0.2 rad/s: one second of
  inversion-time error costs as much as 0.2 rad of theta RMS. The inversion time is the
  paper's headline observable and the RMS alone weighs it only through the few tenths of a
  second around the flip.
* Jellett penalty: native condim-3 friction acts at the contact point, so Jellett's constant J
  must stay conserved; settings whose worst relative drift on the calibration set exceeds
  :data:`J_MAX` = 1e-4 (the harness's tolerance) pay :data:`W_J` = 0.5 rad per decade above it.
  Very soft normal contacts (a small ``solimp`` d0 with a long ``solref`` time constant) sink
  the ball, move the contact point off the nominal geometry and make J drift.
* A failed (diverged) MuJoCo run costs :data:`FAIL_COST` for its scene.

Search (deterministic; parallel through :func:`compare.runner.run_tasks`, cached on disk):

1. A coarse grid (:data:`GRID`): cone x impratio x solref time constant x solimp d0 at the
   paper's mu = 0.1, in that order, every candidate on every calibration scene.
2. Compass (coordinate pattern) search from the best grid point, its cone kept, over the
   continuous settings in decades: log10 impratio, log10 time constant, log10 d0, log10 mu.
   Each round evaluates the 8 neighbours +-step along each axis in one parallel batch, moves to
   the best one if it improves the objective, else halves the steps; it stops when every step
   is below :data:`MIN_STEP_DECADES` or the run budget (``--budget-runs``, counted as
   candidate x scene runs whether or not they came from the cache, so the search path does not
   depend on the cache) is spent. Values are rounded to 3 significant digits, within
   :data:`BOUNDS`; the time constant's lower bound is 2 timesteps, below which MuJoCo uses
   2 timesteps anyway.
3. A timestep check: the chosen settings rerun at half the timestep on the calibration set;
   the objective and the largest theta difference are reported.
4. Held-out scenes: the chosen settings and MuJoCo's defaults (both written out explicitly)
   against the reference: theta(t) RMS, inversion-time error, theta_asymp error, outcome
   match, Jellett drift. Behaviour that no setting reproduces is listed in ``findings``.

The solref damping ratio (1), the solimp tail (dmax 0.95, width 1 mm, midpoint 0.5, power 2),
the integrator and the timestep are fixed during the search and written with the settings.
MuJoCo's ``solreffriction`` is not fitted: :func:`models.mjcf.make_mjcf` does not write it, so
friction rows share the contact's solref.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import shlex
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.io import check_output_path, write_atomic
from tippetop.compare.metrics import classify_outcome, theta_asymp
from tippetop.compare.runner import Task, TaskResult, code_fingerprint, run_tasks
from tippetop.models.calibrated import CALIBRATION_FILE
from tippetop.models.errors import TippetopError
from tippetop.models.scene import load_scene

#: The shipped result (the default of ``mujoco.friction=native``).
DEFAULT_OUT = CALIBRATION_FILE
#: How the shipped result is named in the reproduce command (run from the repository's root).
DEFAULT_OUT_SHOWN = "models/calibrated_native.toml"
#: Calibration scenes, ``NAME:T_END_S``: two Group II tops that turn over, from theta0 = 0.1
#: (Fig. 3, A/C = 1, a/R = 0.1) and from theta0 = 0.01 (Fig. 11, a/R = 0.15, n0 = 70 rad/s).
DEFAULT_CALIBRATION = "fig3:6,fig11_n070:6"
#: Held-out scenes: another Group II flip (Fig. 4), Group II below n1 (Fig. 6), Group I
#: (Fig. 7a), Group III above and below n1 (Fig. 8a, 8b), the Fig. 11 intermediate states
#: (n0 = 50, 60 rad/s) and a faster flip (n0 = 80 rad/s).
DEFAULT_HOLDOUT = ("fig4:8,fig6:12,fig7a:8,fig8a:20,fig8b:8,fig11_n050:30,fig11_n060:30,"
                   "fig11_n080:10")
#: MuJoCo timestep of the fit (s). At the settings found, theta(t) at 2e-4 s, 1e-4 s and
#: 5e-5 s agreed to about 1e-3 rad and 1 ms in the inversion time (see the timestep check).
DEFAULT_TIMESTEP_S = 2e-4
DEFAULT_INTEGRATOR = "RK4"
#: Candidate x scene runs the search may use.
DEFAULT_BUDGET_RUNS = 160

#: Objective weights (see the module docstring).
W_T = 0.2  # rad per second of inversion-time error
W_J = 0.5  # rad per decade of Jellett drift above J_MAX
J_MAX = 1e-4
FAIL_COST = 10.0  # rad, a failed run
GRID_DT_S = 0.01  # s, the grid theta(t) is compared on
#: Held-out theta_asymp error that counts as "not reproduced" (rad); the same margin as the
#: outcome classes (:data:`compare.metrics.OUTCOME_MARGIN`).
ASYMP_TOL = 0.15
#: Held-out inversion-time error that counts as "not reproduced": more than 0.5 s and more than
#: 10 % of the reference's t_invert. A slow rise (Fig. 11, n0 = 50 rad/s, 15 s) crosses pi/2 at
#: a shallow angle, so its crossing time is as sensitive as 10 % of the whole rise; 10 % of
#: Fig. 3's 2.3 s is 0.23 s.
T_INV_TOL_S = 0.5
T_INV_RTOL = 0.1

#: The coarse grid: cone x impratio x solref time constant (s) x solimp d0, at mu = 0.1.
GRID: dict[str, tuple[Any, ...]] = {
    "cone": ("pyramidal", "elliptic"),
    "impratio": (0.1, 0.3, 1.0),
    "timeconst_s": (0.001, 0.004),
    "d0": (0.05, 0.2),
    "mu": (0.1,),
}
#: Bounds of the continuous settings (the time constant's lower bound is 2 timesteps).
BOUNDS: dict[str, tuple[float, float]] = {
    "impratio": (0.02, 5.0),
    "timeconst_s": (0.0, 0.05),
    "d0": (0.01, 0.95),
    "mu": (0.02, 1.0),
}
#: Compass search: first steps (decades) and the step below which it stops.
INITIAL_STEPS_DECADES: dict[str, float] = {"impratio": 0.3, "timeconst_s": 0.3, "d0": 0.3,
                                           "mu": 0.15}
MIN_STEP_DECADES = 0.02
#: Fixed parts of solref and solimp during the search.
DAMPRATIO = 1.0
SOLIMP_TAIL = (0.95, 0.001, 0.5, 2.0)


def _round_sig(x: float, digits: int = 3) -> float:
    """``x`` rounded to ``digits`` significant digits."""
    if x == 0 or not math.isfinite(x):
        return x
    return float(f"{x:.{digits - 1}e}")


@dataclass(frozen=True)
class Candidate:
    """One set of native contact settings.

    Attributes:
        cone: ``pyramidal`` or ``elliptic``.
        impratio: Frictional-to-normal impedance ratio.
        timeconst_s: solref time constant (s).
        d0: solimp d0 (impedance at zero penetration).
        mu: Sliding friction coefficient.
        dampratio: solref damping ratio.
        solimp_tail: solimp (dmax, width m, midpoint, power).
    """

    cone: str
    impratio: float
    timeconst_s: float
    d0: float
    mu: float
    dampratio: float = DAMPRATIO
    solimp_tail: tuple[float, float, float, float] = SOLIMP_TAIL

    def rounded(self) -> Candidate:
        """The same candidate with its continuous settings at 3 significant digits."""
        return replace(self, impratio=_round_sig(self.impratio),
                       timeconst_s=_round_sig(self.timeconst_s), d0=_round_sig(self.d0),
                       mu=_round_sig(self.mu))

    @property
    def solref(self) -> list[float]:
        """MuJoCo solref (time constant s, damping ratio)."""
        return [self.timeconst_s, self.dampratio]

    @property
    def solimp(self) -> list[float]:
        """MuJoCo solimp (d0, dmax, width m, midpoint, power)."""
        return [self.d0, *self.solimp_tail]

    def overrides(self, timestep_s: float, integrator: str) -> tuple[str, ...]:
        """``--set`` strings that select exactly these settings (nothing left to defaults)."""
        return ("mujoco.friction=native", f"mujoco.cone={self.cone}",
                f"mujoco.impratio={self.impratio!r}", f"mujoco.mu={self.mu!r}",
                f"mujoco.solref={json.dumps(self.solref)}",
                f"mujoco.solimp={json.dumps(self.solimp)}",
                f"mujoco.timestep_s={timestep_s!r}", f"mujoco.integrator={integrator}")

    def label(self) -> str:
        """A short human-readable form."""
        return (f"{self.cone} impratio={self.impratio:g} solref=[{self.timeconst_s:g}, "
                f"{self.dampratio:g}] d0={self.d0:g} mu={self.mu:g}")


#: MuJoCo's own defaults (``mujoco.friction=native`` before calibration), at the paper's mu.
MUJOCO_DEFAULTS = Candidate(cone="elliptic", impratio=1.0, timeconst_s=0.02, d0=0.9, mu=0.1)


@dataclass(frozen=True)
class SceneSpec:
    """A catalogue scene and the horizon it is compared over."""

    name: str
    t_end_s: float

    def overrides(self) -> tuple[str, ...]:
        """The horizon override."""
        return (f"run.t_end_s={self.t_end_s!r}",)

    def text(self) -> str:
        """``NAME:T_END_S``."""
        return f"{self.name}:{self.t_end_s:g}"


def parse_scene_list(text: str, option: str) -> list[SceneSpec]:
    """Parse ``fig3:6,fig11_n070`` (a missing horizon means the scene's own ``run.t_end_s``).

    Raises:
        TippetopError: An unknown scene, a bad horizon, a repeated or an empty list.
    """
    out: list[SceneSpec] = []
    for item in (p.strip() for p in text.split(",")):
        if not item:
            continue
        name, _, horizon = item.partition(":")
        scene = load_scene(name.strip())  # unknown names fail here with the catalogue listed
        if horizon:
            try:
                t_end = float(horizon)
            except ValueError:
                t_end = math.nan
            if not (math.isfinite(t_end) and t_end > 0):
                raise TippetopError(f"{option}: expected NAME or NAME:T_END_S with T_END_S > 0, "
                                    f"got {item!r}")
        else:
            t_end = scene.run.t_end_s
        out.append(SceneSpec(scene.name, t_end))
    if not out:
        raise TippetopError(f"{option}: expected a comma-separated list of scenes, got {text!r}")
    names = [s.name for s in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise TippetopError(f"{option}: expected each scene once, got {', '.join(dup)} twice")
    return out


@dataclass
class Residual:
    """How one MuJoCo run differs from the reference on one scene.

    Attributes:
        scene: Scene name.
        t_end_s: Horizon (s).
        rms_rad: RMS of theta_mujoco - theta_ode over the run (rad).
        t_invert_ode: First time theta > pi/2 in the reference (s), None if never.
        t_invert_mujoco: The same in MuJoCo (s), None if never.
        t_invert_err_s: t_invert_mujoco - t_invert_ode (s) when both turn over, else None.
        t_invert_penalty_s: The inversion-time error the objective uses (s).
        theta_asymp_ode: Mean theta over the last 10 % of the reference run (rad).
        theta_asymp_mujoco: The same in MuJoCo (rad).
        theta_asymp_err: theta_asymp_mujoco - theta_asymp_ode (rad).
        outcome_ode: ``upright``, ``intermediate``, ``inverted`` or ``inconclusive``.
        outcome_mujoco: The same in MuJoCo.
        outcome_match: Whether the two outcomes agree.
        J_rel_drift: MuJoCo's max |J/J0 - 1| over the run.
        cost: rms_rad + W_T * t_invert_penalty_s (rad), or FAIL_COST for a failed run.
        error: The failure message of a failed MuJoCo run, else "".
    """

    scene: str
    t_end_s: float
    rms_rad: float
    t_invert_ode: float | None
    t_invert_mujoco: float | None
    t_invert_err_s: float | None
    t_invert_penalty_s: float
    theta_asymp_ode: float
    theta_asymp_mujoco: float
    theta_asymp_err: float
    outcome_ode: str
    outcome_mujoco: str
    outcome_match: bool
    J_rel_drift: float
    cost: float
    error: str = ""


def _theta_on_grid(table: pd.DataFrame, t_end_s: float) -> np.ndarray:
    grid = np.arange(0.0, t_end_s + 0.5 * GRID_DT_S, GRID_DT_S)
    grid = grid[grid <= t_end_s + 1e-12]
    return np.interp(grid, table["t"].to_numpy(), table["theta"].to_numpy())


def residual(spec: SceneSpec, ode: TaskResult, mj: TaskResult) -> Residual:
    """Compare a MuJoCo run with the reference run of the same scene (see the objective)."""
    if ode.error or ode.table is None or ode.summary is None:
        raise TippetopError(f"calibrate: the reference run of {spec.name} failed: {ode.error}")
    ode_asymp = theta_asymp(ode.table)
    ode_outcome = classify_outcome(ode.table)
    t_ode = ode.summary.get("t_invert")
    if mj.error or mj.table is None or mj.summary is None:
        return Residual(spec.name, spec.t_end_s, math.nan, t_ode, None, None, math.nan,
                        ode_asymp, math.nan, math.nan, ode_outcome, "failed", False, math.nan,
                        FAIL_COST, error=mj.error or "no result")
    th_ode = _theta_on_grid(ode.table, spec.t_end_s)
    th_mj = _theta_on_grid(mj.table, spec.t_end_s)
    rms = float(np.sqrt(np.mean((th_mj - th_ode) ** 2)))
    t_mj = mj.summary.get("t_invert")
    if t_ode is not None and t_mj is not None:
        err: float | None = float(t_mj - t_ode)
        penalty = abs(err)
    elif t_ode is None and t_mj is None:
        err, penalty = None, 0.0
    else:
        err = None
        penalty = spec.t_end_s - float(t_ode if t_ode is not None else t_mj)
    mj_asymp = theta_asymp(mj.table)
    mj_outcome = classify_outcome(mj.table)
    return Residual(
        scene=spec.name, t_end_s=spec.t_end_s, rms_rad=rms, t_invert_ode=t_ode,
        t_invert_mujoco=t_mj, t_invert_err_s=err, t_invert_penalty_s=float(penalty),
        theta_asymp_ode=ode_asymp, theta_asymp_mujoco=mj_asymp,
        theta_asymp_err=mj_asymp - ode_asymp, outcome_ode=ode_outcome,
        outcome_mujoco=mj_outcome, outcome_match=mj_outcome == ode_outcome,
        J_rel_drift=float(mj.summary["J_rel_drift"]), cost=rms + W_T * penalty)


def objective(residuals: Sequence[Residual]) -> float:
    """The calibration objective (rad) of one candidate's residuals (see the module docstring)."""
    cost = float(np.mean([r.cost for r in residuals]))
    drifts = [r.J_rel_drift for r in residuals if math.isfinite(r.J_rel_drift)]
    worst = max(drifts, default=0.0)
    if worst > J_MAX:
        cost += W_J * math.log10(worst / J_MAX)
    return cost


@dataclass
class Evaluation:
    """A candidate's objective and residuals on a set of scenes."""

    candidate: Candidate
    objective: float
    residuals: list[Residual]


@dataclass
class Evaluator:
    """Runs candidates on a fixed set of scenes, in parallel and cached, within a run budget.

    Attributes:
        scenes: The scenes every candidate runs.
        timestep_s: MuJoCo timestep (s).
        integrator: MuJoCo integrator.
        budget_runs: Candidate x scene runs allowed (None: no limit).
        run_options: Keyword arguments of :func:`run_tasks` (workers, cache, scheduler).
    """

    scenes: list[SceneSpec]
    timestep_s: float
    integrator: str
    budget_runs: int | None = None
    run_options: dict[str, Any] = field(default_factory=dict)
    used_runs: int = 0
    computed_runs: int = 0
    cached_runs: int = 0
    memo: dict[Candidate, Evaluation] = field(default_factory=dict)
    _ode: dict[str, TaskResult] = field(default_factory=dict)

    def reference(self) -> dict[str, TaskResult]:
        """The reference ODE runs of the scenes (run once)."""
        if not self._ode:
            tasks = [Task(s.name, s.overrides(), "ode") for s in self.scenes]
            res = run_tasks(tasks, label="reference", **self.run_options)
            self._count(res)
            for spec, r in zip(self.scenes, res, strict=True):
                if r.error:
                    raise TippetopError(f"calibrate: the reference run of {spec.name} failed: "
                                        f"{r.error}")
                self._ode[spec.name] = r
        return self._ode

    def _count(self, results: Iterable[TaskResult]) -> None:
        for r in results:
            if r.cached:
                self.cached_runs += 1
            else:
                self.computed_runs += 1

    def remaining(self) -> int | None:
        """Candidates the budget still allows (None: no limit)."""
        if self.budget_runs is None:
            return None
        return max(0, (self.budget_runs - self.used_runs) // len(self.scenes))

    def evaluate(self, candidates: Sequence[Candidate], *, label: str = "calibrate",
                 budgeted: bool = True) -> list[Evaluation]:
        """Evaluate candidates (memoised); new ones beyond the budget are dropped.

        Returns:
            The evaluations of the candidates that fit the budget, in order.
        """
        ode = self.reference()
        new: list[Candidate] = []
        for c in candidates:
            if c not in self.memo and c not in new:
                new.append(c)
        if budgeted and self.budget_runs is not None:
            new = new[: self.remaining()]
        if new:
            tasks = [Task(s.name, s.overrides() + c.overrides(self.timestep_s, self.integrator),
                          "mujoco") for c in new for s in self.scenes]
            res = run_tasks(tasks, label=label, **self.run_options)
            self._count(res)
            if budgeted:
                self.used_runs += len(tasks)
            k = len(self.scenes)
            for i, c in enumerate(new):
                resid = [residual(s, ode[s.name], r)
                         for s, r in zip(self.scenes, res[i * k:(i + 1) * k], strict=True)]
                self.memo[c] = Evaluation(c, objective(resid), resid)
        return [self.memo[c] for c in candidates if c in self.memo]


def grid_candidates(grid: dict[str, tuple[Any, ...]] = GRID) -> list[Candidate]:
    """The coarse grid, in :data:`GRID` order."""
    keys = ("cone", "impratio", "timeconst_s", "d0", "mu")
    return [Candidate(**dict(zip(keys, vals, strict=True))).rounded()
            for vals in itertools.product(*(grid[k] for k in keys))]


_CONTINUOUS = ("impratio", "timeconst_s", "d0", "mu")


def _bounds(name: str, timestep_s: float) -> tuple[float, float]:
    lo, hi = BOUNDS[name]
    if name == "timeconst_s":
        lo = max(lo, 2.0 * timestep_s)
    return lo, hi


def neighbours(c: Candidate, steps: dict[str, float], timestep_s: float) -> list[Candidate]:
    """The compass neighbours of ``c``: +-step (decades) along each continuous setting."""
    out: list[Candidate] = []
    for name in _CONTINUOUS:
        lo, hi = _bounds(name, timestep_s)
        for sign in (+1.0, -1.0):
            v = getattr(c, name) * 10.0 ** (sign * steps[name])
            n = replace(c, **{name: min(hi, max(lo, v))}).rounded()
            if n != c and n not in out:
                out.append(n)
    return out


@dataclass
class SearchResult:
    """The search's outcome."""

    best: Evaluation
    grid: list[Evaluation]
    path: list[dict[str, Any]]
    stop_reason: str


def search(ev: Evaluator, grid: list[Candidate], *, progress: bool = False) -> SearchResult:
    """Coarse grid, then compass refinement of the best grid point (see the module docstring)."""
    grid_evals = ev.evaluate(grid, label="calibrate grid")
    if not grid_evals:
        raise TippetopError(f"--budget-runs: expected at least {len(ev.scenes)} runs (one "
                            f"candidate on every calibration scene), got {ev.budget_runs}")
    best = min(grid_evals, key=lambda e: e.objective)
    path = [{"stage": "grid", "objective": best.objective, "settings": best.candidate.label()}]
    steps = dict(INITIAL_STEPS_DECADES)
    stop = "converged"
    while max(steps.values()) >= MIN_STEP_DECADES:
        if ev.remaining() == 0:
            stop = "budget"
            break
        cands = neighbours(best.candidate, steps, ev.timestep_s)
        evals = ev.evaluate(cands, label="calibrate refine")
        cand_best = min(evals, key=lambda e: e.objective, default=None)
        if cand_best is not None and cand_best.objective < best.objective - 1e-9:
            best = cand_best
            path.append({"stage": "move", "objective": best.objective,
                         "settings": best.candidate.label(), "steps": dict(steps)})
        elif len(evals) < len(cands):  # the budget cut this round short: no verdict
            stop = "budget"
            break
        else:
            steps = {k: v / 2.0 for k, v in steps.items()}
            path.append({"stage": "shrink", "objective": best.objective, "steps": dict(steps)})
        if progress:
            print(f"calibrate: objective {best.objective:.4f} rad, {best.candidate.label()}, "
                  f"{ev.used_runs} runs", file=sys.stderr, flush=True)
    return SearchResult(best, grid_evals, path, stop)


def timestep_check(ev: Evaluator, best: Candidate) -> dict[str, Any]:
    """Rerun ``best`` at half the timestep on the calibration scenes and compare."""
    half = Evaluator(ev.scenes, ev.timestep_s / 2.0, ev.integrator, None, ev.run_options)
    half._ode = ev.reference()
    e_half = half.evaluate([best], label="timestep check", budgeted=False)[0]
    ev.computed_runs += half.computed_runs
    ev.cached_runs += half.cached_runs
    e = ev.memo[best]
    return {
        "timestep_s": ev.timestep_s / 2.0,
        "objective": e_half.objective,
        "objective_change": e_half.objective - e.objective,
        "max_rms_change_rad": max(abs(a.rms_rad - b.rms_rad)
                                  for a, b in zip(e.residuals, e_half.residuals, strict=True)),
        "max_t_invert_change_s": max(
            (abs(a.t_invert_mujoco - b.t_invert_mujoco)
             for a, b in zip(e.residuals, e_half.residuals, strict=True)
             if a.t_invert_mujoco is not None and b.t_invert_mujoco is not None), default=0.0),
    }


def findings(holdout: list[Residual], default: list[Residual]) -> list[str]:
    """Plain statements of what the calibrated native friction does and does not reproduce."""
    out: list[str] = []
    for r, d in zip(holdout, default, strict=True):
        if r.error:
            out.append(f"{r.scene}: the calibrated run failed ({r.error})")
            continue
        bad = []
        if not r.outcome_match:
            bad.append(f"outcome {r.outcome_mujoco} vs the reference's {r.outcome_ode}")
        if abs(r.theta_asymp_err) > ASYMP_TOL:
            bad.append(f"theta_asymp {r.theta_asymp_mujoco:.3f} vs {r.theta_asymp_ode:.3f} rad "
                       f"(error {r.theta_asymp_err:+.3f})")
        if (r.t_invert_err_s is not None
                and abs(r.t_invert_err_s) > max(T_INV_TOL_S, T_INV_RTOL * r.t_invert_ode)):
            bad.append(f"inverts at {r.t_invert_mujoco:.2f} s vs {r.t_invert_ode:.2f} s")
        elif r.t_invert_err_s is None and (r.t_invert_ode is None) != (r.t_invert_mujoco is None):
            who = "MuJoCo" if r.t_invert_mujoco is not None else "the reference"
            bad.append(f"only {who} turns over within {r.t_end_s:g} s")
        base = (f"(MuJoCo defaults: RMS {d.rms_rad:.3f} rad, theta_asymp "
                f"{d.theta_asymp_mujoco:.3f}, {d.outcome_mujoco})")
        if r.J_rel_drift > J_MAX:
            base += f"; Jellett drift {r.J_rel_drift:.1e} over {r.t_end_s:g} s, above {J_MAX:g}"
        if bad:
            out.append(f"{r.scene} over {r.t_end_s:g} s NOT reproduced: {'; '.join(bad)}; "
                       f"theta RMS {r.rms_rad:.3f} rad {base}")
        else:
            inv = ("" if r.t_invert_err_s is None else
                   f"t_invert error {r.t_invert_err_s:+.2f} s of {r.t_invert_ode:.2f} s, ")
            out.append(f"{r.scene} over {r.t_end_s:g} s reproduced: outcome "
                       f"{r.outcome_mujoco}, {inv}theta_asymp error {r.theta_asymp_err:+.3f} "
                       f"rad, theta RMS {r.rms_rad:.3f} rad {base}")
    return out


# ---------------------------------------------------------------- TOML output
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()
                                if x is not None) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_table(header: str, body: dict[str, Any]) -> list[str]:
    lines = [header]
    lines += [f"{k} = {_toml_value(v)}" for k, v in body.items() if v is not None]
    return lines + [""]


def settings_table(c: Candidate, timestep_s: float, integrator: str) -> dict[str, Any]:
    """The ``[settings]`` table: what :func:`calibrated_native_settings` applies."""
    return {"mu": c.mu, "cone": c.cone, "impratio": c.impratio, "solref": c.solref,
            "solimp": c.solimp, "timestep_s": timestep_s, "integrator": integrator}


def _residual_dict(r: Residual, role: str, default: Residual | None) -> dict[str, Any]:
    d = {"role": role, **asdict(r)}
    if not d["error"]:
        del d["error"]
    if default is not None:
        d.update({"default_rms_rad": default.rms_rad,
                  "default_t_invert_mujoco": default.t_invert_mujoco,
                  "default_theta_asymp_mujoco": default.theta_asymp_mujoco,
                  "default_outcome_mujoco": default.outcome_mujoco})
    return d


def render_toml(report: dict[str, Any]) -> str:
    """The calibration file: a header comment, ``[settings]``, ``[provenance]``, residuals."""
    lines = [
        "# MuJoCo native-friction settings calibrated against the reference ODE.",
        "# Written by `tippetop calibrate` (compare/calibrate.py); the [settings] are the",
        "# defaults of mujoco.friction=native for every key a scene does not set itself.",
        "# Reproduce with the [provenance] command. Residuals: role = \"holdout\" scenes were",
        "# not used by the fit; role = \"calibration\" scenes were.",
        "",
    ]
    lines += _toml_table("[settings]", report["settings"])
    lines += _toml_table("[provenance]", report["provenance"])
    for d in report["residuals"]:
        lines += _toml_table("[[residual]]", d)
    return "\n".join(lines)


# ---------------------------------------------------------------- the command
def reproduce_command(args: argparse.Namespace, out: Path) -> str:
    """The ``tippetop calibrate`` command line that reproduces a result."""
    parts = ["tippetop", "calibrate", "--calibration", args.calibration, "--holdout",
             args.holdout, "--budget-runs", str(args.budget_runs), "--timestep-s",
             repr(args.timestep_s), "--integrator", args.integrator]
    shown = DEFAULT_OUT_SHOWN if out.resolve() == DEFAULT_OUT.resolve() else str(out)
    parts += ["--out", shown, "--force"]
    return " ".join(shlex.quote(p) for p in parts)


def calibrate(args: argparse.Namespace) -> dict[str, Any]:
    """Run the calibration described by parsed ``tippetop calibrate`` arguments.

    Returns:
        The report: ``settings``, ``provenance``, ``residuals`` (as written to the file) and
        ``out`` (the path written).

    Raises:
        TippetopError: Bad arguments, an existing output without ``--force``, overlapping
            calibration and held-out sets, or a failed reference run.
    """
    t0 = time.perf_counter()
    out = check_output_path(args.out, force=args.force, suffixes=(".toml",))
    calib = parse_scene_list(args.calibration, "--calibration")
    hold = parse_scene_list(args.holdout, "--holdout")
    overlap = sorted({s.name for s in calib} & {s.name for s in hold})
    if overlap:
        raise TippetopError(f"--holdout: expected scenes not in --calibration, got "
                            f"{', '.join(overlap)} in both")
    if not (isinstance(args.budget_runs, int) and args.budget_runs >= len(calib)):
        raise TippetopError(f"--budget-runs: expected an integer >= {len(calib)} (one "
                            f"candidate on every calibration scene), got {args.budget_runs!r}")
    if not (math.isfinite(args.timestep_s) and 0 < args.timestep_s <= 1e-3):
        raise TippetopError(f"--timestep-s: expected a number in (0, 1e-3] s, got "
                            f"{args.timestep_s!r}")
    from tippetop.models.options import MUJOCO_INTEGRATORS

    if args.integrator not in MUJOCO_INTEGRATORS:
        raise TippetopError(f"--integrator: expected one of {'|'.join(MUJOCO_INTEGRATORS)}, "
                            f"got {args.integrator!r}")
    run_options: dict[str, Any] = {"workers": args.workers, "use_cache": not args.no_cache,
                                   "scheduler": args.scheduler}
    ev = Evaluator(calib, args.timestep_s, args.integrator, args.budget_runs, run_options)
    result = search(ev, grid_candidates(), progress=not args.json)
    best = result.best
    dt_check = timestep_check(ev, best.candidate)
    hold_ev = Evaluator(hold, args.timestep_s, args.integrator, None, run_options)
    hold_best, hold_default = hold_ev.evaluate([best.candidate, MUJOCO_DEFAULTS],
                                               label="held-out")
    ev.computed_runs += hold_ev.computed_runs
    ev.cached_runs += hold_ev.cached_runs
    wall = time.perf_counter() - t0

    per_cone = {}
    for e in ev.memo.values():
        cone = e.candidate.cone
        if cone not in per_cone or e.objective < per_cone[cone].objective:
            per_cone[cone] = e
    calib_default = objective_of_defaults(ev)
    import mujoco

    provenance: dict[str, Any] = {
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": reproduce_command(args, out),
        "calibration_set": [s.text() for s in calib],
        "holdout_set": [s.text() for s in hold],
        "objective": best.objective,
        "objective_definition": (
            f"mean over calibration scenes of [RMS_t(theta_mujoco - theta_ode) on a "
            f"{GRID_DT_S:g} s grid + {W_T:g} rad/s * |inversion-time error|] + {W_J:g} rad per "
            f"decade of worst Jellett drift above {J_MAX:g} (rad)"),
        "objective_mujoco_defaults": calib_default,
        "holdout_objective": hold_best.objective,
        "holdout_objective_mujoco_defaults": hold_default.objective,
        "search": ("coarse grid over cone x impratio x solref timeconst x solimp d0 at mu 0.1, "
                   "then compass search (8 neighbours per round, steps halved on no "
                   "improvement) in decades of impratio, timeconst, d0, mu, best grid cone kept"),
        "grid": {k: list(v) for k, v in GRID.items()},
        "bounds": {k: list(_bounds(k, args.timestep_s)) for k in _CONTINUOUS},
        "initial_steps_decades": INITIAL_STEPS_DECADES,
        "min_step_decades": MIN_STEP_DECADES,
        "fixed": {"solref_dampratio": DAMPRATIO, "solimp_tail": list(SOLIMP_TAIL),
                  "timestep_s": args.timestep_s, "integrator": args.integrator, "condim": 3},
        "solreffriction": "not fitted: models.mjcf.make_mjcf does not write it",
        "stop_reason": result.stop_reason,
        "search_path": [_path_text(p) for p in result.path],
        "budget_runs": args.budget_runs,
        "runs_used": ev.used_runs,
        "candidates_evaluated": len(ev.memo),
        "runs_computed": ev.computed_runs,
        "runs_cached": ev.cached_runs,
        "best_per_cone": {c: {"objective": e.objective, "settings": e.candidate.label()}
                          for c, e in sorted(per_cone.items())},
        "timestep_check": dt_check,
        "wall_s": wall,
        "mujoco_version": mujoco.__version__,
        "code_fingerprint": code_fingerprint(),
        "findings": findings(hold_best.residuals, hold_default.residuals),
    }
    residuals = [_residual_dict(r, "holdout", d)
                 for r, d in zip(hold_best.residuals, hold_default.residuals, strict=True)]
    residuals += [_residual_dict(r, "calibration", None) for r in best.residuals]
    report = {"settings": settings_table(best.candidate, args.timestep_s, args.integrator),
              "provenance": provenance, "residuals": residuals}
    text = render_toml(report)
    write_atomic(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    report["out"] = str(out)
    return report


def _path_text(step: dict[str, Any]) -> str:
    text = f"{step['stage']}: objective {step['objective']:.4f}"
    if "settings" in step:
        text += f", {step['settings']}"
    if "steps" in step:
        text += ", steps " + "/".join(f"{v:.3g}" for v in step["steps"].values()) + " decades"
    return text


def objective_of_defaults(ev: Evaluator) -> float:
    """MuJoCo's default settings scored on the calibration set (outside the search's budget)."""
    other = Evaluator(ev.scenes, ev.timestep_s, ev.integrator, None, ev.run_options)
    other._ode = ev.reference()
    value = other.evaluate([MUJOCO_DEFAULTS], label="defaults", budgeted=False)[0].objective
    ev.computed_runs += other.computed_runs
    ev.cached_runs += other.cached_runs
    return value


def _print_report(report: dict[str, Any]) -> None:
    p = report["provenance"]
    s = report["settings"]
    print(f"settings: {', '.join(f'{k}={v}' for k, v in s.items())}")
    print(f"objective {p['objective']:.4f} rad on {', '.join(p['calibration_set'])} "
          f"(MuJoCo defaults {p['objective_mujoco_defaults']:.4f}); {p['runs_used']} runs, "
          f"{p['candidates_evaluated']} candidates, stop: {p['stop_reason']}")
    hdr = (f"{'scene':<12} {'role':<11} {'rms':>7} {'t_inv ode':>9} {'t_inv mj':>9} "
           f"{'asymp ode':>9} {'asymp mj':>9} {'outcome':<24} {'J drift':>8}")
    print(hdr)
    for r in report["residuals"]:
        def f(v: Any) -> str:
            return "-" if v is None else f"{v:.3f}"
        outcome = f"{r['outcome_mujoco']}/{r['outcome_ode']}"
        print(f"{r['scene']:<12} {r['role']:<11} {f(r['rms_rad']):>7} {f(r['t_invert_ode']):>9} "
              f"{f(r['t_invert_mujoco']):>9} {f(r['theta_asymp_ode']):>9} "
              f"{f(r['theta_asymp_mujoco']):>9} {outcome:<24} {r['J_rel_drift']:>8.1e}")
    for line in p["findings"]:
        print(f"- {line}")
    print(f"wrote {report['out']} in {p['wall_s']:.0f} s")


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``tippetop calibrate``: run, write the file, print the report."""
    report = calibrate(args)
    if args.json:
        from tippetop.compare.cli import print_json

        print_json(report)
    else:
        _print_report(report)
    return 0


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def add_calibrate_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``calibrate`` subcommand to ``tippetop``'s subparsers.

    Args:
        subparsers: The object ``ArgumentParser.add_subparsers`` returned.

    Returns:
        The new subparser (its ``func`` default is :func:`cmd_calibrate`).
    """
    c = subparsers.add_parser(
        "calibrate", help="fit MuJoCo's native contact settings to the reference ODE",
        description="Fit mu, cone, impratio, solref and solimp of MuJoCo's native friction to "
        "the reference ODE on calibration scenes, report residuals on held-out scenes, and "
        "write the settings with their provenance.")
    c.add_argument("--calibration", default=DEFAULT_CALIBRATION,
                   help=f"scenes fitted, NAME[:T_END_S],... (default {DEFAULT_CALIBRATION})")
    c.add_argument("--holdout", default=DEFAULT_HOLDOUT,
                   help=f"scenes only reported, NAME[:T_END_S],... (default {DEFAULT_HOLDOUT})")
    c.add_argument("--out", default=str(DEFAULT_OUT),
                   help="the calibration file (.toml; default models/calibrated_native.toml)")
    c.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    c.add_argument("--budget-runs", dest="budget_runs", type=int, default=DEFAULT_BUDGET_RUNS,
                   help=f"candidate x scene runs the search may use (default "
                   f"{DEFAULT_BUDGET_RUNS})")
    c.add_argument("--timestep-s", dest="timestep_s", type=_float, default=DEFAULT_TIMESTEP_S,
                   help=f"MuJoCo timestep of the fit (default {DEFAULT_TIMESTEP_S:g} s)")
    c.add_argument("--integrator", default=DEFAULT_INTEGRATOR,
                   help=f"MuJoCo integrator of the fit (default {DEFAULT_INTEGRATOR})")
    c.add_argument("--scheduler", help="tcp://HOST:PORT of a Dask scheduler (default: local "
                   "processes)")
    c.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    c.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    c.add_argument("--json", action="store_true", help="print the report as JSON")
    c.set_defaults(func=cmd_calibrate)
    return c


__all__ = ["Candidate", "Evaluator", "MUJOCO_DEFAULTS", "Residual", "SceneSpec",
           "add_calibrate_parser", "calibrate", "cmd_calibrate", "grid_candidates",
           "objective", "parse_scene_list", "residual", "search"]
