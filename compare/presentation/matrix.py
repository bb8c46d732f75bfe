"""What ``tippetop matrix`` prints: the verdict first, then what changes between engines.

Then which engines ran, read back from their runs.
"""

from __future__ import annotations

from tippetop.compare.measures.metrics import metric as declared
from tippetop.compare.presentation.terminal import fmt, labelled, table
from tippetop.compare.results.matrix import Closer, MatrixResult


def closer_text(metric: str, near: Closer) -> str:
    """Which engine is nearer the reference, and its own converged answer, in words."""
    unit = declared(metric).table_unit
    ref, conv = near.reference, near.converged_nearer
    parts = []
    if ref is None:
        parts.append("to the reference: n/a (a value is missing)")
    elif ref == "tie":
        parts.append("to the reference: a tie")
    else:
        parts.append(f"to the reference ({fmt(near.reference_value, unit)}): {ref}")
    if conv is None:
        parts.append("to its own answer at dt/4: n/a")
    elif conv == "tie":
        parts.append("to its own answer at dt/4: a tie")
    else:
        gaps = ", ".join(f"{k} {fmt(v, unit)} off" for k, v in near.converged.items()
                         if v is not None)
        parts.append(f"to its own answer at dt/4: {conv} ({gaps})")
    return "; ".join(parts)


def print_matrix(res: MatrixResult) -> None:
    """The matrix for a person: the verdict against the theory first.

    Then what changes between engines, then which engines ran.
    """
    engines = res.engines
    print(f"matrix: {len(res.scenes)} scenes x {len(engines)} engines x "
          f"{len(res.modes)} modes, against the theory and each other")
    stem = sum(r.against == "reference" for r in res.runs)
    print("\nagainst the theory and the reference (the verdict's checks, 'tippetop metrics'"
          + (f"; {stem} run(s) on a stem judged against the reference" if stem else "")
          + "):")
    rows = []
    for e in engines:
        for mode in res.modes:
            mine = [r for r in res.runs if r.engine == e.engine and r.mode == mode]
            if not mine:
                continue
            agree = sum(r.agrees for r in mine)
            failed = sum(not r.ran for r in mine)
            why = [f"{r.scene}: {'; '.join(r.reasons) or 'departs'}" for r in mine
                   if not r.agrees]
            rows.append((e.engine, mode, f"{agree} of {len(mine)}", str(failed),
                         why[0] + (f" (and {len(why) - 1} more)" if len(why) > 1 else "")
                         if why else ""))
    print(table(("engine", "mode", "agree", "failed", "first departure"), rows, indent="  "))
    diffs = res.differences
    print("\nwhat changes between engines (beyond the nightly's tolerances):"
          + ("" if diffs else " nothing"))
    width = max([len(f"{d.scene} {d.mode}") for d in diffs] or [0])
    for d in diffs:
        (a, b), (va, vb) = d.engines, d.values
        unit = declared(d.metric).table_unit
        text = (f"{d.metric} {fmt(va, unit)} ({a}) against {fmt(vb, unit)} ({b})"
                + (f", over {fmt(d.tolerance, unit)}" if d.tolerance is not None else ""))
        print(labelled(f"{d.scene} {d.mode}", text, width))
        if d.attribution:
            print(labelled("", f"follows: {d.attribution.follows}", width))
        if d.closer:
            print(labelled("", f"closer: {closer_text(d.metric, d.closer)}", width))
    realised = [r for r in res.runs if r.mode != "paper" and r.engine != "ode"
                and (r.friction_realised or {}).get("samples")]
    if realised:
        from tippetop.compare.measures.friction_realised import realised_sentence

        print("\nthe friction law as each engine realises it (the ball's phase):")
        for r in realised:
            name = f"{r.scene} {r.mode} {r.engine}"
            print(f"  {realised_sentence(name, r.friction_realised)}")
    print("\nengines (read back from their runs):")
    print(table(("engine", "implementation", "version", "precision", "device"),
                [(e.engine, e.implementation, fmt(e.version), e.precision, e.device)
                 for e in engines], indent="  "))


__all__ = ["closer_text", "print_matrix"]
