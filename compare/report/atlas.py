"""The report's measured group diagram: every atlas case's points in one figure, and findings."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tippetop.compare.report.markup import Html, esc, html_table, png


def atlas_section(results: Mapping[str, Any]) -> str:
    """The (a/R, A/C) plane with each run's measured groups, the agreement and findings."""
    from tippetop.compare.presentation.figures import atlas_figure
    from tippetop.compare.studies.atlas import findings

    recs = [r for r in results.get("cases", []) if r["kind"] == "atlas"]
    parts = ["<h2 id='atlas'>The group diagram, measured</h2>",
             "<p class='note'>At every grid point, n1 (the upright state's growth rate crosses "
             "zero) and n4 (the inverted state's, carried to theta = 0 by Jellett's constant) "
             "measured from 2-s runs in each engine's own dynamics, in each mode; the group they "
             "imply (I: "
             "no n1; II: n1 and n4; III: n1 but no n4) against the theory's (the lines A/C = "
             "1 -+ a/R). Circled: a point where a run's group departs from the theory. "
             "Where a run moves a threshold, the findings below say by how much.</p>"]
    ok = [r for r in recs if r.get("atlas")]
    for r in recs:
        if not r.get("atlas"):
            parts.append(f"<p class='fail'>{esc(r['id'])} did not run: "
                         f"{esc(r.get('error'))}</p>")
    if not ok:
        if not recs:
            parts.append("<p>No atlas in this profile (the full profile has one).</p>")
        return "".join(parts)
    # a results.json of the release before named a run by its compound mode in "engine"
    points = [{**p, "run": p.get("run") or p["engine"]} for r in ok for p in r["atlas"]["points"]]
    engines = list(dict.fromkeys(p["run"] for p in points))
    grid = ok[0]["atlas"]["grid"]
    merged = {"points": points, "runs": engines, "grid": grid}
    parts.append(f"<figure>{png(atlas_figure(merged))}</figure>")
    rows, classes = [], []
    for eng in engines:
        mine = [p for p in points if p["run"] == eng]
        agree = sum(p["agrees"] for p in mine)
        rows.append((eng, len(mine), agree, Html(f"{100 * agree / len(mine):.0f} %"),
                     sum(p["n_runs"] for p in mine),
                     "yes" if all(p["settled"] for p in mine) else "no"))
        classes.append("pass" if agree == len(mine) else "fail")
    parts.append(html_table(["run (engine/mode)", "points", "groups agree", "agreement", "runs",
                             "every fit clean"], rows, classes))
    parts.append("<ul>" + "".join(f"<li>{esc(f)}</li>" for f in findings(points)) + "</ul>")
    return "".join(parts)
