"""``tippetop probe``'s text: each run's line, then a line per quantity against its exact value."""

from __future__ import annotations

import math
import sys
from typing import TextIO

from tippetop.compare.probes.study import ProbeResult, ProbeRow


def _num(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:.6g}"


def _err(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:+.3g}"


def row_line(r: ProbeRow, width: int) -> str:
    """One quantity of a run: its name and unit, value, exact value, error, tolerance, verdict.

    Its reason (a failed run) or note follows on the next line, indented.
    """
    verdict = "ok" if r.passed else "FAIL"
    line = (f"  {f'{r.quantity} ({r.unit})'.ljust(width)}  {_num(r.value):>11}  "
            f"{_num(r.exact):>11}  {_err(r.error):>10}  {r.tolerance:>8g}  {verdict}")
    why = r.reason or r.note
    return f"{line}\n      {why}" if why else line


def run_header(r: ProbeRow) -> str:
    """A run's line: the probe in its mode on its engine, the integrator and step that ran."""
    return f"{r.probe} [{r.mode}] on {r.engine} {r.version}, {r.integrator} at {r.timestep_s:g} s"


def print_probes(res: ProbeResult, out: TextIO | None = None) -> None:
    """Print each run's line and its quantities under it, then how many passed."""
    out = out or sys.stdout
    rows = res.rows
    if not rows:
        print("no probe ran (no probe has the modes asked for)", file=out)
        return
    width = max(8, *(len(f"{r.quantity} ({r.unit})") for r in rows))
    print(f"  {'quantity'.ljust(width)}  {'value':>11}  {'exact':>11}  {'error':>10}  "
          f"{'tol':>8}", file=out)
    for run in res.runs:
        if not run.rows:
            continue
        print(run_header(run.rows[0]), file=out)
        for r in run.rows:
            print(row_line(r, width), file=out)
    n_ok = sum(r.passed for r in rows)
    cached = sum(run.cached for run in res.runs)
    print(f"\n{n_ok} of {len(rows)} quantities within tolerance; {len(res.runs)} runs "
          f"({cached} from the cache) in {res.wall_s:.1f} s", file=out)
    for name in res.skipped:
        print(f"not run: {name} (none of its modes asked for)", file=out)


def move_lines(probes: dict) -> list[str]:
    """``matrix --probes``: which probe quantities moved between which engines, one a line."""
    moved = probes.get("moved", [])
    n = probes.get("total", 0)
    if not moved:
        return [f"probes: no probe quantity moved between the engines ({n} rows, each within "
                "a tenth of its tolerance against the exact value of the other engines')"]
    out = [f"probes: {len(moved)} quantities moved between the engines (beyond a tenth of "
           "their tolerance against the exact value):"]
    for m in moved:
        a, b = m["engines"]
        va, vb = m["values"]

        def num(x: float | None) -> str:
            return "failed" if x is None else f"{x:.6g}"

        near = f"; nearer the exact value: {m['nearer_exact']}" if m.get("nearer_exact") else ""
        out.append(f"  {m['probe']} [{m['mode']}] {m['quantity']}: {a} {num(va)}, {b} "
                   f"{num(vb)} (exact {num(m['exact'])}){near}")
    return out


def print_moves(probes: dict, out: TextIO | None = None) -> None:
    """Print :func:`move_lines`."""
    print("\n" + "\n".join(move_lines(probes)), file=out or sys.stdout)


__all__ = ["move_lines", "print_moves", "print_probes", "row_line", "run_header"]
