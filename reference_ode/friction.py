"""Sliding-friction laws as separate compiled terms.

Every law is written as F = N * phi(v_P) + psi(v_P): a Coulomb-type part proportional to the
normal force N and a viscous part that is not, so that the contact constraint, solved for N
together with the accelerations, is linear in N. A law is the pair (``coulomb_kind``,
``viscous``) of :data:`LAW_TERMS`, carried in the parameter vector; :func:`friction_terms`
computes its terms. Each law, and the exact Coulomb law's ramp at v_P = 0: docs/design.md.
"""

from __future__ import annotations

import math

import numba as nb

COULOMB_NONE = 0
COULOMB_MODIFIED = 1
COULOMB_EXACT = 2

#: law name -> (coulomb_kind, viscous)
LAW_TERMS: dict[str, tuple[int, bool]] = {
    "modified_coulomb": (COULOMB_MODIFIED, False),
    "coulomb": (COULOMB_EXACT, False),
    "viscous": (COULOMB_NONE, True),
    "coulomb_viscous": (COULOMB_EXACT, True),
    "none": (COULOMB_NONE, False),
}


@nb.njit(cache=True, inline="always")
def friction_terms(coulomb_kind, viscous, vx, vy, mu, lam, c_visc, v_eps):
    """Return (phi_x, phi_y, psi_x, psi_y) with F = N phi + psi for the slip (vx, vy) in m/s."""
    phix = 0.0
    phiy = 0.0
    psix = 0.0
    psiy = 0.0
    if coulomb_kind == COULOMB_MODIFIED:
        s = mu / math.sqrt(vx * vx + vy * vy + lam * lam)
        phix = -s * vx
        phiy = -s * vy
    elif coulomb_kind == COULOMB_EXACT:
        speed = math.sqrt(vx * vx + vy * vy)
        s = mu / (speed if speed > v_eps else v_eps)
        phix = -s * vx
        phiy = -s * vy
    if viscous:
        psix = -c_visc * vx
        psiy = -c_visc * vy
    return phix, phiy, psix, psiy
