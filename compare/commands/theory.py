"""``tippetop theory``: the paper's predictions for a top, from its ratios or an MJCF file."""

from __future__ import annotations

import argparse
from typing import Any

from tippetop.compare.commands.options import add_json_option, finite_float, print_json
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
        from tippetop.compare.presentation.theory import print_theory

        print_theory(out, top, args.n0)
    return 0
