"""Frames and the map from the paper's initial state to rigid-body kinematics.

Conventions, shared by every engine:

* Table frame: z up, the table is the plane z = 0.
* ``k`` is the unit symmetry axis pointing from the centre of mass O towards the sphere's
  centre S (the stem-up direction when theta = 0). S = O + a k; the contact point is
  P = S - R e_z, so X_P = P - O = a k - R e_z and the height of O is h = R - a k_z.
* The body's orientation is the ZYZ Euler rotation Rz(phi) Ry(theta) Rz(psi): k =
  (sin theta cos phi, sin theta sin phi, cos theta). The paper's rotating frame OXYZ has
  e_X = (cos phi, sin phi, 0), e_Y = (-sin phi, cos phi, 0), e_Z = e_z, so k tilts towards +X.
* Quaternions are (w, x, y, z), MuJoCo's order, body to world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tippetop.models.params import InitialState, TopParams


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of two (w, x, y, z) quaternions."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def euler_zyz_quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of Rz(phi) Ry(theta) Rz(psi)."""
    qz1 = np.array([math.cos(phi / 2), 0.0, 0.0, math.sin(phi / 2)])
    qy = np.array([math.cos(theta / 2), 0.0, math.sin(theta / 2), 0.0])
    qz2 = np.array([math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)])
    return quat_mul(quat_mul(qz1, qy), qz2)


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3), body to world, of a (w, x, y, z) quaternion (normalised here)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


@dataclass(frozen=True)
class RigidState:
    """Rigid-body kinematics in the table frame, SI.

    Attributes:
        com_m: Centre-of-mass position, shape (3,).
        quat: Orientation (w, x, y, z), body to world, shape (4,).
        omega_radps: Angular velocity in the table frame, shape (3,).
        v_com_mps: Centre-of-mass velocity in the table frame, shape (3,).
    """

    com_m: np.ndarray
    quat: np.ndarray
    omega_radps: np.ndarray
    v_com_mps: np.ndarray

    def axis(self) -> np.ndarray:
        """The unit symmetry axis k, shape (3,)."""
        return quat_to_mat(self.quat)[:, 2]

    def sphere_centre_m(self, top: TopParams) -> np.ndarray:
        """Position of the sphere's centre S = O + a k (MuJoCo's body origin), shape (3,)."""
        return self.com_m + top.a_m * self.axis()

    def sphere_centre_velocity_mps(self, top: TopParams) -> np.ndarray:
        """Velocity of S: v_O + omega x (a k), shape (3,)."""
        return self.v_com_mps + np.cross(self.omega_radps, top.a_m * self.axis())


def initial_rigid_state(top: TopParams, init: InitialState) -> RigidState:
    """Map the paper's initial state to rigid-body kinematics, with phi = psi = 0 and x = y = 0.

    In the rotating frame (which is the table frame at phi = 0) the paper gives
    omega = ((n - Omega cos theta) sin theta, theta_dot, Omega sin^2 theta + n cos theta) and
    u_O = (u_OX, u_OY, a sin theta theta_dot).
    """
    th, thd, Om, n = init.theta0, init.thetadot0, init.Omega0, init.n0
    s, c = math.sin(th), math.cos(th)
    omega = np.array([(n - Om * c) * s, thd, Om * s * s + n * c])
    v = np.array([init.uOX, init.uOY, top.a_m * s * thd])
    com = np.array([0.0, 0.0, top.R_m - top.a_m * c])
    return RigidState(com_m=com, quat=euler_zyz_quat(0.0, th, 0.0), omega_radps=omega,
                      v_com_mps=v)


def free_joint_start(top: TopParams, init: InitialState, paper_from_body_quat: np.ndarray,
                     centre_body_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's free-joint qpos (7,) and qvel (6,) for the paper's initial state.

    The top starts with phi = psi = 0 and its centre of mass above the origin, the ball just
    touching the table (S at height R), as in :func:`initial_rigid_state`. The body frame is
    the model's: ``paper_from_body_quat`` rotates body-frame vectors into the paper's body
    frame (whose z axis is k) and ``centre_body_m`` is S in the body frame (identity and zero
    for :func:`tippetop.models.mjcf.make_mjcf` tops). qpos is the body origin and its world
    quaternion; qvel the origin's world velocity and the body-frame angular velocity.
    """
    rigid = initial_rigid_state(top, init)
    quat = quat_mul(rigid.quat, paper_from_body_quat)
    quat /= np.linalg.norm(quat)
    rot = quat_to_mat(quat)
    origin = rigid.sphere_centre_m(top) - rot @ centre_body_m
    v_origin = rigid.v_com_mps + np.cross(rigid.omega_radps, origin - rigid.com_m)
    qpos = np.concatenate([origin, quat])
    qvel = np.concatenate([v_origin, rot.T @ rigid.omega_radps])
    return qpos, qvel
