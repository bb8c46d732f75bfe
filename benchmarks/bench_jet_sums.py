"""The Taylor jet's sums of products: in index order against newest-coefficient-last.

Each coefficient of a product of series, c_k = sum_j u_j v_{k-j}, waits on the newest
coefficients u_k and v_k, and each order's coefficients wait on the last order's through every
operation of the right-hand side in turn (w, k -> the spin -> the slip -> the law's factor ->
the torque -> N -> the rates -> the next order). Written in index order, one chain of fused
multiply-adds, the newest coefficient enters first (u_0 v_k) and the whole chain follows it on
that path; written with the terms of the newest coefficients last and the rest (the history) in
two chains, a product adds one or two operations to it (``taylor_jet.op_lines``); the power's
and the quotient's newest terms are one operation after their input, each rate term is scaled
by a number per order, and each sum adds its terms in the order their inputs are ready
(``taylor_jet.by_depth``).

This times the reference's jet both ways, in one process, at the orders the method runs (7, 9,
12), for a sphere's inertia (A = C, the catalogue's tops) and for A != C (its other jet): best
CPU time of ``--rounds`` rounds of 20,000 jets, the two forms alternated. The index-order form
is compiled as it was until 2026-11-28, with reassociation allowed (LLVM then folds any split
back into one chain), today's with contraction only. Both give the same coefficients to ~2e-14
of each row's largest. It also counts each compiled jet's instructions: the latency form has
more (it adds the chains' partial sums), so what it gains is time on the path, not work.

Measured 2026-11-28 (2 cores, best of 5): 1.37x, 1.37x and 1.39x at orders 7, 9 and 12 for
A = C, 1.24x, 1.30x and 1.36x for A/C = 0.9; with the products' order alone (newest terms last,
two chains), 1.14-1.27x.

Run: ``python benchmarks/bench_jet_sums.py [--rounds 7] [--orders 7,9,12]`` (each jet compiles
in ~5-15 s).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Callable

#: The inertia ratios A/C of the two jets (1: the sphere's jet, ``symmetric``).
JETS = {"A = C": 1.0, "A/C = 0.9": 0.9}


def best_per_call(rounds: int, n: int, *runs: Callable[[], None]) -> list[float]:
    """Each run's best CPU time per jet (s) over ``rounds``, the runs alternated."""
    best = [float("inf")] * len(runs)
    for _ in range(rounds):
        for i, run in enumerate(runs):
            t0 = time.process_time()
            run()
            best[i] = min(best[i], (time.process_time() - t0) / n)
    return best


def instructions(jet) -> int:
    """The compiled jet's instruction count (its assembly's instruction lines)."""
    asm = next(iter(jet.inspect_asm().values()))
    return sum(1 for line in asm.splitlines()
               if line.startswith("\t") and not line.strip().startswith("."))


def compile_jet(order: int, symmetric: bool, sums: str, fastmath: set[str]):
    """The reference's jet source of that form, compiled as the kernel compiles it."""
    import numba as nb

    from tippetop.reference_ode.taylor_jet import jet_source

    v1, m2 = nb.types.float64[::1], nb.types.float64[:, ::1]
    ns: dict = {}
    exec("import math\nfrom tippetop.reference_ode.params_array import *\n"  # noqa: S102
         + jet_source(order, symmetric, sums=sums), ns)  # the reference's own jet source
    return nb.njit(nb.types.none(v1, v1, m2), error_model="numpy", fastmath=fastmath)(ns["jet"])


def loop_of(jet):
    """A compiled loop of ``n`` jets, each depending on the last (none is hoisted)."""
    import numba as nb

    @nb.njit
    def loop(y, p, T, n):
        for _ in range(n):
            jet(y, p, T)
            y[0] += T[0, 3] * 1e-300

    return loop


def measure(order: int, label: str, ratio: float, rounds: int) -> float:
    """One order and jet: both forms, one line; the speed ratio (index order / today)."""
    import numpy as np

    from tippetop.models.params import FrictionParams, InitialState, TopParams
    from tippetop.reference_ode.params_array import P_IA, P_IC, pack_params
    from tippetop.reference_ode.solve import initial_state_vector
    from tippetop.reference_ode.taylor_jet import N_ROWS

    top = TopParams.from_ratios(ratio, 0.15)
    p = pack_params(top, FrictionParams())
    y = initial_state_vector(top, InitialState(theta0=0.3, n0=60.0))
    y[2:4] = [0.03, -0.02]  # a slip and a turned top: every term of the jet at work
    y[8:11] += [1.0, -2.0, 0.5]
    symmetric = bool(p[P_IA] == p[P_IC])
    old = compile_jet(order, symmetric, "plain", {"contract", "reassoc"})
    new = compile_jet(order, symmetric, "latency", {"contract"})
    T_old, T_new = np.zeros((N_ROWS, order + 1)), np.zeros((N_ROWS, order + 1))
    old(y, p, T_old)
    new(y, p, T_new)
    rows = T_old[:12]
    diff = float(np.max(np.abs(rows - T_new[:12]) / np.abs(rows).max(axis=1, keepdims=True)))
    loop_old, loop_new = loop_of(old), loop_of(new)
    loop_old(y.copy(), p, T_old, 10)
    loop_new(y.copy(), p, T_new, 10)
    n = 20000
    to, tn = best_per_call(rounds, n, lambda: loop_old(y.copy(), p, T_old, n),
                           lambda: loop_new(y.copy(), p, T_new, n))
    print(f"{label:10s} {order:5d} {to * 1e6:10.3f} {tn * 1e6:10.3f} {to / tn:7.2f}x "
          f"{instructions(old):8d} {instructions(new):8d} {diff:9.0e}", flush=True)
    return to / tn


def main(argv: list[str] | None = None) -> int:
    """Every order and jet; one table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--orders", default="7,9,12", help="comma-separated jet orders")
    a = ap.parse_args(argv)
    if a.rounds < 1:
        print(f"bench_jet_sums: expected --rounds >= 1, got {a.rounds}", file=sys.stderr)
        return 2
    if not re.fullmatch(r"\d+(,\d+)*", a.orders) or any(
            not 2 <= int(o) <= 30 for o in a.orders.split(",")):
        print(f"bench_jet_sums: expected --orders as comma-separated integers 2-30, got "
              f"{a.orders!r}", file=sys.stderr)
        return 2
    print(f"the reference's jet, best CPU time per jet of {a.rounds} rounds; index order "
          "(reassociation allowed, as until 2026-11-28) against today's (newest terms last, "
          "two chains, each sum in the order its inputs are ready):")
    print(f"{'jet':10s} {'order':>5s} {'index us':>10s} {'today us':>10s} {'speed':>8s} "
          f"{'instr':>8s} {'instr':>8s} {'agree':>9s}")
    for label, ratio in JETS.items():
        for order in (int(o) for o in a.orders.split(",")):
            measure(order, label, ratio, a.rounds)
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except KeyboardInterrupt:
        print("bench_jet_sums: interrupted", file=sys.stderr)
        raise SystemExit(130) from None
