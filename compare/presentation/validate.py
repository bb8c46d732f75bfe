"""What ``tippetop validate`` and ``tippetop calibrate --mjcf`` print.

The verdict with each departing check, the file's findings, the realised friction law, the
tuned settings and each start's verification, the candidates tried, the contact's lift and,
last, what to paste (:func:`print_validate`); a tuning alone (:func:`print_tune_only`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tippetop.compare.presentation.terminal import (
    check_note,
    check_text,
    fmt,
    fmt_duration,
    wrapped,
)
from tippetop.compare.results.tune import Tuned, TuneOnlyResult, TuneSkipped, start_label
from tippetop.compare.results.validate import ValidateModel, ValidateResult
from tippetop.models.numbers import solver_text


def show_value(v: Any) -> str:
    """A setting as the report and the terminal show it: ``0.02``, ``[0.02, 1]``, ``RK4``."""
    if isinstance(v, list | tuple):
        return "[" + ", ".join(f"{x:g}" for x in v) + "]"
    return f"{v:g}" if isinstance(v, float) else str(v)


def show_setting(setting: str, v: Any) -> str:
    """A setting of validate's ``SETTINGS`` with its units: ``0.002 s``, ``[0.02 s, 1]``.

    solref's first number is a time (s) when it is positive (MuJoCo's timeconst, dampratio;
    negative, it is a stiffness and a damping); solimp's third is a width (m).
    """
    if setting == "timestep_s" and isinstance(v, int | float):
        return f"{v:g} s"
    if setting in ("solref", "solimp") and isinstance(v, list | tuple):
        return f"[{solver_text(setting, v)}]"
    return show_value(v)


def model_line(m: ValidateModel) -> str:
    """The top as read from the file, and the theory's outcome: every number with its unit.

    A/C and a/R are ratios and mu a coefficient (no unit); a value the file does not give says
    so.
    """
    mu = (fmt(float(m.mu)) if m.mu is not None
          else "not read (the file's ball geom gives no friction)")
    theta_s = (f"theta_s = {fmt(float(m.theta_s), 'rad')}" if m.theta_s is not None
               else "no theta_s for this spin")
    return (f"tippetop validate {m.file}: Group {m.group}, A/C = {m.A_over_C:.4g}, "
            f"a/R = {m.a_over_R:.4g}, mu = {mu}, n0 = {fmt(float(m.n0), 'rad/s')}: the "
            f"theory says {m.theory_outcome} ({theta_s})")


def print_friction(runs: dict[str, dict[str, Any]]) -> None:
    """The law each MuJoCo run realised, and whether the refit reference explains the run."""
    from tippetop.compare.measures.friction_realised import realised_sentence

    lines = []
    for mode, r in runs.items():
        fr = r.get("friction_realised")
        if mode.startswith("ode/") or not fr:
            continue
        lines.append(f"    {realised_sentence(mode, fr)}")
        refit = fr.get("refit")
        if refit:
            lines.append(f"      refit: {refit['sentence']}")
            if refit.get("remains"):
                lines.append("      what else differs: " + ", ".join(refit["remains"]))
    if lines:
        from tippetop.compare.measures.friction_realised import SENTENCE_TERMS

        print("  the friction law as each run realises it (the ball's phase):")
        print("\n".join(lines))
        print(wrapped(f"({SENTENCE_TERMS})", indent="    "))


def print_validate(res: ValidateResult, out: Path | None) -> None:
    """A validation for a person: the verdict, what departs and why, and what to paste last.

    Args:
        res: The validation.
        out: The report's folder, if one was written.
    """
    checks = res.verdict
    n_pass = sum(c["passed"] is not False for c in checks)
    print(model_line(res.model))
    print(f"verdict: {'AGREES' if res.agrees else 'DEPARTS'} ({n_pass} of {len(checks)} "
          f"checks pass, {res.t_end_s:g} s simulated)")
    width = max(len(c["check"]) for c in checks)
    mwidth = max(len(c["run"]) for c in checks)
    for c in checks:
        if c["passed"] is False:
            shown = check_text(c, res.t_end_s, res.runs)
            why = f"; {note}" if (note := check_note(c)) else ""
            print(f"  departs: {c['run']:<{mwidth}} {c['check']:<{width}}  {shown}  "
                  f"(tolerance {c['tolerance']}{why})")
    for mode, r in res.runs.items():
        if r.get("note"):
            print(f"  note: {mode}: {r['note']}")
    for f in res.findings:
        print(f"  the file's own settings: {f}")
    print_friction(res.runs)
    print_tuned(res.tuned, show_mjcf=False)
    _print_candidates(res)
    lifted = res.lift
    if lifted.sentences or lifted.scan:
        print("  the contact's lift (MuJoCo's soft contact turns friction into normal force):")
        for line in lifted.sentences:
            print(f"    {line}")
        if lifted.scan:
            print(f"    {lifted.scan['sentence']}")
    if out is not None:
        print(f"report: {out / 'report.html'}")
    # the last lines: the file's verdict and what to paste
    ans = res.answer
    f = ans.file
    print(f"the file: {'AGREES' if f.agrees else 'DEPARTS'} ({f.passes} of "
          f"{f.checks} of its checks pass)")
    print(ans.label + (":" if ans.mjcf else ""))
    for line in (ans.mjcf or "").splitlines():
        print(f"    {line}")


def _print_candidates(res: ValidateResult) -> None:
    """Every set of settings tried: agrees or departs, its checks, what it changes."""
    tried = res.answer.candidates
    if not tried:
        return
    print("  candidates tried:")
    for c in tried:
        state = "agrees" if c.agrees else "departs"
        print(f"    {c.what}: {state}, {c.passes} of {c.checks} checks pass")
        if c.note:
            print(f"      {c.note}")
        if c.changes:
            print("      changes from the file's: " + "; ".join(
                f"{ch.setting} {show_setting(ch.setting, ch.file)} -> "
                f"{show_setting(ch.setting, ch.calibrated)}"
                for ch in c.changes))


def print_tuned(tuned: Tuned | None, indent: str = "  ", *, show_mjcf: bool = True) -> None:
    """The tuned settings: the fit, the MJCF (``show_mjcf``), each start's verification."""
    if tuned is None:
        return
    if isinstance(tuned, TuneSkipped):
        print(f"{indent}tuned settings: not run ({tuned.skipped})")
        return
    fit = tuned.fit
    start = fit.starts[0]
    limited = " (budget-limited)" if tuned.budget_limited else ""
    print(f"{indent}tuned settings: {'AGREE' if tuned.agrees else 'DEPART'}{limited}: "
          f"{tuned.note}")
    print(f"{indent}  fitted at {start_label(start.n0, start.theta0)} over "
          f"{fmt(start.t_end_s, 's')}: residual "
          f"{fmt(fit.residual, 'rad')} (theta and J), {fit.runs} MuJoCo runs"
          f"{' of --budget-runs ' + str(fit.budget_runs) if fit.budget_runs else ''}, "
          f"{fmt_duration(fit.wall_s)} (mujoco.sysid"
          f"{'; from the cache' if tuned.cached else ''})")
    if show_mjcf:
        for line in tuned.mjcf.splitlines():
            print(f"{indent}  {line}")
    base_t_end = min((v.t_end_s for v in tuned.verified if v.t_end_s), default=None)
    for v in tuned.verified:
        where = f"{v.label()} ({v.role})"
        if v.t_end_s and base_t_end and v.t_end_s > base_t_end * (1 + 1e-9):
            where += (f" over {fmt(v.t_end_s, 's')}, its reference still moving at "
                      f"{fmt(base_t_end, 's')}")
        if v.passed is None:
            state = v.note if v.note is not None else "not verified"
        elif v.passed:
            state = f"passes all {len(v.checks)} checks"
        else:
            state = "departs in " + ", ".join(v.failed_checks())
        print(f"{indent}  from {where}: {state}")


def print_tune_only(res: TuneOnlyResult) -> None:
    """``tippetop calibrate --mjcf FILE``: the file's start, then its tuned settings."""
    print(f"tippetop calibrate --mjcf {res.file}: mu = {res.mu}, "
          f"{start_label(res.n0, res.theta0)}")
    print_tuned(res.tuned, indent="")


__all__ = ["model_line", "print_friction", "print_tune_only", "print_tuned",
           "print_validate", "show_setting", "show_value"]
