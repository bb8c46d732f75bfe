"""The compiled passive callback that applies the paper's friction law."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tippetop.models.mjcf import make_mjcf
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.mujoco_runner.friction_callback import (
    PaperFriction,
    friction_xy,
    law_force,
    law_parameters,
)
from tippetop.mujoco_runner.model import TopModelWarning, load_top
from tippetop.mujoco_runner.state import initial_qpos_qvel, kinematics
from tippetop.reference_ode.friction import LAW_TERMS

TOP = TopParams.from_ratios(0.95, 0.125)
INIT = InitialState(theta0=0.4, thetadot0=1.0, Omega0=5.0, n0=100.0, uOX=0.02, uOY=-0.01)
FRICTION = FrictionParams()
_GENERIC = """<mujoco><option timestep="2e-5" integrator="RK4" gravity="0 0 -9.8"/>
  <worldbody><geom type="plane" size="1 1 .1" condim="1"/>
  <body pos="0 0 0.1"><freejoint/>
    <inertial pos="0 0 0" mass="0.015" diaginertia="1.2825e-6 1.35e-6 1.2825e-6"/>
    <geom type="sphere" size="0.015" pos="0 -0.001875 0" condim="1"/>
  </body></worldbody></mujoco>"""


@pytest.fixture(autouse=True)
def _no_leftover_callback():
    yield
    mujoco.set_mjcb_passive(None)


def _start(tm):
    data = mujoco.MjData(tm.model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(tm, INIT)
    return data


def _python_reference(tm, data, params):
    """The plain path: same law, N and P, applied with MuJoCo's own mj_applyFT."""
    top = tm.top

    def callback(model, d):
        if d._address != data._address:
            return
        kin = kinematics(tm, d.qpos, d.qvel)
        N = max(d.qfrc_constraint[tm.dof_adr + 2], 0.0)
        force = law_force(params, kin.v_P_mps, np.array([N]))[0]
        point = kin.centre_m[0] - [0.0, 0.0, top.R_m]
        mujoco.mj_applyFT(model, d, force, np.zeros(3), point, tm.body_id, d.qfrc_passive)

    return callback


@pytest.mark.parametrize("xml", ["generated", "generic"])
def test_compiled_callback_matches_mj_applyFT_reference(xml: str) -> None:
    # Same law, same N source, same point: the trajectories agree to rounding after 600
    # RK4 steps (2400 callback calls) through the tilted, spinning, sliding start.
    if xml == "generated":
        tm = load_top(make_mjcf(TOP))
    else:
        with pytest.warns(TopModelWarning, match="origin"):
            tm = load_top(_GENERIC)
    fast, slow = _start(tm), _start(tm)
    with PaperFriction(tm, fast, FRICTION):
        mujoco.mj_forward(tm.model, fast)
        mujoco.mj_step(tm.model, fast, 600)
    mujoco.set_mjcb_passive(_python_reference(tm, slow, law_parameters(FRICTION, tm)))
    mujoco.mj_forward(tm.model, slow)
    mujoco.mj_step(tm.model, slow, 600)
    mujoco.set_mjcb_passive(None)
    np.testing.assert_allclose(fast.qpos, slow.qpos, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(fast.qvel, slow.qvel, rtol=1e-10, atol=1e-12)
    assert np.abs(fast.qvel - _start(tm).qvel).max() > 1e-3  # friction did act


@pytest.mark.parametrize(("integrator", "calls_per_step"), [("RK4", 4), ("Euler", 1)])
def test_calls_per_step(integrator: str, calls_per_step: int) -> None:
    tm = load_top(make_mjcf(TOP, integrator=integrator))
    data = _start(tm)
    with PaperFriction(tm, data, FRICTION) as friction:
        mujoco.mj_step(tm.model, data, 100)
        assert friction.n_calls == calls_per_step * 100


def test_callback_acts_on_its_data_only_and_restores_previous() -> None:
    tm = load_top(make_mjcf(TOP))
    data, other = _start(tm), _start(tm)

    def previous(model, d):  # a user's callback, restored on exit
        d.qfrc_passive[0] += 0.0

    mujoco.set_mjcb_passive(previous)
    with PaperFriction(tm, data, FRICTION):
        mujoco.mj_step(tm.model, data, 200)  # into the contact: N > 0
        mujoco.mj_step(tm.model, other, 200)
        assert np.abs(data.qfrc_passive).max() > 0
        np.testing.assert_array_equal(other.qfrc_passive, 0.0)
        with pytest.raises(RuntimeError, match="already installed"):
            PaperFriction(tm, other, FRICTION).__enter__()
    assert mujoco.get_mjcb_passive() is previous
    mujoco.mj_forward(tm.model, data)
    np.testing.assert_array_equal(data.qfrc_passive, 0.0)


def test_normal_force_is_the_previous_evaluation_constraint_force() -> None:
    tm = load_top(make_mjcf(TOP, integrator="Euler"))
    data = _start(tm)
    with PaperFriction(tm, data, FRICTION) as friction:
        mujoco.mj_step(tm.model, data, 500)  # settle into the contact
        before = data.qfrc_constraint[tm.dof_adr + 2]
        mujoco.mj_step(tm.model, data)
        assert friction.last_force[2] == before
        assert before == pytest.approx(TOP.M_kg * TOP.g_mps2, rel=0.3)


def test_law_values() -> None:
    """The callback's law is the reference's: same terms, same numbers."""
    v = np.array([0.03, -0.04])  # |v| = 0.05 m/s
    N, mu, lam, c, eps = 0.147, 0.1, 0.01, 2.0, 1e-5

    def f(law: str, vx: float, vy: float) -> tuple[float, float]:
        ck, visc = LAW_TERMS[law]
        return friction_xy(vx, vy, N, ck, int(visc), mu, lam, c, eps)

    np.testing.assert_allclose(f("modified_coulomb", *v), -mu * N * v / np.sqrt(0.05**2 + lam**2),
                               rtol=1e-15)
    np.testing.assert_allclose(f("coulomb", *v), -mu * N * v / 0.05, rtol=1e-15)
    assert f("coulomb", 1e-6, 0.0)[0] == pytest.approx(-mu * N * 1e-6 / eps)  # the ramp
    np.testing.assert_allclose(f("viscous", *v), -c * v, rtol=1e-15)
    np.testing.assert_allclose(f("coulomb_viscous", *v), -mu * N * v / 0.05 - c * v, rtol=1e-14)
    assert f("none", *v) == (0.0, 0.0)


def test_every_reference_law_is_available() -> None:
    tm = load_top(make_mjcf(TOP))
    for law in LAW_TERMS:
        params = law_parameters(FrictionParams(law=law), tm)
        assert (params["coulomb_kind"], bool(params["viscous_on"])) == LAW_TERMS[law]
