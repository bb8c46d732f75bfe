"""Stabilized Taylor updates: can the same jet take longer steps on the Fig. 3 and Fig. 11 tops?

The reference's Taylor method (``ode.method = taylor``) is held by stability on these tops: the
friction law relaxes the slip at ~-400/s, so its order-12 steps sit near the series' real
stability boundary (h 400 ~ 5.8) over most of each run, and heyoka's Taylor method, held the
same way, is level with it (docs/guide/accuracy.md). This benchmark measures the remedy the
accuracy guide names: an update from the same jet with a longer real stability interval.

From the normalized coefficients T[:, k] of degree P, the update is sum_k w_k T[:, k] h^k with
w_k = 1 for k <= p (order p) and the free w_k chosen (a linear programme in a Chebyshev basis,
scipy's HiGHS, bisected on beta) so that R(z) = sum_k w_k z^k / k! keeps |R| <= 0.95 on
[-beta, -1], |R| <= 1 on [-1, 0] and |R(iy)| <= ~1 for |y| <= 2 (the rotation modes). A second
polynomial of order p - 1, stable on the same interval, gives the embedded error estimate
(their difference, bounded on the damped mode, where the plain a-priori rule is not). Per step
the "hybrid" driver takes the longer of the plain a-priori step and the stabilized one (a
stabilized trial that fails its estimate is re-summed shorter on the same jet, no new jet).

In one run, on each top: plain Taylor of orders 7-14 (the project's jets, this driver) and the
stabilized and hybrid variants, over rtol 1e-2 ... 1e-12, all (method, rtol) runs interleaved
in a shuffled order each round, best CPU time (time.process_time) of ``--rounds``. Errors:
|theta(t_end) - truth| and the largest error over samples (every 1 s on Fig. 11, 0.1 s on Fig.
3), the truth DOP853 at rtol 1e-14 (Verner 9(8) at the same rtol agrees to ~3e-13 rad). The
table keeps, per level 1e-4 ... 1e-10 rad, the cheapest run reaching both errors (end <=
level, samples <= 3 x level: a single end-point error can be met by a lucky cancellation) for
the reference's orders (models.options.TAYLOR_ORDERS), the best plain order and the best
stabilized variant, and prints the ratio best plain / best stabilized (> 1: stabilizing pays).

Measured (2026-11-28, 2 shared cores, best of 7/15): the stabilized steps are 1.3-2x fewer, but
the time is not: 1.18x, 1.17x, 0.99x, 1.00x (Fig. 11) and 0.88x, 1.04x, 1.07x, 1.03x (Fig. 3)
at 1e-4, 1e-6, 1e-8, 1e-10 rad; a second run, sharing the machine with a CI run: 1.07x,
0.93x, 1.01x, 1.10x and 0.85x, 0.95x, 1.06x, 1.00x. Stabilizing buys beta 1.4-3x by giving
up 1-4 orders, and the lower-order steps are then held by the rotation's accuracy (omega
~16-58/s: h omega ~1 at twice the step), or need a larger jet (cost ~P^2, beta of plain Taylor
only +0.37 a degree).

Run: ``python benchmarks/bench_stabilized_taylor.py [--tops fig11,fig3] [--rounds 7]
[--quick] [--json FILE]`` (a few minutes; the jets of orders 7-14 compile once, ~20-70 s each,
into the numba cache).
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
import time
from collections import defaultdict
from pathlib import Path

import numba as nb
import numpy as np
from numpy.polynomial import chebyshev as cheb
from scipy.optimize import linprog

from tippetop.compare.studies.work_precision import make_top
from tippetop.models.options import TAYLOR_ORDERS, OdeOptions
from tippetop.reference_ode import taylor
from tippetop.reference_ode.solve import simulate_ode
from tippetop.reference_ode.taylor_jet import N_ROWS

LEVELS = (1e-4, 1e-6, 1e-8, 1e-10)
RTOLS = tuple(m * 10.0 ** -e for e in range(2, 13) for m in (1.0, 3.0) if m * 10.0 ** -e >= 1e-12
              and m * 10.0 ** -e <= 1e-2)
#: Sampling of the max-over-samples error, per top (s).
SAMPLE_DT = {"fig11": 1.0, "fig3": 0.1}
#: The damping kept on [-beta, -1], and the imaginary segment |y| <= YMAX kept in |R| <= ~1.
ETA, YMAX = 0.95, 2.0
PLAIN = (7, 8, 9, 10, 11, 12, 13, 14)
#: (P, p, kappa): the stabilized pairs run, by the driver's hybrid rule; kappa loosens the
#: stabilized estimate (kappa sc_i). The fastest of 24 variants in the first measurement.
HYBRID = ((9, 6, 1.0), (9, 8, 1.0), (10, 8, 1.0), (12, 11, 1.0), (13, 11, 10.0),
          (13, 12, 100.0), (14, 13, 10.0))
QUICK_PLAIN, QUICK_HYBRID = (7, 9, 12), ((9, 6, 1.0), (12, 11, 1.0))


# ---------------------------------------------------------------- the polynomials
def _cheb_deriv_at_1(k: int, j: int) -> float:
    v = 1.0
    for i in range(j):
        v *= (k * k - i * i) / (2 * i + 1)
    return v


def _lp(P: int, p: int, beta: float, ymax: float) -> tuple[float, np.ndarray | None]:
    """min t = max |R| on [-beta, -1] with order p, |R| <= 1 on [-1, 0], R(iy) in a 32-gon of
    radius 1 for |y| <= ymax; R in Chebyshev coefficients on u = 1 + 2x/beta."""
    n = P + 1
    a_eq = np.zeros((p + 1, n + 1))
    b_eq = np.ones(p + 1)
    for j in range(p + 1):  # R^(j)(0) = 1
        a_eq[j, :n] = [_cheb_deriv_at_1(k, j) / (beta / 2.0) ** j for k in range(n)]
        scale = np.max(np.abs(a_eq[j, :n]))
        a_eq[j] /= scale
        b_eq[j] /= scale
    u = np.unique(np.concatenate([np.cos(np.linspace(0, np.pi, 600)), np.linspace(-1, 1, 600)]))
    x = (u - 1.0) * beta / 2.0
    V = cheb.chebvander(u, P)
    far = x < -1.0
    rows, rhs = [], []
    for sgn in (1.0, -1.0):
        rows.append(np.hstack([sgn * V[far], -np.ones((far.sum(), 1))]))
        rhs.append(np.zeros(far.sum()))
        rows.append(np.hstack([sgn * V[~far], np.zeros(((~far).sum(), 1))]))
        rhs.append(np.ones((~far).sum()))
    if ymax > 0:
        y = np.linspace(0, ymax, 200)
        Vc = cheb.chebvander(1.0 + 2.0j * y / beta, P)
        for m in range(32):
            rows.append(np.hstack([np.real(Vc * np.exp(-2j * np.pi * m / 32)),
                                   np.zeros((y.size, 1))]))
            rhs.append(np.ones(y.size))
    c = np.zeros(n + 1)
    c[-1] = 1.0
    res = linprog(c, A_ub=np.vstack(rows), b_ub=np.concatenate(rhs), A_eq=a_eq, b_eq=b_eq,
                  bounds=[(None, None)] * (n + 1), method="highs")
    return (res.x[-1], res.x[:n]) if res.status == 0 else (math.inf, None)


def _weights(d: np.ndarray, P: int, p: int, beta: float) -> np.ndarray:
    """Chebyshev coefficients on [-beta, 0] -> w_k (R = sum w_k z^k / k!), w_k = 1 to p."""
    mono_u = cheb.cheb2poly(d)
    cx = np.zeros(P + 1)
    for j, m in enumerate(mono_u):
        for i in range(j + 1):
            cx[i] += m * math.comb(j, i) * (2.0 / beta) ** i
    w = np.array([cx[k] * math.factorial(k) for k in range(P + 1)])
    w[: p + 1] = 1.0
    return w


def stability_poly(w: np.ndarray, z: np.ndarray) -> np.ndarray:
    """R(z) = sum_k w_k z^k / k!."""
    z = np.asarray(z, dtype=complex)
    s = np.zeros_like(z)
    for k in range(len(w) - 1, -1, -1):
        s = s * z + w[k] / math.factorial(k)
    return s


def real_beta(w: np.ndarray, xmax: float = 400.0) -> float:
    """The largest beta with |R(x)| <= 1 on [-beta, 0] (a fine scan)."""
    x = -np.linspace(0, xmax, 400001)
    bad = np.abs(stability_poly(w, x)) > 1.0 + 1e-9
    bad[0] = False
    return float(-x[np.argmax(bad) - 1]) if bad.any() else xmax


def design_pair(P: int, p: int) -> dict:
    """The widest order-p polynomial of degree P (bisection on beta), and its order p - 1
    partner on the same interval (the embedded estimate)."""
    for ymax in (YMAX, 1.5, 1.0, 0.5, 0.0):
        lo, hi, best = 1.0, 4.0 * P * P, None
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            t, d = _lp(P, p, mid, ymax)
            if t <= ETA:
                lo, best = mid, (mid, d)
            else:
                hi = mid
            if hi - lo < 1e-3 * lo:
                break
        if best is not None:
            break
    if best is None:
        raise RuntimeError(f"no stabilized polynomial of degree {P}, order {p}")
    beta, d = best
    for ym in (ymax, 1.0, 0.5, 0.0):
        _, dv = _lp(P, p - 1, beta, ym)
        if dv is not None:
            break
    else:
        raise RuntimeError(f"no embedded polynomial of degree {P}, order {p - 1}")
    w, v = _weights(d, P, p, beta), _weights(dv, P, p - 1, beta)
    return {"P": P, "p": p, "beta_design": beta, "beta": real_beta(w),
            "beta_taylor": real_beta(np.ones(P + 1)),
            "rotation_error_1i": float(abs(stability_poly(w, 1j) - np.exp(1j))),
            "w": w, "v": v}


# ---------------------------------------------------------------- the driver
_DRIVERS: dict = {}


def driver(mod, P: int):
    """A driver on the project's compiled jet of degree P: mode 0 the plain a-priori step (the
    kernel's rule), mode 2 the hybrid (per step the longer of the plain and the stabilized
    step). Samples theta on each step's own polynomial. No events, no stiff hand-over."""
    key = (id(mod), P)
    if key in _DRIVERS:
        return _DRIVERS[key]
    jet = mod.jet

    @nb.njit(cache=False)
    def run(mode, y0, p, t_end, rtol, atol, w, v, q, fac, kappa, ts, th, stats):  # noqa: PLR0912, PLR0915
        n = y0.size
        T = np.zeros((N_ROWS, P + 1))
        y = y0.copy()
        ytmp = np.empty(n)
        t = 0.0
        e = w - v
        kmin = 0
        while kmin < P and e[kmin] == 0.0:
            kmin += 1
        nsteps = nrej = nstab = 0
        hs = 0.0
        inv_q = 1.0 / q
        inv_sc = np.empty(n)
        js = 0
        while js < ts.size and ts[js] <= t:
            th[js] = math.nan
            js += 1
        while t < t_end:
            jet(y, p, T)
            rem = t_end - t
            r1 = 0.0
            r2 = 0.0
            for i in range(n):
                inv_sc[i] = 1.0 / (atol + rtol * abs(y[i]))
                r1 = max(r1, abs(T[i, P]) * inv_sc[i])
                r2 = max(r2, abs(T[i, P - 1]) * inv_sc[i])
            hjz = math.inf
            if r1 > 0.0:
                hjz = r1 ** (-1.0 / P)
            if r2 > 0.0:
                hjz = min(hjz, r2 ** (-1.0 / (P - 1)))
            use_stab = False
            if mode != 0 and hjz < rem:
                h = max(hs, hjz)
                while h > hjz:
                    hh = min(h, rem)
                    err = 0.0
                    for i in range(n):
                        s = e[P] * T[i, P]
                        for k in range(P - 1, kmin - 1, -1):
                            s = s * hh + e[k] * T[i, k]
                        s *= hh ** kmin
                        err = max(err, abs(s) * inv_sc[i])
                    err /= kappa
                    if err <= 1.0:
                        use_stab = True
                        h = hh
                        hs = h * (min(4.0, fac * err ** -inv_q) if err > 0.0 else 4.0)
                        break
                    nrej += 1
                    h *= max(0.2, fac * err ** -inv_q)
                if not use_stab:
                    hs = h
            if not use_stab:
                h = min(hjz, rem)
            if use_stab:  # the weighted sum; the plain one as the kernel's (no weights)
                nstab += 1
                for i in range(n):
                    s = w[P] * T[i, P]
                    for k in range(P - 1, -1, -1):
                        s = s * h + w[k] * T[i, k]
                    y[i] = s
            else:
                for i in range(n):
                    s = T[i, P]
                    for k in range(P - 1, -1, -1):
                        s = s * h + T[i, k]
                    y[i] = s
            t_new = t_end if h >= rem else t + h
            while js < ts.size and ts[js] <= t_new:
                x = ts[js] - t
                for i in range(4, 8):
                    s = T[i, P] * (w[P] if use_stab else 1.0)
                    for k in range(P - 1, -1, -1):
                        s = s * x + T[i, k] * (w[k] if use_stab else 1.0)
                    ytmp[i] = y[i] if ts[js] == t_new else s
                qw, qx, qy, qz = ytmp[4], ytmp[5], ytmp[6], ytmp[7]
                inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
                kx = 2.0 * (qx * qz + qw * qy) * inv
                ky = 2.0 * (qy * qz - qw * qx) * inv
                kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
                th[js] = math.atan2(math.sqrt(kx * kx + ky * ky), kz)
                js += 1
            t = t_new
            nsteps += 1
            if not (h > 1e-9) or nsteps > 300000 or not math.isfinite(y[8]):
                for i in range(n):
                    y[i] = math.nan
                break
        stats[0] = nsteps
        stats[1] = nrej
        stats[2] = nstab
        return y

    _DRIVERS[key] = run
    return run


def theta_of(y: np.ndarray) -> float:
    """theta of a vector state (the axis k from the quaternion)."""
    qw, qx, qy, qz = y[4:8]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx, ky = 2.0 * (qx * qz + qw * qy) * inv, 2.0 * (qy * qz - qw * qx) * inv
    return math.atan2(math.hypot(kx, ky), (qw * qw - qx * qx - qy * qy + qz * qz) * inv)


# ---------------------------------------------------------------- one top
def truth(name: str):
    """theta at the sample times: DOP853 at rtol 1e-14 (and Verner 9(8), their difference)."""
    tp = make_top(name)
    out = {}
    for m in ("dop853", "vern9"):
        res = simulate_ode(tp.top, tp.friction, tp.init, t_end_s=tp.t_end_s,
                           sample_dt_s=SAMPLE_DT[name], stiff="off",
                           options=OdeOptions(method=m, rtol=1e-14, atol=1e-17))
        out[m] = (res.table["t"].to_numpy(), res.table["theta"].to_numpy())
    ts, th = out["dop853"]
    return ts, th, float(np.max(np.abs(th - out["vern9"][1])))


def measure_top(name: str, plain, hybrid, pairs, rounds: int, progress) -> list[dict]:
    """Every (method, rtol) run of one top: steps, errors, best CPU time."""
    tp = make_top(name)
    p, y0 = tp.p.copy(), tp.y0.copy()
    ts, th_true, agree = truth(name)
    print(f"{name}: truth (DOP853 and Verner 9(8) at rtol 1e-14 agree to {agree:.1e} rad)")
    progress(f"{name}: compiling the jets and the drivers")
    methods = [(0, f"taylor{P}", P, np.ones(P + 1), np.ones(P + 1), float(P), 1.0)
               for P in plain]
    for P, q, kappa in hybrid:
        d = pairs[(P, q)]
        methods.append((2, f"hybrid {P},{q}" + ("" if kappa == 1 else f" k{kappa:g}"), P,
                        d["w"], d["v"], float(q), kappa))
    calls = []
    for mode, label, P, w, v, q, kappa in methods:
        f = driver(taylor.kernel(P, taylor.is_symmetric(p)), P)
        for rtol in RTOLS:
            st = np.zeros(3)
            th = np.zeros(ts.size)
            args = (mode, y0, p, tp.t_end_s, rtol, rtol * 1e-3, w, v, q, 0.9, kappa, ts, th, st)
            y = f(*args)
            ok = bool(np.all(np.isfinite(y)))
            calls.append({"method": label, "rtol": rtol, "steps": int(st[0]),
                          "retries": int(st[1]), "stabilized": int(st[2]),
                          "err": abs(theta_of(y) - th_true[-1]) if ok else math.inf,
                          "err_samples": float(np.nanmax(np.abs(th - th_true))) if ok
                          else math.inf, "ms": math.inf, "_f": f, "_args": args})
    rng = random.Random(1)
    bar = None
    if sys.stderr.isatty():  # a bar on a terminal, nothing otherwise
        from tqdm import tqdm

        bar = tqdm(total=rounds * len(calls), desc=f"{name}: timed runs", leave=False)
    for _ in range(rounds):
        order = list(range(len(calls)))
        rng.shuffle(order)
        for i in order:
            c = calls[i]
            t0 = time.process_time()
            c["_f"](*c["_args"])
            c["ms"] = min(c["ms"], 1e3 * (time.process_time() - t0))
            if bar is not None:
                bar.update()
    if bar is not None:
        bar.close()
    return [{k: v for k, v in c.items() if not k.startswith("_")} for c in calls]


def level_table(name: str, rows: list[dict]) -> tuple[list[str], list[dict]]:
    """Per level: the reference's order, the best plain order, the best stabilized variant."""
    by = defaultdict(list)
    for r in rows:
        by[r["method"]].append(r)

    def cheapest(methods, level):
        ok = [r for m in methods for r in by[m]
              if r["err"] <= level and r["err_samples"] <= 3 * level]
        return min(ok, key=lambda r: r["ms"]) if ok else None

    lines = [f"{name}: the cheapest run reaching |theta(t_end) error| <= level and the samples' "
             "<= 3 x level",
             f"  {'level':>6s}  {'':17s} {'method':16s} {'rtol':>6s} {'steps':>6s} {'ms':>7s} "
             f"{'err end':>8s} {'err samp':>8s}  plain/stab"]
    out = []
    for level in LEVELS:
        ours = cheapest([f"taylor{q}" for _, q in TAYLOR_ORDERS], level)
        plain = cheapest([m for m in by if m.startswith("taylor")], level)
        stab = cheapest([m for m in by if not m.startswith("taylor")], level)
        ratio = plain["ms"] / stab["ms"] if plain and stab else None
        for what, r in (("reference's order", ours), ("best plain", plain),
                        ("best stabilized", stab)):
            tail = f"  {ratio:.2f}x" if what == "best stabilized" and ratio else ""
            if r is None:
                lines.append(f"  {level:6.0e}  {what:17s} not reached")
                continue
            lines.append(f"  {level:6.0e}  {what:17s} {r['method']:16s} {r['rtol']:6.0e} "
                         f"{r['steps']:6d} {r['ms']:7.3f} {r['err']:8.1e} "
                         f"{r['err_samples']:8.1e}{tail}")
        out.append({"level": level, "plain": plain, "stabilized": stab, "ratio": ratio,
                    "steps_ratio": plain["steps"] / stab["steps"] if plain and stab else None})
    return lines, out


def main(argv: list[str] | None = None) -> int:
    """Design the polynomials, run the tops, print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tops", default="fig11,fig3")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="orders 7, 9, 12 and two pairs")
    ap.add_argument("--json", default=None, help="write the rows and tables here")
    a = ap.parse_args(argv)
    tops = [t for t in a.tops.split(",") if t]
    bad = [t for t in tops if t not in SAMPLE_DT]
    if bad or a.rounds < 1:
        print(f"bench_stabilized_taylor: expected --tops from {', '.join(SAMPLE_DT)} and "
              f"--rounds >= 1, got --tops {a.tops!r} --rounds {a.rounds}", file=sys.stderr)
        return 2
    if a.json and Path(a.json).exists():
        print(f"bench_stabilized_taylor: expected a new --json file, got {a.json!r} (exists)",
              file=sys.stderr)
        return 2
    plain, hybrid = (QUICK_PLAIN, QUICK_HYBRID) if a.quick else (PLAIN, HYBRID)

    def progress(msg: str) -> None:
        if sys.stderr.isatty():
            print(f"bench_stabilized_taylor: {msg}", file=sys.stderr, flush=True)

    pairs = {}
    print("the polynomials (degree P, order p): real stability boundary beta against plain "
          "Taylor's of degree P, and |R(i) - e^i| (the rotation's error at h omega = 1)")
    for P, q, _ in hybrid:
        if (P, q) in pairs:
            continue
        d = pairs[(P, q)] = design_pair(P, q)
        print(f"  P = {P:2d}, p = {q:2d}: beta {d['beta']:6.2f} (plain {d['beta_taylor']:5.2f}:"
              f" {d['beta'] / d['beta_taylor']:.2f}x), |R(i) - e^i| "
              f"{d['rotation_error_1i']:.1e}")
    doc = {"rounds": a.rounds, "timing": "CPU time (time.process_time), best of the rounds",
           "pairs": {f"{P},{q}": {k: (v.tolist() if isinstance(v, np.ndarray) else v)
                                  for k, v in d.items()} for (P, q), d in pairs.items()},
           "tops": {}}
    for name in tops:
        rows = measure_top(name, plain, hybrid, pairs, a.rounds, progress)
        lines, table = level_table(name, rows)
        print("\n".join(lines))
        doc["tops"][name] = {"rows": rows, "levels": table}
    if a.json:
        Path(a.json).write_text(json.dumps(doc, indent=1, default=float))
    return 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except KeyboardInterrupt:
        print("bench_stabilized_taylor: interrupted (nothing written)", file=sys.stderr)
        raise SystemExit(130) from None
