"""What ``tippetop fidelity`` prints: a row per point (agrees, residual, cause), and a summary."""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.terminal import fmt_duration
from tippetop.compare.results.fidelity import FidelityResult


def _cell(v: Any, fmt: str) -> str:
    return "-" if v is None else f"{v:{fmt}}"


def table_lines(res: FidelityResult) -> list[str]:
    """The terminal table: one row per point (A/C, a/R, mu, group, agrees, residual, cause)."""
    head = f"{'A/C':>5} {'a/R':>5} {'mu':>4} {'group':>5} {'agrees':>6} {'residual':>11}  cause"
    lines = [head]
    for p in res.points:
        agrees = "yes" if p.agrees else "no"
        resid = "-" if p.residual is None else f"{p.residual:.2g} rad"
        group = p.group or "-"
        lines.append(f"{_cell(p.A_over_C, '5.3g')} {_cell(p.a_over_R, '5.3g')} "
                     f"{_cell(p.mu, '4.3g')} {group:>5} {agrees:>6} {resid:>11}  "
                     f"{p.cause or '-'}")
    return lines


def summary_lines(res: FidelityResult) -> list[str]:
    """Sentences: how many points agree, per mu and per group."""
    pts = res.points
    lines = [f"MuJoCo's native contact, tuned, follows the paper's law at "
             f"{sum(p.agrees for p in pts)} of {len(pts)} points"]
    for key, label in (("mu", "mu"), ("group", "Group")):
        parts = []
        for v in dict.fromkeys(getattr(p, key) for p in pts):
            mine = [p for p in pts if getattr(p, key) == v]
            name = f"{v:g}" if isinstance(v, float) else v or "-"
            parts.append(f"{label} {name}: {sum(p.agrees for p in mine)}/{len(mine)}")
        lines.append("; ".join(parts))
    return lines


def print_fidelity(res: FidelityResult) -> None:
    """The header (grid, what ran), the table and the summary."""
    g = res.grid
    cached = res.cached
    whence = ("" if not cached else " (every point's tuning from the cache)"
              if cached == len(res.points) else f" ({cached} points' tuning from the cache)")
    at_once = res.points_at_once
    where = (f" on the Dask cluster at {res.scheduler}" if res.scheduler
             else f", {at_once} points at once" if at_once and at_once > 1 else "")
    print(f"tippetop fidelity: grid {g.name}, {g.points} points; engine "
          f"{res.engine} (MuJoCo {res.mujoco_version}), mode {res.mode}, tuned and "
          f"verified from 4 starts of {res.t_end_s:g} s; {res.runs} fit rollouts, "
          f"{fmt_duration(res.wall_s)}{where}{whence}")
    for line in table_lines(res):
        print(line)
    for line in summary_lines(res):
        print(line)


__all__ = ["print_fidelity", "summary_lines", "table_lines"]
