"""The flat float64 parameter vector the compiled right-hand sides read.

Compiled code takes one array, not objects; these indices name its slots.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from tippetop.models.options import DEFAULT_SINGULAR_SIN
from tippetop.models.params import FrictionParams, TopParams
from tippetop.reference_ode.friction import LAW_TERMS

P_R = 0  # sphere radius (m)
P_A_OFF = 1  # centre-of-mass offset a (m)
P_M = 2  # mass (kg)
P_IA = 3  # transverse moment A (kg m^2)
P_IC = 4  # axial moment C (kg m^2)
P_G = 5  # gravity (m/s^2)
P_MU = 6  # Coulomb coefficient
P_LAM = 7  # modified Coulomb speed Lambda (m/s)
P_CVISC = 8  # viscous coefficient (N s/m)
P_VEPS = 9  # exact Coulomb ramp half-width (m/s)
P_SING = 10  # paper formulation: |sin theta| below which it is declared singular
P_COULOMB_KIND = 11  # the friction law's Coulomb part: friction.COULOMB_* code
P_VISCOUS = 12  # the friction law's viscous part: 1.0 if present, else 0.0
# The contact. P_R and P_A_OFF describe the ACTIVE contact, whose point is X_P = b k + c from
# the centre of mass: b = P_A_OFF and, for a sphere, c = -P_R e_z (the ball: b = a, radius R;
# a stem's rounded end: b = a + offset, its radius); for a rim (a stem's flat end), c = P_R u
# with u the unit vector in the end's plane pointing most downward.
P_RIM = 13  # 1.0: the active contact is a rim, 0.0: a sphere
P_OTHER = 14  # the other contact surface: -1.0 none, 0.0 a sphere, 1.0 a rim
P_OTHER_B = 15  # its b (m)
P_OTHER_R = 16  # its radius (m)
P_GAP_TOL = 17  # the other surface "touches" when its gap falls below -P_GAP_TOL (m)
N_PARAMS = 18


def pack_params(top: TopParams, friction: FrictionParams,
                singular_sin: float = DEFAULT_SINGULAR_SIN) -> np.ndarray:
    """Pack the parameters and the friction law into the compiled functions' vector.

    Args:
        top: The loaded sphere.
        friction: The sliding-friction law (its terms go to ``P_COULOMB_KIND`` and
            ``P_VISCOUS``) and its coefficients.
        singular_sin: The paper formulation's singular threshold on |sin theta|.

    Returns:
        The vector, shape (N_PARAMS,).
    """
    p = np.empty(N_PARAMS)
    p[P_R] = top.R_m
    p[P_A_OFF] = top.a_m
    p[P_M] = top.M_kg
    p[P_IA] = top.A_kgm2
    p[P_IC] = top.C_kgm2
    p[P_G] = top.g_mps2
    p[P_MU] = friction.mu
    p[P_LAM] = friction.Lambda_mps
    p[P_CVISC] = friction.viscous_coefficient(top)
    p[P_VEPS] = friction.coulomb_v_eps_mps
    p[P_SING] = singular_sin
    p[P_COULOMB_KIND], p[P_VISCOUS] = friction_law_codes(friction)
    p[P_RIM] = 0.0  # the ball, alone: the paper's loaded sphere
    p[P_OTHER] = -1.0
    p[P_OTHER_B] = p[P_OTHER_R] = p[P_GAP_TOL] = 0.0
    return p


def friction_law_codes(friction: FrictionParams) -> tuple[float, float]:
    """The values of the ``P_COULOMB_KIND`` and ``P_VISCOUS`` slots for a friction law."""
    coulomb_kind, viscous = LAW_TERMS[friction.law]
    return float(coulomb_kind), 1.0 if viscous else 0.0


@nb.njit(cache=True, inline="always")
def top_params(p):
    """(R, a, M, A, C, g) of a packed parameter vector."""
    return p[P_R], p[P_A_OFF], p[P_M], p[P_IA], p[P_IC], p[P_G]


@nb.njit(cache=True, inline="always")
def friction_law(p):
    """(coulomb_kind, viscous) of a packed parameter vector, as ``friction.LAW_TERMS``."""
    return int(p[P_COULOMB_KIND]), p[P_VISCOUS] != 0.0
