"""The observables table every engine returns, with the same column names.

Angles in rad, rates in rad/s, velocities in m/s, forces in N, energy in J, Jellett's constant
in kg m^3/s (angular momentum times length). Paper-frame quantities (Omega, xi, vPX, vPY, uOX,
uOY) are undefined when the symmetry axis is vertical (sin theta = 0); they are NaN there.
"""

from __future__ import annotations

#: Required columns, in order (the contract shared by the ODE and MuJoCo runners).
COLUMNS: tuple[str, ...] = (
    "t", "theta", "theta_dot", "Omega", "n", "xi", "xi_plus", "xi_minus", "J", "E",
    "vPX", "vPY", "N", "uOX", "uOY", "x", "y",
)

#: Extra columns every engine also writes: the centre of mass height, the body pose (w, x, y,
#: z quaternion, body to world) for replays and renders, the friction power F . v_P (W), and
#: the friction force on the top at the contact in the paper's frame, beside the slip (FX,
#: FY; N): the reference's law (both points' summed while the stem touches too, the rolling
#: phase's force while it rolls), MuJoCo's own contact forces rotated out of each contact's
#: frame in native mode, the harness's law in paper mode. NaN where the frame is undefined.
EXTRA_COLUMNS: tuple[str, ...] = ("z", "qw", "qx", "qy", "qz", "P_fric", "FX", "FY")

#: Below this |sin theta| the paper-frame quantities are reported as NaN.
SIN_THETA_UNDEFINED = 1e-9
