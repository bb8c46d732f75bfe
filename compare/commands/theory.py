"""``tippetop theory``: the paper's predictions for a top, from its ratios or an MJCF file."""

from __future__ import annotations

import argparse
from typing import Any

from tippetop.compare.commands.options import add_json_option, finite_float, print_json
from tippetop.compare.presentation.terminal import fmt, fmt_value, table
from tippetop.models.errors import TippetopError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Declare ``tippetop theory`` and its options."""
    p = sub.add_parser("theory", help="the paper's predictions for a top",
                       description="The paper's group, critical spins n1...n4 and nc, the "
                       "angles theta_c/f/d and (with --n0) theta_s, for a top given by its "
                       "ratios or an MJCF file.")
    p.add_argument("--A-over-C", dest="A_over_C", type=finite_float, metavar="X",
                   help="A/C, the transverse over the axial moment of inertia (no default: "
                   "required unless --mjcf)")
    p.add_argument("--a-over-R", dest="a_over_R", type=finite_float, metavar="Y",
                   help="a/R, the centre of mass's offset from the ball's centre over the "
                   "radius (no default: required unless --mjcf)")
    p.add_argument("--C-factor", dest="C_factor", type=finite_float, default=1.0, metavar="F",
                   help="C = F (2/5) M R^2, the axial moment over a uniform ball's (default 1)")
    p.add_argument("--R-m", dest="R_m", type=finite_float, default=0.015, metavar="M",
                   help="ball radius (m; default 0.015)")
    p.add_argument("--M-kg", dest="M_kg", type=finite_float, default=0.015, metavar="KG",
                   help="mass (kg; default 0.015)")
    p.add_argument("--g-mps2", dest="g_mps2", type=finite_float, default=9.8, metavar="G",
                   help="gravity (m/s^2; default 9.8)")
    p.add_argument("--n0", type=finite_float, metavar="RAD_S",
                   help="initial spin near theta = 0 (rad/s); adds theta_s (default: none)")
    p.add_argument("--mjcf", metavar="FILE", help="derive the top from an MJCF file instead "
                   "of the ratios (default: none)")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """``tippetop theory``: the paper's predictions for a top."""
    from tippetop.compare.measures import theory
    from tippetop.models.params import TopParams

    extra: dict[str, Any] = {}
    if args.mjcf:
        from tippetop.mujoco_runner.model import top_from_mjcf_file

        top = top_from_mjcf_file(args.mjcf)
        extra = {"R_m": top.R_m, "a_m": top.a_m, "A": top.A_kgm2, "C": top.C_kgm2,
                 "M_kg": top.M_kg, "A_over_C": top.A_over_C, "a_over_R": top.a_over_R}
    else:
        if args.A_over_C is None or args.a_over_R is None:
            raise TippetopError("theory: expected --A-over-C and --a-over-R (or --mjcf FILE), "
                                "got neither")
        top = TopParams.from_ratios(args.A_over_C, args.a_over_R, args.C_factor,
                                    R_m=args.R_m, M_kg=args.M_kg, g_mps2=args.g_mps2)
    out = theory.summary(top, n0=args.n0)
    out.update(extra)
    if args.json:
        print_json(out)
    else:
        _print_theory(out, top, args.n0)
    return 0


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


def _print_theory(out: dict[str, Any], top: Any, n0: float | None) -> None:
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
