"""A compiled Verner 9(8) Runge-Kutta pair, with the contract of :mod:`reference_ode.dop853`.

Verner's "most efficient" IIIXb-9(8) pair (Julia's Vern9; coefficients in
:mod:`reference_ode.verner_tableau`): 16 stages a step plus f(y_new) (the next step's first
stage; not FSAL, so 16 evaluations per accepted step, 15 per rejected one), the 9th-order
solution carried, the embedded 8th-order one for the error estimate. Its 9th-order interpolant
needs 9 more evaluations (stages 17-25, f(y_new) being stage 16), made only for a step that holds
a sample or an event. :func:`run` is :func:`dop853.dop853_run`'s contract exactly: the same
arguments, statuses, ``stats`` slots, events, chunks and stiffness hook.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from tippetop.reference_ode import verner_tableau as _coef
from tippetop.reference_ode.dop853 import (
    BISECTION_ITERS,
    GUARD_SCAN,
    MAX_FACTOR,
    MIN_FACTOR,
    MIN_STEP_ULPS,
    RHS_TYPE,
    S_H,
    S_HLAMBDA_MAX,
    S_MONITOR_MIN,
    S_NREJECT,
    S_NRHS,
    S_NSTEPS,
    S_NSTIFF,
    S_STIFF_STOP,
    S_T_MARK,
    SAFETY,
    STATUS_GUARD,
    STATUS_MAX_STEPS,
    STATUS_MONITOR,
    STATUS_OK,
    STATUS_RUNNING,
    STATUS_STEP_TOO_SMALL,
    STATUS_STIFF,
    WATCH_TYPE,
    initial_step,
    new_stats,
    padded,
)

__all__ = ["new_stats", "run", "fixed_steps", "dense_coeffs", "dense_eval"]

# ---------------------------------------------------------------- the tableau
N_STAGES = _coef.N_STAGES  # 16 stages per step
N_K = _coef.N_EXTENDED  # rows of the stage buffer K: 16 stages, f(y_new), 9 interpolant stages
F_NEW = N_STAGES  # the row of f(y_new) in K
A = np.ascontiguousarray(_coef.A)
B = np.ascontiguousarray(_coef.B)
E = np.ascontiguousarray(_coef.E)
R = np.ascontiguousarray(_coef.R)  # interpolant weights b_i(x) = sum_r R[i, r-1] x^r
DEG = _coef.INTERP_DEGREE  # 9

# ---------------------------------------------------------------- tuning
ERROR_EXPONENT = -1.0 / 9.0  # -1 / (embedded order + 1)
#: h lambda above this flags a step as stiff. The real stability interval of the 9th-order
#: method is [-4.476, 0], that of the embedded 8th-order one [-3.879, 0] (|R(z)| <= 1 for the
#: stability polynomials; tests/reference_ode/test_verner.py): past 3.88 the error estimate
#: itself is amplified (|R(z) - R_hat(z)| = 1.2 at z = -3.9, 7.0 at -4.476), so 3.88 is the
#: ceiling of a stiff step. On y' = -1000 y the steps reach it (h lambda 4.26-4.87, the
#: estimate atol-dominated), but on the tippe top's stiff slip mode the error estimate holds
#: them below it: h lambda 3.97-4.00 at Lambda = 1e-6 and only 2.69-3.07 (5-95 %) with the
#: exact Coulomb law's ramp (v_eps = 1e-5), while non-stiff runs stay at <= 2.14 (fig3 at
#: Lambda = 1e-4 over 8 s; the catalogue at the paper's 1e-2: <= 1.83). Hairer's 6.1 (0.955
#: of DOP853's 6.394) would miss the ramp; 2.5 (0.645 of 3.879) lies between the two groups.
STIFF_HLAMBDA = 2.5
_OPTS = {"cache": True, "error_model": "numpy"}  # as dop853: x / 0 gives inf or NaN
_V = nb.types.float64[::1]
_M = nb.types.float64[:, ::1]
_F8 = nb.types.float64
_I8 = nb.types.int64


# ---------------------------------------------------------------- dense output and events
@nb.njit(nb.types.none(RHS_TYPE, _V, _F8, _V, _M, _M, _V), **_OPTS)
def dense_coeffs(rhs, y_old, h, p, K, F, ytmp):
    """Fill ``F`` (9, n) with the step's interpolant coefficients; 9 extra evaluations.

    ``K`` is the stage buffer of the step, (26, >= n): rows 0-15 the stages, 16 f(y_new); rows
    17-25 receive the extra stages. Then y(t + x h) = y_old + sum_r F[r - 1] x^r.
    """
    n = y_old.size
    for s in range(N_STAGES + 1, N_K):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * K[j, i]
            ytmp[i] = y_old[i] + h * acc
        rhs(ytmp, p, K[s][:n])
    for r in range(DEG):
        for i in range(n):
            acc = 0.0
            for j in range(N_K):
                acc += R[j, r] * K[j, i]
            F[r, i] = h * acc


@nb.njit(nb.types.none(_M, _V, _F8, _V), **_OPTS)
def dense_eval(F, y_old, x, out):
    """The 9th-order interpolant at the fraction ``x = (t - t_old) / h`` of the step."""
    n = y_old.size
    for i in range(n):
        v = F[DEG - 1, i]
        for r in range(DEG - 2, -1, -1):
            v = v * x + F[r, i]
        out[i] = y_old[i] + v * x


@nb.njit(_F8(RHS_TYPE, WATCH_TYPE, nb.types.boolean, _M, _V, _V, _V, _V, _F8, _F8), **_OPTS)
def locate(rhs, watch, use_guard, F, y_old, p, ytmp, dy, lo, hi):
    """:func:`dop853.locate` on this interpolant.

    The fraction in (lo, hi] of the step where the guard (``use_guard``) or the mark falls from
    > 0 to <= 0, to 2^-BISECTION_ITERS of the step.
    """
    for _ in range(BISECTION_ITERS):
        mid = 0.5 * (lo + hi)
        dense_eval(F, y_old, mid, ytmp)
        if use_guard:
            v = rhs(ytmp, p, dy)
        else:
            v = watch(ytmp, p)[0]
        if v > 0.0:
            lo = mid
        else:
            hi = mid
    return hi


# ---------------------------------------------------------------- the kernel
@nb.njit(nb.types.Tuple((_I8, _F8, _I8))(RHS_TYPE, WATCH_TYPE, _V, _F8, _F8, _F8, _V, _F8, _F8,
                                          _I8, _F8, _V, _M, _I8, _V, _F8, _M), **_OPTS)
def _kernel(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor,
            t_out, Y_out, i_out, stats, h_fixed, K_out):
    """:func:`run`; with ``h_fixed`` > 0, steps of that size with no error control.

    (For tests: a ``K_out`` of shape (26, n) then receives each step's stage buffer, rows 0-16.)
    """
    n = y.size
    m = padded(n)
    # as dop853._kernel: padded buffers, views made once, the stages written out
    K = np.zeros((N_K, m))
    yc = np.zeros(m)  # the state at t
    y_new = np.zeros(m)
    yt = np.zeros(m)  # a stage's point; after a step the last one (stage 15, c = 1)
    yc_v = yc[:n]
    y_new_v = y_new[:n]
    yt_v = yt[:n]
    f = K[0][:n]  # f(y) at t
    k1 = K[1][:n]
    k2 = K[2][:n]
    k3 = K[3][:n]
    k4 = K[4][:n]
    k5 = K[5][:n]
    k6 = K[6][:n]
    k7 = K[7][:n]
    k8 = K[8][:n]
    k9 = K[9][:n]
    k10 = K[10][:n]
    k11 = K[11][:n]
    k12 = K[12][:n]
    k13 = K[13][:n]
    k14 = K[14][:n]
    k15 = K[15][:n]
    f_new = K[F_NEW][:n]  # f(y_new)
    F = np.empty((DEG, n))
    dy = np.empty(n)
    for i in range(n):
        yc[i] = y[i]
    g0 = rhs(yc_v, p, f)
    stats[S_NRHS] += 1
    if not g0 > 0.0:
        return STATUS_GUARD, t, i_out
    h_abs = stats[S_H]
    if h_fixed > 0.0:
        h_abs = h_fixed
    elif not h_abs > 0.0:
        h_abs = initial_step(rhs, t, yc_v, f, t_end, p, rtol, atol)
        stats[S_NRHS] += 1
    mark_old = watch(yc_v, p)[0]
    n_out = t_out.size
    while i_out < n_out and t_out[i_out] <= t:
        Y_out[i_out, :] = yc_v
        i_out += 1
    status = STATUS_RUNNING
    while t < t_stop:
        if stats[S_NSTEPS] >= max_steps:
            status = STATUS_MAX_STEPS
            break
        min_step = MIN_STEP_ULPS * abs(np.nextafter(t, np.inf) - t)
        rejected = False
        while True:
            if not h_abs >= min_step:  # also catches a NaN step size
                status = STATUS_STEP_TOO_SMALL
                break
            t_new = t + h_abs
            if t_new > t_end:
                t_new = t_end
            h = t_new - t
            # --- the 15 new stages (K[1:16]); each sum's zero entries skipped
            g_min = np.inf
            for i in range(m):
                yt[i] = yc[i] + h * (A[1, 0] * K[0, i])
            g_min = min(g_min, rhs(yt_v, p, k1))
            for i in range(m):
                yt[i] = yc[i] + h * (A[2, 0] * K[0, i] + A[2, 1] * K[1, i])
            g_min = min(g_min, rhs(yt_v, p, k2))
            for i in range(m):
                yt[i] = yc[i] + h * (A[3, 0] * K[0, i] + A[3, 2] * K[2, i])
            g_min = min(g_min, rhs(yt_v, p, k3))
            for i in range(m):
                yt[i] = yc[i] + h * (A[4, 0] * K[0, i] + A[4, 2] * K[2, i] + A[4, 3] * K[3, i])
            g_min = min(g_min, rhs(yt_v, p, k4))
            for i in range(m):
                yt[i] = yc[i] + h * (A[5, 0] * K[0, i] + A[5, 3] * K[3, i] + A[5, 4] * K[4, i])
            g_min = min(g_min, rhs(yt_v, p, k5))
            for i in range(m):
                yt[i] = yc[i] + h * (A[6, 0] * K[0, i] + A[6, 3] * K[3, i] + A[6, 4] * K[4, i]
                                     + A[6, 5] * K[5, i])
            g_min = min(g_min, rhs(yt_v, p, k6))
            for i in range(m):
                yt[i] = yc[i] + h * (A[7, 0] * K[0, i] + A[7, 5] * K[5, i] + A[7, 6] * K[6, i])
            g_min = min(g_min, rhs(yt_v, p, k7))
            for i in range(m):
                yt[i] = yc[i] + h * (A[8, 0] * K[0, i] + A[8, 5] * K[5, i] + A[8, 6] * K[6, i]
                                     + A[8, 7] * K[7, i])
            g_min = min(g_min, rhs(yt_v, p, k8))
            for i in range(m):
                yt[i] = yc[i] + h * (A[9, 0] * K[0, i] + A[9, 5] * K[5, i] + A[9, 6] * K[6, i]
                                     + A[9, 7] * K[7, i] + A[9, 8] * K[8, i])
            g_min = min(g_min, rhs(yt_v, p, k9))
            for i in range(m):
                yt[i] = yc[i] + h * (A[10, 0] * K[0, i] + A[10, 5] * K[5, i]
                                     + A[10, 6] * K[6, i] + A[10, 7] * K[7, i]
                                     + A[10, 8] * K[8, i] + A[10, 9] * K[9, i])
            g_min = min(g_min, rhs(yt_v, p, k10))
            for i in range(m):
                yt[i] = yc[i] + h * (A[11, 0] * K[0, i] + A[11, 5] * K[5, i]
                                     + A[11, 6] * K[6, i] + A[11, 7] * K[7, i]
                                     + A[11, 8] * K[8, i] + A[11, 9] * K[9, i]
                                     + A[11, 10] * K[10, i])
            g_min = min(g_min, rhs(yt_v, p, k11))
            for i in range(m):
                yt[i] = yc[i] + h * (A[12, 0] * K[0, i] + A[12, 5] * K[5, i]
                                     + A[12, 6] * K[6, i] + A[12, 7] * K[7, i]
                                     + A[12, 8] * K[8, i] + A[12, 9] * K[9, i]
                                     + A[12, 10] * K[10, i] + A[12, 11] * K[11, i])
            g_min = min(g_min, rhs(yt_v, p, k12))
            for i in range(m):
                yt[i] = yc[i] + h * (A[13, 0] * K[0, i] + A[13, 5] * K[5, i]
                                     + A[13, 6] * K[6, i] + A[13, 7] * K[7, i]
                                     + A[13, 8] * K[8, i] + A[13, 9] * K[9, i]
                                     + A[13, 10] * K[10, i] + A[13, 11] * K[11, i]
                                     + A[13, 12] * K[12, i])
            g_min = min(g_min, rhs(yt_v, p, k13))
            for i in range(m):
                yt[i] = yc[i] + h * (A[14, 0] * K[0, i] + A[14, 5] * K[5, i]
                                     + A[14, 6] * K[6, i] + A[14, 7] * K[7, i]
                                     + A[14, 8] * K[8, i] + A[14, 9] * K[9, i]
                                     + A[14, 10] * K[10, i] + A[14, 11] * K[11, i]
                                     + A[14, 12] * K[12, i] + A[14, 13] * K[13, i])
            g_min = min(g_min, rhs(yt_v, p, k14))
            for i in range(m):
                yt[i] = yc[i] + h * (A[15, 0] * K[0, i] + A[15, 5] * K[5, i]
                                     + A[15, 6] * K[6, i] + A[15, 7] * K[7, i]
                                     + A[15, 8] * K[8, i] + A[15, 9] * K[9, i]
                                     + A[15, 10] * K[10, i] + A[15, 11] * K[11, i]
                                     + A[15, 12] * K[12, i])
            g_min = min(g_min, rhs(yt_v, p, k15))
            stats[S_NRHS] += N_STAGES - 1
            for i in range(m):
                y_new[i] = yc[i] + h * (B[0] * K[0, i] + B[7] * K[7, i] + B[8] * K[8, i]
                                        + B[9] * K[9, i] + B[10] * K[10, i] + B[11] * K[11, i]
                                        + B[12] * K[12, i] + B[13] * K[13, i]
                                        + B[14] * K[14, i])
            if h_fixed > 0.0:
                break
            # --- the error norm: the RMS of h sum_i (b_i - b_hat_i) k_i scaled by
            # atol + max(|y|, |y_new|) rtol (< 1: accept; NaN or inf: overflow)
            s2 = 0.0
            for i in range(n):
                sc = atol + max(abs(yc[i]), abs(y_new[i])) * rtol
                ev = h * (E[0] * K[0, i] + E[7] * K[7, i] + E[8] * K[8, i] + E[9] * K[9, i]
                          + E[10] * K[10, i] + E[11] * K[11, i] + E[12] * K[12, i]
                          + E[13] * K[13, i] + E[14] * K[14, i] + E[15] * K[15, i]) / sc
                s2 += ev * ev
            err = math.sqrt(s2 / n)
            if err < 1.0:
                if err == 0.0:
                    factor = MAX_FACTOR
                else:
                    factor = min(MAX_FACTOR, SAFETY * err ** ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            # rejected (a non-finite error estimate also lands here and shrinks the step)
            if math.isfinite(err):
                h_abs *= max(MIN_FACTOR, SAFETY * err ** ERROR_EXPONENT)
            else:
                h_abs *= MIN_FACTOR
            rejected = True
            stats[S_NREJECT] += 1
        if status == STATUS_STEP_TOO_SMALL:
            break
        # --- f(y_new): the guard at the step's end and the next step's first stage
        g_new = rhs(y_new_v, p, f_new)
        stats[S_NRHS] += 1
        g_min = min(g_min, g_new)
        stats[S_NSTEPS] += 1
        if h_fixed > 0.0 and K_out.shape[0] > 0:
            for r in range(N_STAGES + 1):
                for i in range(n):
                    K_out[r, i] = K[r, i]
        # --- stiffness detection: yt holds the last stage's point (c = 1, t + h), K[15] its
        # derivative; lambda ~ |f(y_new) - k_15| / |y_new - yt|
        st_num = 0.0
        st_den = 0.0
        for i in range(n):
            dk = K[F_NEW, i] - K[N_STAGES - 1, i]
            dyv = y_new[i] - yt[i]
            st_num += dk * dk
            st_den += dyv * dyv
        if st_den > 0.0:
            h_lambda = h * math.sqrt(st_num / st_den)
            if h_lambda > stats[S_HLAMBDA_MAX]:
                stats[S_HLAMBDA_MAX] = h_lambda
            if h_lambda > STIFF_HLAMBDA:
                stats[S_NSTIFF] += 1
        # --- events and samples on the interpolant (its stages only for a step that holds a
        # sample or an event)
        mark_new, monitor = watch(y_new_v, p)
        if monitor < stats[S_MONITOR_MIN]:
            stats[S_MONITOR_MIN] = monitor
        guard_dip = not (g_min > 0.0)
        mark_hit = math.isnan(stats[S_T_MARK]) and mark_old > 0.0 and mark_new <= 0.0
        need_dense = guard_dip or mark_hit or (i_out < n_out and t_out[i_out] <= t_new)
        if need_dense:
            dense_coeffs(rhs, yc_v, h, p, K, F, yt_v)
            stats[S_NRHS] += N_K - N_STAGES - 1
            t_final = t_new
            guard_hit = False
            if guard_dip:
                lo = 0.0
                for k in range(1, GUARD_SCAN + 1):
                    x = k / GUARD_SCAN
                    dense_eval(F, yc_v, x, yt_v)
                    stats[S_NRHS] += 1
                    if not (rhs(yt_v, p, dy) > 0.0):
                        guard_hit = True
                        t_final = t + h * locate(rhs, watch, True, F, yc_v, p, yt_v, dy, lo, x)
                        stats[S_NRHS] += BISECTION_ITERS
                        break
                    lo = x
            if mark_hit:
                t_mark = t + h * locate(rhs, watch, False, F, yc_v, p, yt_v, dy, 0.0, 1.0)
                if t_mark <= t_final:
                    stats[S_T_MARK] = t_mark
            while i_out < n_out and t_out[i_out] <= t_final:
                if t_out[i_out] == t_new:
                    Y_out[i_out, :] = y_new_v
                else:
                    dense_eval(F, yc_v, (t_out[i_out] - t) / h, yt_v)
                    Y_out[i_out, :] = yt_v
                i_out += 1
            if guard_hit:
                dense_eval(F, yc_v, (t_final - t) / h, y)
                stats[S_H] = h_abs
                return STATUS_GUARD, t_final, i_out
        t = t_new
        for i in range(m):
            yc[i] = y_new[i]
            K[0, i] = K[F_NEW, i]
        mark_old = mark_new
        if monitor < monitor_floor:
            status = STATUS_MONITOR
            break
        if stats[S_NSTIFF] >= stats[S_STIFF_STOP]:  # the hook of solve.py's rolling phases
            status = STATUS_STIFF
            break
    stats[S_H] = h_abs
    for i in range(n):
        y[i] = yc[i]
    if status == STATUS_RUNNING and t >= t_end:
        status = STATUS_OK
    return status, t, i_out


def run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
        rtol: float, atol: float, max_steps: int, monitor_floor: float, t_out: np.ndarray,
        Y_out: np.ndarray, i_out: int, stats: np.ndarray) -> tuple[int, float, int]:
    """Integrate y' = rhs(y) from (t, y) until t >= t_stop (the last step ends at t_end).

    Exactly :func:`dop853.dop853_run`'s contract (arguments, ``STATUS_*`` codes, ``stats``
    slots, events on the dense output, chunks), with Verner's 9(8) pair. One call of the
    compiled :func:`_kernel`.

    Returns:
        (status, t, i_out), as :func:`dop853.dop853_run`.
    """
    return _kernel(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor,
                   t_out, Y_out, i_out, stats, 0.0, _NO_K_OUT)


_NO_K_OUT = np.empty((0, 0))


def fixed_steps(rhs, watch, y: np.ndarray, p: np.ndarray, h: float, n_steps: int,
                t_out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_steps`` steps of size ``h`` from (0, ``y``), no error control (for tests).

    Returns:
        (the state after the steps (``y``, advanced in place), the samples at ``t_out``, the
        last step's stage buffer, (26, n): rows 0-15 the stages, 16 f(y_new)).
    """
    t_out = np.empty(0) if t_out is None else np.ascontiguousarray(t_out, dtype=float)
    Y = np.full((t_out.size, y.size), np.nan)
    K = np.zeros((N_K, y.size))
    t_end = float(h * n_steps)
    _kernel(rhs, watch, y, 0.0, t_end, t_end, np.ascontiguousarray(p, dtype=float), 1.0, 1.0,
            n_steps, -np.inf, t_out, Y, 0, new_stats(), float(h), K)
    return y, Y, K
