"""A compiled Dormand-Prince 8(5,3) integrator, generic over a compiled right-hand side.

Hairer's DOP853 with scipy's coefficients (:mod:`reference_ode.dop853_tableau`), the loop, the
right-hand side and the events all compiled. :func:`dop853_run` integrates a problem given as
two numba ``njit`` functions of :data:`RHS_SIG` and :data:`WATCH_SIG` (float64, C-contiguous
arrays): ``rhs(y, p, dy) -> guard``, the run stopping where the guard falls to <= 0, and
``watch(y, p) -> (mark, monitor)``, evaluated at every step end. The contract in full, why the
kernel takes function pointers, what a step costs and the stiffness detector: docs/design.md.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from tippetop.reference_ode import dop853_tableau as _coef

STATUS_OK = 0  # reached t_end
STATUS_GUARD = 1  # the guard returned by rhs fell to <= 0 (located on the dense output)
STATUS_MONITOR = 2  # the monitor returned by watch fell below monitor_floor at a step end
STATUS_MAX_STEPS = 3  # max_steps accepted steps taken
STATUS_STEP_TOO_SMALL = 4  # the step size fell below 10 ulp of t (or became NaN)
STATUS_RUNNING = 5  # a chunk ended at t_stop before t_end; the caller continues
STATUS_STIFF = 6  # stats[S_NSTIFF] reached stats[S_STIFF_STOP] (a step end; off by default)

# ---------------------------------------------------------------- the tableau (scipy's)
N_STAGES = _coef.N_STAGES  # 12 stages per step (the 13th, f(y_new), is reused: FSAL)
A = np.ascontiguousarray(_coef.A[:N_STAGES, :N_STAGES])  # stage coefficients a_ij
B = np.ascontiguousarray(_coef.B)  # 8th-order weights b_i
C = np.ascontiguousarray(_coef.C[:N_STAGES])  # nodes c_i
E3 = np.ascontiguousarray(_coef.E3)  # 3rd-order error estimator (13 entries, last: f(y_new))
E5 = np.ascontiguousarray(_coef.E5)  # 5th-order error estimator
D = np.ascontiguousarray(_coef.D)  # dense output, (4, 16)
A_EXTRA = np.ascontiguousarray(_coef.A[N_STAGES + 1:])  # the 3 dense-output stages, (3, 16)
C_EXTRA = np.ascontiguousarray(_coef.C[N_STAGES + 1:])  # their nodes
N_K = N_STAGES + 4  # rows of the stage buffer K: 12 stages, f(y_new), 3 dense-output stages

# ---------------------------------------------------------------- tuning
SAFETY = 0.9  # step-size safety factor
MIN_FACTOR = 0.2  # largest allowed decrease of the step in one go
MAX_FACTOR = 10.0  # largest allowed increase of the step in one go
ERROR_EXPONENT = -1.0 / 8.0  # -1 / (error estimator order + 1)
BISECTION_ITERS = 60  # event location on the dense output: 2^-60 of a step
GUARD_SCAN = 32  # a guard that dipped at a stage is looked for at 32 points of the step
STIFF_HLAMBDA = 6.1  # h lambda above this flags a step as stiff (Hairer's DOP853 threshold)
MIN_STEP_ULPS = 10.0  # a step below this many ulp of t is an underflow (as scipy)

# ---------------------------------------------------------------- compiled signatures
_V = nb.types.float64[::1]  # a C-contiguous float64 vector
_M = nb.types.float64[:, ::1]  # a C-contiguous float64 matrix
_F8 = nb.types.float64
_I8 = nb.types.int64
#: ``rhs(y, p, dy) -> guard``
RHS_SIG = _F8(_V, _V, _V)
#: ``watch(y, p) -> (mark, monitor)``
WATCH_SIG = nb.types.UniTuple(_F8, 2)(_V, _V)
RHS_TYPE = nb.types.FunctionType(RHS_SIG)
WATCH_TYPE = nb.types.FunctionType(WATCH_SIG)
_OPTS = {"cache": True, "error_model": "numpy"}  # x / 0 gives inf or NaN (a rejected step)

# ---------------------------------------------------------------- stats slots
S_NRHS = 0  # right-hand-side evaluations
S_NSTEPS = 1  # accepted steps
S_NREJECT = 2  # rejected steps
S_T_MARK = 3  # time of the first > 0 to <= 0 crossing of the mark, NaN if none
S_H = 4  # step size carried to the next chunk (0: choose a starting step)
S_MONITOR_MIN = 5  # smallest monitor at a step end, +inf before the first step
S_NSTIFF = 6  # accepted steps with h lambda > STIFF_HLAMBDA
S_HLAMBDA_MAX = 7  # largest h lambda estimate of an accepted step
S_STIFF_STOP = 8  # return STATUS_STIFF once S_NSTIFF reaches this (+inf: never)
N_STATS = 9


def new_stats(n: int = 0) -> np.ndarray:
    """A fresh ``stats`` vector for :func:`dop853_run`: counters 0, no mark, no monitor.

    (``n``, the state's size, is the methods' common signature, :mod:`.methods`; unused.)
    """
    stats = np.zeros(N_STATS)
    stats[S_T_MARK] = np.nan
    stats[S_MONITOR_MIN] = np.inf
    stats[S_STIFF_STOP] = np.inf
    return stats


# ---------------------------------------------------------------- layout
# The stage buffers are padded to a multiple of LANES (4 float64: one AVX2 register) so that
# LLVM turns the loops over the entries into vector instructions with no scalar remainder.
LANES = 4


# ---------------------------------------------------------------- dense output and events
@nb.njit(nb.types.none(RHS_TYPE, _V, _V, _V, _F8, _V, _M, _M, _V), **_OPTS)
def dense_coeffs(rhs, y_old, y_new, f_new, h, p, K, F, ytmp):
    """Fill ``F`` (7, n) with the step's dense-output coefficients; 3 extra evaluations.

    ``K`` is the stage buffer of the step, (16, >= n) (rows 0-12 from the step); rows 13-15
    receive the extra stages. ``ytmp`` is scratch.
    """
    n = y_old.size
    for s in range(3):
        a = A_EXTRA[s]
        for i in range(n):
            acc = 0.0
            for j in range(N_STAGES + 1 + s):
                acc += a[j] * K[j, i]
            ytmp[i] = y_old[i] + h * acc
        rhs(ytmp, p, K[N_STAGES + 1 + s][:n])
    for i in range(n):
        dy = y_new[i] - y_old[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (f_new[i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(N_K):
                acc += D[r, j] * K[j, i]
            F[3 + r, i] = h * acc


@nb.njit(nb.types.none(_M, _V, _F8, _V), **_OPTS)
def dense_eval(F, y_old, x, out):
    """The 7th-order dense output at the fraction ``x = (t - t_old) / h`` of the step."""
    n = y_old.size
    for i in range(n):
        v = 0.0
        for r in range(7):
            v += F[6 - r, i]
            if r % 2 == 0:
                v *= x
            else:
                v *= 1.0 - x
        out[i] = v + y_old[i]


@nb.njit(_F8(RHS_TYPE, WATCH_TYPE, nb.types.boolean, _M, _V, _V, _V, _V, _F8, _F8), **_OPTS)
def locate(rhs, watch, use_guard, F, y_old, p, ytmp, dy, lo, hi):
    """Where in the step an event function falls from > 0 to <= 0, by bisection.

    The event function is the guard ``rhs(y, p, dy)`` if ``use_guard``, else the mark
    ``watch(y, p)[0]``, evaluated on the dense output ``F`` of the step from ``y_old``. The
    caller has checked that it is > 0 at the fraction ``lo`` of the step and <= 0 at ``hi``.

    Returns:
        The fraction x in (lo, hi] of the step (within 2^-BISECTION_ITERS of the step) at which
        the event function is found <= 0.
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


# ---------------------------------------------------------------- the adaptive driver
@nb.njit(_F8(RHS_TYPE, _F8, _V, _V, _F8, _V, _F8, _F8), **_OPTS)
def initial_step(rhs, t0, y0, f0, t_end, p, rtol, atol):
    """Hairer's starting step (as ``scipy.integrate._ivp.common.select_initial_step``).

    One evaluation of ``rhs``. NaN or 0 if the start overflows (the driver then reports
    :data:`STATUS_STEP_TOO_SMALL`).
    """
    n = y0.size
    d0 = 0.0
    d1 = 0.0
    for i in range(n):
        sc = atol + abs(y0[i]) * rtol
        d0 += (y0[i] / sc) ** 2
        d1 += (f0[i] / sc) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    if d0 < 1e-5 or d1 < 1e-5 or not (d0 < np.inf and d1 < np.inf):
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, t_end - t0)
    if not h0 > 0.0:
        h0 = 1e-6 * (t_end - t0)
    y1 = y0 + h0 * f0
    f1 = np.empty(n)
    rhs(y1, p, f1)
    d2 = 0.0
    for i in range(n):
        sc = atol + abs(y0[i]) * rtol
        d2 += ((f1[i] - f0[i]) / sc) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, t_end - t0)


# ---------------------------------------------------------------- the kernel
@nb.njit(inline="always", **_OPTS)
def padded(n):
    """The length of the kernel's stage buffers for a state of size n: a multiple of LANES."""
    return (n + LANES - 1) // LANES * LANES


@nb.njit(nb.types.Tuple((_I8, _F8, _I8))(RHS_TYPE, WATCH_TYPE, _V, _F8, _F8, _F8, _V, _F8, _F8,
                                          _I8, _F8, _V, _M, _I8, _V, _F8, _M), **_OPTS)
def _kernel(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor,
            t_out, Y_out, i_out, stats, h_fixed, K_out):
    """:func:`dop853_run`; with ``h_fixed`` > 0, steps of that size with no error control.

    (Every step accepted: for tests of the method's order and dense output; a ``K_out`` of
    shape (16, n) then receives each step's stage buffer, rows 0-12.)
    """
    n = y.size
    m = padded(n)
    # The stage buffer K and the states, padded to m with zeros (rhs writes the first n
    # entries, so the padding stays 0); rhs and watch see views of the first n entries,
    # made once here. The step is written out below, not in helper functions: an array
    # handed to a function numba inlines costs two atomic reference-count updates per call,
    # and a view made per call as many.
    K = np.zeros((N_K, m))
    yc = np.zeros(m)  # the state at t
    y_new = np.zeros(m)
    yt = np.zeros(m)  # a stage's point; after a step the last one (c = 1)
    e5 = np.zeros(m)
    e3 = np.zeros(m)
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
    f_new = K[N_STAGES][:n]  # f(y_new)
    F = np.empty((7, n))
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
            # --- the 12 stages (derivatives into K[1:12]), y_new and f(y_new) (K[12]); the
            # terms of each sum in the tableau's order, its zero entries skipped
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
                yt[i] = yc[i] + h * (A[7, 0] * K[0, i] + A[7, 3] * K[3, i] + A[7, 4] * K[4, i]
                                     + A[7, 5] * K[5, i] + A[7, 6] * K[6, i])
            g_min = min(g_min, rhs(yt_v, p, k7))
            for i in range(m):
                yt[i] = yc[i] + h * (A[8, 0] * K[0, i] + A[8, 3] * K[3, i] + A[8, 4] * K[4, i]
                                     + A[8, 5] * K[5, i] + A[8, 6] * K[6, i] + A[8, 7] * K[7, i])
            g_min = min(g_min, rhs(yt_v, p, k8))
            for i in range(m):
                yt[i] = yc[i] + h * (A[9, 0] * K[0, i] + A[9, 3] * K[3, i] + A[9, 4] * K[4, i]
                                     + A[9, 5] * K[5, i] + A[9, 6] * K[6, i] + A[9, 7] * K[7, i]
                                     + A[9, 8] * K[8, i])
            g_min = min(g_min, rhs(yt_v, p, k9))
            for i in range(m):
                yt[i] = yc[i] + h * (A[10, 0] * K[0, i] + A[10, 3] * K[3, i] + A[10, 4] * K[4, i]
                                     + A[10, 5] * K[5, i] + A[10, 6] * K[6, i] + A[10, 7] * K[7, i]
                                     + A[10, 8] * K[8, i] + A[10, 9] * K[9, i])
            g_min = min(g_min, rhs(yt_v, p, k10))
            for i in range(m):
                yt[i] = yc[i] + h * (A[11, 0] * K[0, i] + A[11, 3] * K[3, i] + A[11, 4] * K[4, i]
                                     + A[11, 5] * K[5, i] + A[11, 6] * K[6, i] + A[11, 7] * K[7, i]
                                     + A[11, 8] * K[8, i] + A[11, 9] * K[9, i]
                                     + A[11, 10] * K[10, i])
            g_min = min(g_min, rhs(yt_v, p, k11))
            for i in range(m):
                y_new[i] = yc[i] + h * (B[0] * K[0, i] + B[5] * K[5, i] + B[6] * K[6, i]
                                        + B[7] * K[7, i] + B[8] * K[8, i] + B[9] * K[9, i]
                                        + B[10] * K[10, i] + B[11] * K[11, i])
            g_new = rhs(y_new_v, p, f_new)
            g_min = min(g_min, g_new)
            stats[S_NRHS] += N_STAGES
            if h_fixed > 0.0:
                if K_out.shape[0] > 0:
                    for r in range(N_STAGES + 1):
                        for i in range(n):
                            K_out[r, i] = K[r, i]
                break
            # --- the error norm, as scipy's DOP853 (< 1: accept; NaN or inf: overflow):
            # |h| e5 / sqrt(e5^2 + 0.01 e3^2), e5 and e3 the RMS of the 5th- and 3rd-order
            # estimates scaled by atol + max(|y|, |y_new|) rtol
            for i in range(m):
                sc = atol + max(abs(yc[i]), abs(y_new[i])) * rtol
                e5[i] = (E5[0] * K[0, i] + E5[5] * K[5, i] + E5[6] * K[6, i] + E5[7] * K[7, i]
                         + E5[8] * K[8, i] + E5[9] * K[9, i] + E5[10] * K[10, i]
                         + E5[11] * K[11, i]) / sc
                e3[i] = (E3[0] * K[0, i] + E3[5] * K[5, i] + E3[6] * K[6, i] + E3[7] * K[7, i]
                         + E3[8] * K[8, i] + E3[9] * K[9, i] + E3[10] * K[10, i]
                         + E3[11] * K[11, i]) / sc
            s5 = 0.0
            s3 = 0.0
            for i in range(n):
                s5 += e5[i] * e5[i]
                s3 += e3[i] * e3[i]
            if s5 == 0.0 and s3 == 0.0:
                err = 0.0
            else:
                err = abs(h) * s5 / math.sqrt((s5 + 0.01 * s3) * n)
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
        stats[S_NSTEPS] += 1
        # --- stiffness detection: yt holds the last stage's point (c_12 = 1, t + h)
        st_num = 0.0
        st_den = 0.0
        for i in range(n):
            dk = K[N_STAGES, i] - K[N_STAGES - 1, i]
            dyv = y_new[i] - yt[i]
            st_num += dk * dk
            st_den += dyv * dyv
        if st_den > 0.0:
            h_lambda = h * math.sqrt(st_num / st_den)
            if h_lambda > stats[S_HLAMBDA_MAX]:
                stats[S_HLAMBDA_MAX] = h_lambda
            if h_lambda > STIFF_HLAMBDA:
                stats[S_NSTIFF] += 1
        # --- events and samples on the dense output (its coefficients only for a step that
        # holds a sample or an event)
        mark_new, monitor = watch(y_new_v, p)
        if monitor < stats[S_MONITOR_MIN]:
            stats[S_MONITOR_MIN] = monitor
        # the guard may have dipped inside the step even if it is > 0 at its end: whenever a
        # stage saw it <= 0, the dense output is scanned for the first point where it is
        guard_dip = not (g_min > 0.0)
        mark_hit = math.isnan(stats[S_T_MARK]) and mark_old > 0.0 and mark_new <= 0.0
        need_dense = guard_dip or mark_hit or (i_out < n_out and t_out[i_out] <= t_new)
        if need_dense:
            dense_coeffs(rhs, yc_v, y_new_v, f_new, h, p, K, F, yt_v)
            stats[S_NRHS] += 3
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
            K[0, i] = K[N_STAGES, i]
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


def dop853_run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
               rtol: float, atol: float, max_steps: int, monitor_floor: float,
               t_out: np.ndarray, Y_out: np.ndarray, i_out: int,
               stats: np.ndarray) -> tuple[int, float, int]:
    """Integrate y' = rhs(y) from (t, y) until t >= t_stop (the last step ends at t_end).

    One call of the compiled :func:`_kernel` (this wrapper is Python: a compiled one would
    compile the kernel's code again, numba optimising every callee inside its caller).

    Args:
        rhs: ``rhs(y, p, dy) -> guard`` (njit); the run stops where the guard falls to <= 0.
        watch: ``watch(y, p) -> (mark, monitor)`` (njit), see docs/design.md.
        y: The state (float64, (n,)), advanced in place.
        t: The start time.
        t_stop: This call returns once a step ends at or after ``t_stop`` (a chunk).
        t_end: The end of the whole run; no step goes beyond it.
        p: Parameters passed to ``rhs`` and ``watch``.
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_steps: Stop with :data:`STATUS_MAX_STEPS` once ``stats[S_NSTEPS]`` reaches it.
        monitor_floor: Stop with :data:`STATUS_MONITOR` once a step ends with the monitor
            below it (``-inf``: never).
        t_out: Sample times, increasing.
        Y_out: Samples, (t_out.size, n); row i receives the state at ``t_out[i]`` (dense
            output), for every i >= ``i_out`` passed.
        i_out: The first sample not yet written.
        stats: Counters and the carried step size (``S_*`` slots; :func:`new_stats`); pass
            the same vector to the calls of one run so that it resumes where it stopped.

    Returns:
        (status, t, i_out): one of the ``STATUS_*`` codes, the time reached (at a guard stop:
        the located crossing, with ``y`` on the dense output there) and the next sample.
    """
    return _kernel(rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps, monitor_floor,
                   t_out, Y_out, i_out, stats, 0.0, _NO_K_OUT)


_NO_K_OUT = np.empty((0, 0))


def fixed_steps(rhs, watch, y: np.ndarray, p: np.ndarray, h: float, n_steps: int,
                t_out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_steps`` steps of size ``h`` from (0, ``y``), no error control (for tests).

    The kernel of :func:`dop853_run` with every step accepted; ``y`` (float64) is advanced in
    place.

    Returns:
        (the state after the steps, the samples at ``t_out`` on the dense output, the last
        step's stage buffer K, (16, n): rows 0-11 the stages, 12 f(y_new)).
    """
    t_out = np.empty(0) if t_out is None else np.ascontiguousarray(t_out, dtype=float)
    Y = np.full((t_out.size, y.size), np.nan)
    K = np.zeros((N_K, y.size))
    t_end = float(h * n_steps)
    _kernel(rhs, watch, y, 0.0, t_end, t_end, np.ascontiguousarray(p, dtype=float), 1.0, 1.0,
            n_steps, -np.inf, t_out, Y, 0, new_stats(), float(h), K)
    return y, Y, K


#: The method contract's name for the kernel (:mod:`reference_ode.methods`).
run = dop853_run
