"""The search: candidates evaluated in parallel within a run budget, grid then compass steps.

The steps are in docs/design.md.
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from tippetop.compare.running.runner import Task, TaskResult, run_tasks
from tippetop.compare.tuning.calibrate.scoring import (
    Candidate,
    Residual,
    SceneSpec,
    mujoco_defaults,
    objective,
    residual,
)
from tippetop.models.errors import TippetopError
from tippetop.models.numbers import number_text

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


CONTINUOUS = ("impratio", "timeconst_s", "d0", "mu")


def setting_bounds(name: str, timestep_s: float) -> tuple[float, float]:
    """The bounds of a continuous setting (the time constant's lower one is 2 timesteps)."""
    lo, hi = BOUNDS[name]
    if name == "timeconst_s":
        lo = max(lo, 2.0 * timestep_s)
    return lo, hi


def neighbours(c: Candidate, steps: dict[str, float], timestep_s: float) -> list[Candidate]:
    """The compass neighbours of ``c``: +-step (decades) along each continuous setting."""
    out: list[Candidate] = []
    for name in CONTINUOUS:
        lo, hi = setting_bounds(name, timestep_s)
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
            print(f"calibrate: objective {number_text(best.objective, 'rad')}, "
                  f"{best.candidate.label()}, {ev.used_runs} runs", file=sys.stderr, flush=True)
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


def objective_of_defaults(ev: Evaluator) -> float:
    """MuJoCo's default settings scored on the calibration set (outside the search's budget).

    The defaults are :func:`.scoring.mujoco_defaults`: read from MuJoCo itself, at the
    paper's mu, at the calibration's own timestep and integrator.
    """
    other = Evaluator(ev.scenes, ev.timestep_s, ev.integrator, None, ev.run_options)
    other._ode = ev.reference()
    value = other.evaluate([mujoco_defaults()], label="defaults",
                           budgeted=False)[0].objective
    ev.computed_runs += other.computed_runs
    ev.cached_runs += other.cached_runs
    return value
