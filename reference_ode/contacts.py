"""The top's contact surfaces, the parameters of a contact phase, and the impact between phases.

The reference models two contact surfaces on the symmetry axis, the ball
(:func:`ball_contact`) and the stem's end (:func:`stem_contact`), each touching the table at
one point X_P = b k + c from the centre of mass (:class:`Contact`). One is active at a time
(:func:`phase_params`); when the other reaches the table the run switches to it through a
perfectly inelastic, frictionless impact (:func:`impact`). Each surface's geometry and what
happens at a switch: docs/design.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tippetop.models.params import StemParams, TopParams
from tippetop.reference_ode.params_array import (
    P_A_OFF,
    P_GAP_TOL,
    P_OTHER,
    P_OTHER_B,
    P_OTHER_R,
    P_R,
    P_RIM,
)

#: The other surface counts as touching once it is this far below the table, in sphere radii
#: (1.5e-10 m for the paper's top): a switch places it exactly at the table, and it must not
#: trigger again at once; the two-point phase holds the tilt to ~1e-11 m at rtol 1e-9.
GAP_TOL_R = 1e-8
#: A run that switches contact more often than this stops (a chatter the Zeno rule missed).
MAX_SWITCHES = 10_000
#: A rim contact degenerates when the flat end lies face down (sin theta -> 0): the run stops
#: with status ``flat_end`` below this |sin theta|.
RIM_MIN_SIN = 1e-3


@dataclass(frozen=True)
class Contact:
    """One contact surface: its point X_P = b k + c from the centre of mass.

    Attributes:
        name: ``ball`` or ``stem``.
        rim: A flat end's rim (c = r u) rather than a sphere (c = -r e_z).
        b_m: Distance of the surface's centre from the centre of mass along k (m).
        r_m: The sphere's or the rim's radius (m).
    """

    name: str
    rim: bool
    b_m: float
    r_m: float


def ball_contact(top: TopParams) -> Contact:
    """The loaded sphere's ball."""
    return Contact("ball", False, top.a_m, top.R_m)


def stem_contact(top: TopParams, stem: StemParams) -> Contact:
    """The stem's end."""
    return Contact("stem", stem.kind == "cylinder", top.a_m + stem.offset_m, stem.radius_m)


def phase_params(p: np.ndarray, active: Contact, other: Contact | None,
                 R_m: float) -> np.ndarray:
    """A copy of the packed parameters ``p`` for the phase on ``active`` (watching ``other``)."""
    q = p.copy()
    q[P_R], q[P_A_OFF], q[P_RIM] = active.r_m, active.b_m, float(active.rim)
    if other is None:
        q[P_OTHER] = -1.0
    else:
        q[P_OTHER], q[P_OTHER_B], q[P_OTHER_R] = float(other.rim), other.b_m, other.r_m
    q[P_GAP_TOL] = GAP_TOL_R * R_m
    return q


def _axis(y: np.ndarray) -> np.ndarray:
    q = y[4:8] / np.linalg.norm(y[4:8])
    w, x, yy, z = q
    return np.array([2 * (x * z + w * yy), 2 * (yy * z - w * x), w * w - x * x - yy * yy + z * z])


def contact_point(k: np.ndarray, c: Contact) -> np.ndarray:
    """X_P of a surface for the axis k (world frame, from the centre of mass), shape (3,)."""
    if not c.rim:
        return c.b_m * k - np.array([0.0, 0.0, c.r_m])
    s = math.hypot(k[0], k[1])
    if s == 0.0:  # the end horizontal: every rim point is as low; take one
        return c.b_m * k + c.r_m * np.array([1.0, 0.0, 0.0])
    u = np.array([k[2] * k[0] / s, k[2] * k[1] / s, -s])
    return c.b_m * k + c.r_m * u


def gap(y: np.ndarray, active: Contact, other: Contact) -> float:
    """Height of ``other``'s lowest point above the table while ``active`` touches it (m)."""
    k = _axis(y)
    z_O = -contact_point(k, active)[2]
    return z_O + contact_point(k, other)[2]


def _vz_com(k: np.ndarray, omega: np.ndarray, c: Contact) -> float:
    """Vertical velocity of the centre of mass while surface ``c`` touches (its constraint)."""
    kd = np.cross(omega, k)
    vz = -c.b_m * kd[2]
    if c.rim:
        s = math.hypot(k[0], k[1])
        vz += c.r_m * (k[0] * kd[0] + k[1] * kd[1]) / s
    return vz


@dataclass(frozen=True)
class Impact:
    """What happened when a surface reached the table.

    Attributes:
        y: The state just after (the angular velocity changed; positions and the horizontal
            velocity did not).
        impulse_Ns: The new surface's impulse (N s).
        both: True if the old surface would have to push too (both touching at once:
            :func:`impact_both` then starts the two-point phase; ``y`` is the state before).
        approach_mps: The new point's downward speed before the impact (m/s).
    """

    y: np.ndarray
    impulse_Ns: float
    both: bool
    approach_mps: float


def impact(y: np.ndarray, top: TopParams, old: Contact, new: Contact) -> Impact:
    """The perfectly inelastic, frictionless impact of ``new`` on the table while ``old`` touched.

    An impulse j e_z at the new point X_n changes the centre of mass's velocity by j/M e_z and
    the angular velocity by j I^-1 (X_n x e_z); j makes the new point's vertical velocity zero.
    Afterwards the old point must not be pushed into the table: if its vertical velocity
    would be negative, both surfaces push (:attr:`Impact.both`).
    """
    k = _axis(y)
    omega = np.array(y[8:11], dtype=float)
    A, C, M = top.A_kgm2, top.C_kgm2, top.M_kg

    def inv_inertia(v: np.ndarray) -> np.ndarray:
        return v / A + (1.0 / C - 1.0 / A) * float(k @ v) * k

    ez = np.array([0.0, 0.0, 1.0])
    x_old, x_new = contact_point(k, old), contact_point(k, new)
    vz = _vz_com(k, omega, old)
    v_new = vz + np.cross(omega, x_new)[2]
    v_old = vz + np.cross(omega, x_old)[2]  # 0: the old surface's constraint

    def w(xa: np.ndarray, xb: np.ndarray) -> float:
        return 1.0 / M + float(np.cross(inv_inertia(np.cross(xa, ez)), xb)[2])

    if v_new >= 0.0:  # grazing: nothing to stop
        return Impact(y.copy(), 0.0, False, -v_new)
    j = -v_new / w(x_new, x_new)
    v_old_after = v_old + w(x_new, x_old) * j
    if v_old_after < -1e-12 * max(1.0, abs(v_new)):
        return Impact(y.copy(), j, True, -v_new)
    out = y.copy()
    out[8:11] = omega + j * inv_inertia(np.cross(x_new, ez))
    return Impact(out, j, False, -v_new)


def normal_velocity(y: np.ndarray, touching: Contact, c: Contact) -> float:
    """Vertical velocity of surface ``c``'s lowest material point while ``touching`` holds."""
    k = _axis(y)
    omega = np.array(y[8:11], dtype=float)
    return _vz_com(k, omega, touching) + float(np.cross(omega, contact_point(k, c))[2])


def impact_both(y: np.ndarray, top: TopParams, old: Contact, new: Contact) -> np.ndarray:
    """The impulses at both points that leave both at rest vertically (a two-point start).

    Solves W j = -v for the two vertical impulses (W_ab: the vertical velocity change at b per
    unit impulse at a). Used when the new surface's impact would push the old one into the
    table, and to end a chatter of vanishing bounces (see :data:`ZENO_SPEED_MPS`): then the
    old point's impulse may be a small pull, the truncation of that chatter.
    """
    k = _axis(y)
    omega = np.array(y[8:11], dtype=float)
    A, C, M = top.A_kgm2, top.C_kgm2, top.M_kg

    def inv_inertia(v: np.ndarray) -> np.ndarray:
        return v / A + (1.0 / C - 1.0 / A) * float(k @ v) * k

    ez = np.array([0.0, 0.0, 1.0])
    xs = (contact_point(k, old), contact_point(k, new))
    vz = _vz_com(k, omega, old)
    v = np.array([vz + np.cross(omega, x)[2] for x in xs])
    W = np.array([[1.0 / M + float(np.cross(inv_inertia(np.cross(xa, ez)), xb)[2])
                   for xa in xs] for xb in xs])
    j = np.linalg.solve(W, -v)
    out = y.copy()
    out[8:11] = omega + sum(ji * inv_inertia(np.cross(x, ez)) for ji, x in zip(j, xs,
                                                                             strict=True))
    return out


#: Below this speed (m/s) of the old point lifting off after an impact, with both points able
#: to push, the top is taken to rest on both points at once: an inelastic bounce this slow
#: would rise less than v^2 / 2g = 0.05 um and start a chatter of ever shorter bounces.
ZENO_SPEED_MPS = 1e-3


__all__ = ["GAP_TOL_R", "MAX_SWITCHES", "RIM_MIN_SIN", "ZENO_SPEED_MPS", "Contact", "Impact",
           "ball_contact",
           "contact_point", "gap", "impact", "impact_both", "normal_velocity", "phase_params",
           "stem_contact"]
