"""``tippetop probe --out``: a figure per probe (the motion against its exact curve) and HTML.

Each probe's figure has one panel per mode; each engine's run is a line, the exact curve a
dashed black line. The page holds the rows' table (every quantity against its exact value)
and the figures, which it links as files beside it.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

from tippetop.compare.probes.study import ProbeResult, ProbeRun


def figure(res: ProbeResult, probe: str, path: Path) -> bool:
    """Draw ``probe``'s runs into ``path`` (PNG); False when it has no curve to draw.

    One panel per mode, at most four to a row.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    runs: list[ProbeRun] = [r for r in res.runs if r.probe == probe and r.curve is not None]
    if not runs:
        return False
    modes = list(dict.fromkeys(r.mode for r in runs))
    ncols = min(4, len(modes))  # a grid of at most 4 columns: readable at a page's width
    nrows = -(-len(modes) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.2 * nrows), squeeze=False)
    for ax in axes.flat[len(modes):]:
        ax.set_visible(False)
    for ax, mode in zip(axes.flat, modes, strict=False):
        drawn_exact = False
        for r in (r for r in runs if r.mode == mode):
            c = r.curve
            assert c is not None
            ax.plot(c.t, c.value, lw=1.2, label=r.engine)
            if not drawn_exact and np.isfinite(c.exact).any():
                ax.plot(c.t, c.exact, "k--", lw=1.0, label="exact")
                drawn_exact = True
            ax.set_ylabel(c.label)
        ax.set_title(mode, fontsize=10)
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle(probe, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _num(x: float) -> str:
    return f"{x:.6g}" if math.isfinite(x) else "-"


def render(res: ProbeResult, figures: dict[str, str]) -> str:
    """The page: the table of rows, then each probe's figure."""
    rows = []
    for r in res.rows:
        cls = "ok" if r.passed else "fail"
        why = html.escape(r.reason or r.note or "")
        rows.append(
            f"<tr class='{cls}'><td>{html.escape(r.probe)}</td><td>{html.escape(r.mode)}</td>"
            f"<td>{html.escape(r.engine)} {html.escape(r.version)}</td>"
            f"<td>{html.escape(r.integrator)} {r.timestep_s:g} s</td>"
            f"<td>{html.escape(r.quantity)} ({html.escape(r.unit)})</td>"
            f"<td>{_num(r.value)}</td><td>{_num(r.exact)}</td>"
            f"<td>{_num(r.error)}</td><td>{r.tolerance:g}</td>"
            f"<td>{'ok' if r.passed else 'FAIL'}</td><td>{why}</td></tr>")
    figs = "\n".join(f"<h2>{html.escape(p)}</h2><img src='{html.escape(f)}' alt='{html.escape(p)}"
                     f": the motion against its exact curve'>" for p, f in figures.items())
    n_ok = sum(r.passed for r in res.rows)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>tippetop probes</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table {{ border-collapse: collapse; font-size: 13px; }}
td, th {{ border: 1px solid #ccc; padding: 3px 6px; text-align: left; }}
tr.fail td {{ background: #fde2e2; }}
img {{ max-width: 100%; }}
</style></head><body>
<h1>Probes: the engine's parts against exact answers</h1>
<p>{n_ok} of {len(res.rows)} quantities within tolerance, {len(res.runs)} runs on
{html.escape(", ".join(res.engines))}. Each value is measured from every step of its run; the
exact values are closed forms (docs/physics/probes.md).</p>
<table><tr><th>probe</th><th>mode</th><th>engine</th><th>integrator, step</th>
<th>quantity</th><th>value</th><th>exact</th><th>error</th><th>tolerance</th><th></th>
<th>reason or note</th></tr>
{chr(10).join(rows)}
</table>
{figs}
</body></html>
"""


def write_outputs(res: ProbeResult, folder: Path) -> None:
    """The figures (``<probe>.png``) and ``report.html`` into ``folder``."""
    figures = {}
    for probe in res.probes:
        name = f"{probe}.png"
        if figure(res, probe, folder / name):
            figures[probe] = name
    (folder / "report.html").write_text(render(res, figures), "utf-8")


def moves_section(probes: dict) -> str:
    """``matrix --probes``'s section: the probe quantities that moved between the engines."""
    from tippetop.compare.presentation.probes import move_lines

    lines = move_lines(probes)
    items = "".join(f"<li>{html.escape(x.strip())}</li>" for x in lines[1:])
    return (f"<h2>Probes</h2><p>{html.escape(lines[0])}</p>"
            + (f"<ul>{items}</ul>" if items else ""))


def nightly_section(results: dict) -> str:
    """The nightly report's probes: each quantity of each probe case against its exact value.

    Empty when the nightly ran no probe case.
    """
    from tippetop.compare.report.markup import html_table

    recs = [r for r in results.get("cases", []) if r.get("kind") == "probe"]
    if not recs:
        return ""
    rows, classes = [], []
    for r in recs:
        for row in (r.get("probe") or {}).get("rows", []):
            def num(x: float | None) -> str:
                return "-" if x is None else f"{x:.6g}"

            rows.append((row["probe"], row["mode"], f"{row['engine']} {row['version']}",
                         f"{row['integrator']} {row['timestep_s']:g} s",
                         f"{row['quantity']} ({row['unit']})", num(row["value"]),
                         num(row["exact"]), num(row["error"]), f"{row['tolerance']:g}",
                         "ok" if row["passed"] else "FAIL", row.get("reason") or ""))
            classes.append("pass" if row["passed"] else "fail")
        if r.get("error") and not (r.get("probe") or {}).get("rows"):
            rows.append((r["scene"], r["mode"], r["engine"], "-", "-", "-", "-", "-", "-",
                         "FAIL", r["error"]))
            classes.append("fail")
    n_ok = sum(c == "pass" for c in classes)
    return ("<h2 id='probes'>Probes: the engine's parts against exact answers</h2>"
            f"<p>{n_ok} of {len(rows)} quantities within their tolerance of the exact value "
            "(each case's checks against its baseline are with the others, below). The "
            "closed forms: docs/physics/probes.md.</p>"
            + html_table(["probe", "mode", "engine", "integrator, step", "quantity", "value",
                          "exact", "error", "tolerance", "", "reason"], rows, classes))


__all__ = ["figure", "moves_section", "nightly_section", "render", "write_outputs"]
