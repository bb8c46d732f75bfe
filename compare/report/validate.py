"""The validation report of one MJCF top: a self-contained HTML page, the verdict first."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.measures.friction_realised import realised_sentence
from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.presentation.terminal import (
    check_note,
    check_text,
    fmt,
    fmt_duration,
    within_run,
)
from tippetop.compare.report.figures import friction_law_figure
from tippetop.compare.report.groupmap import draw_groups
from tippetop.compare.report.markup import Cell, Html, esc, fmt_num, html_table, page, png
from tippetop.compare.results.tune import TuneSkipped, start_label
from tippetop.compare.results.validate import ValidateResult
from tippetop.compare.studies.validate import (
    REFERENCE_RUN,
    RUNS,
    engine_of,
    mode_of,
)

_COLOURS = {"mujoco/file": "#d62728", "ode/paper": "#111111", "mujoco/paper": "#1f77b4",
            "mujoco/native": "#2ca02c"}
#: What each mode of a validation's runs is, in words.
_LABELS = {"file": "MuJoCo, the file's own settings", "paper": "MuJoCo, the paper's law",
           "native": "MuJoCo, calibrated"}
_CHECKS = {"completed": "the run completed",
           "outcome": "outcome against the theory (the reference's, for a top on its stem)",
           "stays_on_table": "the ball stays on the table (as the reference's)",
           "t_invert": "inversion time against the reference's",
           "t_stem": "first stem contact against the reference's",
           "jellett_before_stem": "Jellett's drift while the ball alone touches (relative)",
           "energy_never_rises": "energy never rises (its largest rise, of E0)"}


def _keys(res: ValidateResult) -> list[str]:
    """The runs' keys in the page's order: each mode, then its runs on other engines."""
    keys = list(res.runs)
    return [k for fam, m in RUNS for k in keys
            if mode_of(k) == m and (engine_of(k) == "ode") == (fam == "ode")]


def _label(key: str) -> str:
    engine, mode = engine_of(key), mode_of(key)
    if engine == "ode":
        return "reference ODE"
    return _LABELS.get(mode, key) + (f" [{engine}]" if engine != "mujoco" else "")


_OTHER = ("#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf", "#bcbd22")


def _colour(key: str, keys: list[str]) -> str:
    if key in _COLOURS:
        return _COLOURS[key]
    others = [k for k in keys if k not in _COLOURS]
    return _OTHER[others.index(key) % len(_OTHER)]


def _cell(check: Mapping[str, Any], t_end_s: float | None = None,
          runs: Mapping[str, Any] | None = None) -> Html:
    """A check's cell: its value with its unit, or why there is none (never ``-`` alone)."""
    shown = esc(check_text(dict(check), t_end_s, dict(runs) if runs is not None else None))
    cls, mark = {True: ("pass", "agrees"), False: ("fail", "departs")}.get(
        check["passed"], ("", "not judged"))
    note = f"<br><small>{esc(why)}</small>" if (why := check_note(dict(check))) else ""
    return Cell(f"{shown} ({mark}){note}", cls)


def verdict_section(res: ValidateResult) -> str:
    """The verdict: one row per check, one column per mode; then findings and the fix."""
    checks = res.verdict
    modes = _keys(res)
    names = list(dict.fromkeys(c["check"] for c in checks))
    rows = []
    for name in names:
        row: list[Any] = [_CHECKS.get(name, name)]
        tol = next(c["tolerance"] for c in checks if c["check"] == name)
        for m in modes:
            c = next((c for c in checks if c["check"] == name and c["run"] == m), None)
            row.append(_cell(c, res.t_end_s, res.runs) if c else
                       "the reference itself" if m == REFERENCE_RUN else "not checked")
        row.append(tol)
        rows.append(row)
    n_pass = sum(c["passed"] is not False for c in checks)
    ok = res.agrees
    head = (f"<p><span class='verdict {'ok' if ok else 'bad'}'>"
            f"{'AGREES' if ok else 'DEPARTS'}</span> {n_pass} of {len(checks)} checks pass "
            f"against the paper's theory and the reference ODE "
            f"({res.t_end_s:g} s simulated).</p>")
    parts = ["<section id='verdict'><h2>Verdict</h2>", head,
             html_table(["check", *(_label(m) for m in modes), "tolerance"], rows)]
    if res.findings:
        parts.append("<h3>What the file's own settings get wrong</h3><ul>"
                     + "".join(f"<li>{esc(f)}</li>" for f in res.findings) + "</ul>")
    parts.append(answer_html(res))
    parts.append("</section>")
    return "".join(parts)


#: Where a pasted block goes.
_WHERE = ("paste it as it is inside the file's <mujoco> element (before </mujoco>, say): its "
          "<option> sets only the options it names, and each of its contact pairs makes one "
          "contact of the top with the table as the run had it, whatever the geoms' own "
          "attributes (a pair supersedes them); its comments say which of the file's own pairs "
          "it replaces and which unnamed geoms it names")


def answer_html(res: ValidateResult) -> str:
    """What to paste: one MJCF block (or none, and why), and every candidate tried."""
    ans = res.answer
    cls = "ok" if ans.agrees else "bad"
    parts = [f"<h3 id='paste'>What to paste</h3><p><span class='verdict {cls}'>"
             f"{'AGREES' if ans.agrees else 'NONE AGREES'}</span> {esc(ans.label)}.</p>"]
    if ans.mjcf:
        parts.append(f"<p class='note'>As MJCF; {esc(_WHERE)}:</p><pre>{esc(ans.mjcf)}</pre>")
    tried = ans.candidates
    if tried:
        rows = [(Cell(esc(c.what), "pass" if c.agrees else "fail"),
                 "agrees" if c.agrees else "departs", f"{c.passes} of {c.checks}",
                 ", ".join(dict.fromkeys(c.departs)) or "none") for c in tried]
        parts.append("<p class='note'>The settings tried:</p>"
                     + html_table(["candidate", "verdict", "checks passed", "departs in"],
                                  rows))
    return "".join(parts)


def tuned_section(res: ValidateResult) -> str:
    """The tuned settings: the MJCF to paste, the fit, each start's checks."""
    t = res.tuned
    if isinstance(t, TuneSkipped):
        return (f"<section id='tuned'><h2>Tuned settings</h2><p class='note'>Not run: "
                f"{esc(t.skipped)}.</p></section>")
    fit = t.fit
    start = fit.starts[0]
    ok = t.agrees
    head = (f"<p><span class='verdict {'ok' if ok else 'bad'}'>"
            f"{'AGREE' if ok else 'DEPART'}</span> {esc(t.note)}.</p>")
    how = (f"<p class='note'>The file's contact settings fitted to the reference at its own "
           f"start ({start_label(start.n0, start.theta0)}, "
           f"over {fmt(start.t_end_s, 's')}) with MuJoCo's identification (mujoco.sysid): "
           f"residual {fmt(fit.residual, 'rad')} ({esc(fit.residual_definition)}), "
           f"{fit.runs} MuJoCo runs, {fmt_duration(fit.wall_s)}; then run by the "
           f"harness from every start "
           f"below over {res.t_end_s:g} s and checked as the verdict checks (what to paste: "
           f"<a href='#paste'>above</a>).</p>")
    names = list(dict.fromkeys(c["check"] for v in t.verified for c in v.checks))
    rows = []
    for v in t.verified:
        row: list[Any] = [v.label(), v.role]
        by = {c["check"]: c for c in v.checks}
        row += [_cell(by[n], res.t_end_s) if n in by else "not checked" for n in names]
        if v.passed is None:
            row[-1] = v.note if v.note is not None else "not verified"
        rows.append(row)
    needs = "".join(
        f"<li>{esc(n.integrator)} at dt = {n.timestep_s:g} s: "
        f"{'kept' if n.kept else 'not kept: ' + esc(n.why)}</li>"
        for n in fit.needs)
    needs_html = (f"<p class='note'>The file's own integrator and step, tried with the fitted "
                  f"contact (the fit ran {esc(fit.integrator)} at dt = "
                  f"{fit.timestep_s:g} s):</p><ul>{needs}</ul>" if needs else "")
    return ("<section id='tuned'><h2>Tuned settings for this top</h2>" + head + how
            + html_table(["start", "role", *(_CHECKS.get(n, n) for n in names)], rows)
            + needs_html + "</section>")


def model_section(res: ValidateResult) -> str:
    """The top's parameters read from the file and the theory's numbers."""
    m = res.model
    group = f"none for a Group {m.group} top"
    rows = [("file", m.file), ("R (m)", m.R_m), ("a (m)", m.a_m),
            ("A (kg m^2)", m.A), ("C (kg m^2)", m.C), ("M (kg)", m.M_kg),
            ("A/C", m.A_over_C), ("a/R", m.a_over_R),
            ("mu (ball on table)", _or(m.mu, "not read: the ball geom gives no friction")),
            ("timestep (s)", _or(m.timestep_s, "not read from the file")),
            ("start (keyframe)", m.keyframe or "the scene's state"),
            ("n0 (rad/s)", m.n0), ("theta0 (rad)", m.theta0),
            ("group", m.group), ("n1 (rad/s)", _or(m.n1, group)),
            ("n4 (rad/s)", _or(m.n4, group)), ("n_c (rad/s)", _or(m.nc, group)),
            ("theta_s for this spin (rad)", _or(m.theta_s, "none for this spin")),
            ("the theory's outcome", m.theory_outcome),
            ("stem", _or(m.stem_note, "none in the file"))]
    return ("<section id='model'><h2>The top, read from the file</h2>"
            + html_table(["what", "value"], rows) + "</section>")


def _or(value: Any, why: str) -> Any:
    """A cell's value, or why there is none (never a bare ``-``)."""
    return why if value is None else value


def runs_section(res: ValidateResult) -> str:
    """What each run ran and how it ended; a missing number says why."""
    rows = []
    within = within_run(res.t_end_s)
    for m in _keys(res):
        r = res.runs[m]
        s = r
        failed = "the run failed" if r.get("error") or s.get("theta_final") is None else None
        note = f"<br><small>{esc(r['note'])}</small>" if r.get("note") else ""
        drift = s.get("J_rel_drift")
        rows.append((_label(m), Html(f"<div class='wide'>{esc(r['ran'] or '-')}{note}</div>"),
                     s.get("status", r.get("error")),
                     _or(s.get("t_invert"), failed or f"does not turn over {within}"),
                     _or(s.get("t_stem"), failed or f"no stem contact {within}"),
                     _or(s.get("theta_final"), failed or "not measured"),
                     _or(r.get("end_state"), failed or "not measured"),
                     (Html(fmt_num(drift, ".2e")) if math.isfinite(drift) else fmt(drift))
                     if drift is not None else
                     (failed or "not measured: the ball alone never touched before the stem")))
    return ("<section id='runs'><h2>The runs</h2>"
            + html_table(["run (engine/mode)", "what ran", "status", "t_invert (s)", "t_stem (s)",
                          "theta_final (rad)", "ends", "J drift before the stem (relative)"],
                         rows)
            + "</section>")


def theta_section(res: ValidateResult, tables: Mapping[str, pd.DataFrame]) -> str:
    """theta(t) of every run, and each MuJoCo run minus the reference underneath."""
    plt = pyplot()
    fig, (ax, ax_d) = plt.subplots(2, 1, figsize=(9.5, 6.2), sharex=True,
                                   gridspec_kw={"height_ratios": [3, 2]})
    ref = tables.get(REFERENCE_RUN)
    keys = _keys(res)
    for m in keys:
        t = tables.get(m)
        if t is None:
            continue
        ax.plot(t["t"], t["theta"], color=_colour(m, keys), lw=1.4 if m == REFERENCE_RUN
                else 1.0,
                label=_label(m))
        t_stem = res.runs[m].get("t_stem")
        if t_stem is not None:
            ax.axvline(t_stem, color=_colour(m, keys), ls=":", lw=0.8)
        if ref is not None and m != REFERENCE_RUN:
            d = t["theta"].to_numpy() - np.interp(t["t"], ref["t"], ref["theta"])
            ax_d.plot(t["t"], d, color=_colour(m, keys), lw=1.0)
    ax.axhline(math.pi / 2, color="0.7", lw=0.8, ls="--")
    ax.set_ylabel("theta (rad)")
    ax.set_ylim(-0.1, math.pi + 0.1)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax_d.axhline(0.0, color="0.5", lw=0.8)
    ax_d.set_ylabel("MuJoCo - reference (rad)")
    ax_d.set_xlabel("t (s)")
    fig.tight_layout()
    return ("<section id='theta'><h2>theta(t)</h2><p class='note'>Dotted lines: each run's "
            "first stem contact. Below: each MuJoCo run minus the reference.</p>"
            + png(fig) + "</section>")


def friction_section(res: ValidateResult, tables: Mapping[str, pd.DataFrame]) -> str:
    """The friction law as each run realises it: |F_t| / (mu N) against the slip speed.

    Each run's samples as points (log slip axis), the paper's law as the curve, and a sentence
    with the numbers per run (``friction_realised``).
    """
    keys = [k for k in _keys(res) if k in tables and res.runs[k].get("friction_realised")]
    if not keys:
        return ""
    fig = friction_law_figure([(_label(k), _colour(k, keys), tables[k],
                                res.runs[k]["friction_realised"]) for k in keys])

    def sentence(k: str) -> str:
        fr = res.runs[k]["friction_realised"]
        refit = (fr.get("refit") or {}).get("sentence")
        remains = (fr.get("refit") or {}).get("remains") or []
        more = f"<br><span class='note'>Refit: {esc(refit)}.</span>" if refit else ""
        if remains:
            more += (f"<br><span class='note'>What else differs: {esc(', '.join(remains))} "
                     "(Jellett's drift: a torque off the contact point, or a first-order "
                     "integrator on a top with A != C).</span>")
        return f"<li>{esc(realised_sentence(_label(k), fr))}{more}</li>"

    lines = "".join(sentence(k) for k in keys)
    return ("<section id='friction'><h2>The friction law as each run realises it</h2>"
            "<p class='note'>Each sample that touches and slips while the ball alone touches "
            "(before the stem): the friction force at the contact over mu N, against the slip "
            "speed; the curve is the paper's law. Refit: the reference run again with the law "
            "each run realised; if it turns over and brings the stem down when the run does "
            "(within the nightly's tolerances), the friction law is the difference.</p>"
            + fig + f"<ul>{lines}</ul></section>")


def groups_section(res: ValidateResult) -> str:
    """The top's place on the paper's group diagram."""
    plt = pyplot()
    m = res.model
    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    x, y = m.a_over_R, m.A_over_C
    draw_groups(ax, (0.0, max(0.5, 1.3 * x)), (0.5, max(1.6, 1.2 * y)))
    ax.plot([x], [y], "k*", ms=14)
    ax.annotate(f"this top (Group {m.group})", (x, y), xytext=(8, 8),
                textcoords="offset points", fontsize=9)
    for label, (gx, gy) in (("I", (0.05, 0.65)), ("II", (0.05, 1.0)), ("III", (0.05, 1.45))):
        ax.text(gx, gy, f"Group {label}", fontsize=8, color="0.3")
    fig.tight_layout()
    return ("<section id='groups'><h2>The group diagram</h2>" + png(fig) + "</section>")


def render(res: ValidateResult, tables: Mapping[str, pd.DataFrame] | None = None) -> str:
    """The page's HTML: verdict, model, runs, theta(t), group diagram.

    Args:
        res: The validation.
        tables: Each run's observables (default: the validation's own).
    """
    tables = res.tables if tables is None else tables
    title = f"tippetop validate: {res.model.file}"
    body = [f"<h1>{esc(title)}</h1>", verdict_section(res), tuned_section(res),
            model_section(res),
            runs_section(res), theta_section(res, tables), friction_section(res, tables),
            groups_section(res)]
    return page(title, body)


__all__ = ["render"]
