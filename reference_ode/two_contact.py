"""The top on two points at once: the ball and the stem's end both on the table.

:func:`two_contact_core` is that phase's right-hand side: the tilt and the centre of mass's
height are fixed, and the normal forces N1 (the active contact, ``P_R``, ``P_A_OFF``,
``P_RIM``) and N2 (the other, ``P_OTHER*``) follow from the constraints. The phase ends when
either force falls to 0 (the guard is min(N1, N2)). The equations: docs/design.md.
"""

from __future__ import annotations

import math

import numba as nb

from tippetop.reference_ode.friction import friction_terms
from tippetop.reference_ode.params_array import (
    P_A_OFF,
    P_CVISC,
    P_LAM,
    P_MU,
    P_OTHER,
    P_OTHER_B,
    P_OTHER_R,
    P_R,
    P_RIM,
    P_VEPS,
    top_params,
)
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
    to_paper_xy,
    vector_observe,
)


@nb.njit(cache=True, inline="always")
def _point(rim, b, r, kx, ky, kz):
    """X = b k + c: c = -r e_z (a sphere) or r u (a rim, u most downward in the end's plane)."""
    if rim:
        s = math.sqrt(kx * kx + ky * ky)
        return b * kx + r * kz * kx / s, b * ky + r * kz * ky / s, b * kz - r * s
    return b * kx, b * ky, b * kz - r


@nb.njit(cache=True, inline="always")
def two_contact_core(coulomb_kind, viscous, y, p, dy):
    """Write dy/dt into ``dy``; return (N1, N2, P_fric, Fx, Fy).

    The two normal forces, the friction power, and the friction force of both points (world
    frame).
    """
    R, a, M, A, C, g = top_params(p)
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
    wx, wy, wz = y[IWX], y[IWY], y[IWZ]
    n = wx * kx + wy * ky + wz * kz
    kdx = wy * kz - wz * ky
    kdy = wz * kx - wx * kz
    mu, lam, cv, ve = p[P_MU], p[P_LAM], p[P_CVISC], p[P_VEPS]
    p1x, p1y, p1z = _point(p[P_RIM] != 0.0, p[P_A_OFF], p[P_R], kx, ky, kz)
    p2x, p2y, p2z = _point(p[P_OTHER] == 1.0, p[P_OTHER_B], p[P_OTHER_R], kx, ky, kz)
    v1x = y[IVX] + wy * p1z - wz * p1y
    v1y = y[IVY] + wz * p1x - wx * p1z
    v2x = y[IVX] + wy * p2z - wz * p2y
    v2y = y[IVY] + wz * p2x - wx * p2z
    f1x, f1y, s1x, s1y = friction_terms(coulomb_kind, viscous, v1x, v1y, mu, lam, cv, ve)
    f2x, f2y, s2x, s2y = friction_terms(coulomb_kind, viscous, v2x, v2y, mu, lam, cv, ve)
    iA = 1.0 / A
    dC = 1.0 / C - iA
    # torque per unit N_i: X_i x (e_z + phi_i)
    t1x, t1y, t1z = p1y - p1z * f1y, p1z * f1x - p1x, p1x * f1y - p1y * f1x
    t2x, t2y, t2z = p2y - p2z * f2y, p2z * f2x - p2x, p2x * f2y - p2y * f2x
    # the rest: X_1 x psi_1 + X_2 x psi_2 - (C - A) n dk/dt
    g0 = (C - A) * n
    t0x = -p1z * s1y - p2z * s2y - g0 * kdx
    t0y = p1z * s1x + p2z * s2x - g0 * kdy
    t0z = p1x * s1y - p1y * s1x + p2x * s2y - p2y * s2x - g0 * (wx * ky - wy * kx)
    k1 = dC * (kx * t1x + ky * t1y + kz * t1z)
    a1x, a1y, a1z = iA * t1x + k1 * kx, iA * t1y + k1 * ky, iA * t1z + k1 * kz
    k2 = dC * (kx * t2x + ky * t2y + kz * t2z)
    a2x, a2y, a2z = iA * t2x + k2 * kx, iA * t2y + k2 * ky, iA * t2z + k2 * kz
    k0 = dC * (kx * t0x + ky * t0y + kz * t0z)
    bx, by, bz = iA * t0x + k0 * kx, iA * t0y + k0 * ky, iA * t0z + k0 * kz
    c1 = a1x * ky - a1y * kx
    c2 = a2x * ky - a2y * kx
    d = (bx * ky - by * kx) + (wx * kdy - wy * kdx)
    det = c2 - c1
    N1 = (M * g * c2 + d) / det
    N2 = -(M * g * c1 + d) / det
    Fx = N1 * f1x + s1x + N2 * f2x + s2x
    Fy = N1 * f1y + s1y + N2 * f2y + s2y
    dy[IX] = y[IVX]
    dy[IY] = y[IVY]
    dy[IVX] = Fx / M
    dy[IVY] = Fy / M
    dy[IQW] = -0.5 * (wx * qx + wy * qy + wz * qz)
    dy[IQX] = 0.5 * (qw * wx + wy * qz - wz * qy)
    dy[IQY] = 0.5 * (qw * wy + wz * qx - wx * qz)
    dy[IQZ] = 0.5 * (qw * wz + wx * qy - wy * qx)
    dy[IWX] = N1 * a1x + N2 * a2x + bx
    dy[IWY] = N1 * a1y + N2 * a2y + by
    dy[IWZ] = N1 * a1z + N2 * a2z + bz
    power = ((N1 * f1x + s1x) * v1x + (N1 * f1y + s1y) * v1y
             + (N2 * f2x + s2x) * v2x + (N2 * f2y + s2y) * v2y)
    return N1, N2, power, Fx, Fy


@nb.njit(cache=True)
def two_contact_observe(coulomb_kind, viscous, y, p, sin_undefined, out, scratch):
    """Observables of a two-point state: the active contact's, with N = N1 + N2.

    The friction power is that of both points.
    """
    vector_observe(coulomb_kind, viscous, y, p, sin_undefined, out, scratch)
    N1, N2, power, Fx, Fy = two_contact_core(coulomb_kind, viscous, y, p, scratch)
    out[11] = N1 + N2
    out[21] = power
    out[22], out[23] = to_paper_xy(y, Fx, Fy, sin_undefined)


__all__ = ["two_contact_core", "two_contact_observe"]
