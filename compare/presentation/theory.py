"""What ``tippetop theory`` prints: the paper's numbers for a top, each with what it is."""

from __future__ import annotations

from typing import Any

from tippetop.compare.presentation.terminal import fmt, fmt_value, table

#: What each number of ``tippetop theory`` is (the paper's names in brackets).
THEORY_MEANINGS: dict[str, str] = {
    "group": "the paper's classification by A/C and a/R (Sec. 4)",
    "n1": "spin above which the vertical state theta = 0 is unstable (eq. 4.13)",
    "n2": "spin below which no precession exists at theta = pi",
    "n3": "spin at theta = pi above which the inverted state is stable",
    "n4": "spin at theta = 0 that leaves n3 after inversion",
    "nc": "spin above which a Group II top inverts fully (Sec. 4.3)",
    "rc": "A/C at which F(-1) = F(1) (depends on a/R only)",
    "theta_c": "Group I: critical angle (below it theta falls back to 0)",
    "theta_f": "Group III: the fixed point theta settles at",
    "theta_d": "Group II (rc < A/C < 1): the jump angle",
    "theta_s": "asymptotic angle predicted for the start near theta = 0",
}


def print_theory(out: dict[str, Any], top: Any, n0: float | None) -> None:
    """The theory's numbers with units and what each one is; ``-`` where it does not exist."""
    print(f"Group {out['group']} top: A/C = {fmt(top.A_over_C)}, a/R = {fmt(top.a_over_R)}, "
          f"R = {fmt(top.R_m, 'm')}, M = {fmt(top.M_kg, 'kg')}")
    rows = []
    for k, v in out.items():
        meaning = THEORY_MEANINGS.get(k, "")
        if k == "theta_s" and n0 is not None:
            meaning = f"{meaning} at n0 = {fmt(n0, 'rad/s')}"
        if v is None:
            meaning = f"{meaning}; none for this top" if meaning else "none for this top"
        rows.append((k, fmt_value(k, v), meaning))
    print(table(("quantity", "value", "meaning"), rows))


__all__ = ["THEORY_MEANINGS", "print_theory"]
