"""The flat float64 parameter vector the compiled right-hand sides read.

Compiled code takes one array, not objects; these indices name its slots.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from tippetop.models.options import DEFAULT_SINGULAR_SIN
from tippetop.models.params import FrictionParams, TopParams

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
N_PARAMS = 11



def pack_params(top: TopParams, friction: FrictionParams,
                singular_sin: float = DEFAULT_SINGULAR_SIN) -> np.ndarray:
    """Pack the parameters into the compiled functions' vector, shape (N_PARAMS,)."""
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
    return p


@nb.njit(cache=True, inline="always")
def top_params(p):
    """(R, a, M, A, C, g) of a packed parameter vector."""
    return p[P_R], p[P_A_OFF], p[P_M], p[P_IA], p[P_IC], p[P_G]
