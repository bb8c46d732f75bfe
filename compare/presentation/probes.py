"""``tippetop probe``'s text: one line per quantity, its value against its exact value."""

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


def row_line(r: ProbeRow, widths: dict[str, int]) -> str:
    """One row: probe, mode, engine, integrator and step, quantity, value, exact, error, tol."""
    verdict = "ok" if r.passed else "FAIL"
    parts = [r.probe.ljust(widths["probe"]), r.mode.ljust(widths["mode"]),
             f"{r.engine} {r.version}".ljust(widths["engine"]),
             f"{r.integrator} {r.timestep_s:g}s".ljust(widths["integrator"]),
             f"{r.quantity} ({r.unit})".ljust(widths["quantity"]),
             _num(r.value).rjust(12), _num(r.exact).rjust(12), _err(r.error).rjust(10),
             f"{r.tolerance:g}".rjust(8), verdict]
    line = "  ".join(parts)
    if r.reason:
        line += f"  ({r.reason})"
    elif r.note:
        line += f"  ({r.note})"
    return line


def print_probes(res: ProbeResult, out: TextIO | None = None) -> None:
    """Print every row, then how many passed and what did not."""
    out = out or sys.stdout
    rows = res.rows
    if not rows:
        print("no probe ran (no probe has the modes asked for)", file=out)
        return
    widths = {
        "probe": max(5, *(len(r.probe) for r in rows)),
        "mode": max(4, *(len(r.mode) for r in rows)),
        "engine": max(6, *(len(f"{r.engine} {r.version}") for r in rows)),
        "integrator": max(10, *(len(f"{r.integrator} {r.timestep_s:g}s") for r in rows)),
        "quantity": max(8, *(len(f"{r.quantity} ({r.unit})") for r in rows)),
    }
    head = "  ".join(["probe".ljust(widths["probe"]), "mode".ljust(widths["mode"]),
                      "engine".ljust(widths["engine"]), "integrator".ljust(widths["integrator"]),
                      "quantity".ljust(widths["quantity"]), "value".rjust(12),
                      "exact".rjust(12), "error".rjust(10), "tol".rjust(8), ""])
    print(head.rstrip(), file=out)
    for r in rows:
        print(row_line(r, widths), file=out)
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


__all__ = ["move_lines", "print_moves", "print_probes", "row_line"]
