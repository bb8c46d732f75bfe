"""Rolling phases: the paper's law in its stiff limit, replaced by the rolling constraint.

Where the modified Coulomb law (or the exact Coulomb law's ramp) is stiff, the slip sits at a
quasi-steady value of order Lambda and the law is, to leading order, the rolling constraint.
:data:`ROLLING` is that reduced model as a formulation of the vector state (:mod:`.vector`);
:mod:`reference_ode.solve` enters a phase where the stiffness detector flags the law, and the
phase ends where the force reaches :data:`F_EXIT` mu N or N falls to 0. The derivation and the
thresholds: docs/design.md; the accuracy: tests/reference_ode/test_stiff.py.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from tippetop.reference_ode.friction import COULOMB_EXACT
from tippetop.reference_ode.params_array import (
    N_PARAMS,
    P_A_OFF,
    P_COULOMB_KIND,
    P_LAM,
    P_M,
    P_MU,
    P_R,
    P_VEPS,
    top_params,
)
from tippetop.reference_ode.top import Formulation, vector_watch
from tippetop.reference_ode.vector import (
    IQW,
    IQX,
    IQY,
    IQZ,
    IVX,
    IVY,
    IWX,
    IWY,
    IWZ,
    IX,
    IY,
    N_STATE,
    to_paper_xy,
    vector_observe,
)

#: Baumgarte time of the slip (s): v_P returns to the quasi-steady slip in about this time
#: after a departure (the entry's mismatch, the integrator's drift); the slip's own motion is
#: followed through dv_qs/dt. Far above the law's relaxation time (Lambda / (mu g) < 1e-4 s
#: wherever a phase is entered), and below the slow motion's (the nutation's period, ~0.06 s
#: on the paper's tops). Measured on fig3 at Lambda = 1e-6 m/s against the law at rtol 1e-11:
#: theta within 1.1e-9, 1.3e-9, 2.1e-9, 3.1e-9 rad for tau = 1, 3, 10, 30 ms, at 149k, 57k,
#: 23k, 20k evaluations (the law alone: 46M), with v_qs of the pure rolling force; with v_qs of
#: the force applied (2026-11-28, DOP853 at the scene's rtol 1e-9): 2.6e-10, 7.4e-10 and 1.4e-9
#: for tau = 1, 3 and 10 ms (before: 1.1e-9, 1.3e-9, 2.1e-9 in the same runs), and after the
#: first second 1.9e-11, 2.5e-11 and 1.1e-10 (before: 9.4e-11, 9.1e-11, 2.2e-10).
TAU_S = 1e-2
#: The time step of the difference quotient dv_qs/dt (s).
FF_STEP_S = 1e-6
#: A rolling phase starts only where the slip is below this many Lambda (the law's quasi-steady
#: slip at F_ENTER: 1.33 Lambda) ...
SLIP_ENTER = 2.0
#: ... and the rolling force below this fraction of mu N.
F_ENTER = 0.8
#: A rolling phase ends where the force it needs reaches this fraction of mu N.
F_EXIT = 0.9
#: Slots appended to the packed parameters for a rolling phase.
P_TAU = N_PARAMS
P_FEXIT = N_PARAMS + 1
N_ROLLING_PARAMS = N_PARAMS + 2


def rolling_params(p: np.ndarray, tau_s: float | None = None,
                   f_exit: float | None = None) -> np.ndarray:
    """The packed parameters ``p`` extended with a rolling phase's tau and exit fraction.

    None: :data:`TAU_S` and :data:`F_EXIT` (read at the call).
    """
    return np.concatenate([p[:N_PARAMS], [TAU_S if tau_s is None else tau_s,
                                          F_EXIT if f_exit is None else f_exit]])


@nb.njit(cache=True, inline="always")
def _system(p, vx, vy, qw, qx, qy, qz, wx, wy, wz):
    """The rolling phase's linear system at one state, solved for the pure rolling force.

    Returns (Fx0, Fy0, N0, the inverse's first two columns (6 values), the torque columns
    T_x, T_y, T_z (9), beta (3), the slip (2)): dw/dt = F_x T_x + F_y T_y + N T_z + beta, and
    a wanted slip acceleration (ex, ey) adds inverse . (ex, ey, 0) to (F_x, F_y, N).
    """
    R, a, M, A, C, g = top_params(p)
    b = p[P_A_OFF]
    r = p[P_R]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
    n = wx * kx + wy * ky + wz * kz
    kdx = wy * kz - wz * ky
    kdy = wz * kx - wx * kz
    kdz = wx * ky - wy * kx
    # the contact point X = b k - r e_z and the slip v_P = v + w x X
    px = b * kx
    py = b * ky
    pz = b * kz - r
    vpx = vx + wy * pz - wz * py
    vpy = vy + wz * px - wx * pz
    iA = 1.0 / A
    dC = 1.0 / C - iA
    # beta = I^-1 (-(C - A) n kd): dw/dt = sum_j u_j T_j + beta, T_j = I^-1 (X x e_j)
    g0 = -(C - A) * n
    s0 = dC * g0 * (kx * kdx + ky * kdy + kz * kdz)
    btx = iA * g0 * kdx + s0 * kx
    bty = iA * g0 * kdy + s0 * ky
    btz = iA * g0 * kdz + s0 * kz
    # X x e_x = (0, pz, -py), X x e_y = (-pz, 0, px), X x e_z = (py, -px, 0)
    s1 = dC * (ky * pz - kz * py)
    t1x, t1y, t1z = s1 * kx, iA * pz + s1 * ky, -iA * py + s1 * kz
    s2 = dC * (-kx * pz + kz * px)
    t2x, t2y, t2z = -iA * pz + s2 * kx, s2 * ky, iA * px + s2 * kz
    s3 = dC * (kx * py - ky * px)
    t3x, t3y, t3z = iA * py + s3 * kx, -iA * px + s3 * ky, s3 * kz
    # w x kd
    wkx = wy * kdz - wz * kdy
    wky = wz * kdx - wx * kdz
    wkz = wx * kdy - wy * kdx
    # rows: (T x X)_x, (T x X)_y of the slip; M b (T x k)_z of the height
    iM = 1.0 / M
    m00 = iM + (t1y * pz - t1z * py)
    m01 = t2y * pz - t2z * py
    m02 = t3y * pz - t3z * py
    m10 = t1z * px - t1x * pz
    m11 = iM + (t2z * px - t2x * pz)
    m12 = t3z * px - t3x * pz
    Mb = M * b
    m20 = Mb * (t1x * ky - t1y * kx)
    m21 = Mb * (t2x * ky - t2y * kx)
    m22 = 1.0 + Mb * (t3x * ky - t3y * kx)
    r0 = -(bty * pz - btz * py) - b * wkx
    r1 = -(btz * px - btx * pz) - b * wky
    r2 = M * g - Mb * wkz - Mb * (btx * ky - bty * kx)
    # inverse by cofactors
    c00 = m11 * m22 - m12 * m21
    c01 = m02 * m21 - m01 * m22
    c02 = m01 * m12 - m02 * m11
    c10 = m12 * m20 - m10 * m22
    c11 = m00 * m22 - m02 * m20
    c12 = m02 * m10 - m00 * m12
    c20 = m10 * m21 - m11 * m20
    c21 = m01 * m20 - m00 * m21
    c22 = m00 * m11 - m01 * m10
    idet = 1.0 / (m00 * c00 + m01 * c10 + m02 * c20)
    Fx0 = (c00 * r0 + c01 * r1 + c02 * r2) * idet
    Fy0 = (c10 * r0 + c11 * r1 + c12 * r2) * idet
    N0 = (c20 * r0 + c21 * r1 + c22 * r2) * idet
    return (Fx0, Fy0, N0, c00 * idet, c01 * idet, c10 * idet, c11 * idet, c20 * idet,
            c21 * idet, t1x, t1y, t1z, t2x, t2y, t2z, t3x, t3y, t3z, btx, bty, btz, vpx, vpy)


@nb.njit(cache=True, inline="always")
def _qs_slip(kind, lam, v_eps, mu, Fx, Fy, N):
    """The law's quasi-steady slip under the force (Fx, Fy) and N, and f = |F| / (mu N).

    The modified Coulomb law: v = -Lambda F / (mu N sqrt(1 - f^2)), f capped at 0.999 (beyond
    1 the law has no such slip; the phase ends at F_EXIT before). The exact law's ramp
    (``kind`` = COULOMB_EXACT, |v| < v_eps): v = -v_eps F / (mu N).
    """
    muN = mu * N
    if not muN > 0.0:
        return 0.0, 0.0, math.inf
    f = math.sqrt(Fx * Fx + Fy * Fy) / muN
    if kind == COULOMB_EXACT:
        q = v_eps / muN
    else:
        fc = f if f < 0.999 else 0.999
        q = lam / (muN * math.sqrt(1.0 - fc * fc))
    return -q * Fx, -q * Fy, f


@nb.njit(cache=True, inline="always")
def rolling_core(y, p, dy):
    """Write dy/dt of the rolling phase into ``dy``; return (N, Fx, Fy, f0, vpx, vpy).

    ``f0`` is the pure rolling force over mu N (the one that holds v_P constant). The slip
    is driven to the law's quasi-steady slip v_qs: dv_P/dt = dv_qs/dt - (v_P - v_qs) / tau,
    with dv_qs/dt a difference quotient along the pure rolling motion (over
    :data:`FF_STEP_S`; v_qs is O(Lambda), so the difference from the actual motion is of
    second order). v_qs is the law's slip under the force applied (F0 and the part that
    moves the slip, in one fixed-point pass: the departures measured in TAU_S are with one),
    not under F0 alone: the law slips by the force that acts, and the force that
    follows dv_qs/dt differs from F0 by ~M dv_qs/dt, enough for a departure of ~1e-10 rad in
    the first second of the stiff Fig. 3 top (tests/reference_ode/test_stiff.py).
    """
    M = p[P_M]
    mu = p[P_MU]
    lam = p[P_LAM]
    tau = p[P_TAU]
    vx, vy = y[IVX], y[IVY]
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    wx, wy, wz = y[IWX], y[IWY], y[IWZ]
    (Fx0, Fy0, N0, a00, a01, a10, a11, a20, a21, t1x, t1y, t1z, t2x, t2y, t2z, t3x, t3y, t3z,
     btx, bty, btz, vpx, vpy) = _system(p, vx, vy, qw, qx, qy, qz, wx, wy, wz)
    kind = p[P_COULOMB_KIND]
    v_eps = p[P_VEPS]
    vqx, vqy, f0 = _qs_slip(kind, lam, v_eps, mu, Fx0, Fy0, N0)
    # the same along the pure rolling motion, a short time ahead
    e = FF_STEP_S
    w1x = wx + e * (Fx0 * t1x + Fy0 * t2x + N0 * t3x + btx)
    w1y = wy + e * (Fx0 * t1y + Fy0 * t2y + N0 * t3y + bty)
    w1z = wz + e * (Fx0 * t1z + Fy0 * t2z + N0 * t3z + btz)
    h = 0.5 * e
    s1 = _system(p, vx + e * Fx0 / M, vy + e * Fy0 / M,
                 qw - h * (wx * qx + wy * qy + wz * qz), qx + h * (qw * wx + wy * qz - wz * qy),
                 qy + h * (qw * wy + wz * qx - wx * qz), qz + h * (qw * wz + wx * qy - wy * qx),
                 w1x, w1y, w1z)
    vq1x, vq1y, _ = _qs_slip(kind, lam, v_eps, mu, s1[0], s1[1], s1[2])
    ex = (vq1x - vqx) / e - (vpx - vqx) / tau
    ey = (vq1y - vqy) / e - (vpy - vqy) / tau
    Fx = Fx0 + a00 * ex + a01 * ey
    Fy = Fy0 + a10 * ex + a11 * ey
    N = N0 + a20 * ex + a21 * ey
    # the quasi-steady slip of the force applied, not of the pure rolling force: the target
    # moves by (vq2 - vq), and the force with it
    vq2x, vq2y, _ = _qs_slip(kind, lam, v_eps, mu, Fx, Fy, N)
    ex += (vq2x - vqx) / tau
    ey += (vq2y - vqy) / tau
    Fx = Fx0 + a00 * ex + a01 * ey
    Fy = Fy0 + a10 * ex + a11 * ey
    N = N0 + a20 * ex + a21 * ey
    iM = 1.0 / M
    dy[IX] = vx
    dy[IY] = vy
    dy[IVX] = Fx * iM
    dy[IVY] = Fy * iM
    dy[IQW] = -0.5 * (wx * qx + wy * qy + wz * qz)
    dy[IQX] = 0.5 * (qw * wx + wy * qz - wz * qy)
    dy[IQY] = 0.5 * (qw * wy + wz * qx - wx * qz)
    dy[IQZ] = 0.5 * (qw * wz + wx * qy - wy * qx)
    dy[IWX] = Fx * t1x + Fy * t2x + N * t3x + btx
    dy[IWY] = Fx * t1y + Fy * t2y + N * t3y + bty
    dy[IWZ] = Fx * t1z + Fy * t2z + N * t3z + btz
    return N, Fx, Fy, f0, vpx, vpy


@nb.njit(cache=True, error_model="numpy")
def rolling_rhs(y, p, dy):
    """dy/dt of a rolling phase; the guard is min(N, F_exit mu N - |F|) (both in newtons)."""
    N, Fx, Fy, _, _, _ = rolling_core(y, p, dy)
    margin = p[P_FEXIT] * p[P_MU] * N - math.sqrt(Fx * Fx + Fy * Fy)
    return N if N < margin else margin


@nb.njit(cache=True, error_model="numpy")
def rolling_rhs_alloc(y, p):
    """dy/dt of a rolling phase in a new array."""
    dy = np.empty_like(y)
    rolling_rhs(y, p, dy)
    return dy


@nb.njit(cache=True, error_model="numpy")
def rolling_state(y, p):
    """(N, |F| / (mu N), f0, |v_P|) of a state under the rolling constraint."""
    dy = np.empty_like(y)
    N, Fx, Fy, f0, vpx, vpy = rolling_core(y, p, dy)
    return N, math.sqrt(Fx * Fx + Fy * Fy) / (p[P_MU] * N), f0, math.sqrt(vpx * vpx + vpy * vpy)


@nb.njit(cache=True, error_model="numpy")
def contact_slip(y, p):
    """|v_P| of a vector state at its (sphere) contact point X = b k - r e_z (m/s)."""
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    b = p[P_A_OFF]
    px = b * 2.0 * (qx * qz + qw * qy) * inv
    py = b * 2.0 * (qy * qz - qw * qx) * inv
    pz = b * (qw * qw - qx * qx - qy * qy + qz * qz) * inv - p[P_R]
    wx, wy, wz = y[IWX], y[IWY], y[IWZ]
    vpx = y[IVX] + wy * pz - wz * py
    vpy = y[IVY] + wz * px - wx * pz
    return math.sqrt(vpx * vpx + vpy * vpy)


@nb.njit(cache=True, error_model="numpy")
def rolling_observe_all(Y, p, sin_undefined, out):
    """Observables of rolling states: the law's columns, with the rolling phase's N and power.

    The slip columns are the state's own (v_P, held at the law's quasi-steady slip).
    """
    kind = int(p[P_COULOMB_KIND])
    scratch = np.empty(Y.shape[1])
    for i in range(Y.shape[0]):
        vector_observe(kind, False, Y[i], p, sin_undefined, out[i], scratch)
        N, Fx, Fy, _, vpx, vpy = rolling_core(Y[i], p, scratch)
        out[i, 11] = N
        out[i, 21] = Fx * vpx + Fy * vpy
        out[i, 22], out[i, 23] = to_paper_xy(Y[i], Fx, Fy, sin_undefined)


#: The rolling phase as a formulation of the vector state (a phase, not a scene's choice).
ROLLING = Formulation("vector", N_STATE, rolling_rhs, vector_watch, rolling_rhs_alloc,
                      rolling_observe_all, singular=False)
