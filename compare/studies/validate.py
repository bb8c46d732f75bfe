"""The work of ``tippetop validate``: one MJCF top against the theory and the reference.

Four runs of the file's top, the checks, the findings and the settings to paste
(:func:`validate`; docs/design.md).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from tippetop.compare.measures import theory
from tippetop.compare.measures.metrics import EVENT_RTOL, EVENT_TOL_S, J_TOL
from tippetop.compare.measures.summary import mjcf_attributes, paste_block
from tippetop.compare.measures.verdict import (
    ENERGY_RISE_FLOOR,
    FIRST_ORDER,
    ISOTROPIC_TOL,
    engine_of,
    gyroscopic_drift,
    mode_of,
    predicted_outcome,
    run_entry,
    verdict,
)
from tippetop.compare.presentation.validate import show_setting, show_value
from tippetop.compare.results.tune import Tuned, TuneOnlyResult, TuneResult, TuneSkipped
from tippetop.compare.results.validate import (
    FileChecks,
    Suggestion,
    ValidateAnswer,
    ValidateCandidate,
    ValidateModel,
    ValidateResult,
)
from tippetop.compare.running.runner import Task, run_tasks
from tippetop.compare.studies.defaults import DEFAULT_T_END_S
from tippetop.compare.studies.lift import lift as lift_study
from tippetop.compare.tuning import TUNE_BUDGET_RUNS
from tippetop.compare.tuning.judge import widening_step
from tippetop.models.calibrated import CALIBRATION_MU
from tippetop.models.errors import TippetopError, expect
from tippetop.models.modes import run_label
from tippetop.models.numbers import number_text
from tippetop.models.scene import Override

#: The runs of a validation (engine family, mode), in report order: the file as it says first,
#: the reference, the paper's law in MuJoCo, the calibrated settings.
RUNS: tuple[tuple[str, str], ...] = (("mujoco", "file"), ("ode", "paper"), ("mujoco", "paper"),
                                     ("mujoco", "native"))
#: The modes of the MuJoCo runs, in report order.
MUJOCO_MODES: tuple[str, ...] = ("file", "paper", "native")
#: The names of the runs on the MuJoCo installed here (``ENGINE/MODE``).
FILE_RUN, REFERENCE_RUN, PAPER_RUN, CALIBRATED_RUN = (run_label(e, m) for e, m in RUNS)


@dataclass(frozen=True)
class ValidateConfig:
    """What ``tippetop validate`` was asked for.

    Attributes:
        model: The MJCF file.
        t_end_s: Simulated time of every run (s).
        keyframe: The file's keyframe to start from (None: its first).
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes (None: all cores).
        use_cache: Read and write the runs cache.
        engines: The engines the MuJoCo runs run on (:mod:`tippetop.models.engines`); each
            names its runs (``mujoco==3.3.7/file``).
        tune: Fit the file's contact settings to the reference and verify them
            (:mod:`tippetop.compare.tuning.tune`; ``--no-tune`` skips it).
        progress: Progress lines of the tuning on a terminal.
        budget_runs: MuJoCo runs the tuning may use (``--budget-runs``).
    """

    model: Path
    t_end_s: float = DEFAULT_T_END_S
    keyframe: str | None = None
    scheduler: str | None = None
    workers: int | None = None
    use_cache: bool = True
    engines: tuple[str, ...] = ("mujoco",)
    tune: bool = True
    progress: bool = True
    budget_runs: int = TUNE_BUDGET_RUNS


def run_key(engine: str, mode: str) -> str:
    """A run's key in ``runs``: its name, ``ENGINE/MODE``."""
    return run_label(engine, mode)


def _overrides(config: ValidateConfig) -> tuple[Override, ...]:
    over = [Override.of("top.mjcf", str(config.model)), Override.of("run.t_end_s", config.t_end_s)]
    if config.keyframe is not None:
        over.append(Override.of("init.keyframe", config.keyframe))
    return tuple(over)


def findings(runs: dict[str, dict[str, Any]], checks: list[dict[str, Any]],
             A_over_C: float | None = None, t_end_s: float | None = None) -> list[str]:
    """What the file's own settings get wrong against the reference, with numbers.

    With ``A_over_C`` (the top's) a Jellett drift under a first-order integrator names the
    gyroscopic torque's integration among its causes (:func:`gyroscopic_drift`); with
    ``t_end_s`` (the runs' horizon, s) an event only one run reaches says within how long.
    """
    f, ref = runs.get(FILE_RUN), runs.get(REFERENCE_RUN)
    if not f or not ref:
        return []
    fs, rs = f, ref
    if fs.get("theta_final") is None:
        return [f"the file's own settings fail: {fs.get('message', f.get('error'))}"]
    if rs.get("theta_final") is None:
        return [f"the reference run failed: {rs.get('message', ref.get('error'))}"]
    out = []
    for key, what in (("t_invert", "turns the top over"), ("t_stem", "brings the stem down")):
        a, b = fs.get(key), rs.get(key)
        if a is not None and b is not None and abs(a - b) > max(EVENT_TOL_S, EVENT_RTOL * b):
            later = "later" if a > b else "earlier"
            out.append(f"its friction {what} {number_text(abs(a - b), 's')} {later} than the "
                       f"reference ({number_text(a, 's')} against {number_text(b, 's')})")
        elif (a is None) != (b is None):
            who = "the reference" if a is None else "the file"
            within = f"the run's {number_text(t_end_s, 's')}" if t_end_s is not None \
                else "the run"
            out.append(f"only {who} {what} within {within}")
    if f["end_state"] != ref["end_state"]:
        out.append(f"it ends {f['end_state']} (theta {number_text(fs['theta_final'], 'rad')}) "
                   f"where the reference ends {ref['end_state']} (theta "
                   f"{number_text(rs['theta_final'], 'rad')})")
    integ, dt = fs.get("integrator"), fs.get("timestep_s")
    step = f"its {integ} at dt = {dt:g} s" if integ and dt else "its integrator"
    j = fs.get("J_rel_drift")
    if j is not None and j > J_TOL["mujoco"]:
        causes = ["a soft contact's sink"]
        if (fs.get("condim") or 3) >= 4:
            causes.append("torsional or rolling friction (condim "
                          f"{fs.get('condim')})")
        gyro = gyroscopic_drift(fs, A_over_C)
        causes.append(f"the integration ({step} is {gyro})" if gyro else
                      f"the integration ({step}; RK4 or a shorter step tells)")
        out.append(f"Jellett's constant drifts by {number_text(j, 'relative')} (relative) "
                   f"before the stem (a torque off the contact point or an error: "
                   f"{', '.join(causes)})")
    by_check = {c["check"]: c for c in checks if c["run"] == FILE_RUN}
    energy = by_check.get("energy_never_rises")
    if energy is not None and not energy["passed"] and energy["value"] is not None:
        hint = (": Euler integrates a spinning body's gyroscopic forces explicitly, which gains "
                "energy; use integrator=\"implicitfast\" or \"RK4\"" if integ == "Euler"
                else "; a shorter timestep or RK4 tells whether the integration gains it")
        out.append(f"its energy rises by {number_text(energy['value'], 'relative')} of E0, more "
                   f"than its soft contacts can give back ({step}){hint}")
    return out


#: The settings ``suggestion`` lists where the file's run and the calibrated run differ.
SETTINGS = ("timestep_s", "integrator", "cone", "impratio", "noslip_iterations", "condim", "mu",
            "solref", "solimp")


def setting_changes(file_run: dict[str, Any], native: dict[str, Any]) -> list[dict[str, Any]]:
    """Where the calibrated settings differ from the file's, as both ran (read back)."""
    out = []
    for key in SETTINGS:
        a, b = file_run.get(key), native.get(key)
        if a is None or b is None:
            continue
        same = (a == b if isinstance(a, str) else
                len(a) == len(b) and all(math.isclose(x, y, rel_tol=1e-9) for x, y in
                                         zip(a, b, strict=True))
                if isinstance(a, list | tuple) else math.isclose(a, b, rel_tol=1e-9))
        if not same:
            out.append({"setting": key, "file": a, "calibrated": b})
    return out


def scaled_mu_clause(file_mu: float | None, native_mu: float | None) -> str:
    """How the calibrated settings' friction came to this file: its mu and theirs, both said.

    The calibration was made at :data:`CALIBRATION_MU` and its MuJoCo mu is scaled in
    proportion to the law's: at the file's mu the calibrated contact's mu may differ from the
    file's (1.04 for a file's 1, say), and then the sentence gives both.

    Args:
        file_mu: The file's mu (its ball geom's sliding friction), or None if unknown.
        native_mu: The mu the calibrated run's contact ran with, or None if unknown.
    """
    head = f"They were calibrated on the paper's tops at mu = {CALIBRATION_MU:g}"
    if file_mu is None or native_mu is None or file_mu <= 0:
        known = file_mu if file_mu is not None else native_mu
        if known is None:
            return f"{head} and their friction scaled to this file's mu"
        return f"{head} and their friction scaled to mu = {number_text(known)}"
    if math.isclose(native_mu, file_mu, rel_tol=1e-9):
        return f"{head} and their friction scaled to the file's mu = {number_text(file_mu)}"
    at_calibration = native_mu / file_mu * CALIBRATION_MU
    return (f"{head} (where MuJoCo's contact needs mu = {number_text(at_calibration)} to "
            f"follow the law's {CALIBRATION_MU:g}) and scaled to the file's mu = "
            f"{number_text(file_mu)}, which gives MuJoCo's contact mu = {number_text(native_mu)}")


def suggestion(native: dict[str, Any], checks: list[dict[str, Any]],
               file_run: dict[str, Any] | None = None,
               file_mu: float | None = None) -> dict[str, Any]:
    """The calibrated native settings that ran, as MJCF to paste, and whether they agree.

    Args:
        native: The calibrated run, ``mujoco/native`` (:func:`run_entry`).
        checks: The verdict's checks (:func:`verdict`).
        file_run: The file's own run, ``mujoco/file``, for the settings that differ from the
            file's.
        file_mu: The file's mu as read from it (default: the file's run's ``mu``).

    Returns:
        ``option`` and ``geom`` (MJCF text), ``where`` (which geoms take the attributes),
        ``changes`` (list of {setting, file, calibrated} where they differ from the file's),
        ``agrees`` (every check of the ``mujoco/native`` run passed), ``departs`` (the checks
        it fails) and ``note`` (one sentence: a fix, or why the calibration does not fix it).
        Empty if the native run failed before it ran.
    """
    s = native
    if s.get("timestep_s") is None:
        return {}

    option, geom = mjcf_attributes(s)
    mine = [c for c in checks if c["run"] == CALIBRATED_RUN]
    departs = [c["check"] for c in mine if c["passed"] is False]
    agrees = bool(mine) and not departs
    paper = [c for c in checks if c["run"] == PAPER_RUN]
    paper_agrees = bool(paper) and all(c["passed"] is not False for c in paper)
    if agrees:
        note = ("with these settings MuJoCo's own friction passes every check against the "
                "theory and the reference: paste them into the file")
    else:
        if file_mu is None and file_run is not None:
            file_mu = file_run.get("mu")
        note = (f"these settings do not fix it: with them MuJoCo still departs in "
                f"{', '.join(departs)}. {scaled_mu_clause(file_mu, s.get('mu'))}: the "
                f"calibration does not carry over to this top")
        if paper_agrees:
            note += ("; the paper's law in the same model (mujoco/paper, the harness's "
                     "callback) does follow the reference")
    return {
        "option": option,
        "geom": geom,
        "where": "on the ball's, the stem's and the table's geoms (MuJoCo mixes the two "
                 "geoms' values of a contact), or on the file's contact pairs if it has any "
                 "(they override the geoms')",
        "changes": setting_changes(file_run, s) if file_run else [],
        "agrees": agrees,
        "departs": departs,
        "note": note,
    }


def candidates(checks: list[dict[str, Any]], sug: Suggestion | None,
               tuned: Tuned, calibrated_mjcf: str | None = None) -> list[ValidateCandidate]:
    """Every set of contact settings validate tried for the file, best evidence first.

    The tuned settings (fitted, verified from every start), the seeds the tuning verified
    when its fit departed (the calibrated settings among them), and the calibrated settings
    as validate ran them from the file's start (``mujoco/native``). Each: ``name``, ``what``,
    ``agrees``, ``passes`` and ``checks`` (the checks that pass, of all run), ``mjcf`` (to
    paste) and ``departs`` (the checks that do not); the calibrated settings, where they
    depart, also ``note`` (why the calibration does not carry over, with its mu and the file's),
    and ``changes`` (each setting they change from the file's: {setting, file, calibrated}).
    ``calibrated_mjcf`` is the calibrated run's block to paste, named with the file's geoms
    (:func:`paste_block`); without it, the suggestion's option and geom attributes.
    """
    out = []
    if isinstance(tuned, TuneResult) and tuned.mjcf:
        n = len(tuned.checked())
        chosen = tuned.fit.chosen
        if chosen == "fit":
            what = f"the tuned settings (fitted with mujoco.sysid, verified from {n} starts)"
        elif widening_step(chosen) is not None:
            what = (f"the tuning's widening, {widening_step(chosen)} (verified from {n} "
                    "starts; the fit's own optimum departs)")
        else:
            what = (f"the tuning's {chosen} (verified from {n} starts; the fit's own optimum "
                    "departs)")
        checked = [c for v in tuned.verified for c in v.checks]
        out.append(ValidateCandidate("tuned", what, bool(tuned.agrees),
                                     sum(c["passed"] is not False for c in checked),
                                     len(checked), tuned.mjcf, tuned.departs))
        for alt in tuned.fit.alternatives:
            if (not alt.mjcf or alt.settings == chosen.removeprefix("seed: ")
                    or alt.what == chosen):  # the answer itself, listed above
                continue
            label = ("the calibrated settings" if alt.calibrated else
                     alt.what or "a seed of the tuning")
            out.append(ValidateCandidate("seed", f"{label}: {alt.settings} (verified from {n} "
                                         "starts)", bool(alt.agrees), int(alt.passes),
                                         int(alt.checks), alt.mjcf, alt.departs))
    if sug is not None:
        mine = [c for c in checks if c["run"] == CALIBRATED_RUN]
        out.append(ValidateCandidate(
            "calibrated", "the calibrated settings (models/calibrated_native.toml, the "
            "tuning's first seed), run from the file's start only", bool(sug.agrees),
            sum(c["passed"] is not False for c in mine), len(mine),
            calibrated_mjcf or f"{sug.option}\n<geom ... {sug.geom}/>", sug.departs,
            changes=sug.changes,
            # why the calibration does not carry over, its mu said
            note=None if sug.agrees else sug.note))
    return out


def answer(checks: list[dict[str, Any]], sug: Suggestion | None,
           tuned: Tuned, calibrated_mjcf: str | None = None) -> ValidateAnswer:
    """The one answer to paste: the file's own settings, the best candidate, or none and why.

    Returns:
        The answer (:class:`ValidateAnswer`): ``agrees`` (what to paste follows the
        reference; also when nothing needs pasting), ``source`` (``file``: the file as it is;
        else the chosen candidate's ``name``, or None), ``label`` (one line: what it is and
        whether it agrees), ``mjcf`` (to paste; None when nothing is), ``why`` (None, or why
        nothing is pasted), ``candidates`` (:func:`candidates`) and ``file`` ({agrees,
        passes, checks}: the file's own runs' checks). ``calibrated_mjcf``: the calibrated
        run's block (:func:`candidates`).
    """
    mine = [c for c in checks if mode_of(c["run"]) == "file"]
    file_ok = bool(mine) and all(c["passed"] is not False for c in mine)
    file_pass = sum(c["passed"] is not False for c in mine)
    found = tuple(candidates(checks, sug, tuned, calibrated_mjcf))
    # the tuning verifies from every start, the calibrated settings among its seeds: where it
    # ran, its candidates are the answers; the calibrated run from the file's start alone is
    # evidence, listed, not an answer (its settings may depart from another start)
    tuned_ran = isinstance(tuned, TuneResult)
    eligible = [c for c in found if c.name != "calibrated"] if tuned_ran else list(found)
    file = FileChecks(file_ok, file_pass, len(mine))

    def said(agrees: bool, source: str | None, mjcf: str | None, why: str | None,
             label: str) -> ValidateAnswer:
        return ValidateAnswer(found, file, agrees, source, mjcf, why, label)

    if file_ok:
        return said(True, "file", None, None,
                    "nothing to paste: the file's own settings follow the reference")
    agreeing = [c for c in eligible if c.agrees]
    if agreeing:
        c = agreeing[0]
        where = ("from every start checked" if c.name != "calibrated" else
                 "from the file's start (tuning skipped: held-out starts not checked)"
                 if isinstance(tuned, TuneSkipped) else "from the file's start")
        return said(True, c.name, c.mjcf, None,
                    f"paste {c.what}: they follow the reference {where}")
    if not eligible:
        why = ("no candidate: the tuning did not run (" + tuned.skipped
               + ") and the calibrated settings did not run"
               if isinstance(tuned, TuneSkipped) else "no candidate settings ran")
        return said(False, None, None, why, f"nothing to paste: {why}")
    best = max(eligible, key=lambda c: c.passes / max(c.checks, 1))
    share = best.passes / max(best.checks, 1)
    if share <= file_pass / max(len(mine), 1):
        why = (f"no candidate passes a larger share of its checks than the file's own "
               f"settings ({file_pass} of {len(mine)}); the closest, {best.what}, passes "
               f"{best.passes} of {best.checks}")
        return said(False, None, None, why, f"nothing to paste: {why}")
    return said(False, best.name, best.mjcf,
                f"no setting tried follows the reference: {len(eligible)} candidate(s) depart",
                f"the closest, NOT agreeing: {best.what}, passing {best.passes} "
                f"of {best.checks} checks (departs in "
                f"{', '.join(dict.fromkeys(best.departs)) or '-'})")


def validate(config: ValidateConfig) -> ValidateResult:
    """Validate one MJCF top (see the module docstring).

    Returns:
        The validation (:class:`ValidateResult`): ``model``, ``runs`` (run, ``ENGINE/MODE``
        -> the simulate summary's keys, ``t_invert``, ``t_stem`` and ``status`` always among
        them, and ``outcome``, ``end_state``, ``ran`` (one line), ``E0_J``, ``error`` (None,
        or why the run could not start), ``note`` (where the run differs from the file's
        settings)),
        ``verdict``, ``agrees`` (no check departs), ``findings``, ``suggestion`` (the
        calibrated settings as they ran), ``tuned``, ``answer`` (the one MJCF block to paste,
        or none and why: :func:`answer`), ``lift``, ``t_end_s`` and ``tables`` (run ->
        observables, not in the JSON: the caller writes them).

    Raises:
        TippetopError: A missing or invalid file, or a bad ``t_end_s`` (before any run).
    """
    expect(config.model.is_file(), "MODEL", "an existing MJCF file", str(config.model))
    expect(math.isfinite(config.t_end_s) and 0 < config.t_end_s <= 600, "--t-end-s",
           "a number of seconds in (0, 600]", config.t_end_s)
    over = _overrides(config)
    plan = Task(None, over, "ode", "paper").plan()  # the file and keyframe, before any run
    loaded = plan_file_info(over)
    # the paper's law runs at a step it can follow: the file's, or the largest 1-2-5 step
    # below the law's limit, which the plan chooses and says (mujoco.fit_paper_timestep)
    paper = (*over, Override.of("mujoco.fit_paper_timestep", True))
    jobs = [(run_key(engine, mode), Task(None, paper if (family, mode) == ("mujoco", "paper")
                                         else over, engine, mode))
            for family, mode in RUNS
            for engine in (config.engines if family == "mujoco" else ("ode",))]
    tasks = [t for _, t in jobs]
    paper_note = "; ".join(next(t for k, t in jobs if k == PAPER_RUN or (
        mode_of(k) == "paper" and engine_of(k) != "ode")).plan().mujoco.notes)
    results = run_tasks(tasks, scheduler=config.scheduler, workers=config.workers,
                        use_cache=config.use_cache, label="validate")
    top = plan.top
    init = plan.init
    J0 = float(theory.jellett_from_spin(top, init.n0, init.theta0, init.Omega0))
    theta_pred, outcome_pred = predicted_outcome(top, J0)
    th = theory.summary(top)
    model = ValidateModel(
        file=str(config.model), R_m=top.R_m, a_m=top.a_m, A=top.A_kgm2, C=top.C_kgm2,
        M_kg=top.M_kg, A_over_C=top.A_over_C, a_over_R=top.a_over_R, mu=loaded["mu"],
        group=th["group"], n1=th["n1"], n4=th["n4"], nc=th["nc"], theta_s=theta_pred,
        theory_outcome=outcome_pred, n0=init.n0, theta0=init.theta0,
        keyframe=loaded["keyframe"], stem=loaded["stem"], stem_note=loaded["stem_note"],
        timestep_s=loaded["timestep_s"])
    runs: dict[str, dict[str, Any]] = {}
    tables = {}
    for (mode, _task), res in zip(jobs, results, strict=True):
        runs[mode] = run_entry(res)
        if runs[mode]["error"]:
            continue
        if mode_of(mode) == "paper" and engine_of(mode) != "ode" and paper_note:
            runs[mode]["note"] = paper_note
        if res.table is not None and len(res.table):
            tables[mode] = res.table
    refit(runs, tables, over, config)
    checks = verdict(runs, outcome_pred, top.A_over_C, reference=REFERENCE_RUN,
                     theta_s=theta_pred)
    tuned = (tune_file(config, over, loaded, plan, runs) if config.tune
             else TuneSkipped("--no-tune"))
    sug_json = (suggestion(runs[CALIBRATED_RUN], checks, runs.get(FILE_RUN),
                           file_mu=loaded["mu"]) if CALIBRATED_RUN in runs else {})
    sug = Suggestion.from_json(sug_json) if sug_json else None
    # the calibrated run set condim, torsional and rolling on every geom (the tuning's keep
    # the file's): its block says so to name each contact as it ran
    pasted = (paste_block(runs[CALIBRATED_RUN], loaded["contacts"], keeps_dims=False)
              if sug is not None else None)
    ans = answer(checks, sug, tuned, pasted or None)
    agreeing = {c["run"] for c in checks} - {c["run"] for c in checks if c["passed"] is False}
    if tuned.agrees:
        agreeing.add("tuned")
    # where nothing agrees and a contact lifts the ball, that is why: the scan asks whether
    # any geom setting can both follow the law and stay on
    lifted = lift_study(runs, tables, top, REFERENCE_RUN, tuned, mu=plan.ode.friction.mu,
                        Lambda_mps=plan.ode.friction.Lambda_mps, scan=not ans.agrees,
                        agrees=agreeing)
    return ValidateResult(
        model=model, t_end_s=config.t_end_s, engines=tuple(config.engines), runs=runs,
        verdict=tuple(checks), agrees=all(c["passed"] is not False for c in checks),
        findings=tuple(findings(runs, checks, top.A_over_C, config.t_end_s)),
        suggestion=sug, tuned=tuned, answer=ans, lift=lifted, tables=tables)


def refit(runs: dict[str, dict[str, Any]], tables: dict[str, Any], over: tuple[Override, ...],
          config: ValidateConfig) -> None:
    """Each MuJoCo run's ``friction_realised.refit`` (:func:`.refit.attach_refits`)."""
    from tippetop.compare.studies.refit import attach_refits

    attach_refits(runs, tables, REFERENCE_RUN,
                  lambda ov: Task(None, (*over, *ov), "ode", "paper"),
                  {"scheduler": config.scheduler, "workers": config.workers,
                   "use_cache": config.use_cache})


def tune_file(config: ValidateConfig, over: tuple[Override, ...], loaded: dict[str, Any],
              plan: Any, runs: dict[str, dict[str, Any]]) -> Tuned:
    """``tuned``: the file's contact settings fitted and verified, or what stopped it.

    See :func:`tippetop.compare.tuning.tune.tune`: fitted to the reference at the file's
    start, verified from held-out starts.
    """
    from tippetop.compare.running.options import RunOptions
    from tippetop.compare.tuning.tune import TuneFile, tune

    if (runs.get(REFERENCE_RUN) or {}).get("status") != "ok":
        return TuneSkipped("the reference run from the file's start did not complete", False)
    top, init = plan.top, plan.init
    file_run = runs.get(FILE_RUN) or {}

    def outcome_at(n0: float, theta0: float, role: str) -> tuple[float | None, str]:
        Omega0 = init.Omega0 if role == "fit" else 0.0
        return predicted_outcome(top, float(theory.jellett_from_spin(top, n0, theta0,
                                                                     Omega0)))

    base = tuple(o for o in over if o.name != "run.t_end_s")
    path = _tune_cache_path(over, config.budget_runs) if config.use_cache else None
    if path is not None and path.is_file():
        try:
            cached = json.loads(path.read_text("utf-8"))
            if isinstance(cached, dict) and cached.get("fit"):
                return replace(TuneResult.from_json(cached), cached=True)
        except (OSError, ValueError, KeyError, TypeError):  # a damaged entry: computed again
            pass
    try:
        out = tune(base, float(loaded["mu"]), init.n0, init.theta0, config.t_end_s,
                   file=TuneFile(run=file_run, timestep_s=file_run.get("timestep_s"),
                                 integrator=file_run.get("integrator"),
                                 A_over_C=top.A_over_C, theory=outcome_at,
                                 contacts=loaded.get("contacts")),
                   run=RunOptions(scheduler=config.scheduler, workers=config.workers,
                                  use_cache=config.use_cache, progress=config.progress),
                   budget_runs=config.budget_runs)
    except TippetopError as exc:
        return TuneSkipped(str(exc), False)
    if path is not None:
        from tippetop.compare.running.io import json_ready, write_atomic

        text = json.dumps(json_ready(out))
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda tmp: tmp.write_text(text, "utf-8"))
    return replace(out, cached=False)


def _tune_cache_path(over: tuple[Override, ...], budget_runs: int = TUNE_BUDGET_RUNS) -> Path:
    """Where a tuning is kept in the cache.

    Keyed by the file's run plan (its MJCF text, start and horizon), the run budget and the
    code, as every cached run.
    """
    import hashlib

    from tippetop.compare.running.runner import code_fingerprint
    from tippetop.compare.tuning.tune import source_digest
    from tippetop.models.resources import user_cache_dir

    plan = Task(None, over, "mujoco", "file").plan()
    # the runs' code, and the tuning's own (which the runs' fingerprint does not hold)
    own = source_digest()
    key = hashlib.sha256(json.dumps({"plan": plan.to_json(), "code": code_fingerprint(),
                                     "tune": own, "what": "tune/1",
                                     "budget_runs": budget_runs}, sort_keys=True,
                                    default=str).encode()).hexdigest()[:32]
    return user_cache_dir() / "tune" / f"{key}.json"


def tune_only(model: Path, t_end_s: float, *, scheduler: str | None = None,
              workers: int | None = None, use_cache: bool = True,
              progress: bool = True, budget_runs: int = TUNE_BUDGET_RUNS) -> TuneOnlyResult:
    """``tippetop calibrate --mjcf FILE``: the file's contact settings tuned, no report.

    The reference and the file's own run at its start, then :func:`tune_file` (no paper or
    calibrated runs).

    Raises:
        TippetopError: A missing or invalid file (before any run).
    """
    expect(model.is_file(), "--mjcf", "an existing MJCF file", str(model))
    config = ValidateConfig(model=model, t_end_s=t_end_s, scheduler=scheduler,
                            workers=workers, use_cache=use_cache, progress=progress,
                            budget_runs=budget_runs)
    over = _overrides(config)
    plan = Task(None, over, "ode", "paper").plan()
    loaded = plan_file_info(over)
    results = run_tasks([Task(None, over, "ode", "paper"), Task(None, over, "mujoco", "file")],
                        scheduler=scheduler, workers=workers, use_cache=use_cache,
                        label="calibrate --mjcf")
    runs = {REFERENCE_RUN: run_entry(results[0]), FILE_RUN: run_entry(results[1])}
    return TuneOnlyResult(str(model), loaded["mu"], plan.init.n0, plan.init.theta0, t_end_s,
                          tune_file(config, over, loaded, plan, runs))


def plan_file_info(overrides: tuple[Override, ...]) -> dict[str, Any]:
    """The file's mu, keyframe and stem as the plan reads them, and its contacts.

    ``contacts``: the file's contacts with its geoms' names, places, margins and gaps, which
    the blocks to paste name (:class:`FileContacts`).
    """
    from tippetop.compare.measures.summary import FileContacts
    from tippetop.models.scene import load_scene
    from tippetop.mujoco_runner.model import load_model
    from tippetop.mujoco_runner.state import file_top

    scene = load_scene(None, list(overrides))
    if scene.top_mjcf is None:  # pragma: no cover - the overrides always set it
        raise TippetopError("validate: expected an MJCF top")
    ft = file_top(scene.top_mjcf)
    key = scene.init_keyframe or (ft.keyframes[0] if ft.keyframes else None)
    stem = ft.stem
    return {"mu": ft.mu, "keyframe": key, "timestep_s": ft.timestep_s,
            "stem": None if stem is None else {"kind": stem.kind, "offset_m": stem.offset_m,
                                               "radius_m": stem.radius_m},
            "stem_note": ft.stem_note,
            "contacts": FileContacts.of_model(load_model(ft.path), ft.contacts)}


__all__ = ["DEFAULT_T_END_S", "ENERGY_RISE_FLOOR", "EVENT_RTOL", "EVENT_TOL_S", "FIRST_ORDER",
           "ISOTROPIC_TOL", "J_TOL", "MUJOCO_MODES", "REFERENCE_RUN", "RUNS", "ValidateConfig",
           "engine_of", "findings",
           "gyroscopic_drift", "mode_of", "run_entry", "run_key", "scaled_mu_clause",
           "show_setting", "show_value", "suggestion", "validate", "verdict"]
