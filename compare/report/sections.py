"""The report's text sections: header, verdict, scenes, thresholds, accuracy, checks, machine."""

from __future__ import annotations

import base64
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tippetop.compare.report.markup import Html, esc, fmt_num, html_table


def scene_key(rec: Mapping[str, Any]) -> str:
    """Runs of the same scene with the same ``set`` overrides share their figures."""
    extra = ", ".join(rec.get("set") or [])
    return f"{rec['scene']}" + (f" ({extra})" if extra else "")


def header(results: Mapping[str, Any]) -> str:
    """The title, the verdict and the counts, and where and how the nightly ran."""
    env = results.get("environment", {})
    c = results.get("counts", {})
    verdict = results.get("verdict", "?")
    cls = "ok" if verdict == "OK" else "bad"
    pk = env.get("packages", {})
    commit = env.get("git_commit") or "unknown"
    if env.get("git_dirty"):
        commit += " (with uncommitted changes)"
    return (
        f"<h1>tippetop model-validation report</h1>"
        f'<p><span class="verdict {cls}">{esc(verdict)}</span> '
        f"profile <b>{esc(results.get('profile'))}</b>: {c.get('cases', 0)} cases, "
        f"{c.get('checks', 0)} checks: {c.get('checks_pass', 0)} pass, "
        f"{c.get('checks_fail', 0)} fail, {c.get('checks_new', 0)} new, "
        f"{c.get('checks_error', 0)} error; {results.get('wall_s', 0):.0f} s.</p>"
        f"<p class='note'>{esc(results.get('profile_description', ''))}</p>"
        f"<p>Started {esc(results.get('started'))}; git {esc(commit)}; MuJoCo "
        f"{esc(pk.get('mujoco'))}; Python {esc(env.get('python'))} on {esc(env.get('platform'))}"
        f"; baseline <code>{esc(results.get('baseline_file'))}</code>.</p>")


def verdict_section(results: Mapping[str, Any]) -> str:
    """Regressions, cases that did not run, new metrics and the videos."""
    recs = results.get("cases", [])
    parts = ["<h2 id='checks'>Regression checks</h2>"]
    fails = [(r, ch) for r in recs for ch in r["checks"] if ch["status"] == "fail"]
    errors = [r for r in recs if r["status"] == "error"]
    new = [(r, ch) for r in recs for ch in r["checks"] if ch["status"] == "new"]
    if not (fails or errors or new):
        parts.append("<p>Every metric is within its tolerance of the stored baseline.</p>")
    if fails:
        parts.append("<h3>Regressions</h3>" + html_table(
            ["case", "metric", "message"],
            [(r["id"], ch["metric"], ch["message"]) for r, ch in fails],
            ["fail"] * len(fails)))
    if errors:
        parts.append("<h3>Cases that did not run</h3>" + html_table(
            ["case", "error"], [(r["id"], r["error"]) for r in errors], ["error"] * len(errors)))
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
    return "".join(parts)


def scenes_section(results: Mapping[str, Any]) -> str:
    """One row per scene: parameters, group, the theory's numbers, outcomes."""
    runs = [r for r in results.get("cases", []) if r["kind"] == "run"]
    by_scene: dict[str, list[Mapping[str, Any]]] = {}
    for r in runs:
        by_scene.setdefault(scene_key(r), []).append(r)
    rows = []
    for key, recs in by_scene.items():
        p, th = recs[0]["params"], recs[0].get("theory", {})
        outcomes = "; ".join(f"{r['mode']}: {r['values'].get('outcome', 'error')}"
                             for r in recs)
        desc = Html(f"<div style='min-width:16em'>{esc(recs[0].get('description', ''))}</div>")
        rows.append((
            key, desc, th.get("group", "-"), p["A_over_C"],
            p["a_over_R"], p["C_factor"], p["R_m"], p["a_m"], p["M_kg"], p["law"], p["mu"],
            p["Lambda_mps"], p["theta0"], p["n0"], p["t_end_s"], th.get("n1"), th.get("n4"),
            th.get("nc"), th.get("theta_s"), th.get("outcome", "-"),
            (recs[0].get("expect") or {}).get("outcome", "-"), outcomes))
    return ("<h2 id='scenes'>Scenes, parameters and groups</h2>"
            "<p class='note'>SI units: R, a in m, M in kg, Lambda in m/s, angles in rad, spins "
            "in rad/s. n1, n4, n_c and theta_s(n0) are the theory's (eq. 4.13, Sec. 4.3, "
            "F(x) = kappa); theta_s assumes a start near theta = 0.</p>"
            + html_table(["scene", "description", "group", "A/C", "a/R", "C factor", "R", "a", "M",
                          "law", "mu", "Lambda", "theta0", "n0", "t_end (s)", "n1", "n4", "n_c",
                          "theta_s(n0)", "theory outcome", "expected", "simulated"], rows))


def threshold_section(results: Mapping[str, Any]) -> str:
    """Critical spins: the theory's against the measured, per engine."""
    recs = [r for r in results.get("cases", []) if r["kind"] == "threshold"]
    parts = ["<h2 id='thresholds'>Thresholds: theory against measured</h2>",
             "<p class='note'>Critical spins found by bisection on n0 (n1: theta = 0 turns "
             "unstable; n_c: full inversion), each run over the scene's horizon. The measured "
             "value is the final bracket's midpoint.</p>"]
    if not recs:
        parts.append("<p>No threshold cases in this profile.</p>")
        return "".join(parts)
    rows, classes = [], []
    for r in recs:
        th = r.get("threshold")
        if th is None:
            rows.append((r["scene_name"], r["name"], r["mode"], "-", "-", "-", "-", "-", "-",
                         "-", f"error: {r.get('error')}"))
            classes.append("error")
            continue
        rows.append((r["scene_name"], th["which"], r["mode"], th["theory"], th["measured"],
                     Html(f"{100 * th['rel_diff']:+.2f} %"),
                     Html(f"[{th['bracket'][0]:.4g}, {th['bracket'][1]:.4g}]"),
                     th.get("rel_tol"), th["n_runs"], th.get("horizon_s"),
                     "converged" if th.get("converged") else "not converged"))
        classes.append(r["status"])
    parts.append(html_table(["scene", "which", "mode", "theory (rad/s)", "measured (rad/s)",
                             "measured / theory - 1", "bracket", "rel_tol", "runs", "horizon (s)",
                             "bisection"], rows, classes))
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
