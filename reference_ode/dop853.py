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
from collections.abc import Callable
from types import ModuleType

import numba as nb
import numpy as np

from tippetop.reference_ode import dop853_tableau as _coef
from tippetop.reference_ode import explicit_rk
from tippetop.reference_ode.explicit_rk import Pair

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
STIFF_HLAMBDA = 6.1  # h lambda above this flags a step as stiff (Hairer's DOP853 threshold)

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


def _error(wsum: Callable[[str], str]) -> str:
    """The error norm, as scipy's DOP853 (< 1: accept; NaN or inf: overflow).

    |h| e5 / sqrt(e5^2 + 0.01 e3^2), e5 and e3 the RMS of the 5th- and 3rd-order estimates
    scaled by atol + max(|y|, |y_new|) rtol.
    """
    return f"""
for i in range(m):
    sc = atol + max(abs(yc[i]), abs(y_new[i])) * rtol
    e5[i] = ({wsum("E5")}) / sc
    e3[i] = ({wsum("E3")}) / sc
s5 = 0.0
s3 = 0.0
for i in range(n):
    s5 += e5[i] * e5[i]
    s3 += e3[i] * e3[i]
if s5 == 0.0 and s3 == 0.0:
    err = 0.0
else:
    err = abs(h) * s5 / math.sqrt((s5 + 0.01 * s3) * n)
"""


#: The pair, as the driver writes its kernel (:mod:`reference_ode.explicit_rk`): 12 stages and
#: f(y_new) in every attempt (FSAL), the interpolant's 3 extra stages for a step read densely.
PAIR = Pair(name="dop853", module=__name__, a=A, b=B, weights={"E3": E3, "E5": E5},
            n_stages=N_STAGES, n_k=N_K, fsal=True,
            error=_error, buffers="e5 = np.zeros(m)\ne3 = np.zeros(m)", imports=("E3", "E5"),
            dense_prepare="dense_coeffs(rhs, yc_v, y_new_v, f_new, h, p, K, F, yt_v)",
            dense_stages="3", interp_rows="7")


def kernel() -> ModuleType:
    """The compiled kernel's module: :func:`explicit_rk.kernel` of :data:`PAIR`.

    (A ``K_out`` of shape (16, n) receives each fixed step's stage buffer, rows 0-12.)
    """
    return explicit_rk.kernel(PAIR)


def dop853_run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
               rtol: float, atol: float, max_steps: int, monitor_floor: float,
               t_out: np.ndarray, Y_out: np.ndarray, i_out: int,
               stats: np.ndarray) -> tuple[int, float, int]:
    """Integrate y' = rhs(y) from (t, y) until t >= t_stop (the last step ends at t_end).

    One call of the compiled kernel (:func:`explicit_rk.run`; this wrapper is Python: a
    compiled one would compile the kernel's code again, numba optimising every callee inside
    its caller).

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
    return explicit_rk.run(PAIR, rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps,
                           monitor_floor, t_out, Y_out, i_out, stats)


def fixed_steps(rhs, watch, y: np.ndarray, p: np.ndarray, h: float, n_steps: int,
                t_out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_steps`` steps of size ``h`` from (0, ``y``), no error control (for tests).

    :func:`explicit_rk.fixed_steps` of :data:`PAIR`: (the state after the steps, the samples
    at ``t_out`` on the dense output, the last step's stage buffer K, (16, n): rows 0-11 the
    stages, 12 f(y_new)).
    """
    return explicit_rk.fixed_steps(PAIR, rhs, watch, y, p, h, n_steps, t_out, new_stats())


#: The method contract's name for the kernel (:mod:`reference_ode.methods`).
run = dop853_run
