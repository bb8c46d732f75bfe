"""The report's group map: the (a/R, A/C) plane, Groups I-III, and each top's simulated outcome."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.presentation.verdict import run_of
from tippetop.compare.report.markup import html_table, png

#: Groups are shaded in pale neutral tints and outcomes drawn in saturated colours that none
#: of the tints resembles, so a marker never disappears into its group.
GROUP_COLOURS = {"I": "#e6e6e6", "II": "#fff5cc", "III": "#ecdff5"}
_OUTCOME_COLOURS = {"upright": "#1565c0", "intermediate": "#e65100", "inverted": "#1b5e20",
                    "inconclusive": "#9e9e9e", None: "#c62828"}
_ENGINE_MARKERS = {"ode/paper": "o", "mujoco/paper": "s", "mujoco/native": "^"}


def draw_groups(ax: Any, xlim: tuple[float, float], ylim: tuple[float, float]) -> None:
    """Shade Groups I/II/III and draw the lines A/C = 1 - a/R and 1 + a/R."""
    xs = np.linspace(0.0, 1.0, 200)
    for lo, hi, colour in zip((0.0 * xs, 1 - xs, 1 + xs), (1 - xs, 1 + xs, 5.0 + 0 * xs),
                              GROUP_COLOURS.values(), strict=True):
        ax.fill_between(xs, lo, hi, color=colour, lw=0)
    ax.plot(xs, 1 - xs, "k-", lw=1, label="_A/C = 1 - a/R")
    ax.plot(xs, 1 + xs, "k-", lw=1, label="_A/C = 1 + a/R")
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_xlabel("a/R")
    ax.set_ylabel("A/C")


def group_map_section(results: Mapping[str, Any]) -> str:
    """The (a/R, A/C) plane with Groups I-III and the catalogue's simulated tops."""
    plt = pyplot()
    from matplotlib.lines import Line2D
    from matplotlib.transforms import offset_copy

    recs = [r for r in results.get("cases", []) if r["kind"] in ("run", "sweep")]
    points: dict[tuple[float, float], list[Mapping[str, Any]]] = {}
    for r in recs:
        p = r["params"]
        points.setdefault((round(p["a_over_R"], 6), round(p["A_over_C"], 6)), []).append(r)
    fig, (ax_all, ax_zoom) = plt.subplots(1, 2, figsize=(13, 5.4),
                                          gridspec_kw={"width_ratios": [1, 1.3]})
    draw_groups(ax_all, (0.0, 0.7), (0.5, 2.0))
    ax_all.text(0.55, 0.58, "I", fontsize=16, weight="bold")
    ax_all.text(0.6, 1.0, "II", fontsize=16, weight="bold")
    ax_all.text(0.05, 1.85, "III", fontsize=16, weight="bold")
    ax_all.text(0.40, 0.51, "A/C = 1 - a/R", fontsize=8, rotation=-25)
    ax_all.text(0.40, 1.45, "A/C = 1 + a/R", fontsize=8, rotation=25)
    xs = [x for x, _ in points] or [0.1]
    ys = [y for _, y in points] or [1.0]
    zx = (max(0.0, min(xs) - 0.03), max(xs) + 0.03)
    zy = (min(ys) - 0.08, max(ys) + 0.08)
    draw_groups(ax_zoom, zx, zy)
    ax_all.add_patch(plt.Rectangle((zx[0], zy[0]), zx[1] - zx[0], zy[1] - zy[0], fill=False,
                                   ls="--", lw=0.8, color="0.3"))
    rows = []
    for num, ((x, y), group) in enumerate(sorted(points.items()), start=1):
        runs = [r for r in group if r["kind"] == "run"]
        radius = 0.0 if len(runs) <= 1 else 4.0 + 1.2 * len(runs)  # (points) around the top
        for ax in (ax_all, ax_zoom):
            ax.annotate(str(num), (x, y), xytext=(radius + 6, 4), textcoords="offset points",
                        fontsize=7 if ax is ax_all else 8, color="0.15")
        if not runs:
            for ax in (ax_all, ax_zoom):
                ax.plot(x, y, "+", ms=9, color="0.3")
        for k, r in enumerate(runs):
            ang = 2 * math.pi * k / max(1, len(runs))
            shift = offset_copy(ax_zoom.transData, fig=fig, units="points",
                                x=radius * math.cos(ang), y=radius * math.sin(ang))
            outcome = (r.get("values") or {}).get("outcome")
            mk = _ENGINE_MARKERS.get(run_of(r), "o" if r["engine"] == "ode" else "v")
            colour = _OUTCOME_COLOURS.get(outcome, "#7f7f7f")
            ax_all.plot(x, y, mk, ms=5, color=colour, mec="k", mew=0.4)
            ax_zoom.plot(x, y, mk, ms=6, color=colour, mec="k", mew=0.4, transform=shift)
        if len(runs) > 1:
            ax_zoom.plot(x, y, ".", ms=2, color="k")
        names = ", ".join(f"{r['name']}[{run_of(r)}]: {(r.get('values') or {}).get('outcome')}"
                          if r["kind"] == "run" else f"{r['name']}[{run_of(r)}]: sweep"
                          for r in group)
        th = group[0].get("theory", {})
        rows.append((num, x, y, th.get("group", "-"), names))
    handles = [Line2D([], [], ls="", marker="o", color=c, mec="k", mew=0.4, label=o)
               for o, c in _OUTCOME_COLOURS.items() if o is not None]
    handles += [Line2D([], [], ls="", marker=m, color="w", mec="k", label=e)
                for e, m in _ENGINE_MARKERS.items()]
    handles.append(Line2D([], [], ls="", marker="+", color="0.3", label="swept top"))
    ax_zoom.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax_all.set_title("the (a/R, A/C) plane", fontsize=10)
    ax_zoom.set_title("the catalogue's tops (runs of one top spread around its point)",
                      fontsize=10)
    fig.subplots_adjust(left=0.06, right=0.89, bottom=0.1, top=0.93, wspace=0.18)
    return ("<h2 id='groups'>Group map</h2><p class='note'>Background: Group I (A/C &lt; 1 - a/R, "
            "grey): theta = 0 is stable for every spin; Group II (between the lines, pale "
            "yellow): the top can turn over; Group III (A/C &gt; 1 + a/R, pale lilac): it rises "
            "to an intermediate angle below theta_f. Markers: colour the simulated outcome "
            "(blue upright, orange intermediate, dark green inverted, grey inconclusive), "
            "shape the engine/mode. "
            "Numbers refer to the table below.</p>"
            f"<figure>{png(fig)}</figure>"
            + html_table(["#", "a/R", "A/C", "group", "cases and simulated outcomes"], rows))
