"""What ``tippetop bisect`` prints: what ran, then each metric's move; and its report.html."""

from __future__ import annotations

import html

from tippetop.compare.measures.metrics import metric as declared
from tippetop.compare.presentation.matrix import closer_text
from tippetop.compare.presentation.terminal import fmt, labelled, table, wrapped
from tippetop.compare.results.bisect import BisectContext, BisectResult


def _unit(metric: str) -> str:
    """The unit printed after a metric's value (:attr:`Metric.table_unit`, declared once)."""
    if metric.startswith("probe."):
        from tippetop.compare.probes import probe_metric

        return probe_metric(metric).table_unit
    return declared(metric).table_unit


def _context(res: BisectResult) -> BisectContext:
    if res.context is None:
        raise ValueError("a bisect is shown with its context (the scene, the mode ...)")
    return res.context


def print_bisect(res: BisectResult) -> None:
    """The search for a person: what ran, then each metric's move."""
    ctx = _context(res)
    n = len(res.releases)
    print(f"bisect: {ctx.scene} in mode {ctx.mode}, {n} {res.kind} from "
          f"{res.between[0]} to {res.between[1]} ({ctx.source})")
    envs = res.environments_made
    print(f"\nran {res.runs} of {n} ({envs} managed environment{'s' if envs != 1 else ''}, "
          f"{res.environments_new} made now; the versions read back from the runs):")
    ms = res.metrics
    own = all(t.engine == f"mujoco@{t.release}" for t in res.tested)
    probe = {m.split(".")[1] for m in ms if m.startswith("probe.")}
    short = len(probe) == 1 and all(m.startswith("probe.") for m in ms)  # one probe's
    cols = ["interpreter" if own else "release", *(() if own else ("engine",)), "version",
            *(() if "status" in ms else ("status",)),
            *(m.rsplit(".", 1)[1] if short else m for m in ms)]
    rows = [(t.release, *(() if own else (t.engine,)), fmt(t.version),
             *(() if "status" in ms else (str(t.status),)),
             *(fmt(t.values.get(m), _unit(m)) for m in ms)) for t in res.tested]
    print(table(cols, rows, indent="  "))
    for sk in res.skipped:
        print(f"  skipped {sk.release}: {sk.reason}")
    width = max(len(m) for m in ms)
    print("\nwhat moved (beyond the nightly's tolerances):")
    still = [m for m in ms if not res.by_metric[m].moved and not res.by_metric[m].moves]
    if still:
        a, b = res.searched
        print(wrapped(f"no move of {', '.join(still)}: {b} is like {a} (a move and a move "
                      "back between two runs would not be seen)", indent="  "))
    for m in ms:
        e = res.by_metric[m]
        u = _unit(m)
        if m in still:
            continue
        if not e.moved or e.values is None or e.pair is None:
            print(labelled(m, f"{e.summary}", width))
            continue
        (va, vb), pair = e.values, e.pair
        print(labelled(m, f"{fmt(va, u)} ({pair.last_like_a}, like "
                       f"{res.searched[0]}) -> {fmt(vb, u)} ({pair.first_like_b}), "
                       f"over {e.tolerance['text']}", width))
        print(labelled("", e.summary, width))
        att = e.attribution
        if att:
            print(labelled("", f"follows: {att.follows}", width))
        if e.closer:
            print(labelled("", f"closer: {closer_text(m, e.closer)}", width))
        if not att and e.attribution_note:
            print(labelled("", e.attribution_note, width))
    for note in res.notes:
        print(f"note: {note}")


def render_html(res: BisectResult) -> str:
    """A small page: the runs and each metric's move."""
    ctx = _context(res)
    esc = html.escape
    ms = res.metrics
    head = "".join(f"<th>{esc(h)}</th>" for h in ("release", "engine", "version", "status",
                                                  *ms))
    body = "".join(
        "<tr>" + "".join(f"<td>{esc(str(x))}</td>" for x in (
            t.release, t.engine, fmt(t.version), t.status,
            *(fmt(t.values.get(m), _unit(m)) for m in ms))) + "</tr>"
        for t in res.tested)
    moves = "".join(
        f"<li><b>{esc(m)}</b>: {esc(e.summary)}"
        + (f"; follows: {esc(str(e.attribution.follows))}" if e.attribution else "") + "</li>"
        for m, e in res.by_metric.items())
    skipped = "".join(f"<li>{esc(s.release)}: {esc(s.reason)}</li>"
                      for s in res.skipped) or "<li>none</li>"
    return (f"<!doctype html><meta charset='utf-8'><title>tippetop bisect</title>"
            f"<style>body{{font-family:sans-serif}}td,th{{padding:2px 8px;text-align:right}}"
            f"</style><h1>bisect: {esc(ctx.scene)} ({esc(ctx.mode)})</h1>"
            f"<p>{len(res.releases)} {res.kind} from {esc(res.between[0])} to "
            f"{esc(res.between[1])}; {res.runs} run, {res.environments_made} "
            f"managed environments.</p><h2>What moved</h2><ul>{moves}</ul>"
            f"<h2>Runs</h2><table><tr>{head}</tr>{body}</table>"
            f"<h2>Skipped</h2><ul>{skipped}</ul>\n")


__all__ = ["print_bisect", "render_html"]
