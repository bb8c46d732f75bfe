"""The calibration itself: :func:`calibrate` for a :class:`CalibrateConfig`.

The search, then the held-out scenes with the chosen settings and MuJoCo's defaults.
"""

from __future__ import annotations

import math
import shlex
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from tippetop.compare.running.io import check_output_path, write_atomic
from tippetop.compare.running.runner import code_fingerprint
from tippetop.compare.tuning.calibrate.config import (
    DEFAULT_OUT,
    DEFAULT_OUT_SHOWN,
    CalibrateConfig,
)
from tippetop.compare.tuning.calibrate.fit import (
    CONTINUOUS,
    GRID,
    INITIAL_STEPS_DECADES,
    MIN_STEP_DECADES,
    Evaluation,
    Evaluator,
    SearchResult,
    grid_candidates,
    objective_of_defaults,
    search,
    setting_bounds,
    timestep_check,
)
from tippetop.compare.tuning.calibrate.identify import Identified
from tippetop.compare.tuning.calibrate.output import (
    findings,
    path_text,
    render_toml,
    residual_dict,
    settings_table,
)
from tippetop.compare.tuning.calibrate.scoring import (
    DAMPRATIO,
    GRID_DT_S,
    J_MAX,
    SOLIMP_TAIL,
    W_J,
    W_T,
    SceneSpec,
    mujoco_defaults,
    mujoco_defaults_label,
    parse_scene_list,
    standard_seeds,
)
from tippetop.models.calibrated import CALIBRATION_MU
from tippetop.models.errors import TippetopError


def reproduce_command(config: CalibrateConfig, out: Path) -> str:
    """The ``tippetop calibrate`` command line that reproduces a result."""
    parts = ["tippetop", "calibrate", "--calibration", config.calibration, "--holdout",
             config.holdout, "--budget-runs", str(config.budget_runs), "--timestep-s",
             repr(config.timestep_s), "--integrator", config.integrator, "--search",
             config.search]
    shown = DEFAULT_OUT_SHOWN if out.resolve() == DEFAULT_OUT.resolve() else str(out)
    parts += ["--out", shown, "--force"]
    return " ".join(shlex.quote(p) for p in parts)


#: How the sysid search is described in the provenance.
SYSID_SEARCH = ("mujoco.sysid.optimize (MuJoCo's bounded Levenberg-Marquardt on log10 mu, "
                "solref time constant, impratio, solimp d0; finite-difference step 0.01 "
                "decade) on theta(t) and Jellett's constant of every calibration scene, from "
                "the best of the seeds (the shipped settings, MuJoCo's defaults in both cones) "
                "per cone; the best fit scored with the objective below")
#: Rollouts per Levenberg-Marquardt iteration and scene, as ``--budget-runs`` counts them: a
#: Jacobian of 4 settings and about 1.5 trial points. Measured, sysid uses more (its final
#: Jacobian, rejected steps: 386 rollouts for 2 fits of 6 iterations on 2 scenes in the
#: benchmark), which the provenance reports.
ROLLOUTS_PER_ITERATION = 6


def sysid_iterations(budget_runs: int, scenes: int, fits: int = 2) -> int:
    """Levenberg-Marquardt iterations per fit that ``--budget-runs`` allows.

    ``budget_runs / (ROLLOUTS_PER_ITERATION x scenes x fits)``, at least 1.
    """
    return max(1, budget_runs // (ROLLOUTS_PER_ITERATION * scenes * fits))


def sysid_search(ev: Evaluator, config: CalibrateConfig) -> tuple[SearchResult, Identified]:
    """The sysid search (:mod:`.identify`) on the calibration scenes.

    Its best fit is scored as the compass search's candidates are: the objective, through
    the harness's own runs.
    """
    import sys

    from tippetop.compare.tuning.calibrate.identify import (
        Bounds,
        FitStart,
        Problem,
        identify,
        reference_theta,
    )
    from tippetop.mujoco_runner.batch import default_threads

    ode = ev.reference()
    starts = [FitStart(s.name, s.name, s.overrides(), s.t_end_s) for s in ev.scenes]
    refs = [reference_theta(ode[s.name].table, s.t_end_s) for s in ev.scenes]
    ball = [float(ode[s.name].summary.get("t_stem") or math.inf) for s in ev.scenes]
    bounds = Bounds.around(CALIBRATION_MU, config.timestep_s)
    problem = Problem(starts, refs, config.timestep_s, config.integrator, bounds,
                      max(1, default_threads()), ball)
    seeds = standard_seeds()

    def say(line: str) -> None:
        if config.progress:
            print(f"calibrate: {line}", file=sys.stderr, flush=True)

    found = identify(problem, seeds, max_iters=sysid_iterations(config.budget_runs,
                                                                 len(ev.scenes)), say=say)
    ev.used_runs += found.rollouts
    best = ev.evaluate([found.best], label="calibrate sysid", budgeted=False)[0]
    path = [{"stage": "seed (sysid residual)", "objective": s["rms_rad"],
             "settings": s["settings"]} for s in found.seeds]
    path += [{"stage": "fit (sysid residual)", "objective": f["rms_rad"], "settings": f["to"]}
             for f in found.fits]
    return SearchResult(best, [], path, "sysid"), found


def calibrate(config: CalibrateConfig) -> dict[str, Any]:
    """Run the calibration that ``config`` describes and write its file.

    Returns:
        The report: ``settings``, ``provenance``, ``residuals`` (as written to the file) and
        ``out`` (the path written).

    Raises:
        TippetopError: Bad arguments, an existing output without ``--force``, overlapping
            calibration and held-out sets, or a failed reference run.
    """
    t0 = time.perf_counter()
    out = check_output_path(config.out, force=config.force, suffixes=(".toml",))
    calib = parse_scene_list(config.calibration, "--calibration")
    hold = parse_scene_list(config.holdout, "--holdout")
    _check_config(config, calib, hold)
    run_options: dict[str, Any] = {"workers": config.workers, "use_cache": config.use_cache,
                                   "scheduler": config.scheduler}
    ev = Evaluator(calib, config.timestep_s, config.integrator, config.budget_runs, run_options)
    if config.search == "compass":
        result = search(ev, grid_candidates(), progress=config.progress)
        identified = None
    else:
        result, identified = sysid_search(ev, config)
    best = result.best
    dt_check = timestep_check(ev, best.candidate)
    hold_ev = Evaluator(hold, config.timestep_s, config.integrator, None, run_options)
    hold_best, hold_default = hold_ev.evaluate([best.candidate, mujoco_defaults()],
                                               label="held-out")
    ev.computed_runs += hold_ev.computed_runs
    ev.cached_runs += hold_ev.cached_runs
    wall = time.perf_counter() - t0

    per_cone = _best_per_cone(ev)
    calib_default = objective_of_defaults(ev)
    import mujoco

    provenance: dict[str, Any] = {
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": reproduce_command(config, out),
        "calibration_set": [s.text() for s in calib],
        "holdout_set": [s.text() for s in hold],
        "objective": best.objective,
        "objective_definition": (
            f"mean over calibration scenes of [RMS_t(theta_mujoco - theta_ode) on a "
            f"{GRID_DT_S:g} s grid + {W_T:g} rad/s * |inversion-time error|] + {W_J:g} rad per "
            f"decade of worst Jellett drift above {J_MAX:g} (rad)"),
        "mujoco_defaults": mujoco_defaults_label(),
        "objective_mujoco_defaults": calib_default,
        "holdout_objective": hold_best.objective,
        "holdout_objective_mujoco_defaults": hold_default.objective,
        "search": ("coarse grid over cone x impratio x solref timeconst x solimp d0 at mu 0.1, "
                   "then compass search (8 neighbours per round, steps halved on no "
                   "improvement) in decades of impratio, timeconst, d0, mu, best grid cone kept"
                   if identified is None else SYSID_SEARCH),
        "grid": {k: list(v) for k, v in GRID.items()},
        "bounds": {k: list(setting_bounds(k, config.timestep_s)) for k in CONTINUOUS},
        "initial_steps_decades": INITIAL_STEPS_DECADES,
        "min_step_decades": MIN_STEP_DECADES,
        "fixed": {"solref_dampratio": DAMPRATIO, "solimp_tail": list(SOLIMP_TAIL),
                  "timestep_s": config.timestep_s, "integrator": config.integrator, "condim": 3},
        "solreffriction": "not fitted: models.mjcf.make_mjcf does not write it",
        "stop_reason": result.stop_reason,
        "search_path": [path_text(p) for p in result.path],
        "budget_runs": config.budget_runs,
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
    if identified is not None:
        provenance["sysid"] = _sysid_provenance(identified, config, len(calib))
    residuals = [residual_dict(r, "holdout", d)
                 for r, d in zip(hold_best.residuals, hold_default.residuals, strict=True)]
    residuals += [residual_dict(r, "calibration", None) for r in best.residuals]
    report = {"settings": settings_table(best.candidate, config.timestep_s, config.integrator),
              "provenance": provenance, "residuals": residuals}
    text = render_toml(report)
    write_atomic(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    report["out"] = str(out)
    return report


def _check_config(config: CalibrateConfig, calib: list[SceneSpec],
                  hold: list[SceneSpec]) -> None:
    """Refuse overlapping scene sets, a budget, timestep, integrator or search out of range."""
    overlap = sorted({s.name for s in calib} & {s.name for s in hold})
    if overlap:
        raise TippetopError(f"--holdout: expected scenes not in --calibration, got "
                            f"{', '.join(overlap)} in both")
    if not (isinstance(config.budget_runs, int) and config.budget_runs >= len(calib)):
        raise TippetopError(f"--budget-runs: expected an integer >= {len(calib)} (one "
                            f"candidate on every calibration scene), got {config.budget_runs!r}")
    if not (math.isfinite(config.timestep_s) and 0 < config.timestep_s <= 1e-3):
        raise TippetopError(f"--timestep-s: expected a number in (0, 1e-3] s, got "
                            f"{config.timestep_s!r}")
    from tippetop.models.options import MUJOCO_INTEGRATORS

    if config.integrator not in MUJOCO_INTEGRATORS:
        raise TippetopError(f"--integrator: expected one of {'|'.join(MUJOCO_INTEGRATORS)}, "
                            f"got {config.integrator!r}")
    from tippetop.compare.tuning.calibrate.config import SEARCHES

    if config.search not in SEARCHES:
        raise TippetopError(f"--search: expected one of {'|'.join(SEARCHES)}, got "
                            f"{config.search!r}")


def _best_per_cone(ev: Evaluator) -> dict[str, Evaluation]:
    """The best evaluated candidate of each cone (the first of equals), by cone."""
    per_cone: dict[str, Evaluation] = {}
    for e in ev.memo.values():
        cone = e.candidate.cone
        if cone not in per_cone or e.objective < per_cone[cone].objective:
            per_cone[cone] = e
    return per_cone


def _sysid_provenance(identified: Identified, config: CalibrateConfig,
                      n_scenes: int) -> dict[str, Any]:
    """The sysid search's own provenance: its residual, rollouts, seeds, fits and limits."""
    return {
        "residual": identified.rms_rad, "rollouts": identified.rollouts,
        "seeds": identified.seeds, "fits": identified.fits, "wall_s": identified.wall_s,
        "max_iters": sysid_iterations(config.budget_runs, n_scenes),
        "residual_definition": (
            "sqrt(mean over scenes of RMS(theta_mujoco - theta_ode)^2 + (100 rad x "
            "RMS(J/J0 - 1) before the stem)^2) on a 0.01 s grid (rad)")}
