"""The singularity-free formulation (the default reference).

State, all in the table frame (SI), shape (11,):
``[x, y, vx, vy, qw, qx, qy, qz, wx, wy, wz]`` - the centre of mass's horizontal position and
velocity, the body quaternion (body to world) and the angular velocity. The height of the
centre of mass is not a state: contact holds it at z = R - a k_z. :func:`vector_core` is the
right-hand side, regular at theta = 0 and pi; its equations: docs/design.md.
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

N_STATE = 11
IX, IY, IVX, IVY, IQW, IQX, IQY, IQZ, IWX, IWY, IWZ = range(N_STATE)


@nb.njit(cache=True, inline="always")
def _axis(y):
    """Unit symmetry axis k of the (normalised) quaternion in ``y``."""
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    inv = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    kx = 2.0 * (qx * qz + qw * qy) * inv
    ky = 2.0 * (qy * qz - qw * qx) * inv
    kz = (qw * qw - qx * qx - qy * qy + qz * qz) * inv
    return kx, ky, kz


@nb.njit(cache=True, inline="always")
def contact_height(p, kz, s):
    """Height of the centre of mass above the table, from the active contact (m).

    A sphere: z_O = R - a k_z; a rim: z_O = R s - a k_z (``P_R``, ``P_A_OFF``: the active
    contact's radius and offset; s = sin theta).
    """
    if p[P_RIM] != 0.0:
        return p[P_R] * s - p[P_A_OFF] * kz
    return p[P_R] - p[P_A_OFF] * kz


@nb.njit(cache=True, inline="always")
def other_gap(p, kz, s, h):
    """Height above the table of the other contact surface's lowest point (m); +inf if none.

    ``h`` is the centre of mass's height. The other surface's point is X = b k + c: a sphere's
    lowest point is at h + b k_z - r, a rim's at h + b k_z - r s.
    """
    kind = p[P_OTHER]
    if kind < 0.0:
        return math.inf
    if kind == 0.0:
        return h + p[P_OTHER_B] * kz - p[P_OTHER_R]
    return h + p[P_OTHER_B] * kz - p[P_OTHER_R] * s


@nb.njit(cache=True, inline="always")
def vector_core(coulomb_kind, viscous, y, p, dy):
    """Write dy/dt into ``dy`` and return (N, Fx, Fy, vPx, vPy).

    Inlined (numba IR) into its callers: a separately compiled call adds atomic
    reference-count updates of its array arguments to every evaluation (with them, and the
    division-by-zero checks ``top`` compiles out, the vector rhs took 68 ns, now 46 ns).
    """
    R, a, M, A, C, g = top_params(p)
    kx, ky, kz = _axis(y)
    wx, wy, wz = y[IWX], y[IWY], y[IWZ]
    n = wx * kx + wy * ky + wz * kz
    # dk/dt = w x k
    kdx = wy * kz - wz * ky
    kdy = wz * kx - wx * kz
    kdz = wx * ky - wy * kx
    # X_P = a k - R e_z (a sphere: the ball, or a stem's rounded end) or a k + R u (a rim);
    # the slip v_P = v + w x X_P (its z-component vanishes by the constraint)
    rim = p[P_RIM] != 0.0
    if rim:
        s = math.sqrt(kx * kx + ky * ky)
        inv_s = 1.0 / s
        px = a * kx + R * kz * kx * inv_s
        py = a * ky + R * kz * ky * inv_s
        pz = a * kz - R * s
    else:
        px = a * kx
        py = a * ky
        pz = a * kz - R
    vpx = y[IVX] + wy * pz - wz * py
    vpy = y[IVY] + wz * px - wx * pz
    phix, phiy, psix, psiy = friction_terms(
        coulomb_kind, viscous, vpx, vpy, p[P_MU], p[P_LAM], p[P_CVISC], p[P_VEPS])
    # torque per unit N: X_P x (e_z + phi); torque independent of N: X_P x psi - (C-A) n kd
    t1x = py * 1.0 - pz * phiy
    t1y = pz * phix - px * 1.0
    t1z = px * phiy - py * phix
    g0 = (C - A) * n
    t0x = -pz * psiy - g0 * kdx
    t0y = pz * psix - g0 * kdy
    t0z = px * psiy - py * psix - g0 * kdz
    # I^-1 v = v / A + (1/C - 1/A) (k . v) k
    iA = 1.0 / A
    dC = 1.0 / C - iA
    k1 = dC * (kx * t1x + ky * t1y + kz * t1z)
    ax_ = iA * t1x + k1 * kx
    ay_ = iA * t1y + k1 * ky
    k0 = dC * (kx * t0x + ky * t0y + kz * t0z)
    bx = iA * t0x + k0 * kx
    by = iA * t0y + k0 * ky
    # z'' = -a (dw/dt x k + w x kd)_z, with dw/dt = N alpha + beta. A rim: z_O = R s - a k_z,
    # so z'' = extra - b_eff k_z'' with b_eff = a + R k_z / s and
    # extra = -R (k_z'^2 + s'^2) / s, s' = -k_z k_z' / s
    wkd_z = wx * kdy - wy * kdx
    b_eff = a
    extra = 0.0
    if rim:
        sd = -kz * kdz * inv_s
        b_eff = a + R * kz * inv_s
        extra = -R * (kdz * kdz + sd * sd) * inv_s
    denom = 1.0 + M * b_eff * (ax_ * ky - ay_ * kx)
    N = M * (g + extra - b_eff * ((bx * ky - by * kx) + wkd_z)) / denom
    Fx = N * phix + psix
    Fy = N * phiy + psiy
    wdx = N * ax_ + bx
    wdy = N * ay_ + by
    wdz = N * (iA * t1z + k1 * kz) + (iA * t0z + k0 * kz)
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    dy[IX] = y[IVX]
    dy[IY] = y[IVY]
    dy[IVX] = Fx / M
    dy[IVY] = Fy / M
    dy[IQW] = -0.5 * (wx * qx + wy * qy + wz * qz)
    dy[IQX] = 0.5 * (qw * wx + wy * qz - wz * qy)
    dy[IQY] = 0.5 * (qw * wy + wz * qx - wx * qz)
    dy[IQZ] = 0.5 * (qw * wz + wx * qy - wy * qx)
    dy[IWX] = wdx
    dy[IWY] = wdy
    dy[IWZ] = wdz
    return N, Fx, Fy, vpx, vpy


@nb.njit(cache=True)
def vector_observe(coulomb_kind, viscous, y, p, sin_undefined, out, scratch):
    """Fill ``out`` (24,) with one state's observables (``COLUMNS[1:] + EXTRA_COLUMNS``)."""
    R, a, M, A, C, g = top_params(p)
    N, Fx, Fy, vpx, vpy = vector_core(coulomb_kind, viscous, y, p, scratch)
    kx, ky, kz = _axis(y)
    wx, wy, wz = y[IWX], y[IWY], y[IWZ]
    n = wx * kx + wy * ky + wz * kz
    kdx = wy * kz - wz * ky
    kdy = wz * kx - wx * kz
    kdz = wx * ky - wy * kx
    s = math.sqrt(kx * kx + ky * ky)
    theta = math.atan2(s, kz)
    h = contact_height(p, kz, s)
    nan = math.nan
    if s > sin_undefined:
        theta_dot = -kdz / s
        Omega = (kx * kdy - ky * kdx) / (s * s)
        ex, ey = kx / s, ky / s
        vPX = vpx * ex + vpy * ey
        vPY = -vpx * ey + vpy * ex
        uOX = y[IVX] * ex + y[IVY] * ey
        uOY = -y[IVX] * ey + y[IVY] * ex
    else:
        theta_dot = math.sqrt(kdx * kdx + kdy * kdy)
        Omega = nan
        vPX = nan
        vPY = nan
        uOX = nan
        uOY = nan
    xi = C * n - A * Omega * kz
    Lz = A * wz + (C - A) * n * kz
    J = R * Lz - a * C * n
    vz = -a * kdz
    if p[P_RIM] != 0.0 and s > 0.0:
        vz += R * (kx * kdx + ky * kdy) / s
    E = (0.5 * M * (y[IVX] ** 2 + y[IVY] ** 2 + vz * vz)
         + 0.5 * (A * (wx * wx + wy * wy + wz * wz) + (C - A) * n * n) + M * g * h)
    xi_p, xi_m = xi_curves(J, kz, R, a, M, A, g)
    qw, qx, qy, qz = y[IQW], y[IQX], y[IQY], y[IQZ]
    qn = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    FX, FY = to_paper_xy(y, Fx, Fy, sin_undefined)
    write_observables(out, theta, theta_dot, Omega, n, xi, xi_p, xi_m, J, E, vPX, vPY, N, uOX,
                      uOY, y[IX], y[IY], h, qw * qn, qx * qn, qy * qn, qz * qn,
                      Fx * vpx + Fy * vpy, FX, FY)


@nb.njit(cache=True, inline="always")
def to_paper_xy(y, fx, fy, sin_undefined):
    """A horizontal world vector (fx, fy) in the paper's frame, NaN where that is undefined.

    X is along the symmetry axis's horizontal projection, Y a quarter turn on.
    """
    kx, ky, _kz = _axis(y)
    s = math.sqrt(kx * kx + ky * ky)
    if s > sin_undefined:
        ex, ey = kx / s, ky / s
        return fx * ex + fy * ey, -fx * ey + fy * ex
    return math.nan, math.nan


@nb.njit(cache=True, inline="always")
def write_observables(out, theta, theta_dot, Omega, n, xi, xi_p, xi_m, J, E, vPX, vPY, N, uOX,
                      uOY, x, y, z, qw, qx, qy, qz, P_fric, FX, FY):
    """Write one row of observables into ``out`` in the order of ``COLUMNS[1:] + EXTRA``."""
    out[0] = theta
    out[1] = theta_dot
    out[2] = Omega
    out[3] = n
    out[4] = xi
    out[5] = xi_p
    out[6] = xi_m
    out[7] = J
    out[8] = E
    out[9] = vPX
    out[10] = vPY
    out[11] = N
    out[12] = uOX
    out[13] = uOY
    out[14] = x
    out[15] = y
    out[16] = z
    out[17] = qw
    out[18] = qx
    out[19] = qy
    out[20] = qz
    out[21] = P_fric
    out[22] = FX
    out[23] = FY


@nb.njit(cache=True, inline="always")
def xi_curves(J, c, R, a, M, A, g):
    """The paper's xi_+ and xi_- (eq. 3.13) at cos(theta) = c, with N = M g.

    xi_- is evaluated as -2 A M g a h / (J + sqrt(D)), free of cancellation.
    """
    h = R - a * c
    r = R * c - a
    D = J * J + 4.0 * A * M * g * r * h * a
    if D < 0.0:
        return math.nan, math.nan
    sq = math.sqrt(D)
    xi_p = (J + sq) / (2.0 * r) if r != 0.0 else math.nan
    den = J + sq
    xi_m = -2.0 * A * M * g * a * h / den if den != 0.0 else math.nan
    return xi_p, xi_m


@nb.njit(cache=True, inline="always")
def vector_cos_theta(y):
    """cos(theta) = k_z of a vector state."""
    return _axis(y)[2]
