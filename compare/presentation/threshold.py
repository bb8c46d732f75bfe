"""What ``tippetop threshold`` prints: the measured critical spin against the theory's."""

from __future__ import annotations

from typing import TYPE_CHECKING

from tippetop.compare.presentation.terminal import fmt, fmt_percent, table

if TYPE_CHECKING:
    from tippetop.compare.results.threshold import ThresholdResult

#: Where the theory's value of each threshold comes from.
THRESHOLD_THEORY = {"n1": "eq. 4.13", "n4": "n3 (1 + a/R) / (1 - a/R)",
                    "nc": "Sec. 4.3: n4, or n1 for A/C <= rc"}


def print_threshold(res: ThresholdResult) -> None:
    """A measured critical spin for a person.

    The measured spin against the theory's, how it was measured (growth rates or a
    bisection), the check at twice the horizon (bisection), and a warning when the answer is
    not to be trusted.
    """
    which = res.which
    method = res.method
    if method == "growth":
        how = (f"from growth rates of {res.n_runs} runs of {fmt(res.horizon_s, 's')} near the "
               "steady state")
    else:
        how = f"by bisection on n0 over {res.n_runs} runs of {fmt(res.horizon_s, 's')}"
    print(f"{which} of {res.scene} on {res.engine} in mode "
          f"{'?' if res.mode is None else res.mode}, {how}:")
    bracket = res.bracket or (None, None)
    rows = [
        ("measured", fmt(res.measured, "rad/s"),
         f"bracket {fmt(bracket[0])} to {fmt(bracket[-1], 'rad/s')}"),
        ("theory", fmt(res.theory, "rad/s"), THRESHOLD_THEORY.get(which, "")),
        ("difference", fmt_percent(res.rel_diff), "measured / theory - 1"),
    ]
    if which == "nc" and method == "growth":
        rows += [("n1", fmt(res.n1, "rad/s"), "measured"), ("n4", fmt(res.n4, "rad/s"),
                                                            "measured")]
    print(table(("", "value", ""), rows, indent="  ", header=False))
    check = res.horizon_check
    if check is not None:
        h2 = fmt(check.horizon_s, "s")
        if check.depends_on_horizon:
            print(f"  horizon check: over {h2} the bracket's ends change side")
        else:
            print(f"  horizon check: over {h2} the bracket's ends keep their side")
    if method == "growth":
        print("  fits: " + ("every run is two modes, cleanly" if res.settled else
                            "some runs are not two clean modes (see runs in --json)"))
    elif res.unsettled_n0:
        print("  still moving at the end of their runs: n0 = "
              + ", ".join(fmt(n) for n in res.unsettled_n0) + " rad/s")
    why = []
    if res.bracket_converged is False:
        why.append("the bracket is wider than --rel-tol after the rounds allowed")
    if res.depends_on_horizon:
        why.append("the answer depends on the run length")
    if method == "growth" and not res.settled:
        why.append("a fit is not clean")
    conv = res.converged
    print(f"  converged: {fmt(conv)}" + (f" ({'; '.join(why)})" if why and not conv else ""))
    if res.warning:
        print(f"  warning: {res.warning}")


__all__ = ["THRESHOLD_THEORY", "print_threshold"]
