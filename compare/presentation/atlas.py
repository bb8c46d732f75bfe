"""What ``tippetop atlas`` prints: agreement per run, the findings, the points that depart."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tippetop.compare.results.atlas import AtlasResult


def print_atlas(res: AtlasResult) -> None:
    """The human summary: agreement per run, the findings, and the points that depart."""
    ac, ar = res.A_over_C, res.a_over_R
    print(f"tippetop atlas: {len(ac)} x {len(ar)} points (A/C "
          f"{ac[0]:g}..{ac[-1]:g}, a/R {ar[0]:g}.."
          f"{ar[-1]:g}), {res.n_runs} runs of 2 s")
    for eng, frac in res.agreement.items():
        pts = [p for p in res.points if p.run == eng]
        print(f"  {eng:<16} groups agree with the theory at {round(frac * len(pts))} of "
              f"{len(pts)} points ({100 * frac:.0f} %)")
    for f in res.findings:
        print(f"  {f}")
    for p in res.points:
        if p.agrees:
            continue
        print(f"  departs: {p.run} at A/C = {p.A_over_C:.3g}, a/R = "
              f"{p.a_over_R:.3g}: Group {p.group_measured} (theory {p.group_theory});"
              f" n1 {_fmt(p.n1_measured)} (theory {_fmt(p.n1_theory)}), n4 "
              f"{_fmt(p.n4_measured)} (theory {_fmt(p.n4_theory)}) rad/s")


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


__all__ = ["print_atlas"]
