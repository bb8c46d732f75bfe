"""The report's trend figures: every metric that moved over the history's last runs.

The nightly reads them from the history when it appends (``results["history"]["trends"]``,
:func:`tippetop.compare.nightly.history.trends`); this module only draws them: one small figure
per metric, a line per series (case, engine and point), its change-points marked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Any

from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.report.markup import esc, html_table, png

#: Series drawn in one metric's figure, at most (the rest are listed in its table).
LINES_PER_FIGURE = 6


def _x(started: str) -> datetime | None:
    try:
        return datetime.fromisoformat(started)
    except ValueError:
        return None


def _numeric(values: Sequence[Any]) -> bool:
    return all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
               for v in values)


def trend_figure(metric: str, series: Sequence[Mapping[str, Any]]) -> Any:
    """One metric's figure: each series' values over the runs, its changes marked."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 2.8))
    words: list[Any] = []
    said: set[tuple[Any, str]] = set()
    for s in series:
        vals = [v["value"] for v in s["values"]]
        if not _numeric(vals):  # words and flags: one level per distinct value
            for v in vals:
                if v is not None and v not in words:
                    words.append(v)
    unit = series[0].get("unit") or ""
    for s in series[:LINES_PER_FIGURE]:
        xs = [_x(v["started"]) for v in s["values"]]
        ys = [None if v["value"] is None else
              (words.index(v["value"]) if words else float(v["value"])) for v in s["values"]]
        pts = [(x, y) for x, y in zip(xs, ys, strict=True) if x is not None and y is not None]
        if not pts:
            continue
        label = s["case"] + (f" [{s['point']}]" if s.get("point") else "")
        line, = ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", ms=3, lw=1,
                        drawstyle="steps-post" if words else "default", label=label)
        for c in s["changes"]:
            x = _x(c["started"])
            if x is not None:
                ax.axvline(x, color=line.get_color(), ls=":" if c["type"] == "blip" else "--",
                           lw=0.9)
                what = " -> ".join(str(v) for v in c.get("engine_version") or ())
                if c["type"] != "blip" and what and (x, what) not in said:
                    said.add((x, what))  # the engine version that changed, at its step
                    ax.annotate(what, (x, 0.98), xycoords=("data", "axes fraction"),
                                fontsize=6, rotation=90, va="top", ha="right",
                                color=line.get_color())
    if words:
        ax.set_yticks(range(len(words)), [str(w) for w in words])
    ax.set_ylabel(f"{metric}" + (f" ({unit})" if unit and unit != "relative" else ""))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.set_title(f"{metric} over the last runs (dashed: a step, dotted: a blip)", fontsize=9)
    fig.autofmt_xdate()
    fig.tight_layout()
    return fig


def trends_section(results: Mapping[str, Any]) -> str:
    """The trends: a figure per metric that moved or regressed tonight, and its changes."""
    head = "<h2 id='trends'>Trends from the history</h2>"
    hist = results.get("history")
    if not hist:
        return head + ("<p>This run appended nothing to the history (--no-history, or a run "
                       "from before the history): no trends.</p>")
    if hist.get("error"):
        return head + (f"<p>This run was not appended to the history "
                       f"<code>{esc(hist['file'])}</code>: {esc(hist['error'])}. The results "
                       "here are complete; the trends are not drawn.</p>")
    trends = hist.get("trends") or []
    intro = (f"<p class='note'>From the history <code>{esc(hist['file'])}</code> (this run is "
             f"run {esc(hist.get('run'))}): every series of tonight's cases with a change-point "
             "over its last runs (a value beyond the metric's tolerance from its level: a step "
             "if it stays, a blip if it comes back the run after), or that regressed against "
             "the baseline tonight. <code>tippetop history</code> prints them all.</p>")
    if not trends:
        return head + intro + "<p>No metric moved.</p>"
    by_metric: dict[str, list[Mapping[str, Any]]] = {}
    for t in trends:
        by_metric.setdefault(t["metric"], []).append(t)
    parts = [head, intro]
    for metric, series in by_metric.items():
        more = len(series) - LINES_PER_FIGURE
        caption = (f"{metric}: {len(series)} series moved"
                   + (f" (the first {LINES_PER_FIGURE} drawn)" if more > 0 else ""))
        parts.append(f"<figure>{png(trend_figure(metric, series))}<figcaption>"
                     f"{esc(caption)}</figcaption></figure>")
        rows = [(s["case"] + (f" [{s['point']}]" if s.get("point") else ""), s["engine"],
                 "yes" if s.get("regressed") else "",
                 "; ".join(c["text"] for c in s["changes"]) or "-") for s in series]
        parts.append(html_table(["case", "engine", "regressed tonight", "changes"], rows))
    return "".join(parts)
