"""Sliding-friction laws as separate compiled terms.

Every law is written as F = N * phi(v_P) + psi(v_P): a Coulomb-type part proportional to the
normal force N and a viscous part that is not. The normal force is solved from the contact
constraint together with the accelerations, which is linear in N because of this split.

A law is the pair (``coulomb_kind``, ``viscous``) of :data:`LAW_TERMS`. The reference ODE
carries it in its parameter vector (``params_array.P_COULOMB_KIND``, ``P_VISCOUS``) and
:func:`friction_terms` branches on it, so a run computes only the terms its scene names.

* ``modified_coulomb`` (the paper's eq. 2.12): phi = -mu v_P / sqrt(|v_P|^2 + Lambda^2).
* ``coulomb``: phi = -mu v_P / |v_P|. The exact law is set-valued at v_P = 0 (any force with
  |F| <= mu N), and an explicit integrator cannot follow a discontinuous right-hand side. Below
  the slip speed ``v_eps`` (``FrictionParams.coulomb_v_eps_mps``, 1e-5 m/s by default, 1000x
  below the paper's Lambda) the law is replaced by the linear ramp -mu v_P / v_eps, which is
  continuous, equals the exact law for |v_P| >= v_eps and picks the force that drives the slip
  to zero inside the ramp. The ramp is stiff (a relaxation time of about M v_eps / (mu N)),
  which the adaptive step-size control resolves: expect small steps while the top rolls.
* ``viscous``: psi = -c v_P with c = ``FrictionParams.viscous_coefficient``.
* ``coulomb_viscous`` (as in Or's hybrid law): both of the above.
* ``none``: a frictionless table (a scene with ``effects.sliding = false``).
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
