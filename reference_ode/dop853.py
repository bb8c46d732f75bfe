"""A compiled Dormand-Prince 8(5,3) integrator with dense output and the run's events.

The tableau, the error estimator (the 5th- and 3rd-order embedded pair) and the step-size
control are those of Hairer's DOP853 as in ``scipy.integrate.DOP853``; the difference is that
the whole loop, the right-hand side and the events run compiled, so a step costs no Python.

Events, checked after every accepted step:

* theta crossing pi/2 (cos theta changing sign): the first crossing time is located on the
  7th-order dense output by bisection and reported; the run goes on.
* loss of contact (N <= 0): the model assumes contact, so the run stops at the located time
  with status ``contact_lost``.
* paper formulation only: sin theta below ``P_SING`` (theta within that of 0 or pi, or
  outside (0, pi) after a step that jumped across): status ``singular``.

Stiffness detection (Hairer's DOP853, Hairer & Wanner, Solving ODEs II, Sec. IV.2): after
every accepted step the product of the step and the local Lipschitz estimate,
``h lambda = h |f(y_new) - f(y_12)| / |y_new - y_12|`` (the last two stages, both at
``t + h``), is compared with ``STIFF_HLAMBDA`` = 6.1, near the border of the method's
stability region. A step above it is limited by stability rather than accuracy; such steps
are counted (``S_NSTIFF``) and the largest ``h lambda`` is kept (``S_HLAMBDA_MAX``). Hairer
checks every 1000th step and warns after 15 flagged checks in a row; here every accepted step
is checked (2n flops and no extra evaluation) and nothing else changes: the step sequence and
the results are those without the check.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _coef

from tippetop.reference_ode.paper import paper_core
from tippetop.reference_ode.params_array import P_SING
from tippetop.reference_ode.vector import vector_core

FORM_VECTOR = 0
FORM_PAPER = 1

STATUS_OK = 0
STATUS_CONTACT_LOST = 1
STATUS_SINGULAR = 2
STATUS_MAX_STEPS = 3
STATUS_STEP_TOO_SMALL = 4
STATUS_RUNNING = 5  # a chunk ended before t_end; the caller continues

STATUS_NAMES = {
    STATUS_OK: "ok",
    STATUS_CONTACT_LOST: "contact_lost",
    STATUS_SINGULAR: "singular",
    STATUS_MAX_STEPS: "max_steps",
    STATUS_STEP_TOO_SMALL: "step_too_small",
}

_NS = _coef.N_STAGES  # 12 stages
_A = np.ascontiguousarray(_coef.A[:_NS, :_NS])
_B = np.ascontiguousarray(_coef.B)
_C = np.ascontiguousarray(_coef.C[:_NS])
_E3 = np.ascontiguousarray(_coef.E3)
_E5 = np.ascontiguousarray(_coef.E5)
_D = np.ascontiguousarray(_coef.D)
_A_EXTRA = np.ascontiguousarray(_coef.A[_NS + 1:])
_C_EXTRA = np.ascontiguousarray(_coef.C[_NS + 1:])

SAFETY = 0.9  # step-size safety factor
MIN_FACTOR = 0.2  # largest allowed decrease of the step in one go
MAX_FACTOR = 10.0  # largest allowed increase of the step in one go
ERROR_EXPONENT = -1.0 / 8.0  # -1 / (error estimator order + 1)
BISECTION_ITERS = 60  # event location on the dense output: 2^-60 of a step
STIFF_HLAMBDA = 6.1  # h lambda above this flags a step as stiff (Hairer's DOP853 threshold)

# stats slots
S_NRHS = 0
S_NSTEPS = 1
S_NREJECT = 2
S_T_INVERT = 3
S_H = 4
S_MIN_SIN = 5
S_NSTIFF = 6  # accepted steps with h lambda > STIFF_HLAMBDA
S_HLAMBDA_MAX = 7  # largest h lambda estimate of an accepted step
N_STATS = 8


@nb.njit(cache=True)
def rhs(form, coulomb_kind, viscous, y, p, dy):
    """dy/dt of the chosen formulation and friction law; returns the normal force N."""
    if form == FORM_VECTOR:
        return vector_core(coulomb_kind, viscous, y, p, dy)[0]
    return paper_core(coulomb_kind, viscous, y, p, dy)[0]


@nb.njit(cache=True, inline="always")
def _cos_sin(form, y):
    if form == FORM_VECTOR:
        qw, qx, qy, qz = y[4], y[5], y[6], y[7]
        inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
        kx = 2.0 * (qx * qz + qw * qy) * inv
        ky = 2.0 * (qy * qz - qw * qx) * inv
        return (qw * qw - qx * qx - qy * qy + qz * qz) * inv, math.sqrt(kx * kx + ky * ky)
    return math.cos(y[0]), math.sin(y[0])  # signed: theta outside (0, pi) is caught


@nb.njit(cache=True)
def _rms(v, scale):
    s = 0.0
    for i in range(v.size):
        r = v[i] / scale[i]
        s += r * r
    return math.sqrt(s / v.size)


@nb.njit(cache=True)
def _dense_coeffs(form, ck, visc, t_old, y_old, y_new, f_new, h, K, F, p, ytmp):
    """Fill F (7, n) with the dense-output coefficients of the step; 3 extra evaluations."""
    n = y_old.size
    for s in range(3):
        a = _A_EXTRA[s]
        for i in range(n):
            acc = 0.0
            for j in range(_NS + 1 + s):
                acc += a[j] * K[j, i]
            ytmp[i] = y_old[i] + h * acc
        rhs(form, ck, visc, ytmp, p, K[_NS + 1 + s])
    for i in range(n):
        dy = y_new[i] - y_old[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (f_new[i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(16):
                acc += _D[r, j] * K[j, i]
            F[3 + r, i] = h * acc


@nb.njit(cache=True)
def _dense_eval(F, y_old, x, out):
    """Evaluate the dense output at x = (t - t_old) / h into ``out``."""
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


@nb.njit(cache=True)
def initial_step(form, ck, visc, t0, y0, f0, t_end, p, rtol, atol):
    """Hairer's starting step (as ``scipy.integrate._ivp.common.select_initial_step``)."""
    n = y0.size
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol + abs(y0[i]) * rtol
    d0 = _rms(y0, scale)
    d1 = _rms(f0, scale)
    if d0 < 1e-5 or d1 < 1e-5 or not (d0 < np.inf and d1 < np.inf):
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, t_end - t0)
    if not h0 > 0.0:
        h0 = 1e-6 * (t_end - t0)
    y1 = y0 + h0 * f0
    f1 = np.empty(n)
    rhs(form, ck, visc, y1, p, f1)
    d2 = _rms(f1 - f0, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1, t_end - t0)  # NaN or 0 if the start overflows: see solve.py


@nb.njit(cache=True)
def dop853_run(form, coulomb_kind, viscous, y, t, t_stop, t_end, p, rtol, atol, max_steps,
               t_out, Y_out, i_out, stats):
    """Integrate from (t, y) until t >= t_stop (the last step ends at t_end, never beyond).

    ``y`` is advanced in place; samples at the times ``t_out[i_out:]`` passed are written to
    ``Y_out``. ``stats`` carries counters, the inversion time and the step size across calls
    (see the ``S_*`` slots). Returns (status, t, i_out).
    """
    n = y.size
    K = np.empty((16, n))
    F = np.empty((7, n))
    y_new = np.empty(n)
    f_new = np.empty(n)
    ytmp = np.empty(n)
    scale = np.empty(n)
    err5 = np.empty(n)
    err3 = np.empty(n)
    f = np.empty(n)
    N0 = rhs(form, coulomb_kind, viscous, y, p, f)
    stats[S_NRHS] += 1
    if not N0 > 0.0:
        return STATUS_CONTACT_LOST, t, i_out
    h_abs = stats[S_H]
    if not h_abs > 0.0:
        h_abs = initial_step(form, coulomb_kind, viscous, t, y, f, t_end, p, rtol, atol)
        stats[S_NRHS] += 1
    n_out = t_out.size
    while i_out < n_out and t_out[i_out] <= t:
        Y_out[i_out, :] = y
        i_out += 1
    steps_here = 0
    while t < t_stop:
        if stats[S_NSTEPS] >= max_steps:
            stats[S_H] = h_abs
            return STATUS_MAX_STEPS, t, i_out
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        rejected = False
        while True:
            if not h_abs >= min_step:  # also catches a NaN step size
                stats[S_H] = h_abs
                c, s = _cos_sin(form, y)
                if form == FORM_PAPER and abs(s) < 1e-3:
                    return STATUS_SINGULAR, t, i_out
                return STATUS_STEP_TOO_SMALL, t, i_out
            t_new = t + h_abs
            if t_new > t_end:
                t_new = t_end
            h = t_new - t
            # --- one Runge-Kutta step
            for i in range(n):
                K[0, i] = f[i]
            for s in range(1, _NS):
                for i in range(n):
                    acc = 0.0
                    for j in range(s):
                        acc += _A[s, j] * K[j, i]
                    ytmp[i] = y[i] + h * acc
                rhs(form, coulomb_kind, viscous, ytmp, p, K[s])
            for i in range(n):
                acc = 0.0
                for j in range(_NS):
                    acc += _B[j] * K[j, i]
                y_new[i] = y[i] + h * acc
            N_new = rhs(form, coulomb_kind, viscous, y_new, p, f_new)
            stats[S_NRHS] += _NS
            for i in range(n):
                K[_NS, i] = f_new[i]
                scale[i] = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                a5 = 0.0
                a3 = 0.0
                for j in range(_NS + 1):
                    a5 += _E5[j] * K[j, i]
                    a3 += _E3[j] * K[j, i]
                err5[i] = a5 / scale[i]
                err3[i] = a3 / scale[i]
            e5 = 0.0
            e3 = 0.0
            for i in range(n):
                e5 += err5[i] * err5[i]
                e3 += err3[i] * err3[i]
            if e5 == 0.0 and e3 == 0.0:
                err = 0.0
            else:
                err = h * e5 / math.sqrt((e5 + 0.01 * e3) * n)
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
        stats[S_NSTEPS] += 1
        steps_here += 1
        # --- stiffness detection: ytmp still holds the last stage's point (c_12 = 1, t + h)
        st_num = 0.0
        st_den = 0.0
        for i in range(n):
            dk = f_new[i] - K[_NS - 1, i]
            dyv = y_new[i] - ytmp[i]
            st_num += dk * dk
            st_den += dyv * dyv
        if st_den > 0.0:
            h_lambda = h * math.sqrt(st_num / st_den)
            if h_lambda > stats[S_HLAMBDA_MAX]:
                stats[S_HLAMBDA_MAX] = h_lambda
            if h_lambda > STIFF_HLAMBDA:
                stats[S_NSTIFF] += 1
        # --- events and samples on the dense output
        c_old, s_old = _cos_sin(form, y)
        c_new, s_new = _cos_sin(form, y_new)
        if abs(s_new) < stats[S_MIN_SIN]:
            stats[S_MIN_SIN] = abs(s_new)
        lost = not (N_new > 0.0)
        invert = math.isnan(stats[S_T_INVERT]) and c_old > 0.0 and c_new <= 0.0
        need_dense = lost or invert or (i_out < n_out and t_out[i_out] <= t_new)
        t_final = t_new
        if need_dense:
            _dense_coeffs(form, coulomb_kind, viscous, t, y, y_new, f_new, h, K, F, p, ytmp)
            stats[S_NRHS] += 3
            if lost:
                lo = 0.0
                hi = 1.0
                for _ in range(BISECTION_ITERS):
                    mid = 0.5 * (lo + hi)
                    _dense_eval(F, y, mid, ytmp)
                    if rhs(form, coulomb_kind, viscous, ytmp, p, err3) > 0.0:
                        lo = mid
                    else:
                        hi = mid
                stats[S_NRHS] += BISECTION_ITERS
                t_final = t + hi * h
            if invert:
                lo = 0.0
                hi = 1.0
                for _ in range(BISECTION_ITERS):
                    mid = 0.5 * (lo + hi)
                    _dense_eval(F, y, mid, ytmp)
                    if _cos_sin(form, ytmp)[0] > 0.0:
                        lo = mid
                    else:
                        hi = mid
                t_inv = t + hi * h
                if t_inv <= t_final:
                    stats[S_T_INVERT] = t_inv
            while i_out < n_out and t_out[i_out] <= t_final:
                if t_out[i_out] == t_new:
                    Y_out[i_out, :] = y_new
                else:
                    _dense_eval(F, y, (t_out[i_out] - t) / h, ytmp)
                    Y_out[i_out, :] = ytmp
                i_out += 1
            if lost:
                _dense_eval(F, y, (t_final - t) / h, ytmp)
                y[:] = ytmp
                stats[S_H] = h_abs
                return STATUS_CONTACT_LOST, t_final, i_out
        t = t_new
        y[:] = y_new
        f[:] = f_new
        if form == FORM_PAPER and s_new < p[P_SING]:
            stats[S_H] = h_abs
            return STATUS_SINGULAR, t, i_out
    stats[S_H] = h_abs
    if t >= t_end:
        return STATUS_OK, t, i_out
    return STATUS_RUNNING, t, i_out
