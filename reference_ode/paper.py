"""The paper's own equations (Appendix A), in its variables.

State, shape (10,): ``[theta, theta_dot, Omega, n, uOX, uOY, phi, psi, x, y]`` where
(phi, theta, psi) are the ZYZ Euler angles, Omega = dphi/dt, n = Omega cos(theta) + dpsi/dt,
(uOX, uOY) the centre-of-mass velocity in the rotating frame OXYZ and (x, y) its position on
the table. :func:`paper_core` is the right-hand side, singular at theta = 0 and pi: a run stops
where |sin(theta)| falls below ``P_SING`` (status ``singular``). The equations: docs/design.md.
"""

from __future__ import annotations

import math

import numba as nb

from tippetop.reference_ode.friction import friction_terms
from tippetop.reference_ode.params_array import (
    P_CVISC,
    P_LAM,
    P_MU,
    P_VEPS,
    top_params,
)
from tippetop.reference_ode.vector import write_observables, xi_curves

N_STATE = 10
ITH, ITHD, IOM, IN, IUX, IUY, IPHI, IPSI, IX, IY = range(N_STATE)


@nb.njit(cache=True, inline="always")
def paper_core(coulomb_kind, viscous, y, p, dy):
    """Write dy/dt into ``dy`` and return (N, FX, FY, vPX, vPY) in the rotating frame.

    Inlined (numba IR) into its callers: a separately compiled call adds atomic
    reference-count updates of its array arguments to every evaluation (with them, and the
    division-by-zero checks ``top`` compiles out, the vector rhs took 68 ns, now 46 ns).
    """
    R, a, M, A, C, g = top_params(p)
    th, thd, Om, n = y[ITH], y[ITHD], y[IOM], y[IN]
    uX, uY = y[IUX], y[IUY]
    s = math.sin(th)
    c = math.cos(th)
    h = R - a * c
    vPX = uX - h * thd
    vPY = uY + (R * (n - Om * c) + a * Om) * s
    phix, phiy, psix, psiy = friction_terms(
        coulomb_kind, viscous, vPX, vPY, p[P_MU], p[P_LAM], p[P_CVISC], p[P_VEPS])
    xi = C * n - A * Om * c
    # A theta_ddot = P A + Q A N, then N from the vertical constraint
    Pt = (-Om * xi * s - h * psix) / A
    Qt = (-a * s - h * phix) / A
    N = M * (g + a * thd * thd * c + a * s * Pt) / (1.0 - M * a * s * Qt)
    FX = N * phix + psix
    FY = N * phiy + psiy
    dy[ITH] = thd
    dy[ITHD] = Pt + Qt * N
    dy[IOM] = ((C * n - 2.0 * A * Om * c) * thd + (a - R * c) * FY) / (A * s)
    dy[IN] = R * s * FY / C
    dy[IUX] = Om * uY + FX / M
    dy[IUY] = -Om * uX + FY / M
    dy[IPHI] = Om
    dy[IPSI] = n - Om * c
    cp = math.cos(y[IPHI])
    sp = math.sin(y[IPHI])
    dy[IX] = uX * cp - uY * sp
    dy[IY] = uX * sp + uY * cp
    return N, FX, FY, vPX, vPY


@nb.njit(cache=True)
def paper_observe(coulomb_kind, viscous, y, p, sin_undefined, out, scratch):
    """Fill ``out`` (24,) with one state's observables (``COLUMNS[1:] + EXTRA_COLUMNS``)."""
    R, a, M, A, C, g = top_params(p)
    N, FX, FY, vPX, vPY = paper_core(coulomb_kind, viscous, y, p, scratch)
    th, thd, Om, n = y[ITH], y[ITHD], y[IOM], y[IN]
    s = math.sin(th)
    c = math.cos(th)
    h = R - a * c
    J = C * n * (R * c - a) + A * Om * R * s * s
    uOZ = a * s * thd
    E = (0.5 * M * (y[IUX] ** 2 + y[IUY] ** 2 + uOZ * uOZ)
         + 0.5 * (A * (thd * thd + Om * Om * s * s) + C * n * n) + M * g * h)
    xi_p, xi_m = xi_curves(J, c, R, a, M, A, g)
    defined = abs(s) > sin_undefined
    nan = math.nan
    # quaternion of Rz(phi) Ry(theta) Rz(psi)
    hp, ht, hs = 0.5 * y[IPHI], 0.5 * th, 0.5 * y[IPSI]
    ct, st = math.cos(ht), math.sin(ht)
    cs, ss = math.cos(hp + hs), math.sin(hp + hs)
    cd, sd = math.cos(hp - hs), math.sin(hp - hs)
    write_observables(out, th, thd, Om if defined else nan, n,
                      C * n - A * Om * c if defined else nan, xi_p, xi_m, J, E,
                      vPX if defined else nan, vPY if defined else nan, N,
                      y[IUX] if defined else nan, y[IUY] if defined else nan, y[IX], y[IY], h,
                      ct * cs, -st * sd, st * cd, ct * ss, FX * vPX + FY * vPY,
                      FX if defined else nan, FY if defined else nan)
