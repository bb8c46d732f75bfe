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

from collections.abc import Callable
from types import ModuleType

import numba as nb
import numpy as np

from tippetop.reference_ode import explicit_rk
from tippetop.reference_ode import verner_tableau as _coef
from tippetop.reference_ode.dop853 import (  # noqa: F401 (the pair's constants, for its kernel)
    MAX_FACTOR,
    MIN_FACTOR,
    RHS_TYPE,
    SAFETY,
    initial_step,
    new_stats,
    padded,
)
from tippetop.reference_ode.explicit_rk import Pair

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


# ---------------------------------------------------------------- the kernel
def _error(wsum: Callable[[str], str]) -> str:
    """The error norm (< 1: accept; NaN or inf: overflow).

    The RMS of h sum_i (b_i - b_hat_i) k_i scaled by atol + max(|y|, |y_new|) rtol.
    """
    return f"""
s2 = 0.0
for i in range(n):
    sc = atol + max(abs(yc[i]), abs(y_new[i])) * rtol
    ev = h * ({wsum("E")}) / sc
    s2 += ev * ev
err = math.sqrt(s2 / n)
"""


#: The pair, as the driver writes its kernel (:mod:`reference_ode.explicit_rk`): 16 stages,
#: f(y_new) once a step is accepted (not FSAL), the interpolant's 9 extra stages for a step
#: read densely.
PAIR = Pair(name="vern9", module=__name__, a=A, b=B, weights={"E": E}, n_stages=N_STAGES,
            n_k=N_K, fsal=False,
            error=_error, buffers="", imports=("E", "DEG"),
            dense_prepare="dense_coeffs(rhs, yc_v, h, p, K, F, yt_v)",
            dense_stages="N_K - N_STAGES - 1", interp_rows="DEG")


def kernel() -> ModuleType:
    """The compiled kernel's module: :func:`explicit_rk.kernel` of :data:`PAIR`.

    (A ``K_out`` of shape (26, n) receives each fixed step's stage buffer, rows 0-16.)
    """
    return explicit_rk.kernel(PAIR)


def run(rhs, watch, y: np.ndarray, t: float, t_stop: float, t_end: float, p: np.ndarray,
        rtol: float, atol: float, max_steps: int, monitor_floor: float, t_out: np.ndarray,
        Y_out: np.ndarray, i_out: int, stats: np.ndarray) -> tuple[int, float, int]:
    """Integrate y' = rhs(y) from (t, y) until t >= t_stop (the last step ends at t_end).

    Exactly :func:`dop853.dop853_run`'s contract (arguments, ``STATUS_*`` codes, ``stats``
    slots, events on the dense output, chunks), with Verner's 9(8) pair
    (:func:`explicit_rk.run`).

    Returns:
        (status, t, i_out), as :func:`dop853.dop853_run`.
    """
    return explicit_rk.run(PAIR, rhs, watch, y, t, t_stop, t_end, p, rtol, atol, max_steps,
                           monitor_floor, t_out, Y_out, i_out, stats)


def fixed_steps(rhs, watch, y: np.ndarray, p: np.ndarray, h: float, n_steps: int,
                t_out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_steps`` steps of size ``h`` from (0, ``y``), no error control (for tests).

    :func:`explicit_rk.fixed_steps` of :data:`PAIR`: (the state after the steps (``y``,
    advanced in place), the samples at ``t_out``, the last step's stage buffer, (26, n):
    rows 0-15 the stages, 16 f(y_new)).
    """
    return explicit_rk.fixed_steps(PAIR, rhs, watch, y, p, h, n_steps, t_out, new_stats())
