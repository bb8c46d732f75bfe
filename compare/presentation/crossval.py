"""What ``tippetop compare`` prints: the theory, one line per run, what differs and why."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from tippetop.compare.measures.metrics import METRICS, Wording
from tippetop.compare.presentation.terminal import MISSING, fmt, fmt_value, labelled, table

if TYPE_CHECKING:
    from tippetop.compare.results.crossval import CompareResult


def _unit(metric: str) -> str:
    """A metric's declared unit (:mod:`tippetop.compare.measures.metrics`)."""
    m = METRICS.get(metric)
    return m.unit if m is not None and m.unit != "fraction" else ""


def _tolerance_why(metric: str, d: dict[str, Any]) -> str:
    """Why a tolerance is what it is: the difference's own ``why``, else crossval's table."""
    why = d.get("why")
    if not why:
        try:
            from tippetop.compare.measures.verdict import TOLERANCES

            why = TOLERANCES.get(metric, (None, ""))[1]
        except ImportError:  # pragma: no cover - crossval is part of the package
            why = ""
    # the table's reasons start with the unit ("s; 1 ms sampling ..."): the unit is shown
    head, sep, tail = str(why or "").partition("; ")
    return tail if sep and len(head) <= 12 else str(why or "")


def difference_text(d: dict[str, Any]) -> str:
    """One difference from the reference in words, naming the tolerance it broke.

    Worded as the metric's declaration says (:class:`~tippetop.compare.measures.metrics.
    Wording`). Example: ``t_invert 2.496 s against the reference's 2.329 s: 0.167 s apart,
    over the t_invert tolerance of 0.1 s (1 ms sampling plus ...)``.
    """
    metric = str(d.get("metric", "?"))
    declared = METRICS.get(metric)
    w = declared.wording if declared is not None else Wording()
    unit = _unit(metric)
    value, ref, tol = d.get("value"), d.get("reference"), d.get("tolerance")
    said = {"value": fmt(value, unit), "ref": fmt(ref, unit), "note": d.get("note") or value}
    if w.whole:
        return w.whole.format(**said)
    if w.by_run:
        return (w.run_none if value is None else w.ref_none).format(**said)
    if w.run_none and value is None and ref is not None:
        return w.run_none.format(**said)
    if w.ref_none and ref is None and value is not None:
        return w.ref_none.format(**said)
    if w.value:
        text = w.value.format(**said)
    else:
        text = f"{metric} {said['value']}"
        if ref is not None:
            text += f" against the reference's {said['ref']}"
    if tol is None:
        return text
    if w.gap and isinstance(value, (int, float)) and isinstance(ref, (int, float)):
        text += f": {fmt(abs(value - ref), unit)} apart"
    why = _tolerance_why(metric, d)
    return f"{text}, over the {metric} {w.bound} of {fmt(tol, unit)}" + (
        f" ({why})" if why else "")


def _print_prediction(res: CompareResult) -> None:
    """The scene, its group and the theory's prediction, in one line."""
    th = res.theory
    head = (f"{'?' if res.scene is None else res.scene} "
            f"(Group {'?' if res.group is None else res.group}): ")
    if th is not None and th.outcome is None:  # needs a run's Jellett constant at t = 0
        print(head + "no prediction from the theory: every run failed")
    else:
        print(head + f"the theory predicts {'?' if th is None else th.outcome}, theta_s = "
              f"{fmt(th.theta_s if th is not None else None, 'rad')}")


def print_compare(res: CompareResult) -> None:
    """``tippetop compare`` for a person: the theory, one line per run, what differs and why.

    Robust to the keys each run and difference has, and to a partial result: a missing
    value is ``-``.
    """
    _print_prediction(res)
    tol_s = res.theory.theta_s_tol if res.theory is not None else None
    runs = {str(s.get("run")): s for s in res.runs}
    rows = []
    for m, s in runs.items():
        matches = s.get("agrees", s.get("matches_theory"))
        if s.get("outcome") == "failed":
            rows.append((m, "failed", "DIFFERS" if matches is False else MISSING,
                         *[MISSING] * 5))
            continue
        word = {True: "agrees", False: "DIFFERS", None: MISSING}.get(matches, fmt(matches))
        if s.get("against") == "reference" and matches is not None:
            word += " (vs ref)"
        rows.append((
            m + (" (reference)" if s.get("reference") else ""),
            fmt(s.get("outcome")),
            word,
            fmt_value("t_invert", s.get("t_invert")).split(" (")[0],
            fmt(s.get("theta_asymp"), "rad"),
            fmt(s.get("J_rel_drift"), "relative"),
            fmt(s.get("energy_dissipated_J"), "J"),
            MISSING if s.get("reference") else fmt(s.get("theta_rms_vs_ref"), "rad"),
        ))
    if rows:
        print()
        print(table(("run", "outcome", "verdict", "t_invert", "theta_asymp", "J drift",
                     "energy lost", "theta RMS vs ref"), rows))
    agree_rule = (f"agrees: every check passes: the theory's outcome, theta_asymp within "
                  f"{fmt(tol_s, 'rad')} of theta_s (vs ref: a top that reaches its stem, "
                  "judged against the reference), the reference's event times, the ball on "
                  "the table, Jellett's constant kept, no energy gained")
    print(f"  (run: engine/mode; {agree_rule}; J drift: Jellett's constant while the ball "
          "alone touches, relative)")
    against = [(str(r.get("run")), r.get("reasons") or []) for r in res.crossval
               if not r.get("agrees", True)]
    if against:
        print("\nwhy not:")
        width = max(len(m) for m, _ in against)
        for m, reasons in against:
            print(labelled(m, "; ".join(reasons) if reasons else "does not agree", width))
    diffs = res.differences
    print()
    if not diffs:
        print("differences from the reference beyond their tolerances: none")
    else:
        print(f"differences from the reference ({res.reference or 'ode'}) beyond their "
              "tolerances:")
        width = max(len(str(d.get("run", ""))) for d in diffs)
        for d in diffs:
            print(labelled(str(d.get("run", "?")), difference_text(d), width))
    realised = [(m, s["friction_realised"]) for m, s in runs.items()
                if s.get("engine") != "ode"
                and (s.get("friction_realised") or {}).get("samples")]
    if realised:
        from tippetop.compare.measures.friction_realised import realised_sentence

        print("\nthe friction law as each run realises it (the ball's phase):")
        width = max(len(m) for m, _ in realised)
        for m, fr in realised:
            print(labelled(m, realised_sentence(m, fr).split(": ", 1)[1], width))
            if (fr.get("refit") or {}).get("sentence"):
                print(labelled("", f"refit: {fr['refit']['sentence']}", width))
                if fr["refit"].get("remains"):
                    print(labelled("", "what else differs: " + ", ".join(fr["refit"]["remains"]),
                                   width))
    ran = []
    for m, s in runs.items():
        if "engine" not in s:
            continue
        try:
            from tippetop.compare.measures.summary import describe_ran

            text = describe_ran(s)
        except (KeyError, TypeError, ValueError):
            text = MISSING
        ran.append((m, re.sub(r"\b(None|nan)\b", MISSING, text)))
    if ran:
        print("\nwhat ran:")
        width = max(len(m) for m, _ in ran)
        for m, text in ran:
            print(labelled(m, text, width))
    notes = [(m, str(s.get("note"))) for m, s in runs.items()
             if s.get("note") and not s.get("reference")]
    if notes:
        print("\nwhy a run may depart from the paper's law:")
        width = max(len(m) for m, _ in notes)
        for m, note in notes:
            print(labelled(m, note, width))


__all__ = ["difference_text", "print_compare"]
