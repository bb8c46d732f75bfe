"""Tuned contact settings for any top: fitted to the reference, verified on starts it did not see.

``tippetop validate MODEL.xml`` (its ``tuned`` key) and ``tippetop calibrate --mjcf FILE``.
The file's own contact settings (mu, solref, solimp, impratio, cone) are fitted to the
reference's theta(t) at the file's start (:mod:`.calibrate.identify`: MuJoCo's own
identification, ``mujoco.sysid``), at RK4 and a step of at most the calibration's 2e-4 s; the
file's own integrator and step are kept when they follow as well (what it *needs*). The result
is then run by the harness, as every run, from the file's start and from held-out starts (a
faster and a slower spin, a larger tilt: none used by the fit), each checked against the
theory and the reference with every check of ``validate``'s verdict.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from tippetop.compare.measures.verdict import FIRST_ORDER, REFERENCE_RUN, run_entry, verdict
from tippetop.compare.results.tune import (
    FittedStart,
    TuneAlternative,
    TunedSettings,
    TuneFit,
    TuneNeed,
    TuneResult,
    TuneVerification,
)
from tippetop.compare.running.options import DEFAULT_RUN, RunOptions
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.compare.tuning import TUNE_BUDGET_RUNS
from tippetop.compare.tuning.calibrate.identify import (
    FITTED,
    FITTED_WIDE,
    LIFT_FREE_FITTED,
    STALL_FRACTION,
    WIDE_MU,
    Bounds,
    FitStart,
    Identified,
    Problem,
    identify,
    lift_free_seeds,
    reference_theta,
)
from tippetop.compare.tuning.calibrate.scoring import Candidate, standard_seeds
from tippetop.compare.tuning.judge import (
    DEFAULT_EFFORT,
    HELD_OUT,
    NO_FILE,
    WIDENED,
    TuneEffort,
    TuneFile,
    TuneStart,
    min_budget_runs,
    start_label,
    starts_for,
    widening_step,
)
from tippetop.compare.tuning.judge import agrees as _agrees
from tippetop.compare.tuning.judge import departs as _departs
from tippetop.compare.tuning.judge import mjcf_block as _mjcf
from tippetop.compare.tuning.judge import passes as _passes
from tippetop.compare.tuning.widen import WIDEN_ONE_IN, Refit, WidenRuns, widen, widen_reserve
from tippetop.models.calibrated import calibrated_native_settings
from tippetop.models.errors import TippetopError
from tippetop.models.modes import run_label
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override

#: The fit's step and integrator: RK4 (a first-order step drifts J on a top with A != C,
#: docs/design.md) at the file's step or the calibration's 2e-4 s, whichever is shorter.
FIT_TIMESTEP_S = 2e-4
FIT_INTEGRATOR = "RK4"
#: The file's own integrator and step are kept if, with the fitted contact, their RMS is
#: within this factor of the fit's (plus :data:`KEEP_FLOOR_RAD`).
KEEP_FACTOR = 1.2
KEEP_FLOOR_RAD = 0.005
#: The fit follows each start until this many times its first event (the stem's contact, or
#: else the inversion), at least :data:`MIN_FIT_S`: after the stem touches, theta(t) is the
#: stem's contact's, which the ball's settings do not set.
EVENT_FACTOR = 1.5
MIN_FIT_S = 1.0
#: The seeds' grid besides the calibrated settings and MuJoCo's defaults: solref time
#: constants (s) and solimp d0 at impratio 1, in both cones.
SEED_TIMECONSTS_S = (0.002, 0.01)
SEED_D0 = (0.1, 0.9)
#: ... and a low impratio (friction softer than the normal contact: a creep like the paper's
#: Lambda) at d0 0.3 in each cone: the elliptic cone's best seed on the paper's top (RMS 0.22
#: rad, where impratio 1 gave 1.4), from which its fit takes 3 iterations, not 14.
SEED_LOW_IMPRATIO = 0.1
SEED_LOW_D0 = 0.3
#: MuJoCo runs the tuning may use by default (``--budget-runs``): the seeds, the fits'
#: rollouts, the file's own step tried, every start verified.
DEFAULT_BUDGET_RUNS = TUNE_BUDGET_RUNS


def fit_horizon(summary: dict[str, Any], t_end_s: float) -> float:
    """How long the fit follows a start (see :data:`EVENT_FACTOR`)."""
    event = summary.get("t_stem") or summary.get("t_invert")
    if event is None:
        return t_end_s
    return min(t_end_s, max(MIN_FIT_S, EVENT_FACTOR * float(event)))


def seeds(mu: float, file_run: dict[str, Any] | None, timestep_s: float) -> list[Candidate]:
    """Where the fit starts.

    The calibrated settings, MuJoCo's defaults in both cones, the file's own (each at the
    file's mu; the calibrated one's mu scaled as the paper's 0.1 is).
    """
    out = standard_seeds(mu)  # the seeds are clipped to the fit's bounds where they are used
    # and a few contacts between the calibrated (stiff, hard from the start) and MuJoCo's
    # (soft) in both cones: scoring a seed is one rollout, a fit a few hundred
    out += [Candidate(cone, 1.0, max(tc, 2.0 * timestep_s), d0, mu)
            for cone in ("pyramidal", "elliptic") for tc in SEED_TIMECONSTS_S
            for d0 in SEED_D0]
    out += [Candidate(cone, SEED_LOW_IMPRATIO, max(SEED_TIMECONSTS_S[0], 2.0 * timestep_s),
                      SEED_LOW_D0, mu) for cone in ("pyramidal", "elliptic")]
    if file_run and file_run.get("solref") and file_run.get("solimp") and file_run.get("cone"):
        out.append(Candidate(file_run["cone"], float(file_run.get("impratio") or 1.0),
                             max(float(file_run["solref"][0]), 2.0 * timestep_s),
                             float(file_run["solimp"][0]), mu))
    if mu >= WIDE_MU:
        # the wide fit's: an overdamped contact (damping ratio 4), in both cones, from a stiff
        # contact (the compass calibration's of 2026-11-22, from which the tutorial top's fit
        # was measured to agree) and from MuJoCo's default one
        out += [Candidate(cone, imp, max(tc, 2.0 * timestep_s), d0, mu, dampratio=4.0)
                for cone in ("pyramidal", "elliptic")
                for imp, tc, d0 in ((1.41, 0.002, 0.05), (1.0, 0.02, 0.9))]
    return out


#: What the fit's residual measures (its record's ``residual_definition``).
RESIDUAL_DEFINITION = ("sqrt(RMS(theta_mujoco - theta_reference)^2 + (100 rad x RMS(J/J0 - 1) "
                       "while the ball alone touches)^2) on a 0.01 s grid (rad)")
#: How the tuning fits, in words (its record's ``method``).
METHOD = ("mujoco.sysid's residual and MuJoCo's bounded Levenberg-Marquardt "
          "(mujoco.minimize.least_squares, log10 settings, finite-difference "
          "step 0.01 decade, stopped when two iterations lower the residual "
          f"by less than {STALL_FRACTION:.0%}) from the best seed of the "
          "file's cone (elliptic first at mu >= 0.5), then of the other cone "
          "if the first departs, then (mu >= 0.5) of the lift-free family; "
          "where all depart, the answer with its integrator, step or cone "
          "changed, then a fit at the best of those (the widening, from "
          f"one in {WIDEN_ONE_IN} of the budget's runs, kept back for it)")

#: The lift-free family's name among the fit's cones (:func:`fit_order`).
LIFT_FREE = "lift-free"


def fit_order(file_run: dict[str, Any] | None, wide: bool = False) -> list[str]:
    """What is fitted, in order (each next one only if the ones before depart).

    :func:`cone_order`'s cones, and in the wide fit the lift-free family (:data:`LIFT_FREE`)
    before the pyramidal cone, which lifts a sliding ball soonest.
    """
    cones = cone_order(file_run, wide)
    return [cones[0], LIFT_FREE, *cones[1:]] if wide else cones


def cone_order(file_run: dict[str, Any] | None, wide: bool = False) -> list[str]:
    """The cones fitted, in order: the file's own first (the answer changes least).

    The other is fitted only if the first one's settings do not agree from every start. In
    the wide fit (mu >= :data:`WIDE_MU`) the elliptic cone comes first: each row of a
    pyramidal cone is normal force and friction at once, and it lifts a sliding ball at the
    lowest slip.
    """
    first = (file_run or {}).get("cone") or "pyramidal"  # MuJoCo's default cone
    if wide:
        first = "elliptic"  # a pyramidal cone lifts the ball soonest (contact_lift)
    return [first, "elliptic" if first == "pyramidal" else "pyramidal"]


def _say(progress: bool) -> Callable[[str], None] | None:
    if not progress or not sys.stderr.isatty():
        return None
    return lambda line: print(f"tune: {line}", file=sys.stderr, flush=True)


def tune(base: tuple[Override, ...], mu: float, n0: float, theta0: float, t_end_s: float, *,
         file: TuneFile = NO_FILE, run: RunOptions = DEFAULT_RUN,
         budget_runs: int = DEFAULT_BUDGET_RUNS,
         effort: TuneEffort = DEFAULT_EFFORT) -> TuneResult:
    """Fit the file's contact settings to the reference and verify them.

    The cones are fitted one at a time (:func:`cone_order`): each cone's seeds scored in one
    batched rollout, a fit from the best, and its result verified from every start; the
    second cone only if the first one's settings do not agree. Where the fits and their seeds
    all depart, the widening (:func:`.widen.widen`) tries the answer with one discrete
    choice changed at a time (integrator, step, cone), then a fit at the best of those, from
    runs kept back for it (:func:`.widen.widen_reserve`). The whole tuning stays within
    ``budget_runs`` MuJoCo runs: where they run out, it verifies its best so far and says so
    (``budget_limited``).

    Args:
        base: The overrides of the top (``top.mjcf``, a keyframe); the starts add
            theirs.
        mu: The file's friction coefficient.
        n0: The file's spin (rad/s).
        theta0: The file's tilt (rad).
        t_end_s: Horizon of the verification runs (s); a start whose reference is still
            moving at its end is verified over a longer one, up to
            :data:`HORIZON_FACTOR_MAX` times it (:func:`settled_references`).
        file: The file's own run, step and integrator (its settings seed the fit), its top's
            A/C and the theory at a start.
        run: How the runs run: ``scheduler``, ``workers`` and ``use_cache`` reach
            :func:`run_tasks`; ``progress``: progress lines on a terminal.
        budget_runs: MuJoCo runs (rollouts and verification runs) the tuning may use, at
            least :func:`min_budget_runs`.
        effort: The fits' iterations and threads, the reference's worker processes.

    Returns:
        The tuning (:class:`TuneResult`): its ``settings``, ``mjcf``, ``fit`` (its starts,
        residual, runs, budget, ...), ``verified`` (each start's checks), ``agrees``,
        ``departs``, ``budget_limited`` and ``note``.

    Raises:
        TippetopError: No spin to fit (n0 = 0), a budget below :func:`min_budget_runs`, or a
            reference run that failed.
    """
    if not (math.isfinite(n0) and abs(n0) > 0):
        raise TippetopError(f"tune: expected a spinning start (n0 != 0), got n0 = {n0!r}")
    if budget_runs < min_budget_runs():
        raise TippetopError(f"--budget-runs: expected at least {min_budget_runs()} (one seed "
                            f"scored and its {min_budget_runs() - 1} starts verified), got "
                            f"{budget_runs}")
    opts = {"scheduler": run.scheduler, "workers": run.workers, "use_cache": run.use_cache}
    say = _say(run.progress)
    # the fits and their seeds stay within the budget less the widening's reserve
    main_budget = budget_runs - widen_reserve(budget_runs)
    t0 = time.perf_counter()
    starts = starts_for(n0, theta0)
    workers = effort.reference_workers
    ref_opts = opts if workers is None else {**opts, "workers": workers}
    horizon = Override.of("run.t_end_s", t_end_s)
    refs = run_tasks([Task(None, (*base, *s.overrides(), horizon), "ode", "paper")
                      for s in starts], label="tune reference", **ref_opts)
    for s, r in zip(starts, refs, strict=True):
        if r.error or r.table is None:
            raise TippetopError(f"tune: the reference run from {s.label()} failed: {r.error}")
    # each start verified over a horizon its reference settles in (the fit keeps t_end_s)
    horizons, verify_refs = settled_references(base, starts, refs, t_end_s, ref_opts)
    fit = _fit_setup(base, starts[0], refs[0], mu, t_end_s, file, effort.threads)
    runs = _Runs(base, starts, verify_refs, horizons, opts, file,
                 [fit.problem, fit.lift_free])  # every fit's rollouts count
    # each cone: its seeds, one fit, its verification (the second cone only if needed)
    tried = _fit_families(fit, runs, fit_order(file.run, fit.wide), mu, main_budget,
                          effort.max_iters, say)
    # the answer: the cone whose settings agree, else the fit with the smallest residual
    pick = next((t for t in tried if _agrees(t["verified"])),
                min(tried, key=lambda t: t["found"].rms_rad))
    answer = {**pick, "chosen": "fit"}
    runs.alternatives += [_tried_alternative(t, file) for t in tried if t is not pick]
    if not _agrees(answer["verified"]):
        # the fit is local and holds at the file's start: where it departs elsewhere, the
        # seeds it started from are verified too (the best of each cone, as scored, and the
        # calibrated settings), and one that passes from every start is the answer, said so
        answer = _verify_seeds(fit, runs, tried, answer, main_budget)
    widened: dict[str, Any] | None = None
    if not _agrees(answer["verified"]) and budget_runs - runs.spent() >= 2 * len(starts):
        # the fits and their seeds depart: the widening, from the runs kept back for it
        answer, widened = _widen(fit, runs, answer, budget_runs, effort.max_iters, say)
    return _report(fit, runs, answer, tried, pick["found"], widened, budget_runs, t0)


@dataclass(frozen=True)
class _Fit:
    """What every fit of one tuning shares: its start, step, bounds, problems and seeds."""

    start: FitStart
    dt: float
    wide: bool
    bounds: Bounds
    threads: int
    ball_until: list[float]
    problem: Problem
    lift_free: Problem
    seeds: list[Candidate]


def _fit_setup(base: tuple[Override, ...], start: TuneStart, fit_ref: Any, mu: float,
               t_end_s: float, file: TuneFile, threads: int | None) -> _Fit:
    """The fit at the file's start: its horizon, step, bounds, problems and seeds."""
    t_fit = fit_horizon(fit_ref.summary or {}, t_end_s)
    fit_start = FitStart(start.label(), None,
                         (*base, *start.overrides(), Override.of("run.t_end_s", t_fit)), t_fit)
    dt = min(file.timestep_s or FIT_TIMESTEP_S, FIT_TIMESTEP_S)
    wide = mu >= WIDE_MU
    bounds = Bounds.wide(mu, dt) if wide else Bounds.around(mu, dt)
    from tippetop.mujoco_runner.batch import default_threads

    threads = max(1, threads or default_threads())
    stem = (fit_ref.summary or {}).get("t_stem")
    ball_until = [math.inf if stem is None else float(stem)]
    problem = Problem([fit_start], [reference_theta(fit_ref.table, t_fit)], dt, FIT_INTEGRATOR,
                      bounds, threads, ball_until, fitted=FITTED_WIDE if wide else FITTED)
    starting = seeds(mu, file.run, dt)
    lift_free = Problem([fit_start], problem.references, dt, FIT_INTEGRATOR,
                        Bounds.lift_free(), threads, ball_until, fitted=LIFT_FREE_FITTED)
    return _Fit(fit_start, dt, wide, bounds, threads, ball_until, problem, lift_free, starting)


@dataclass
class _Runs:
    """A tuning's verification from every start, and its record: runs spent, alternatives."""

    base: tuple[Override, ...]
    starts: list[TuneStart]
    refs: list[Any]
    horizons: list[float]
    opts: dict[str, Any]
    file: TuneFile
    problems: list[Problem]
    verify_runs: int = 0
    alternatives: list[dict[str, Any]] = field(default_factory=list)
    budget_limited: bool = False

    def spent(self) -> int:
        """MuJoCo runs spent so far: every fit's rollouts and every verification's runs."""
        return sum(p.rollouts for p in self.problems) + self.verify_runs

    def check(self, best: Candidate, timestep: float,
              integrator: str) -> tuple[list[dict[str, Any]], list[Any]]:
        """Every start run by the harness with ``best``, checked with validate's verdict.

        Each start over its own horizon (:func:`settled_references`), as its reference ran.
        """
        self.verify_runs += len(self.starts)
        tasks = [Task(None, (*self.base, *s.overrides(), Override.of("run.t_end_s", t_end),
                             *best.overrides(timestep, integrator)), "mujoco")
                 for s, t_end in zip(self.starts, self.horizons, strict=True)]
        mj = run_tasks(tasks, label="tune verify", **self.opts)
        verified: list[dict[str, Any]] = []
        for s, ref, run, t_end in zip(self.starts, self.refs, mj, self.horizons, strict=True):
            # the tuned settings run in MuJoCo's own contact: the mode the run read back
            tuned = run_label("mujoco", (run.summary or {}).get("mode") or "file")
            runs = {REFERENCE_RUN: run_entry(ref), tuned: run_entry(run)}
            if runs[REFERENCE_RUN].get("status") != "ok":  # the reference's model does not hold
                verified.append({"n0": s.n0, "theta0": s.theta0, "role": s.role,
                                 "t_end_s": t_end, "theory_outcome": None, "checks": [],
                                 "passed": None, "note": f"not verifiable: the reference stops "
                                 f"({runs[REFERENCE_RUN].get('message')})"})
                continue
            theory = self.file.theory
            theta_s, outcome = (theory(s.n0, s.theta0, s.role) if theory
                                else (None, runs[REFERENCE_RUN]["outcome"]))
            checks = [c for c in verdict(runs, outcome, self.file.A_over_C, theta_s=theta_s)
                      if c["run"] == tuned]
            verified.append({"n0": s.n0, "theta0": s.theta0, "role": s.role, "t_end_s": t_end,
                             "theory_outcome": outcome, "checks": checks,
                             "passed": all(c["passed"] is not False for c in checks),
                             "friction_realised": runs[tuned].get("friction_realised"),
                             "left_table_s": (run.summary or {}).get("t_left_table")})
        return verified, mj


def _fit_families(fit: _Fit, runs: _Runs, order: list[str], mu: float, main_budget: int,
                  max_iters: int, say: Callable[[str], None] | None) -> list[dict[str, Any]]:
    """Each family's fit, settled and verified, in ``order`` up to the first that agrees."""
    tried: list[dict[str, Any]] = []
    n_starts = len(runs.starts)
    for family in order:
        room = main_budget - runs.spent() - n_starts  # a verification kept back
        if room < 1:
            runs.budget_limited = True
            break
        if family == LIFT_FREE:
            # MuJoCo's contact lifts a fast-sliding ball unless its normal row is far softer
            # than its friction rows: the family that separates them (identify.py)
            fam, fam_seeds = fit.lift_free, lift_free_seeds(mu)
            what = ("the lift-free fit (elliptic cone, constant minimal impedance, "
                    "solreffriction on contact pairs)")
        else:
            fam = fit.problem
            fam_seeds = [c for c in fit.seeds if c.cone == family]
            what = f"the fit in the {family} cone"
        fam.budget = fam.rollouts + room
        found = identify(fam, fam_seeds, max_iters=max_iters, say=say)
        runs.budget_limited = runs.budget_limited or found.budget_spent
        settled = _settle(found, fam, fit, runs.file, runs.check,
                          lambda: main_budget - runs.spent())
        tried.append({**settled, "what": what})
        if say:
            say(f"{family}: {'agrees' if _agrees(settled['verified']) else 'departs'} from "
                f"{n_starts} starts ({runs.spent()} MuJoCo runs so far)")
        if _agrees(settled["verified"]) or runs.budget_limited:
            break
    return tried


def _tried_alternative(t: dict[str, Any], file: TuneFile) -> dict[str, Any]:
    """A fit other than the answer, as an alternative: its settings, verdict and its MJCF."""
    return {"settings": t["best"].label(), "what": t["what"], "agrees": _agrees(t["verified"]),
            "departs": _departs(t["verified"]), **_passes(t["verified"]),
            "mjcf": _mjcf(run_entry(t["mj"][0]), file.contacts), "calibrated": False}


def _verify_seeds(fit: _Fit, runs: _Runs, tried: list[dict[str, Any]],
                  answer: dict[str, Any], main_budget: int) -> dict[str, Any]:
    """The first of the fits' seeds that agrees from every start, else ``answer``."""
    done = {t["best"] for t in tried}
    fit_seeds = [s for t in tried for s in _seed_candidates(t["found"])]
    for seed in [*fit_seeds, fit.bounds.clip(fit.seeds[0]).rounded()]:
        if seed in done:
            continue
        if main_budget - runs.spent() < len(runs.starts):
            runs.budget_limited = True
            break
        done.add(seed)
        v2, mj2 = runs.check(seed, fit.dt, FIT_INTEGRATOR)
        runs.alternatives.append({"settings": seed.label(), "agrees": _agrees(v2),
                                  "departs": _departs(v2), **_passes(v2),
                                  "mjcf": _mjcf(run_entry(mj2[0]), runs.file.contacts),
                                  "calibrated": seed == fit.bounds.clip(fit.seeds[0]).rounded()
                                  and bool(calibrated_native_settings())})
        if _agrees(v2):
            return {**answer, "verified": v2, "mj": mj2, "best": seed, "timestep": fit.dt,
                    "integrator": FIT_INTEGRATOR, "chosen": f"seed: {seed.label()}"}
    return answer


def _widen(fit: _Fit, runs: _Runs, answer: dict[str, Any], budget_runs: int, max_iters: int,
           say: Callable[[str], None] | None) -> tuple[dict[str, Any], dict[str, Any]]:
    """The widening's answer where one agrees (else ``answer``), and the widening's record."""
    best = answer["best"]
    problem = fit.lift_free if best.frictiondamping is not None else fit.problem
    widened = widen(best, answer["timestep"], answer["integrator"], problem,
                    runs.file.A_over_C, Refit(fit.start, fit.threads, fit.ball_until, max_iters),
                    WidenRuns(runs.check, lambda: budget_runs - runs.spent(), runs.problems, say,
                              runs.file.contacts))
    for w in widened["tried"]:
        runs.alternatives.append({k: w[k] for k in ("settings", "what", "agrees", "departs",
                                                    "passes", "checks", "mjcf")}
                                 | {"calibrated": False})
    if widened["answer"] is not None:
        a = widened["answer"]
        runs.budget_limited = False
        needs = [*answer["needs"], {"integrator": a["integrator"], "timestep_s": a["timestep_s"],
                                    "rms_rad": None, "kept": True, "why": f"the widening: "
                                    f"{a['what']} agrees from every start"}]
        answer = {**answer, "verified": a["verified"], "mj": a["mj"], "best": a["cand"],
                  "timestep": a["timestep_s"], "integrator": a["integrator"], "needs": needs,
                  "chosen": f"{WIDENED}{a['what']}"}
    elif widened["budget_spent"]:
        runs.budget_limited = True
    return answer, widened


def _report(fit: _Fit, runs: _Runs, answer: dict[str, Any], tried: list[dict[str, Any]],
            found: Identified, widened: dict[str, Any] | None, budget_runs: int,
            t0: float) -> TuneResult:
    """The tuning's result: the answer's settings and MJCF, the fit's record, the verdict."""
    verified, chosen, alternatives = answer["verified"], answer["chosen"], runs.alternatives
    agrees = _agrees(verified)
    departs = _departs(verified)
    ran = run_entry(answer["mj"][0])
    budget_note = (f"; budget-limited: the tuning stopped at {runs.spent()} of --budget-runs "
                   f"{budget_runs} MuJoCo runs with its best so far"
                   if runs.budget_limited else "")
    record = TuneFit(
        starts=(FittedStart(runs.starts[0].n0, runs.starts[0].theta0, fit.start.t_end_s),),
        residual=found.rms_rad, residual_definition=RESIDUAL_DEFINITION,
        runs=runs.spent(), rollouts=sum(p.rollouts for p in runs.problems),
        verify_runs=runs.verify_runs, budget_runs=budget_runs,
        seeds=tuple(s for t in tried for s in t["found"].seeds),
        fits=tuple(f for t in tried for f in t["found"].fits),
        cones=tuple(t["found"].best.cone for t in tried),
        tried=tuple(t["what"] for t in tried),
        timestep_s=fit.dt, integrator=FIT_INTEGRATOR,
        needs=tuple(TuneNeed.from_json(n) for n in answer["needs"]),
        chosen=chosen, alternatives=tuple(TuneAlternative.from_json(a) for a in alternatives),
        bounds={k: tuple(v) for k, v in fit.bounds.values.items()}, method=METHOD,
        widened=None if widened is None else tuple(
            {k: w[k] for k in ("settings", "what", "agrees", "passes", "checks")}
            for w in widened["tried"]),
        wall_s=time.perf_counter() - t0)
    passes = _passes(verified)
    return TuneResult(
        settings=_settings(ran, answer["best"], answer["timestep"], answer["integrator"]),
        mjcf=_mjcf(ran, runs.file.contacts), fit=record,
        verified=tuple(TuneVerification.from_json(v) for v in verified),
        agrees=agrees, departs=tuple(departs), passes=passes["passes"],
        checks=passes["checks"], budget_limited=runs.budget_limited,
        note=_note(agrees, departs, verified) + (
            f" (the fit's own optimum departs from a held-out start; these are "
            f"{_chosen_words(chosen)})"
            if chosen != "fit" else f"; its seeds verified as well ({len(alternatives)}) "
            f"depart too" if alternatives and not agrees else "") + budget_note)


def _settle(found: Identified, problem: Problem, fit: _Fit, file: TuneFile,
            check: Callable[[Candidate, float, str], tuple[list[dict[str, Any]], list[Any]]],
            left: Callable[[], int]) -> dict[str, Any]:
    """A fit's settings verified: at the file's own step and integrator where they follow.

    The cheapest step and integrator whose runs all pass is kept (what the file *needs*);
    the file's own are tried only while the budget (``left()``) keeps a verification back.
    ``problem`` is the family fitted (its bounds), ``fit`` what every fit shares.
    """
    best, dt, A_over_C = found.best, fit.dt, file.A_over_C
    n_starts = len(problem.starts) + len(HELD_OUT)
    options: list[tuple[str, float]] = []
    needs: list[dict[str, Any]] = []
    for integ, step in _cheaper(file.integrator, file.timestep_s, dt):
        if integ in FIRST_ORDER and A_over_C is not None and abs(A_over_C - 1.0) > 1e-9:
            needs.append({"integrator": integ, "timestep_s": step, "rms_rad": None,
                          "kept": False, "why": f"{integ} is first order: it moves Jellett's "
                          "constant in proportion to dt on a top with A/C = "
                          f"{number_text(A_over_C)} (docs/design.md)"})
            continue
        if best.solref_direct is None and best.timeconst_s < 2.0 * step:
            needs.append({"integrator": integ, "timestep_s": step, "rms_rad": None,
                          "kept": False, "why": f"the fitted solref time constant "
                          f"{best.timeconst_s:g} s is below two of its steps"})
            continue
        if left() < 1 + 2 * n_starts:  # its rollout and verification, and the fit's own
            needs.append({"integrator": integ, "timestep_s": step, "rms_rad": None,
                          "kept": False, "why": "not tried: the run budget (--budget-runs) "
                          "was spent"})
            continue
        other = Problem([fit.start], problem.references, step, integ, problem.bounds,
                        fit.threads, fit.ball_until, fitted=problem.fitted)
        rms = other.rms(best)[0]
        problem.rollouts += other.rollouts
        near = rms <= KEEP_FACTOR * found.rms_rad + KEEP_FLOOR_RAD
        needs.append({"integrator": integ, "timestep_s": step, "rms_rad": rms, "kept": False,
                      "why": "" if near else f"its RMS {number_text(rms, 'rad')} is above "
                      f"{KEEP_FACTOR:g} x the fit's + {KEEP_FLOOR_RAD:g} rad"})
        if near:
            options.append((integ, step))
    options.append((FIT_INTEGRATOR, dt))
    # verification: the harness runs the tuned settings as every run, over the whole horizon,
    # from every start
    for k, (integrator, timestep) in enumerate(options):
        if k < len(options) - 1 and left() < 2 * n_starts:
            continue  # only the fit's own step is verified: the budget keeps it back
        verified, mj = check(best, timestep, integrator)
        entry = next((n for n in needs if (n["integrator"], n["timestep_s"]) ==
                      (integrator, timestep)), None)
        ok = all(v["passed"] is not False for v in verified)
        if entry is not None:
            entry["kept"] = ok
            if not ok:
                entry["why"] = "with it the verification departs (" + "; ".join(
                    _departs(verified)[:2]) + ")"
        if ok:
            break
    return {"found": found, "best": best, "verified": verified, "mj": mj,
            "timestep": timestep, "integrator": integrator, "needs": needs}


def _seed_candidates(found: Any) -> list[Candidate]:
    """The seeds the fits started from (each cone's best as scored), best first."""
    order = sorted(range(len(found.fits)), key=lambda i: found.fits[i]["from_rms_rad"])
    return [found.fit_seeds[i] for i in order]


#: A start whose reference has not settled by the verification's horizon (theta still moving,
#: ``classify_outcome`` inconclusive) is verified over up to this many times the horizon,
#: doubled until its reference settles: two runs still rising at their end say nothing of the
#: contact (the fidelity map's A/C 0.8, a/R 0.25, mu 0.1 from 0.9 n0: both turn over at about
#: 7 s and are mid-rise at 8 s, 0.12 rad apart; over 30 s the run agrees on every check).
HORIZON_FACTOR_MAX = 4.0


def settled_references(base: tuple[Override, ...], starts: list[TuneStart], refs: list[Any],
                       t_end_s: float, opts: dict[str, Any]) -> tuple[list[float], list[Any]]:
    """Each start's verification horizon and its reference run over it.

    ``t_end_s`` where the reference settles within it; else doubled, up to
    :data:`HORIZON_FACTOR_MAX` times, until it does (the longest where it never does). A
    reference that stops (its ball leaves the table) keeps its run.
    """
    from tippetop.compare.measures.series import classify_outcome

    horizons = [t_end_s] * len(starts)
    out = list(refs)

    def unsettled(r: Any) -> bool:
        ok = (r.summary or {}).get("status") == "ok" and r.table is not None and len(r.table)
        return bool(ok) and classify_outcome(r.table) == "inconclusive"

    todo = [i for i, r in enumerate(out) if unsettled(r)]
    while todo:
        for i in todo:
            horizons[i] = min(2.0 * horizons[i], HORIZON_FACTOR_MAX * t_end_s)
        again = run_tasks([Task(None, (*base, *starts[i].overrides(),
                                       Override.of("run.t_end_s", horizons[i])), "ode", "paper")
                           for i in todo], label="tune reference", **opts)
        for i, r in zip(todo, again, strict=True):
            if r.error or r.table is None:
                raise TippetopError(f"tune: the reference run from {starts[i].label()} over "
                                    f"{horizons[i]:g} s failed: {r.error}")
            out[i] = r
        todo = [i for i in todo if unsettled(out[i])
                and horizons[i] < HORIZON_FACTOR_MAX * t_end_s * (1 - 1e-9)]
    return horizons, out


def _cheaper(integ: str | None, step: float | None,
             dt_fit: float) -> list[tuple[str, float]]:
    """The file's own integrator and step, then RK4 at the file's step.

    Each only if it differs from the fit's (what the file would save by keeping them).
    """
    out: list[tuple[str, float]] = []
    if integ and step and (integ, step) != (FIT_INTEGRATOR, dt_fit):
        out.append((integ, step))
    if step and step > dt_fit and (FIT_INTEGRATOR, step) not in out:
        out.append((FIT_INTEGRATOR, step))
    return out


def _settings(ran: dict[str, Any], best: Candidate, timestep: float,
              integrator: str) -> TunedSettings:
    """The tuned settings as the verification run ran them (read back), else as fitted."""
    def get(key: str, default: Any) -> Any:
        v = ran.get(key)
        return default if v is None else v
    # the contact pairs' friction rows' own solref (the lift-free family), else None
    srf = ran.get("solreffriction", best.solreffriction)
    return TunedSettings(mu=get("mu", best.mu), cone=get("cone", best.cone),
                         impratio=get("impratio", best.impratio),
                         solref=tuple(get("solref", best.solref)),
                         solimp=tuple(get("solimp", best.solimp)),
                         timestep_s=get("timestep_s", timestep),
                         integrator=get("integrator", integrator),
                         condim=get("condim", 3),
                         solreffriction=None if srf is None else tuple(srf))


def source_digest() -> str:
    """sha256 of the tuning's own code, which the runs' code fingerprint does not hold.

    This module, its starts and verdict, its widening and the widening's draws, the verdict's
    rules, the fit and its scoring, and its result (its start labels, its JSON): what a cached
    tuning (validate's, a fidelity point's) was computed with.
    """
    import hashlib
    from pathlib import Path

    from tippetop.compare.measures import verdict as verdict_rule
    from tippetop.compare.results import tune as result
    from tippetop.compare.tuning import judge, sobol, widen
    from tippetop.compare.tuning.calibrate import identify, scoring

    modules = (sys.modules[__name__], judge, widen, sobol, verdict_rule, identify,
               scoring, result)
    return hashlib.sha256(b"".join(Path(str(m.__file__)).read_bytes()
                                   for m in modules)).hexdigest()


def _chosen_words(chosen: str) -> str:
    """The answer other than the fit's own, in words: its seed, or what the widening did."""
    step = widening_step(chosen)
    if step is not None:
        return f"the widening's, {step}"
    return f"its {chosen}"


def _note(agrees: bool, departs: list[str], verified: list[dict[str, Any]]) -> str:
    checked = [v for v in verified if v["passed"] is not None]
    skipped = len(verified) - len(checked)
    extra = (f" ({skipped} start(s) not verifiable: the reference's model stops there)"
             if skipped else "")
    if agrees:
        return (f"these settings follow the reference from all {len(checked)} starts "
                f"checked, {sum(v['role'] == 'held-out' for v in checked)} of them not used "
                f"by the fit{extra}: paste them into the file")
    if not departs:
        return f"no held-out start could be verified{extra}"
    why = []
    for v in verified:
        fr = v.get("friction_realised") or {}
        failed = {c["check"] for c in v["checks"] if c["passed"] is False}
        where = f"from {start_label(v['n0'], v['theta0'])}"
        if "stays_on_table" in failed and v.get("left_table_s") is not None:
            why.append(f"{where} the ball leaves the table at "
                       f"{number_text(v['left_table_s'], 's')}, "
                       f"before the stem lands, and the reference's never leaves it")
            break
        if v["passed"] is False and fr.get("half_mu_slip_mps") is not None:
            why.append(f"{where} the contact reaches half of mu N at "
                       f"{number_text(1e3 * fr['half_mu_slip_mps'], 'mm/s')}, the paper's law "
                       f"at {number_text(1e3 * fr['law_half_mu_slip_mps'], 'mm/s')}")
            break
    return (f"no setting within the bounds follows the reference from every start{extra}: "
            f"{len(departs)} check(s) depart ({'; '.join(departs[:3])}"
            f"{'; ...' if len(departs) > 3 else ''})" + (f"; why: {why[0]}" if why else ""))


__all__ = ["DEFAULT_BUDGET_RUNS", "HELD_OUT", "LIFT_FREE", "TuneEffort", "TuneFile",
           "TuneStart", "cone_order", "fit_horizon", "fit_order", "min_budget_runs", "seeds",
           "source_digest", "starts_for", "tune"]
