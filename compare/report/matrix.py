"""``tippetop matrix``'s report.html: verdict first, then what changes between engines.

A column per engine in the verdict table; the differences with their attribution and which
engine is closer; theta(t) of every engine with a difference panel; then what ran.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.report.figures import friction_law_figure
from tippetop.compare.report.markup import Html, esc, fmt_num, html_table, page, png
from tippetop.compare.results.matrix import MatrixResult, MatrixRun
from tippetop.compare.studies.matrix import table_key

_UNITS = {"theta_asymp": "rad", "theta_final": "rad", "t_invert": "s", "t_stem": "s"}
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2")


def _value(metric: str, v: Any) -> str:
    if isinstance(v, float):
        return fmt_num(v, ".4g", _UNITS.get(metric, ""))
    return fmt_num(v)


def _cell(run: MatrixRun) -> tuple[Html, str]:
    if not run.ran:
        return Html(f"&#x2716; {esc(run.status)}<br><span class='j'>"
                    f"{esc((run.message or '')[:120])}</span>"), "failed"
    cls = "agree" if run.agrees else "depart"
    mark = "" if run.agrees else "&ne; "
    text = (f"{mark}{esc(run.outcome)}<br><span class='j'>theta_asymp "
            f"{_value('theta_asymp', run.theta_asymp)}, t_invert "
            f"{_value('t_invert', run.t_invert)}</span>")
    return Html(text), cls


def verdict_section(res: MatrixResult) -> str:
    """One row per (scene, mode), one column per engine: agrees with the theory or not."""
    engines = [e.engine for e in res.engines]
    by = {(r.scene, r.mode, r.engine): r for r in res.runs}
    rows = []
    for scene in res.scenes:
        for mode in res.modes:
            if not any((scene, mode, e) in by for e in engines):
                continue  # this scene does not run in this mode (an MJCF top runs file)
            row: list[Any] = [scene, mode]
            for spec in engines:
                run = by.get((scene, mode, spec))
                if run is None:
                    row.append("-")
                    continue
                cell, cls = _cell(run)
                row.append(Html(f"<div class='{cls}'>{cell}</div>"))
            ref = res.reference.get(scene)
            outcome, theta_s = (None, None) if ref is None else (ref.theory_outcome, ref.theta_s)
            row.append(Html(f"{esc(outcome)}<br><span class='j'>theta_s "
                            f"{_value('theta_asymp', theta_s)}</span>"))
            rows.append(row)
    agree = sum(r.agrees for r in res.runs)
    failed = len(res.failed_runs())
    n_diff = len(res.differences)
    ok = agree == len(res.runs) and not failed
    head = (f"<p><span class='verdict {'ok' if ok else 'bad'}'>"
            f"{'ALL AGREE' if ok else 'SOME DEPART'}</span> {agree} of {len(res.runs)} "
            f"runs agree with the theory (its outcome, and theta_asymp within 0.05 rad of "
            f"theta_s), {failed} failed; {n_diff} difference{'s' if n_diff != 1 else ''} "
            "between engines beyond the nightly's tolerances.</p>")
    return ("<section id='verdict'><h2>Against the theory</h2>" + head
            + html_table(["scene", "mode", *engines, "theory"], rows) + "</section>")


def differences_section(res: MatrixResult) -> str:
    """Every difference, what it follows (the reruns' evidence) and which engine is closer."""
    diffs = res.differences
    parts = ["<section id='differences'><h2>What changes between engines</h2>"]
    if not diffs:
        parts.append("<p>Nothing: every pair of engines agrees on every metric within the "
                     "nightly's tolerance.</p></section>")
        return "".join(parts)
    tol = res.tolerances
    parts.append("<p class='note'>Tolerances: "
                 + "; ".join(f"{esc(k)}: {esc(v['why'])}" for k, v in tol.items()) + "</p>")
    for d in diffs:
        (a, b), (va, vb) = d.engines, d.values
        m = d.metric
        parts.append(f"<h3>{esc(d.scene)} {esc(d.mode)}: {esc(m)}</h3>"
                     f"<p>{esc(a)}: <b>{_value(m, va)}</b>, {esc(b)}: <b>{_value(m, vb)}</b>"
                     + (f" (tolerance {_value(m, d.tolerance)})"
                        if d.tolerance is not None else "") + "</p>")
        att, near = d.attribution, d.closer
        if att:
            parts.append(f"<p>Follows: {esc(att.follows)}</p>")
            rows = []
            for e in att.evidence:
                if not e.applies:
                    rows.append((e.change, "-", "-", "-", "-", f"n/a: {e.why}"))
                    continue
                rows.append((e.change, Html(_value(m, e.a)), Html(_value(m, e.b)),
                             Html(fmt_num(e.difference, ".3g")),
                             Html(fmt_num(e.theta_gap_rad, ".3g", "rad")),
                             "failed: " + e.failed if e.failed
                             else "agree" if e.agree else "differ"))
            parts.append(html_table(["change (both engines)", a, b, "|a - b|",
                                     "max |theta_a - theta_b|", "within tolerance"], rows,
                                    ["pass" if r[-1] == "agree" else "" for r in rows]))
        if near:
            conv = near.converged or {}
            parts.append(
                "<p class='note'>Closer to the reference ODE "
                f"({_value(m, near.reference_value)}): "
                f"<b>{esc(near.reference or 'n/a')}</b>; closer to its own answer at a "
                f"quarter of the timestep: <b>{esc(near.converged_nearer or 'n/a')}</b>"
                + (" (" + ", ".join(f"{esc(k)} {fmt_num(v, '.3g')}" for k, v in conv.items())
                   + ")" if conv else "") + ".</p>")
    parts.append("</section>")
    return "".join(parts)


def theta_section(res: MatrixResult, tables: Mapping[str, pd.DataFrame]) -> str:
    """theta(t) of every engine per (scene, mode), the reference dashed.

    Below it, each engine minus the first engine.
    """
    plt = pyplot()
    engines = [e.engine for e in res.engines]
    parts = ["<section id='theta'><h2>theta(t) on every engine</h2><p class='note'>Dashed: "
             f"the reference ODE. Below: each engine minus {esc(engines[0])}.</p>"]
    for scene in res.scenes:
        for mode in res.modes:
            got = [(spec, tables.get(table_key(scene, mode, spec))) for spec in engines]
            got = [(s, t) for s, t in got if t is not None and len(t)]
            if not got:
                continue
            fig, (ax, ax_d) = plt.subplots(2, 1, figsize=(9.0, 5.0), sharex=True,
                                           gridspec_kw={"height_ratios": [3, 2]})
            ref = tables.get(table_key(scene, "ode", "ode"))
            if ref is not None and len(ref):
                ax.plot(ref["t"], ref["theta"], color="0.15", lw=1.2, ls="--",
                        label="reference ODE")
            base = got[0][1]
            for i, (spec, t) in enumerate(got):
                colour = _COLOURS[i % len(_COLOURS)]
                ax.plot(t["t"], t["theta"], color=colour, lw=1.0, label=spec)
                if i:
                    d = t["theta"].to_numpy() - np.interp(t["t"], base["t"], base["theta"])
                    ax_d.plot(t["t"], d, color=colour, lw=1.0, label=f"{spec} - {got[0][0]}")
            ax.axhline(math.pi / 2, color="0.7", lw=0.8, ls=":")
            ax.set_ylabel("theta (rad)")
            ax.set_title(f"{scene}, {mode} mode", fontsize=10)
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
            ax_d.axhline(0.0, color="0.5", lw=0.8)
            ax_d.set_ylabel("difference (rad)")
            ax_d.set_xlabel("t (s)")
            if len(got) > 1:
                ax_d.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
            fig.tight_layout()
            parts.append(png(fig))
    parts.append("</section>")
    return "".join(parts)


def friction_section(res: MatrixResult, tables: Mapping[str, pd.DataFrame]) -> str:
    """The friction law as each engine realises it: |F_t| / (mu N) against the slip.

    Per scene of MuJoCo's own friction: each engine's samples as points, the paper's law as
    the curve, and a sentence per run.
    """
    from tippetop.compare.measures.friction_realised import realised_sentence

    engines = [e.engine for e in res.engines if e.engine != "ode"]
    by = {(r.scene, r.mode, r.engine): r for r in res.runs}
    parts: list[str] = []
    items: list[str] = []
    for scene in res.scenes:
        for mode in (m for m in res.modes if m != "paper"):
            got = []
            for i, spec in enumerate(engines):
                run, t = by.get((scene, mode, spec)), tables.get(table_key(scene, mode, spec))
                fr = (run.friction_realised if run is not None else None) or {}
                if t is None or not len(t) or not fr.get("samples"):
                    continue
                got.append((spec, _COLOURS[i % len(_COLOURS)], t, fr))
                items.append(realised_sentence(f"{scene} {mode} {spec}", fr))
            if got:
                parts.append(friction_law_figure(got, title=f"{scene}, {mode} mode",
                                                 height=3.8))
    if not parts:
        return ""
    return ("<section id='friction'><h2>The friction law as each engine realises it</h2>"
            "<p class='note'>MuJoCo's own friction (paper mode applies the law itself): each "
            "sample that touches and slips while the ball alone touches, the friction force "
            "at the contact over mu N against the slip speed; the curve is the paper's "
            "law.</p>" + "".join(parts)
            + "<ul>" + "".join(f"<li>{esc(x)}</li>" for x in items) + "</ul></section>")


def ran_section(res: MatrixResult) -> str:
    """The engines and every run's path, version and message, as read back."""
    eng = html_table(["engine", "implementation", "version", "precision", "device"],
                     [(e.engine, e.implementation, e.version, e.precision, e.device)
                      for e in res.engines])
    runs = html_table(["scene", "mode", "engine", "version", "path", "status", "message"],
                      [(r.scene, r.mode, r.engine, r.version, r.path, r.status, r.message)
                       for r in res.runs])
    return ("<section id='ran'><h2>What ran</h2><p class='note'>Read back from the runs.</p>"
            + eng + runs + "</section>")


def render(res: MatrixResult, tables: Mapping[str, pd.DataFrame]) -> str:
    """The page: verdict, differences with their attribution, theta(t), what ran."""
    title = (f"tippetop matrix: {len(res.scenes)} scenes on "
             + ", ".join(e.engine for e in res.engines))
    body = [f"<h1>{esc(title)}</h1>", verdict_section(res), differences_section(res),
            theta_section(res, tables), friction_section(res, tables), ran_section(res)]
    return page(title, body)


__all__ = ["render"]
