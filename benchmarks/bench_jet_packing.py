"""Packing a Taylor jet: a synthetic jet of 36 order-12 products, scalar against side by side.

The reference's jet (reference_ode/taylor_jet.py) is fully unrolled straight-line code, which
numba compiles to scalar instructions only (its SLP vectorizer is off by default). This
measures, on a synthetic jet of the same size (36 Cauchy products to order 12, each variable's
next coefficient from the products: a_j,k+1 = c_j,k / (k + 1), b_j,k+1 = c_j+1,k / (k + 1)):

* ``scalar``: the unrolled form, every coefficient a local variable (as the reference's jet);
* ``flat``: the products of one order side by side in one flat work buffer at constant offsets,
  with constant trip counts, so that LLVM's SLP vectorizer, when on, packs them.

Each runs in a fresh process with ``NUMBA_SLP_VECTORIZE`` 0 and 1 (numba reads it at import),
best CPU time of ``--rounds`` rounds of 20,000 calls, the two forms alternated; both give the
same coefficients (to ~1e-16). Measured 2026-11-28 (2 shared cores, two runs): with SLP on,
flat 2.1-2.6x the scalar form (0.54-0.71 against 1.1-1.8 us); with it off, flat 0.5-0.6x.

Run: ``python benchmarks/bench_jet_packing.py [--rounds 5]`` (about a minute: each process
compiles the unrolled form, ~15 s).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

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
    print(f"  SLP {nb.core.config.SLP_VECTORIZE}: scalar {ts * 1e6:6.3f} us, flat "
          f"{tw * 1e6:6.3f} us, flat / scalar speed {ts / tw:4.2f}x (coefficients agree to "
          f"{diff:.0e})", flush=True)


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
    print(f"a synthetic jet of {N} products to order {P}, best of {a.rounds} rounds:")
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
