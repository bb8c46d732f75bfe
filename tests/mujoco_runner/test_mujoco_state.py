"""The paper's initial state <-> MuJoCo's free-joint qpos/qvel."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from tippetop.models.frames import initial_rigid_state
from tippetop.models.mjcf import make_mjcf
from tippetop.models.params import InitialState, TopParams
from tippetop.mujoco_runner.model import TopModelWarning, load_top
from tippetop.mujoco_runner.state import (
    initial_qpos_qvel,
    initial_state_from_qpos_qvel,
    kinematics,
    paper_angles,
)

TOP = TopParams.from_ratios(0.95, 0.125)
STATES = [
    InitialState(),  # Fig. 3: theta0 = 0.1, n0 = 100
    InitialState(theta0=0.7, thetadot0=0.3, Omega0=2.0, n0=100.0, uOX=0.01, uOY=-0.02),
    InitialState(theta0=2.9, thetadot0=-1.5, Omega0=-30.0, n0=-40.0, uOX=-0.2, uOY=0.05),
    InitialState(theta0=1e-3, n0=150.0),
]
FIELDS = ("theta0", "thetadot0", "Omega0", "n0", "uOX", "uOY")

# A top whose body frame is neither at the sphere's centre nor aligned with k: origin at the
# centre of mass, k along body -y, then turned by an arbitrary inertial-frame quaternion.
_GENERIC = """<mujoco><option gravity="0 0 -9.8"/><worldbody><geom type="plane" size="1 1 .1"/>
  <body pos="0 0 0.1"><freejoint/>
    <inertial pos="0 0 0" mass="0.015" diaginertia="1.2825e-6 1.35e-6 1.2825e-6"/>
    <geom type="sphere" size="0.015" pos="0 -0.001875 0"/>
  </body></worldbody></mujoco>"""


def _load_generic():
    with pytest.warns(TopModelWarning, match="origin"):
        return load_top(_GENERIC)


@pytest.mark.parametrize("init", STATES)
def test_map_is_the_free_joint_convention(init: InitialState) -> None:
    # The paper's start with phi = psi = 0 (Sec. 2), written out in closed form: the symmetry
    # axis k = (sin th, 0, cos th) is e_z turned about e_y by th, so the quaternion is
    # (cos th/2, 0, sin th/2, 0); omega = (0, th_dot, Omega) + (n - Omega cos th) k (the
    # precession about e_z, the tilt rate about e_Y = e_y, the spin relative to the plane about
    # k); the centre of mass O at height R - a cos th, velocity (uOX, uOY, a sin th th_dot);
    # the sphere's centre S = O + a k.
    tm = load_top(make_mjcf(TOP))
    th, thd, Om, n = init.theta0, init.thetadot0, init.Omega0, init.n0
    R, a = TOP.R_m, TOP.a_m
    k = np.array([math.sin(th), 0.0, math.cos(th)])
    omega = np.array([0.0, thd, Om]) + (n - Om * math.cos(th)) * k
    com = np.array([0.0, 0.0, R - a * math.cos(th)])
    v_com = np.array([init.uOX, init.uOY, a * math.sin(th) * thd])
    qpos, qvel = initial_qpos_qvel(tm, init)
    # qpos[0:3]: the body origin, which is the sphere's centre, R above the table;
    # qpos[3:7]: the world quaternion (w, x, y, z)
    np.testing.assert_allclose(qpos[0:3], com + a * k, rtol=0, atol=1e-17)
    assert qpos[2] == pytest.approx(R, rel=1e-15)
    q = qpos[3:7] * np.sign(qpos[3])
    np.testing.assert_allclose(q, [math.cos(th / 2), 0.0, math.sin(th / 2), 0.0], atol=1e-15)
    # qvel[0:3]: world velocity of the body origin; qvel[3:6]: body-frame angular velocity,
    # turned to the world by MuJoCo's own quaternion convention
    scale = 1.0 + abs(n) + abs(Om)
    np.testing.assert_allclose(qvel[0:3], v_com + np.cross(omega, a * k), rtol=0,
                               atol=1e-15 * scale)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, qpos[3:7])
    np.testing.assert_allclose(rot.reshape(3, 3) @ qvel[3:6], omega, rtol=0,
                               atol=1e-13 * scale)


@pytest.mark.parametrize("init", STATES)
@pytest.mark.parametrize("xml", ["generated", "generic"])
def test_map_and_back_recovers_initial_state(init: InitialState, xml: str) -> None:
    tm = load_top(make_mjcf(TOP)) if xml == "generated" else _load_generic()
    assert tm.top.a_m == pytest.approx(TOP.a_m, rel=1e-12)
    qpos, qvel = initial_qpos_qvel(tm, init)
    back = initial_state_from_qpos_qvel(tm, qpos, qvel)
    for name in FIELDS:
        # 1e-12 relative to the rate scale |n0| + |Omega0| (rounding of the rotations).
        scale = max(1.0, abs(init.n0) + abs(init.Omega0)) if name != "theta0" else 1.0
        assert getattr(back, name) == pytest.approx(getattr(init, name), abs=1e-12 * scale), name


def test_map_through_mujoco_kinematics() -> None:
    # MuJoCo's own forward kinematics puts the ball geom and the centre of mass where the map
    # says (for the generic top, whose body origin is the centre of mass).
    tm = _load_generic()
    init = STATES[1]
    data = mujoco.MjData(tm.model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, init)
    mujoco.mj_forward(tm.model, data)
    rigid = initial_rigid_state(TOP, init)
    np.testing.assert_allclose(data.geom_xpos[tm.ball_geom_id], rigid.sphere_centre_m(TOP),
                               atol=1e-15)
    np.testing.assert_allclose(data.xipos[tm.body_id], rigid.com_m, atol=1e-15)
    kin = kinematics(tm, data.qpos, data.qvel)
    np.testing.assert_allclose(kin.omega_radps[0], rigid.omega_radps, atol=1e-12)
    np.testing.assert_allclose(kin.v_com_mps[0], rigid.v_com_mps, atol=1e-15)
    # The contact point's height velocity vanishes (v_PZ = 0, paper eq. 2.10).
    assert abs(kin.v_P_mps[0, 2]) < 1e-15


def test_vertical_axis() -> None:
    tm = load_top(make_mjcf(TOP))
    qpos, qvel = initial_qpos_qvel(tm, InitialState(theta0=0.0, thetadot0=0.5, n0=50.0))
    ang = paper_angles(kinematics(tm, qpos, qvel))
    assert ang["theta"][0] == 0.0 and ang["n"][0] == pytest.approx(50.0)
    assert math.isnan(ang["Omega"][0])
    assert ang["theta_dot"][0] == pytest.approx(0.5)  # leaving the pole
    # Upright, the paper's frame is the one the axis starts to tilt in (the initial state's
    # phi = 0 frame), Omega0 = 0: the map back gives the state it came from (round-off only)
    back = initial_state_from_qpos_qvel(tm, qpos, qvel)
    assert (back.theta0, back.Omega0) == (0.0, 0.0)
    assert (back.thetadot0, back.n0) == (pytest.approx(0.5, rel=1e-14), pytest.approx(50.0,
                                                                                   rel=1e-14))
    assert abs(back.uOX) < 1e-15 and abs(back.uOY) < 1e-15
