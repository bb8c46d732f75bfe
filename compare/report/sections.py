"""The report's text sections: header, verdict, scenes, thresholds, accuracy, checks, machine."""

from __future__ import annotations

import base64
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tippetop.compare.presentation.verdict import REFERENCE_RUN, run_of, scene_key
from tippetop.compare.report.markup import Html, esc, fmt_num, html_table


def header(results: Mapping[str, Any]) -> str:
    """The title and the regression badge (against the stored baseline), on two short lines."""
    c = results.get("counts", {})
    verdict = results.get("verdict", "?")
    cls = "ok" if verdict == "OK" else "bad"
    return (
        f"<h1>tippetop model-validation report <small>{esc(results.get('profile'))} profile, "
        f"{esc(results.get('started'))}</small></h1>"
        f'<p class="badge">Regression against the stored baseline: '
        f'<span class="verdict {cls}">{esc(verdict)}</span> {c.get("checks", 0)} checks: '
        f"{c.get('checks_pass', 0)} pass, {c.get('checks_fail', 0)} fail, "
        f"{c.get('checks_new', 0)} new, {c.get('checks_error', 0)} error "
        f"(<a href='#checks'>details</a>)</p>")


def run_facts(results: Mapping[str, Any]) -> str:
    """Where and how the nightly ran: profile, counts, git commit, MuJoCo, Python, baseline."""
    env = results.get("environment", {})
    c = results.get("counts", {})
    pk = env.get("packages", {})
    commit = env.get("git_commit") or "unknown"
    if env.get("git_dirty"):
        commit += " (with uncommitted changes)"
    return (f"<p class='note'>Profile <b>{esc(results.get('profile'))}</b>: "
            f"{esc(results.get('profile_description', ''))} {c.get('cases', 0)} cases in "
            f"{results.get('wall_s', 0):.0f} s. Started {esc(results.get('started'))}; git "
            f"{esc(commit)}; MuJoCo {esc(pk.get('mujoco'))}; Python {esc(env.get('python'))} on "
            f"{esc(env.get('platform'))}; baseline <code>{esc(results.get('baseline_file'))}"
            f"</code>.</p>" + calibration_facts(results))


def calibration_facts(results: Mapping[str, Any]) -> str:
    """Which calibration the native cases ran with, and which their baselines were made with.

    Empty when no native case ran. A baseline made with another calibration is said: its
    native cases' differences may be the calibration's, not the code's.
    """
    cal = results.get("calibration") or {}
    bases = cal.get("baselines") or {}
    if not bases:
        return ""
    now = cal.get("this_run") or "unknown"
    groups: dict[str, list[str]] = {}
    for case_id, label in sorted(bases.items()):
        groups.setdefault(label, []).append(case_id)
    parts = []
    for label, ids in groups.items():
        same = label == now
        parts.append(f"<li>{'' if same else '<b>another calibration</b>: '}"
                     f"<code>{esc(label)}</code>: {len(ids)} case{'s' if len(ids) != 1 else ''}"
                     + ("" if same else f" ({esc(', '.join(ids[:6]))}"
                        f"{', ...' if len(ids) > 6 else ''})") + "</li>")
    return (f"<p class='note'>The native mode's cases ran with the calibrated settings "
            f"<code>{esc(now)}</code> (models/calibrated_native.toml). Their baselines were "
            f"made with:</p><ul class='note'>{''.join(parts)}</ul>")


def _exp(x: float) -> str:
    """1.3e-09 -> 1e-9: a compact drift."""
    m, e = f"{x:.0e}".split("e")
    return f"{m}e{int(e)}"


_SHORT = {"intermediate": "intermed.", "inconclusive": "inconcl."}
_MARK = {"agree": "", "depart": "&ne; ", "expected": "&ne; ", "inconclusive": "? ",
         "failed": "&#x2716; "}


def _expected(row: Mapping[str, Any]) -> list[str]:
    """The catalogue's reason for a departure it expects, as a note (or none)."""
    from tippetop.compare.presentation.verdict import expected_reason

    why = expected_reason(row)
    return [f"expected by the catalogue: {why}"] if why else []


def _cell(row: Mapping[str, Any]) -> Html:
    """A verdict ``<td>``: the outcome (marked where it departs) and J; the differences below."""
    from tippetop.compare.presentation.verdict import cell_class, expected_reason

    # the catalogue's deliberate departure has a class of its own, its reason in the tooltip
    cls = "expected" if expected_reason(row) else cell_class(row)
    outcome = row.get("outcome") or "-"
    line1 = f"{_MARK[cls]}{esc(_SHORT.get(outcome, outcome))}"
    if row.get("J_rel_drift") is not None:
        line1 += f" <span class='j'>J{_exp(row['J_rel_drift'])}</span>"
    nums = []
    if row.get("d_theta_asymp") is not None:
        nums.append(f"&Delta;&theta;{row['d_theta_asymp']:+.2f}")
    if row.get("d_t_invert") is not None:
        nums.append(f"&Delta;t{row['d_t_invert']:+.2f}")
    elif row.get("t_invert") is not None and row.get("run") == REFERENCE_RUN:
        nums.append(f"t {row['t_invert']:.2f}")
    if row.get("against") == "reference":
        nums.append("&#8224;")
    tip = "; ".join([*row.get("reasons", []), *row.get("notes", []), *_expected(row)]) \
        or "agrees"
    return Html(f"<td class='{cls}' title='{esc(tip)}'>{line1}<br>{' '.join(nums)}</td>")


def crossval_section(results: Mapping[str, Any]) -> str:
    """``<section id="verdict">``: every scene (rows) in every run (columns) against the theory.

    A cell agrees when the outcome class is the theory's and theta_asymp is within the stated
    tolerance of theta_s; it shows the differences and the Jellett drift, and (as a tooltip and
    in the list below the table) why it departs.
    """
    from tippetop.compare.measures.metrics import EVENT_RTOL, EVENT_TOL_S, J_TOL, THETA_S_TOL
    from tippetop.compare.presentation.verdict import agreement_counts, cell_class, run_order

    # a results.json of the release before named a row's run by its compound mode
    rows = [{**r, "run": r.get("run") or r["mode"]} for r in results.get("crossval") or []]
    head = "<section id='verdict'><h2>Does each engine agree with the theory?</h2>"
    if not rows:
        return head + "<p>No runs in these results.</p></section>"
    modes = run_order(rows)
    counts = agreement_counts(rows)
    summary = "; ".join(f"{esc(m)} {counts[m]['agree']}/{counts[m]['runs']}" for m in modes)
    legend = (f"<p class='legend'><span class='agree'>&nbsp;agrees&nbsp;</span>: every check "
              f"passes: the theory's outcome and |theta_asymp - theta_s| &le; "
              f"{THETA_S_TOL:g} rad (&#8224;: a top that reaches its stem, judged against the "
              f"reference instead), the reference's inversion and stem times within "
              f"max({EVENT_TOL_S:g} s, {100 * EVENT_RTOL:g} %), the ball on the table where "
              f"the reference's stays on, Jellett's drift while the ball alone touches &le; "
              f"{J_TOL['mujoco']:g} (the reference: {J_TOL['ode']:g}), no energy gained; "
              f"<span class='depart'>&nbsp;&ne; departs&nbsp;</span> "
              f"<span class='expected'>&nbsp;&ne; departs, as the catalogue expects&nbsp;"
              f"</span> "
              f"<span class='inconclusive'>&nbsp;? still moving&nbsp;</span> "
              f"<span class='failed'>&nbsp;failed&nbsp;</span>. "
              f"&Delta;&theta; = theta_asymp - theta_s (rad); &Delta;t = t_invert - the reference "
              f"ODE's (s); J: Jellett drift. Hover a cell, or open the list below, for why. "
              f"Agreeing: {summary}.</p>")
    by_scene: dict[str, dict[str, Mapping[str, Any]]] = {}
    first: dict[str, Mapping[str, Any]] = {}
    for r in rows:
        by_scene.setdefault(r["scene"], {})[r["run"]] = r
        first.setdefault(r["scene"], r)
    body = []
    for scene, cells in by_scene.items():
        t = first[scene]
        name = t.get("name") or scene
        paper = (f" <span class='j'>paper {t['paper_theta_asymp']:.3g}</span>"
                 if t.get("paper_theta_asymp") is not None else "")
        th = (f"{esc(_SHORT.get(t.get('theory_outcome') or '-', t.get('theory_outcome')))}<br>"
              f"&theta;<sub>s</sub> {fmt_num(t.get('theta_s'), '.2f')}{paper}")
        tds = "".join(_cell(cells[m]) if m in cells else "<td class='na'></td>"
                      for m in modes)
        label = esc(name).replace("-", "-<wbr>").replace("_", "_<wbr>")
        body.append(f"<tr><th scope='row' title='{esc(scene)}'>{label}</th><td>{th}</td>"
                    f"{tds}</tr>")
    table = ("<table class='verdict-table'><thead><tr><th>scene</th><th>theory</th>"
             + "".join(f"<th>{esc(m).replace('/', '/<wbr>').replace('-', '-<wbr>')}</th>"
                       for m in modes)
             + "</tr></thead><tbody>" + "".join(body) + "</tbody></table>")
    where = [f"<li><b>{esc(r.get('name') or r['scene'])}</b> [{esc(r['run'])}]: "
             f"{esc('; '.join([*r['reasons'], *r['notes'], *_expected(r)]))}</li>"
             for r in rows if cell_class(r) != "agree" or r.get("notes")]
    where_html = (f"<details><summary>Where not, and why ({len(where)})</summary>"
                  f"<ul>{''.join(where)}</ul></details>" if where else "")
    return head + legend + table + where_html + "</section>"


def verdict_section(results: Mapping[str, Any]) -> str:
    """The regression checks: regressions, cases that did not run, new metrics, the videos."""
    recs = results.get("cases", [])
    parts = ["<h2 id='checks'>Regression checks</h2>"]
    fails = [(r, ch) for r in recs for ch in r["checks"] if ch["status"] == "fail"]
    errors = [r for r in recs if r["status"] == "error"]
    changed = results.get("model_changed") or {}
    new = [(r, ch) for r in recs for ch in r["checks"]
           if ch["status"] == "new" and r["id"] not in changed]
    if not (fails or errors or new or changed):
        parts.append("<p>Every metric is within its tolerance of the stored baseline.</p>")
    if fails:
        parts.append("<h3>Regressions</h3>" + html_table(
            ["case", "metric", "message"],
            [(r["id"], ch["metric"], ch["message"]) for r, ch in fails],
            ["fail"] * len(fails)))
    if errors:
        parts.append("<h3>Cases that did not run</h3>" + html_table(
            ["case", "error"], [(r["id"], r["error"]) for r in errors], ["error"] * len(errors)))
    if changed:
        parts.append("<h3>Model files changed since their baselines (not compared; "
                     "<code>--update-baseline</code> stores this run's values)</h3>"
                     + html_table(["case", "what changed"], list(changed.items()),
                                  ["new"] * len(changed)))
    if new:
        by_case: dict[str, list[str]] = {}
        for r, ch in new:
            by_case.setdefault(r["id"], []).append(ch["metric"])
        parts.append(f"<details><summary>New (no baseline yet): {len(new)} metrics of "
                     f"{len(by_case)} cases; <code>--update-baseline</code> adds them</summary>"
                     + html_table(["case", "metrics"], [(k, ", ".join(v))
                                                        for k, v in by_case.items()],
                                  ["new"] * len(by_case)) + "</details>")
    videos = results.get("videos", {})
    if videos.get("requested"):
        links = "".join(f'<li><a href="{esc(rel)}">{esc(name)}</a></li>'
                        for name, rel in sorted(videos.get("files", {}).items()))
        parts.append(f"<p>Videos (MuJoCo left, the reference ODE replayed right): "
                     f"{esc(videos['status'])}.</p>" + (f"<ul>{links}</ul>" if links else ""))
        failed = videos.get("failed") or {}
        if failed:
            parts.append("<h3>Videos that failed</h3>" + html_table(
                ["scene", "why"], sorted(failed.items()), ["error"] * len(failed)))
    return "".join(parts)


def scenes_section(results: Mapping[str, Any]) -> str:
    """One row per scene: the key columns; every parameter behind a disclosure."""
    runs = [r for r in results.get("cases", []) if r["kind"] == "run"]
    by_scene: dict[str, list[Mapping[str, Any]]] = {}
    for r in runs:
        by_scene.setdefault(scene_key(r), []).append(r)
    key_rows, all_rows = [], []
    for key, recs in by_scene.items():
        p, th = recs[0]["params"], recs[0].get("theory", {})
        outcomes = "; ".join(f"{run_of(r)}: {r['values'].get('outcome', 'error')}"
                             for r in recs)
        key_rows.append((key, th.get("group", "-"), p["A_over_C"], p["a_over_R"], p["theta0"],
                         p["n0"], p["t_end_s"], th.get("theta_s"), th.get("outcome", "-"),
                         (recs[0].get("expect") or {}).get("outcome", "-"), outcomes))
        desc = Html(f"<div style='min-width:16em'>{esc(recs[0].get('description', ''))}</div>")
        all_rows.append((
            key, desc, th.get("group", "-"), p["A_over_C"],
            p["a_over_R"], p["C_factor"], p["R_m"], p["a_m"], p["M_kg"], p["law"], p["mu"],
            p["Lambda_mps"], p["theta0"], p["n0"], p["t_end_s"], th.get("n1"), th.get("n4"),
            th.get("nc"), th.get("theta_s"), th.get("outcome", "-"),
            (recs[0].get("expect") or {}).get("outcome", "-"), outcomes))
    return ("<h2 id='scenes'>Scenes, parameters and groups</h2>"
            "<p class='note'>SI units: angles in rad, spins in rad/s, times in s. theta_s(n0) "
            "is the theory's (F(x) = kappa) for a start near theta = 0.</p>"
            + html_table(["scene", "group", "A/C", "a/R", "theta0", "n0", "t_end", "theta_s(n0)",
                          "theory", "expected", "simulated"], key_rows)
            + model_files_table(runs)
            + "<details><summary>Every parameter of every scene (R, a, M, law, mu, Lambda, "
              "n1, n4, n_c, description)</summary>"
            + html_table(["scene", "description", "group", "A/C", "a/R", "C factor", "R (m)",
                          "a (m)", "M (kg)", "law", "mu", "Lambda (m/s)", "theta0", "n0",
                          "t_end (s)", "n1", "n4", "n_c", "theta_s(n0)", "theory outcome",
                          "expected", "simulated"], all_rows)
            + "</details>")


def threshold_section(results: Mapping[str, Any]) -> str:
    """Critical spins: the theory's against the measured, per engine."""
    recs = [r for r in results.get("cases", []) if r["kind"] == "threshold"]
    parts = ["<h2 id='thresholds'>Thresholds: theory against measured</h2>",
             "<p class='note'>n1: the spin above which theta = 0 turns unstable; n4: the spin "
             "(carried to theta = 0 by Jellett's constant) above which theta = pi is stable; "
             "n_c: full inversion. <b>growth</b>: the zero of the steady state's growth rate "
             "(a matrix-pencil fit of the tilt over 2-s runs started 0.01 rad from the state), "
             "found by false position; the value is the last secant root and the bracket the "
             "last two spins that straddle it. <b>bisect</b>: the outcome of full runs over "
             "the scene's horizon; the value is the final bracket's midpoint, and the "
             "bracket's ends are run again over twice the horizon: a bracket whose ends change "
             "side measures the horizon, not the threshold. Either agrees with the theory only "
             "if the theory's value lies inside its bracket or within 0.1 % of the value.</p>"]
    if not recs:
        parts.append("<p>No threshold cases in this profile.</p>")
        return "".join(parts)
    rows, classes = [], []
    for r in recs:
        th = r.get("threshold")
        if th is None:
            rows.append((r["scene_name"], r["name"], run_of(r), "-", "-", "-", "-", "-", "-",
                         "-", "-", f"error: {r.get('error')}"))
            classes.append("error")
            continue
        lo, hi = th["bracket"]
        close = abs(th["rel_diff"]) <= 1e-3
        if th.get("depends_on_horizon"):
            verdict, cls = "depends on the horizon: " + (th.get("warning") or ""), "depart"
        elif lo <= th["theory"] <= hi:
            verdict, cls = "the theory lies inside the bracket", "agree"
        elif close:
            verdict, cls = (f"within {100 * abs(th['rel_diff']):.3f} % of the theory (0.1 % "
                            f"allowed; the theory lies just outside the bracket of runs)"), "agree"
        else:
            below = th["theory"] < lo
            end = lo if below else hi
            verdict = (f"the theory lies {'below' if below else 'above'} the bracket, "
                       f"{100 * abs(th['theory'] / end - 1):.2f} % from its "
                       f"{'low' if below else 'high'} end")
            cls = "depart"
        rows.append((r["scene_name"], th["which"], run_of(r), th.get("method", "bisect"),
                     th["theory"],
                     Html(f"[{lo:.4g}, {hi:.4g}]"), th["measured"],
                     Html(f"{100 * th['rel_diff']:+.3f} %"), th["n_runs"], th.get("horizon_s"),
                     "yes" if th.get("bracket_converged", th.get("converged")) else "no",
                     verdict))
        classes.append(cls)
    parts.append(html_table(["scene", "which", "run (engine/mode)", "method", "theory (rad/s)",
                             "bracket (rad/s)", "measured (rad/s)", "measured / theory - 1",
                             "runs", "run length (s)", "converged", "against the theory"],
                            rows, classes))
    return "".join(parts)


def accuracy_section(accuracy_dir: Path | None) -> str:
    """The accuracy-versus-cost PNG figures (and notes) of a folder, if any."""
    head = "<h2 id='accuracy'>Accuracy against cost</h2>"
    pngs = sorted(Path(accuracy_dir).glob("*.png")) if accuracy_dir else []
    if not pngs:
        where = f" in <code>{esc(accuracy_dir)}</code>" if accuracy_dir else ""
        return head + (f"<p>No accuracy-versus-cost figures were found{where}; they are "
                       "embedded here once their PNG files are given (nightly option "
                       "<code>--accuracy-dir DIR</code>).</p>")
    parts = [head]
    for p in pngs:
        data = base64.b64encode(p.read_bytes()).decode("ascii")
        parts.append(f'<figure><img alt="{esc(p.stem)}" src="data:image/png;base64,{data}">'
                     f"<figcaption>{esc(p.name)}</figcaption></figure>")
    for md in sorted(Path(accuracy_dir).glob("*.md")):
        parts.append(f"<details><summary>{esc(md.name)}</summary><pre>"
                     f"{esc(md.read_text(encoding='utf-8'))}</pre></details>")
    return "".join(parts)


def model_files_table(runs: list[Mapping[str, Any]]) -> str:
    """The model files that ran, each one's content hash against its baseline's.

    A catalogue case's ``model`` or a file of ``nightly --models``; empty when none ran.
    """
    files: dict[tuple[str, str, str], list[Mapping[str, Any]]] = {}
    for r in runs:
        if r.get("model"):
            files.setdefault((r["model"]["file"], r["model"]["origin"], r["name"]),
                             []).append(r)
    if not files:
        return ""
    rows, classes = [], []
    for recs in files.values():
        m = recs[0]["model"]
        stored = {str(r["model"].get("baseline_sha256") or "")[:12] for r in recs} - {""}
        changed = any(r["model"].get("changed") for r in recs)
        state = ("changed since its baseline: not compared" if changed else
                 "as in its baseline" if stored else "no baseline yet")
        rows.append((m["given"], m["origin"], ", ".join(run_of(r) for r in recs),
                     Html(f"<code>{esc(m['sha256'][:12])}</code>"),
                     ", ".join(sorted(stored)) or "-", state, ", ".join(m.get("files", []))))
        classes.append("new" if changed or not stored else "pass")
    return ("<h3 id='models'>Model files</h3><p class='note'>MJCF tops run as cases of their "
            "own (a catalogue case's <code>model</code>, or <code>nightly --models</code>), "
            "each baseline entry with the hash (SHA-256, first 12 digits) of the file it ran: "
            "a changed file is said, not compared.</p>"
            + html_table(["model file", "from", "runs", "sha256", "baseline's", "state",
                          "files hashed"], rows, classes))


def checks_section(results: Mapping[str, Any]) -> str:
    """Every check with its value, baseline and tolerance; the tolerances."""
    rows, classes = [], []
    for r in results.get("cases", []):
        for ch in r["checks"]:
            val = ch["value"]
            shown = f"{len(val)} points" if isinstance(val, dict) else fmt_num(val, ".6g")
            base = ch["baseline"]
            bshown = f"{len(base)} points" if isinstance(base, dict) else fmt_num(base, ".6g")
            rows.append((r["id"], ch["metric"], Html(shown), Html(bshown),
                         ch["tolerance"]["text"], ch["status"]))
            classes.append(ch["status"])
    tol_rows = [(k, t["text"], t["why"]) for k, t in results.get("tolerances", {}).items()]
    return ("<h2 id='all'>Every check</h2><details><summary>"
            f"{len(rows)} checks (click to open)</summary>"
            + html_table(["case", "metric", "value", "baseline", "tolerance", "status"], rows,
                         classes) + "</details><h3>Tolerances</h3>"
            + html_table(["metric", "tolerance", "why"], tol_rows))


def environment_section(results: Mapping[str, Any]) -> str:
    """Versions, machine, git commit and the command line."""
    env = results.get("environment", {})
    rows = [(k, v) for k, v in env.items() if k != "packages"]
    rows += [(f"package {k}", v) for k, v in (env.get("packages") or {}).items()]
    rows.append(("command", " ".join(results.get("command", []))))
    return "<h2 id='env'>Environment</h2>" + html_table(["what", "value"], rows)
