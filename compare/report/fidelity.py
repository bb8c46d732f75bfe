"""The fidelity map's figure and page: the group diagram coloured by agreement, one panel per mu."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tippetop.compare.presentation.figures import pyplot
from tippetop.compare.report.groupmap import draw_groups
from tippetop.compare.report.markup import Cell, esc, html_table, page, png

#: A point's marker colour: agrees, departs, not tuned (the tuning stopped).
AGREE_COLOURS = {"agrees": "#2e7d32", "departs": "#c62828", "not tuned": "#757575"}


def point_state(p: Mapping[str, Any]) -> str:
    """``agrees``, ``departs`` or ``not tuned`` (the tuning stopped: ``error``)."""
    if p.get("agrees"):
        return "agrees"
    return "not tuned" if p.get("error") else "departs"


def fidelity_figure(result: Mapping[str, Any]) -> Any:
    """The (a/R, A/C) plane with the paper's groups, each point coloured by agreement.

    One panel per mu; each point numbered as in the table (:func:`point_rows`).
    """
    plt = pyplot()
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    pts = list(result["points"])
    mus = list(dict.fromkeys(p["mu"] for p in pts))
    fig, axes = plt.subplots(1, len(mus), figsize=(3.6 * len(mus) + 1.8, 4.2), squeeze=False,
                             sharey=True)
    xs = [p["a_over_R"] for p in pts]
    ys = [p["A_over_C"] for p in pts]
    xlim = (0.0, max(0.3, 1.2 * max(xs)))
    ylim = (min(0.6, 0.9 * min(ys)), max(1.5, 1.1 * max(ys)))
    for ax, mu in zip(axes[0], mus, strict=True):
        draw_groups(ax, xlim, ylim)
        for num, p in enumerate(pts, start=1):
            if p["mu"] != mu:
                continue
            ax.plot(p["a_over_R"], p["A_over_C"], "o", ms=10,
                    color=AGREE_COLOURS[point_state(p)], mec="k", mew=0.6)
            ax.annotate(str(num), (p["a_over_R"], p["A_over_C"]), xytext=(7, 5),
                        textcoords="offset points", fontsize=8, color="0.15")
        ax.set_title(f"mu = {mu:g}", fontsize=10)
        # panels side by side: round ticks, no clashing labels at the junction
        ax.xaxis.set_major_locator(MaxNLocator(4, steps=[1, 2, 5, 10]))
        ax.text(0.97 * xlim[1], ylim[0] + 0.03 * (ylim[1] - ylim[0]), "I", ha="right",
                fontsize=12, weight="bold", color="0.4")
        ax.text(0.97 * xlim[1], 1.0, "II", ha="right", va="center", fontsize=12,
                weight="bold", color="0.4")
        ax.text(0.03 * xlim[1], ylim[1] - 0.04 * (ylim[1] - ylim[0]), "III", va="top",
                fontsize=12, weight="bold", color="0.4")
    for ax in axes[0][1:]:
        ax.set_ylabel("")
    handles = [Line2D([], [], ls="", marker="o", ms=8, color=c, mec="k", label=s)
               for s, c in AGREE_COLOURS.items()]
    axes[0][-1].legend(handles=handles, fontsize=8, loc="upper left",
                       bbox_to_anchor=(1.02, 1.0))
    fig.suptitle("MuJoCo's native contact, tuned to the reference: does it follow the "
                 "paper's law?", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.84 if len(mus) > 1 else 0.7, bottom=0.13,
                        top=0.84, wspace=0.14)
    return fig


def _num(v: Any, fmt: str = ".3g") -> str:
    return "-" if v is None else f"{v:{fmt}}"


def answer_text(p: Mapping[str, Any]) -> str:
    """How a point's answer was found and what it runs: ``the fit; pyramidal, RK4 at 0.2 ms``.

    ``chosen`` in words (the fit, one of its seeds, or the widening's step), then the cone,
    integrator and step of the settings verified; ``-`` for a point not tuned.
    """
    from tippetop.compare.tuning.judge import widening_step

    s = p.get("settings") or {}
    chosen = str(p.get("chosen") or "")
    if not s or not chosen:
        return "-"
    step = widening_step(chosen)
    how = ("the fit" if chosen == "fit" else f"the widening: {step}" if step is not None
           else f"the fit's {chosen}")
    dt = s.get("timestep_s")
    ran = ", ".join(str(v) for v in (s.get("cone"), s.get("integrator")) if v)
    return f"{how}; {ran}" + (f" at {dt * 1e3:g} ms" if dt else "")


def point_rows(result: Mapping[str, Any]) -> list[tuple[Any, ...]]:
    """The table's rows: #, A/C, a/R, mu, group, agrees, residual (rad), answer, cause."""
    return [(i, _num(p["A_over_C"]), _num(p["a_over_R"]), _num(p["mu"]), p["group"] or "-",
             point_state(p) if not p.get("agrees") else "yes",
             _num(p.get("residual"), ".2g"), answer_text(p), p.get("cause") or "-")
            for i, p in enumerate(result["points"], start=1)]


def report_page(result: Mapping[str, Any]) -> str:
    """report.html: the figure, the summary, one row per point, and what ran."""
    from tippetop.compare.studies.fidelity import summary_lines
    from tippetop.compare.tuning.tune import HELD_OUT

    summary = summary_lines(dict(result))
    rows = point_rows(result)
    cells = [(*r[:5], Cell(esc(r[5]), "pass" if r[5] == "yes" else "fail"), *r[6:])
             for r in rows]
    g = result["grid"]
    ran = (f"engine {esc(result['engine'])} (MuJoCo {esc(result.get('mujoco_version'))}), "
           f"mode {esc(result.get('mode'))}; verification runs of "
           f"{result['t_end_s']:g} s from the fit's start and {len(HELD_OUT)} held-out starts; "
           f"{result['runs']} fit rollouts; {result['wall_s']:.0f} s wall time")
    body = [
        "<h1>tippetop fidelity <small>where MuJoCo's own contact, tuned, follows the paper's "
        "law</small></h1>",
        f"<p class='note'>Grid {esc(g['name'])}: A/C {esc(g['A_over_C'])}, a/R "
        f"{esc(g['a_over_R'])}, mu {esc(g['mu'])} ({g['points']} points). At each point "
        "MuJoCo's native contact (mu, solref, solimp, impratio, cone) is fitted to the "
        "reference's theta(t) at the start and verified from held-out starts (a faster and "
        "a slower spin, a larger tilt) with every check of the verdict, as "
        "<code>tippetop validate</code> tunes a file. A point agrees when every check passes "
        "from every start; the cause is the first check that departs.</p>",
        "<ul>" + "".join(f"<li>{esc(s)}</li>" for s in summary) + "</ul>",
        f"<figure>{png(fidelity_figure(result))}<figcaption>The group diagram (Group I: "
        "A/C &lt; 1 - a/R; II between the lines; III: A/C &gt; 1 + a/R), one panel per mu; "
        "numbers refer to the table.</figcaption></figure>",
        html_table(["#", "A/C", "a/R", "mu", "group", "agrees", "residual (rad)",
                    "answer (how found; what runs)", "cause"], cells),
        f"<p class='note'>What ran: {ran}. The residual is the fit's: "
        "sqrt(RMS(theta_mujoco - theta_reference)^2 + (100 rad x RMS(J/J0 - 1))^2); where "
        "the answer is the widening's, it is the fit's before the widening (a neighbour or a "
        "draw is verified, not fitted). The settings of each answer are results.json's "
        "<code>settings</code>.</p>",
    ]
    return page("tippetop fidelity", body)


def main(argv: list[str] | None = None) -> int:
    """``python -m tippetop.compare.report.fidelity RESULTS.json OUT.png``: the figure again.

    Drawn from a map's results.json (``tippetop fidelity --out DIR`` writes one).
    """
    import json
    import sys
    from pathlib import Path

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or not args[1].endswith(".png"):
        print("fidelity figure: expected RESULTS.json OUT.png, got " + (" ".join(args)
              or "nothing"), file=sys.stderr)
        return 2
    try:
        result = json.loads(Path(args[0]).read_text(encoding="utf-8"))
        points = result["points"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"fidelity figure: expected a fidelity map's results.json, got {args[0]} "
              f"({exc.__class__.__name__}: {exc})", file=sys.stderr)
        return 2
    if not points:
        print(f"fidelity figure: expected points in {args[0]}, got none", file=sys.stderr)
        return 2
    fig = fidelity_figure(result)
    fig.savefig(args[1], dpi=100)
    print(args[1])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["AGREE_COLOURS", "answer_text", "fidelity_figure", "main", "point_rows", "point_state",
           "report_page"]
