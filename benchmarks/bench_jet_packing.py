"""Packing a Taylor jet: a synthetic jet of 36 order-12 products, scalar against side by side.

The reference's jet (reference_ode/taylor_jet.py) is fully unrolled straight-line code, which
numba compiles to scalar instructions only (its SLP vectorizer is off by default). This
measures, on a synthetic jet of the same size (36 Cauchy products to order 12, each variable's
next coefficient from the products: a_j,k+1 = c_j,k / (k + 1), b_j,k+1 = c_j+1,k / (k + 1)):

* ``scalar``: the unrolled form, every coefficient a local variable (as the reference's jet);
* ``flat``: the products of one order side by side in one flat work buffer at constant offsets,
  with constant trip counts, so that LLVM's SLP vectorizer, when on, packs them.

Then the reference's own order-12 jet (A = C) against the same jet written that way: each
order's product histories (the terms that use only lower orders) side by side, the terms that
need the current order finished one by one (:func:`packed_jet_source`); and, with SLP off, two
of the reference's jets with their statements interleaved in one function against one (about
1x: bound by chains of dependent operations; about 2x: by throughput).

Each setting runs in a fresh process with ``NUMBA_SLP_VECTORIZE`` 0 and 1 (numba reads it at
import), best CPU time of ``--rounds`` rounds of 20,000 calls, the forms alternated; both
forms give the same coefficients (to ~1e-16 and ~2e-14). Measured 2026-11-28 (2 shared cores,
five runs): with SLP on, the synthetic flat form 1.9-2.6x its scalar form (off: 0.5x); the
reference's packed jet 1.05-1.28x the index-order jet's, its arithmetic mostly packed (605
packed FMAs in place of most of 2,415 scalar ones) but its instruction count about the same;
two jets interleaved 2.31-2.53x one. That pair doubles the live values (more of them spilled to
memory), so it did not isolate the chains as meant: the packed variant also writes each
product's newest terms last, and that order alone, with no packing, is 1.26-1.33x at order 12
(benchmarks/bench_jet_sums.py), since each order waits on the last through every operation.
So the jet measured here is the one in index order (``sums="plain"``, as until 2026-11-28),
compiled as it was (docs/design.md).

Run: ``python benchmarks/bench_jet_packing.py [--rounds 5]`` (about a minute: each process
compiles the unrolled form, ~15 s).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys

from bench_jet_sums import best_per_call, compile_jet, loop_of  # beside this script

from tippetop.reference_ode.taylor_jet import (
    JET_VARS,
    Constants,
    jet_head,
    jet_system,
    jet_tail,
    op_lines,
    rate_line,
)

P, N = 12, 36
OA, OB, OS = 0, (P + 1) * N, 2 * (P + 1) * N


def scalar_source() -> str:
    """The unrolled form: every coefficient a local."""
    lines = ["def jet_s(a0, b0, out):"]
    for j in range(N):
        lines += [f"    a{j}_0 = a0[{j}]", f"    b{j}_0 = b0[{j}]"]
    for k in range(P):
        for j in range(N):
            terms = " + ".join(f"a{j}_{i} * b{j}_{k - i}" for i in range(k + 1))
            lines.append(f"    c{j}_{k} = {terms}")
        for j in range(N):
            lines.append(f"    a{j}_{k + 1} = c{j}_{k} * {1.0 / (k + 1)!r}")
            lines.append(f"    b{j}_{k + 1} = c{(j + 1) % N}_{k} * {1.0 / (k + 1)!r}")
    lines += [f"    out[{j}] = a{j}_{P}" for j in range(N)]
    return "\n".join(lines)


def packed_jet_source(order: int, symmetric: bool, name: str = "jet") -> tuple[str, int]:
    """The reference's jet (taylor_jet.jet_source) with each order's product histories (the terms
    that use only lower orders) side by side in one flat buffer ``W``, the edge terms (which
    need the current order) finished one by one; and ``W``'s size.

    Only the products, squares and the quotient's sum are written here; every other statement
    is taylor_jet's own (:func:`op_lines`, :func:`rate_line`, :func:`jet_head`,
    :func:`jet_tail`).
    """
    ops, rate = jet_system(symmetric)
    consts = Constants()
    # the batched ops: mul (a, b), sq (a, a), div's history (den v, N)
    batch: list[tuple[str, str, str]] = []
    for nm, kind, args in ops:
        if kind == "mul":
            batch.append((nm, args[0], args[1]))
        elif kind == "sq":
            batch.append((nm, args[0], args[0]))
        elif kind == "div":
            batch.append((nm, args[1], nm))  # sum_j v_j N_{k-j}
    nbp = (len(batch) + 3) // 4 * 4
    idx = {nm: i for i, (nm, _, _) in enumerate(batch)}
    oa, ob, oh = 0, (order + 1) * nbp, 2 * (order + 1) * nbp
    size = oh + nbp
    # where a variable's coefficients go: (offset base, slot)
    slots: dict[str, list[str]] = {}
    for i, (_, a, b) in enumerate(batch):
        slots.setdefault(a, []).append(f"{oa}+{{k}}*{nbp}+{i}")
        slots.setdefault(b, []).append(f"{ob}+{{k}}*{nbp}+{i}")

    def store(var: str, k: int) -> list[str]:
        return [f"W[{s.format(k=k)}] = {var}_{k}" for s in slots.get(var, [])]

    body: list[str] = []
    for v in JET_VARS:  # order 0's stores of the state and k
        body += store(v, 0)
    for k in range(order):
        if k >= 2:  # the histories, side by side
            body.append(f"for i in range({nbp}):")
            body.append(f"    W[{oh} + i] = 0.0")
            body.append(f"for j in range(1, {k}):")
            body.append(f"    for i in range({nbp}):")
            body.append(f"        W[{oh} + i] += W[{oa} + j*{nbp} + i] * "
                        f"W[{ob} + ({k} - j)*{nbp} + i]")
        for nm, kind, args in ops:
            if k == 0 or kind not in ("mul", "sq", "div"):
                body += op_lines(nm, kind, args, k, consts, "plain")
                body += store(nm, k)
                continue
            t, h = f"{nm}_{k}", (f"W[{oh}+{idx[nm]}] + " if k >= 2 else "")
            if kind == "mul":
                a, b = args
                body.append(f"{t} = {h}{a}_0*{b}_{k} + {a}_{k}*{b}_0")
            elif kind == "sq":
                (a,) = args
                body.append(f"{t} = {h}2.0*{a}_0*{a}_{k}")
            else:  # div
                u, v = args
                body.append(f"{t} = ({u}_{k} - ({h}{v}_{k}*{nm}_0)) * {nm}_inv_v0")
            body += store(nm, k)
        for v in JET_VARS:
            body.append(rate_line(v, k, rate, consts, "plain"))
            body += store(v, k + 1)
    src = "\n".join(jet_head(f"{name}(y, p, T, W)", consts) + ["    " + s for s in body]
                    + jet_tail(order)) + "\n"
    return src, size


def measure(rounds: int) -> None:
    """In this process (its NUMBA_SLP_VECTORIZE as set): both forms, one line."""
    import numba as nb
    import numpy as np

    fm = {"contract", "reassoc"}
    ns: dict = {}
    exec(scalar_source(), ns)  # noqa: S102 - the generated unrolled form, as taylor_jet's
    jet_s = nb.njit(fastmath=fm, error_model="numpy")(ns["jet_s"])

    @nb.njit(fastmath=fm, error_model="numpy", boundscheck=False)
    def jet_w(a0, b0, out, W):
        for j in range(N):
            W[OA + j] = a0[j]
            W[OB + j] = b0[j]
        for k in range(P):
            for j in range(N):
                W[OS + j] = 0.0
            for i in range(k + 1):
                for j in range(N):
                    W[OS + j] += W[OA + i * N + j] * W[OB + (k - i) * N + j]
            inv = 1.0 / (k + 1)
            for j in range(N):
                W[OA + (k + 1) * N + j] = W[OS + j] * inv
            for j in range(N - 1):
                W[OB + (k + 1) * N + j] = W[OS + j + 1] * inv
            W[OB + (k + 1) * N + N - 1] = W[OS] * inv
        for j in range(N):
            out[j] = W[OA + P * N + j]

    @nb.njit
    def loop_s(a0, b0, out, n):
        for _ in range(n):
            jet_s(a0, b0, out)
            a0[0] = out[0] * 1e-300 + a0[0]  # a dependence: no call is hoisted

    @nb.njit
    def loop_w(a0, b0, out, W, n):
        for _ in range(n):
            jet_w(a0, b0, out, W)
            a0[0] = out[0] * 1e-300 + a0[0]

    rng = np.random.default_rng(0)
    a0, b0 = rng.uniform(0.5, 1.0, N), rng.uniform(0.5, 1.0, N)
    o1, o2, W = np.empty(N), np.empty(N), np.zeros(2 * (P + 1) * N + N)
    loop_s(a0.copy(), b0, o1, 1)
    loop_w(a0.copy(), b0, o2, W, 1)
    diff = float(np.max(np.abs(o1 - o2) / np.abs(o1)))
    n = 20000
    ts, tw = best_per_call(rounds, n, lambda: loop_s(a0, b0, o1, n),
                           lambda: loop_w(a0, b0, o2, W, n))
    print(f"  SLP {nb.core.config.SLP_VECTORIZE}: synthetic jet: scalar {ts * 1e6:6.3f} us, "
          f"flat {tw * 1e6:6.3f} us, flat / scalar speed {ts / tw:4.2f}x (coefficients agree "
          f"to {diff:.0e})", flush=True)
    real_jet(rounds)


def real_jet(rounds: int, order: int = 12) -> None:
    """The reference's jet (A = C, the Fig. 11 top) against its packed variant."""
    import numba as nb
    import numpy as np

    from tippetop.compare.studies.work_precision import make_top
    from tippetop.reference_ode.taylor_jet import N_ROWS, jet_source

    fm = {"contract", "reassoc"}
    pre = ("import math\nimport numba as nb\nimport numpy as np\n"
           "from tippetop.reference_ode.params_array import *\n")
    v1, m2 = nb.types.float64[::1], nb.types.float64[:, ::1]
    jet_old = compile_jet(order, True, "plain", fm)
    src, size = packed_jet_source(order, True)
    ns: dict = {}
    exec(pre + src, ns)  # noqa: S102 - the packed variant, written above
    jet_new = nb.njit(nb.types.none(v1, v1, m2, v1), error_model="numpy", fastmath=fm,
                      boundscheck=False)(ns["jet"])

    loop_old = loop_of(jet_old)

    @nb.njit
    def loop_new(y, p, T, W, n):
        for _ in range(n):
            jet_new(y, p, T, W)
            y[0] += T[0, 3] * 1e-300

    top = make_top("fig11")
    p, y = top.p.copy(), top.y0.copy()
    y[2:4] = [0.03, -0.02]  # a slip and a turned top: every term of the jet at work
    y[8:11] += [1.0, -2.0, 0.5]
    T1, T2, W = np.zeros((N_ROWS, order + 1)), np.zeros((N_ROWS, order + 1)), np.zeros(size)
    jet_old(y, p, T1)
    jet_new(y, p, T2, W)
    rows = T1[:12]
    diff = float(np.max(np.abs(rows - T2[:12]) / np.abs(rows).max(axis=1, keepdims=True)))
    n = 20000
    loop_old(y.copy(), p, T1, 10)
    loop_new(y.copy(), p, T2, W, 10)
    to, tn = best_per_call(rounds, n, lambda: loop_old(y.copy(), p, T1, n),
                           lambda: loop_new(y.copy(), p, T2, W, n))
    print(f"  SLP {nb.core.config.SLP_VECTORIZE}: the reference's jet (order {order}): index "
          f"order {to * 1e6:6.3f} us, packed {tn * 1e6:6.3f} us, packed / index order speed "
          f"{to / tn:4.2f}x "
          f"(coefficients agree to {diff:.0e} of each row's largest)", flush=True)
    if nb.core.config.SLP_VECTORIZE:
        return
    # two independent jets, their statements interleaved in one function: a jet bound by its
    # chains of dependent operations runs the pair in about one jet's time (the two chains
    # overlap), a jet bound by its instructions' throughput in two
    lines = jet_source(order, True, sums="plain").splitlines()[1:]

    def rename(line: str, suf: str) -> str:
        line = re.sub(r"\b([A-Za-z]\w*?_\d+|K\d+|R|a|M|A|C|g|mu|lam|iA|dC|lam2|inv|"
                      r"s_inv_u0|N_inv_v0)\b", lambda m: m.group(1) + suf, line)
        return line.replace("y[", f"y{suf}[").replace("T[", f"T{suf}[")

    pair = ["def jet2(y_A, y_B, p, T_A, T_B):"]
    for la, lb in zip(lines, lines, strict=True):
        pair += [rename(la, "_A"), rename(lb, "_B")]
    ns = {}
    exec(pre + "\n".join(pair), ns)  # noqa: S102 - two copies of the reference's jet
    jet2 = nb.njit(nb.types.none(v1, v1, v1, m2, m2), error_model="numpy",
                   fastmath=fm)(ns["jet2"])

    @nb.njit
    def loop_pair(ya, yb, p, Ta, Tb, n):
        for _ in range(n):
            jet2(ya, yb, p, Ta, Tb)
            ya[0] += Ta[0, 3] * 1e-300
            yb[0] += Tb[0, 3] * 1e-300

    yb = y.copy()
    yb[8] += 0.1
    Tb = np.zeros_like(T2)
    loop_pair(y.copy(), yb.copy(), p, T2, Tb, 10)
    to_again, tp = best_per_call(rounds, n, lambda: loop_old(y.copy(), p, T1, n),
                                 lambda: loop_pair(y.copy(), yb.copy(), p, T2, Tb, n))
    to = min(to, to_again)
    print(f"  SLP 0: two of the reference's jets interleaved: {tp * 1e6:6.3f} us against one "
          f"{to * 1e6:6.3f} us, {tp / to:4.2f}x (1x: bound by its chains; 2x: by throughput)",
          flush=True)


def main(argv: list[str] | None = None) -> int:
    """Both settings, each in its own process."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.rounds < 1:
        print(f"bench_jet_packing: expected --rounds >= 1, got {a.rounds}", file=sys.stderr)
        return 2
    if a.child:
        measure(a.rounds)
        return 0
    print(f"a synthetic jet of {N} independent products to order {P}, and the reference's jet "
          f"of order 12 (A = C), best of {a.rounds} rounds:")
    for slp in ("0", "1"):
        env = {**os.environ, "NUMBA_SLP_VECTORIZE": slp}
        code = subprocess.call([sys.executable, __file__, "--child", "--rounds", str(a.rounds)],
                               env=env)
        if code:
            print(f"bench_jet_packing: the run with NUMBA_SLP_VECTORIZE={slp} failed "
                  f"(exit {code})", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except KeyboardInterrupt:
        print("bench_jet_packing: interrupted", file=sys.stderr)
        raise SystemExit(130) from None
