"""The paper's state <-> MuJoCo's free-joint qpos/qvel, and the top's kinematics from them.

MuJoCo's free joint: ``qpos = (p, q)`` with p the body origin in the world and q the world
quaternion (w, x, y, z) of the body; ``qvel = (v, w_b)`` with v the world linear velocity of the
body origin and w_b the angular velocity in the BODY frame. For a :func:`models.mjcf.make_mjcf`
top the body origin is the sphere's centre S and the body's z axis is the symmetry axis k; for
any other MJCF top :class:`~mujoco_runner.model.TopModel` says where S and k sit in the body,
and the maps below account for it. Frame conventions are those of :mod:`models.frames` (table
z = 0, k from O to S, the paper's rotating frame e_X = horizontal projection of k normalised,
e_Y = e_Z x e_X).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tippetop.models import mjcf_document
from tippetop.models.contacts import ContactSetting, ball_table_contact
from tippetop.models.frames import free_joint_start
from tippetop.models.observables import SIN_THETA_UNDEFINED
from tippetop.models.params import InitialState
from tippetop.models.plan import FileTop
from tippetop.mujoco_runner.model import TopModel, load_top, stem_from_model, stem_geoms
from tippetop.mujoco_runner.settings import cone_name, integrator_name


def initial_qpos_qvel(top_model: TopModel, init: InitialState) -> tuple[np.ndarray, np.ndarray]:
    """The free joint's qpos (7,) and qvel (6,) for the paper's initial state.

    :func:`tippetop.models.frames.free_joint_start` in this model's body frame.
    """
    return free_joint_start(top_model.top, init, top_model.paper_from_body_quat,
                            top_model.centre_body_m)


@dataclass(frozen=True)
class Kinematics:
    """The top's kinematics at n instants, table frame, SI; every array has n rows.

    Attributes:
        rot: Body-to-world rotation matrices, shape (n, 3, 3).
        k: Symmetry axis (O -> S), shape (n, 3).
        centre_m: Sphere centre S, shape (n, 3).
        com_m: Centre of mass O, shape (n, 3).
        omega_radps: Angular velocity, shape (n, 3).
        v_com_mps: Velocity of O, shape (n, 3).
        v_P_mps: Velocity of the material point at P = S - R e_z (the slip velocity), (n, 3).
        e_X: The paper's e_X (NaN where |sin theta| < SIN_THETA_UNDEFINED), shape (n, 3).
        e_Y: The paper's e_Y = e_z x e_X (NaN likewise), shape (n, 3).
        sin_theta: |horizontal part of k|, shape (n,).
    """

    rot: np.ndarray
    k: np.ndarray
    centre_m: np.ndarray
    com_m: np.ndarray
    omega_radps: np.ndarray
    v_com_mps: np.ndarray
    v_P_mps: np.ndarray
    e_X: np.ndarray
    e_Y: np.ndarray
    sin_theta: np.ndarray


def rotations(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of (n, 4) quaternions (w, x, y, z), normalised here."""
    q = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


def kinematics(top_model: TopModel, qpos: np.ndarray, qvel: np.ndarray) -> Kinematics:
    """Kinematics of the top from the free joint's coordinates.

    Args:
        top_model: The top and where S and k sit in its body.
        qpos: Free-joint positions, shape (n, 7) or (7,).
        qvel: Free-joint velocities, shape (n, 6) or (6,).
    """
    top = top_model.top
    qpos = np.atleast_2d(np.asarray(qpos, dtype=float))
    qvel = np.atleast_2d(np.asarray(qvel, dtype=float))
    rot = rotations(qpos[:, 3:7])
    k = rot @ top_model.axis_body
    arm = rot @ top_model.centre_body_m  # S - body origin
    centre = qpos[:, 0:3] + arm
    com = centre - top.a_m * k
    omega = np.einsum("nij,nj->ni", rot, qvel[:, 3:6])
    v_centre = qvel[:, 0:3] + np.cross(omega, arm)
    v_com = v_centre - top.a_m * np.cross(omega, k)
    v_P = v_centre + np.cross(omega, np.array([0.0, 0.0, -top.R_m]))
    sin_theta = np.hypot(k[:, 0], k[:, 1])
    defined = sin_theta >= SIN_THETA_UNDEFINED
    safe = np.where(defined, sin_theta, 1.0)
    e_X = np.stack([k[:, 0] / safe, k[:, 1] / safe, np.zeros_like(safe)], axis=1)
    e_X[~defined] = np.nan
    e_Y = np.stack([-e_X[:, 1], e_X[:, 0], e_X[:, 2]], axis=1)
    return Kinematics(rot=rot, k=k, centre_m=centre, com_m=com, omega_radps=omega,
                      v_com_mps=v_com, v_P_mps=v_P, e_X=e_X, e_Y=e_Y, sin_theta=sin_theta)


def paper_angles(kin: Kinematics) -> dict[str, np.ndarray]:
    """theta, theta_dot, Omega and n (arrays of shape (n,)) from the kinematics.

    theta = atan2(|k_h|, k_z); n = omega . k; theta_dot = omega . e_Y; Omega = -(omega . x_hat)
    / sin theta with x_hat = cos theta e_X - sin theta e_z (the paper's Ox axis), which avoids
    the cancellation of (omega_z - n cos theta) / sin^2 theta. Where |sin theta| <
    SIN_THETA_UNDEFINED, Omega is NaN and theta_dot is the rate at which theta leaves the pole,
    +|horizontal part of dk/dt| at theta = 0 and -|...| at theta = pi.
    """
    k, omega, s = kin.k, kin.omega_radps, kin.sin_theta
    c = k[:, 2]
    theta = np.arctan2(s, c)
    n = np.einsum("ni,ni->n", omega, k)
    theta_dot = np.einsum("ni,ni->n", omega, kin.e_Y)
    x_hat = c[:, None] * kin.e_X - s[:, None] * np.array([0.0, 0.0, 1.0])
    undefined = np.isnan(kin.e_X[:, 0])
    Omega = -np.einsum("ni,ni->n", omega, x_hat) / np.where(undefined, 1.0, s)
    Omega[undefined] = np.nan
    if undefined.any():
        k_dot = np.cross(omega[undefined], k[undefined])
        theta_dot[undefined] = np.sign(c[undefined]) * np.hypot(k_dot[:, 0], k_dot[:, 1])
    return {"theta": theta, "theta_dot": theta_dot, "Omega": Omega, "n": n}


def initial_state_from_qpos_qvel(top_model: TopModel, qpos: np.ndarray,
                                 qvel: np.ndarray) -> InitialState:
    """The inverse of :func:`initial_qpos_qvel`: the paper's state of one (qpos, qvel).

    With the axis vertical (|sin theta| < SIN_THETA_UNDEFINED) the paper's frame is not
    defined by the tilt; it is then taken along the direction the axis starts to tilt in
    (e_X = dk/dt / |dk/dt|; the world x axis if it does not tilt), where the paper's state is
    (theta0 = 0 or pi, thetadot0 = |dk/dt|, Omega0 = 0, n0 = omega . k): the same motion,
    turned about the vertical.
    """
    kin = kinematics(top_model, qpos, qvel)
    if kin.sin_theta[0] < SIN_THETA_UNDEFINED:
        k = kin.k[0]
        omega = kin.omega_radps[0]
        k_dot = np.cross(omega, k)
        rate = float(np.hypot(k_dot[0], k_dot[1]))
        e_X = np.array([k_dot[0], k_dot[1], 0.0]) / rate if rate > 0 else np.array([1.0, 0, 0])
        e_Y = np.cross([0.0, 0.0, 1.0], e_X)
        v = kin.v_com_mps[0]
        return InitialState(theta0=0.0 if k[2] > 0 else math.pi, thetadot0=rate, Omega0=0.0,
                            n0=float(omega @ k), uOX=float(v @ e_X), uOY=float(v @ e_Y))
    ang = paper_angles(kin)
    return InitialState(
        theta0=float(ang["theta"][0]), thetadot0=float(ang["theta_dot"][0]),
        Omega0=float(ang["Omega"][0]), n0=float(ang["n"][0]),
        uOX=float(kin.v_com_mps[0] @ kin.e_X[0]), uOY=float(kin.v_com_mps[0] @ kin.e_Y[0]),
    )


__all__ = [
    "KEYFRAME_TOUCH_R",
    "Kinematics",
    "contact_reach_m",
    "contact_settings",
    "file_top",
    "initial_qpos_qvel",
    "initial_state_from_qpos_qvel",
    "keyframe_state",
    "kinematics",
    "paper_angles",
    "rotations",
]


#: A keyframe's ball counts as on the table if its lowest point is within this of z = 0, in
#: sphere radii (a file's keyframe may sit its ball a hair above or into the table).
KEYFRAME_TOUCH_R = 0.05


def keyframe_state(top_model: TopModel, index: int) -> InitialState | None:
    """The paper's state of keyframe ``index`` of the model (None: its ball is off the table).

    The paper's state assumes the ball on the table; a keyframe with the ball's lowest point
    more than :data:`KEYFRAME_TOUCH_R` radii from z = 0 has none.
    """
    model = top_model.model
    qa, va = top_model.qpos_adr, top_model.dof_adr
    qpos = np.array(model.key_qpos[index][qa:qa + 7], dtype=float)
    qvel = np.array(model.key_qvel[index][va:va + 6], dtype=float)
    kin = kinematics(top_model, qpos, qvel)
    gap = float(kin.centre_m[0, 2]) - top_model.top.R_m
    if not (abs(gap) <= KEYFRAME_TOUCH_R * top_model.top.R_m and np.isfinite(qvel).all()):
        return None
    return initial_state_from_qpos_qvel(top_model, qpos, qvel)


def file_top(mjcf: str | os.PathLike[str]) -> FileTop:
    """Everything a run plan reads of an MJCF top: parameters, options, contacts, keyframes."""
    import mujoco

    path = Path(os.fspath(mjcf))
    top_model = load_top(path)
    model = top_model.model
    names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, i) or ""
                  for i in range(model.nkey))
    inits = tuple(keyframe_state(top_model, i) for i in range(model.nkey))
    stem, note = stem_from_model(top_model)
    contacts = contact_settings(top_model)
    ball = ball_table_contact(contacts)
    opt = model.opt
    return FileTop(
        top=top_model.top, path=path.resolve(), text=mjcf_document.read_text(path),
        timestep_s=float(opt.timestep), integrator=integrator_name(int(opt.integrator)),
        cone=cone_name(int(opt.cone)), impratio=float(opt.impratio),
        noslip_iterations=int(opt.noslip_iterations),
        gravity_mps2=tuple(float(g) for g in opt.gravity), contacts=contacts,
        ngeom=int(model.ngeom), npair=int(model.npair),
        contact_reach_m=contact_reach_m(top_model),
        centre_body_m=tuple(float(v) for v in top_model.centre_body_m),
        paper_from_body_quat=tuple(float(v) for v in top_model.paper_from_body_quat),
        keyframes=names, keyframe_inits=inits,
        mu=None if ball is None else ball.friction[0], stem=stem,
        stem_note=note, iterations=int(opt.iterations), tolerance=float(opt.tolerance),
        contacts_on=not int(opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_CONTACT))


def contact_settings(top_model: TopModel) -> tuple[ContactSetting, ...]:
    """The model's contact settings, as a plan lists them.

    The colliding geoms of the top and of the static world (the ball; the top's others as
    ``stem``; the static ones as ``table``), then the contact pairs that involve the top.
    """
    import mujoco

    model, b = top_model.model, top_model.body_id
    stems = set(stem_geoms(top_model))

    def name(g: int) -> str:
        return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"

    out = []
    for g in range(model.ngeom):
        if g == top_model.ball_geom_id:
            role = "ball"
        elif g in stems:
            role = "stem"
        elif model.body_weldid[model.geom_bodyid[g]] == 0 and (
                model.geom_contype[g] or model.geom_conaffinity[g]):
            role = "table"
        else:
            continue
        out.append(ContactSetting(
            "geom", g, name(g), role, int(model.geom_condim[g]),
            tuple(float(v) for v in model.geom_friction[g]),
            tuple(float(v) for v in model.geom_solref[g]),
            tuple(float(v) for v in model.geom_solimp[g]),
            contype=int(model.geom_contype[g]), conaffinity=int(model.geom_conaffinity[g]),
            priority=int(model.geom_priority[g]), solmix=float(model.geom_solmix[g])))
    for p in range(model.npair):
        g1, g2 = int(model.pair_geom1[p]), int(model.pair_geom2[p])
        if b not in (model.geom_bodyid[g1], model.geom_bodyid[g2]):
            continue
        out.append(ContactSetting(
            "pair", p, f"{name(g1)} {name(g2)}", "pair", int(model.pair_dim[p]),
            tuple(float(v) for v in model.pair_friction[p]),
            tuple(float(v) for v in model.pair_solref[p]),
            tuple(float(v) for v in model.pair_solimp[p]), geoms=(g1, g2),
            solreffriction=tuple(float(v) for v in model.pair_solreffriction[p])
            if any(model.pair_solreffriction[p]) else ()))
    return tuple(out)


def contact_reach_m(top_model: TopModel) -> float:
    """How far from the centre of mass a contact on the top can be (m).

    Over its colliding geoms, the distance of the geom's centre from G plus its bounding radius.
    """
    model, b = top_model.model, top_model.body_id
    reach = top_model.top.R_m + top_model.top.a_m
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == b and (model.geom_contype[g] or model.geom_conaffinity[g]):
            d = float(np.linalg.norm(model.geom_pos[g] - model.body_ipos[b]))
            reach = max(reach, d + float(model.geom_rbound[g]))
    return reach
