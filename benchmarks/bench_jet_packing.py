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
four runs): with SLP on, the synthetic flat form 1.9-2.6x its scalar form (off: 0.5x); the
reference's packed jet 1.05-1.28x today's, its arithmetic mostly packed (605 packed FMAs in
place of most of 2,415 scalar ones) but its instruction count about the same; two jets
interleaved 2.31-2.34x one: the real jet is bound by its instructions' throughput, much of it
memory moves, not by its chains of dependent operations (docs/design.md).

Run: ``python benchmarks/bench_jet_packing.py [--rounds 5]`` (about a minute: each process
compiles the unrolled form, ~15 s).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time

from tippetop.reference_ode.taylor_jet import ROW_N, ROW_U, STATE, jet_system

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
    need the current order) finished one by one; and ``W``'s size."""
    ops, rate = jet_system(symmetric)
    consts: dict[str, str] = {}

    def scaled(coef: str, var: str) -> str:
        if coef == "1.0":
            return var
        if coef not in consts:
            consts[coef] = f"K{len(consts)}"
        return f"{consts[coef]}*{var}"

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

    jet_vars = (*STATE, "kx", "ky", "kz")
    body: list[str] = []
    # order 0's stores of the state and k
    for v in jet_vars:
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
            t = f"{nm}_{k}"
            h = f"W[{oh}+{idx[nm]}] + " if (k >= 2 and nm in idx) else ""
            if kind == "mul":
                a, b = args
                if k == 0:
                    body.append(f"{t} = {a}_0*{b}_0")
                else:
                    body.append(f"{t} = {h}{a}_0*{b}_{k} + {a}_{k}*{b}_0")
            elif kind == "sq":
                (a,) = args
                if k == 0:
                    body.append(f"{t} = {a}_0*{a}_0")
                else:
                    body.append(f"{t} = {h}2.0*{a}_0*{a}_{k}")
            elif kind == "lin":
                terms, c0 = args
                e = " + ".join(scaled(c, f"{v}_{k}") for c, v in terms)
                if c0 is not None and k == 0:
                    e += f" + {c0}"
                body.append(f"{t} = {e}")
            elif kind == "powm":
                u, alpha, factor = args
                if k == 0:
                    body.append(f"{nm}_inv_u0 = 1.0 / {u}_0")
                    body.append(f"{t} = {factor} * math.sqrt({nm}_inv_u0)" if alpha == -0.5
                                else f"{t} = {factor} * {u}_0 ** {alpha!r}")
                else:
                    parts = [f"{(alpha * (k - j) - j) / k!r}*{u}_{k - j}*{nm}_{j}"
                             for j in range(k)]
                    body.append(f"{t} = ({' + '.join(parts)}) * {nm}_inv_u0")
            elif kind == "div":
                u, v = args
                if k == 0:
                    body.append(f"{nm}_inv_v0 = 1.0 / {v}_0")
                    body.append(f"{t} = {u}_0 * {nm}_inv_v0")
                else:
                    hist = f"W[{oh}+{idx[nm]}] + " if k >= 2 else ""
                    body.append(f"{t} = ({u}_{k} - ({hist}{v}_{k}*{nm}_0)) * {nm}_inv_v0")
            body += store(nm, k)
        for v in jet_vars:
            e = " + ".join(scaled(c, f"{w}_{k}") for c, w in rate[v])
            body.append(f"{v}_{k + 1} = ({e}) * {1.0 / (k + 1)!r}")
            body += store(v, k + 1)
    head = [f"def {name}(y, p, T, W):",
            "    R = p[P_R]; a = p[P_A_OFF]; M = p[P_M]; A = p[P_IA]; C = p[P_IC]; g = p[P_G]",
            "    mu = p[P_MU]; lam = p[P_LAM]",
            "    iA = 1.0 / A; dC = 1.0 / C - iA; lam2 = lam * lam",
            "    inv = 1.0 / (y[4] * y[4] + y[5] * y[5] + y[6] * y[6] + y[7] * y[7])"]
    head += [f"    {kn} = {c}" for c, kn in consts.items()]
    head += [f"    {v}_0 = y[{i}]" for i, v in enumerate(STATE)]
    head += ["    kx_0 = 2.0 * (qx_0 * qz_0 + qw_0 * qy_0) * inv",
             "    ky_0 = 2.0 * (qy_0 * qz_0 - qw_0 * qx_0) * inv",
             "    kz_0 = (qw_0 * qw_0 - qx_0 * qx_0 - qy_0 * qy_0 + qz_0 * qz_0) * inv"]
    tail = [f"    T[{i}, {k}] = {v}_{k}" for k in range(order + 1) for i, v in enumerate(STATE)]
    tail += [f"    T[{ROW_N}, {k}] = N_{k}" for k in range(order)]
    tail += [f"    T[{ROW_N}, {order}] = 0.0", f"    T[{ROW_U}, 0] = u_0"]
    return "\n".join(head + ["    " + b for b in body] + tail) + "\n", size


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
    n, ts, tw = 20000, float("inf"), float("inf")
    for _ in range(rounds):
        t0 = time.process_time()
        loop_s(a0, b0, o1, n)
        ts = min(ts, (time.process_time() - t0) / n)
        t0 = time.process_time()
        loop_w(a0, b0, o2, W, n)
        tw = min(tw, (time.process_time() - t0) / n)
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
    ns: dict = {}
    exec(pre + jet_source(order, True), ns)  # noqa: S102 - the reference's own jet source
    jet_old = nb.njit(nb.types.none(v1, v1, m2), error_model="numpy", fastmath=fm)(ns["jet"])
    src, size = packed_jet_source(order, True)
    ns = {}
    exec(pre + src, ns)  # noqa: S102 - the packed variant, written above
    jet_new = nb.njit(nb.types.none(v1, v1, m2, v1), error_model="numpy", fastmath=fm,
                      boundscheck=False)(ns["jet"])

    @nb.njit
    def loop_old(y, p, T, n):
        for _ in range(n):
            jet_old(y, p, T)
            y[0] += T[0, 3] * 1e-300

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
    n, to, tn = 20000, float("inf"), float("inf")
    loop_old(y.copy(), p, T1, 10)
    loop_new(y.copy(), p, T2, W, 10)
    for _ in range(rounds):
        yy = y.copy()
        t0 = time.process_time()
        loop_old(yy, p, T1, n)
        to = min(to, (time.process_time() - t0) / n)
        yy = y.copy()
        t0 = time.process_time()
        loop_new(yy, p, T2, W, n)
        tn = min(tn, (time.process_time() - t0) / n)
    print(f"  SLP {nb.core.config.SLP_VECTORIZE}: the reference's jet (order {order}): today "
          f"{to * 1e6:6.3f} us, packed {tn * 1e6:6.3f} us, packed / today speed {to / tn:4.2f}x "
          f"(coefficients agree to {diff:.0e} of each row's largest)", flush=True)
    if nb.core.config.SLP_VECTORIZE:
        return
    # two independent jets, their statements interleaved in one function: a jet bound by its
    # chains of dependent operations runs the pair in about one jet's time (the two chains
    # overlap), a jet bound by its instructions' throughput in two
    lines = jet_source(order, True).splitlines()[1:]

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
    tp = float("inf")
    for _ in range(rounds):
        yy = y.copy()
        t0 = time.process_time()
        loop_old(yy, p, T1, n)
        to = min(to, (time.process_time() - t0) / n)
        ya, yy = y.copy(), yb.copy()
        t0 = time.process_time()
        loop_pair(ya, yy, p, T2, Tb, n)
        tp = min(tp, (time.process_time() - t0) / n)
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
