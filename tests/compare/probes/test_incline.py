"""incline: Coulomb's closed forms on a slope, and MuJoCo's creep measured against them.

- The closed forms (the box stays below the friction angle and slides at g (sin - mu cos)
  above it; the ball rolls at 5/7 g sin with no slip at its contact) are checked against
  scipy's solve_ivp of Newton's equations with a tanh-smoothed Coulomb friction, whose creep
  is proportional to its smoothing speed (so 0 in Coulomb's limit), and the probe's own
  measure() is fed that solution: it must read every quantity within its tolerance.
- The frames the probe relies on: its ball slip is MuJoCo's own contact velocity (the
  contact's rows of efc_J times qvel), for a ball turned and spun every way.
- MuJoCo's creep is the docstring's v = F / (b sum D_f) (elliptic), falls as 1/impratio, and is
  the contact model's, not the step's.
- RK4 at 0.5 ms meets every quantity of the noslip (elliptic) and slide modes; the default
  elliptic cone must not meet the creep (MuJoCo's friction has no stick state); the pyramidal
  cone's noslip holds the ball but not the box; a fast slide hops.
- Slow: every mode on MuJoCo 2.3.7 and 3.10.0 through the worker: the same creep.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tippetop.compare.probes import probe_class
from tippetop.compare.probes.base import sphere_inertia
from tippetop.compare.probes.incline import CREEP_TOL_UMPS, SETTLE_S, WINDOW_S, Incline, _rotate
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner.probe_run import ProbeRequest, ProbeTrace, run_here, run_in


def _request(probe: Incline, mode: str, integrator: str | None = None,
             timestep_s: float | None = None) -> ProbeRequest:
    s = probe.setup(mode)
    return ProbeRequest(s.mjcf, s.body, s.qpos, s.qvel, s.duration_s,
                        integrator or s.integrator, timestep_s or s.timestep_s)


@functools.cache
def _run(mode: str, integrator: str | None = None, timestep_s: float | None = None,
         **values: float) -> ProbeTrace:
    return run_here(_request(Incline(values=dict(values)), mode, integrator, timestep_s))


def _measured(mode: str, integrator: str | None = None, timestep_s: float | None = None,
              **values: float) -> dict:
    probe = Incline(values=dict(values))
    trace = _run(mode, integrator, timestep_s, **values)
    return {m.quantity.name: m for m in probe.measure(mode, trace)}


def test_registered_under_its_name() -> None:
    assert probe_class("incline") is Incline


# --- the closed forms against Newton's equations with a smoothed Coulomb friction ----------

def _coulomb_trace(probe: Incline, mode: str, eps: float, dt: float = 0.002) -> ProbeTrace:
    """Newton's equations on the slope, friction mu N tanh(slip / eps), by Radau at rtol 1e-10.

    The box: x'' = g sin a - mu g cos a tanh(x' / eps). The ball (I = 2/5 M R^2 from
    sphere_inertia, not from the 5/7 of the closed form): M v' = M g sin a - F,
    I w' = F R, F = mu M g cos a tanh((v - R w) / eps). Written out as the probe's trace: the
    box flat at z = H, the ball at z = R turning about y.
    """
    g, mu, R, M = probe.p("g"), probe.p("mu"), probe.p("R"), probe.p("M")
    a = probe.slope(mode)
    inertia = sphere_inertia(M, R)
    n_max = mu * g * math.cos(a)  # the friction's limit per unit mass

    def rhs(_t, y):
        xb, vb, xs, vs, th, w = y
        f_box = n_max * math.tanh(vb / eps)
        f_ball = M * n_max * math.tanh((vs - R * w) / eps)
        return [vb, g * math.sin(a) - f_box, vs, g * math.sin(a) - f_ball / M, w,
                f_ball * R / inertia]

    duration = probe.setup(mode).duration_s
    t = np.linspace(0.0, duration, int(round(duration / dt)) + 1)
    sol = solve_ivp(rhs, (0.0, duration), [0.0] * 6, method="Radau", t_eval=t, rtol=1e-10,
                    atol=1e-13)
    assert sol.success
    xb, vb, xs, vs, th, w = sol.y
    n = len(t)
    H, y_ball = probe.p("H"), 3.0 * (probe.p("H") + R)
    qpos = np.zeros((n, 14))
    qpos[:, 0], qpos[:, 2], qpos[:, 3] = xb, H, 1.0
    qpos[:, 7], qpos[:, 8], qpos[:, 9] = xs, y_ball, R
    qpos[:, 10], qpos[:, 12] = np.cos(th / 2), np.sin(th / 2)  # a turn th about y
    qvel = np.zeros((n, 12))
    qvel[:, 0], qvel[:, 6], qvel[:, 10] = vb, vs, w
    return ProbeTrace(time=t, qpos=qpos, qvel=qvel, ncon=np.full(n, 4), normal_N=np.zeros(n),
                      warnings=np.zeros((n, 8), dtype=int), ran={"integrator": "Radau"},
                      engine={"implementation": "scipy"})


@pytest.mark.parametrize("mode", ["elliptic", "slide-elliptic"])
def test_closed_forms_match_newtons_equations_integrated(mode: str) -> None:
    """The accelerations to 1e-6 m/s^2 (Radau at rtol 1e-10; the line fit of an exactly linear
    speed); the creeps are what the smoothed law's steady slip is, eps atanh(load / limit):
    proportional to eps, so 0 in Coulomb's limit; the probe's measure() passes every quantity."""
    probe = Incline()
    a, mu = probe.slope(mode), probe.p("mu")
    for eps in (1e-6, 1e-7):
        trace = _coulomb_trace(probe, mode, eps)
        m = {x.quantity.name: x for x in probe.measure(mode, trace)}
        assert m["ball_roll_accel_mps2"].value == pytest.approx(probe.roll_accel(mode), abs=1e-6)
        if mode.startswith("slide"):
            assert m["slide_accel_mps2"].value == pytest.approx(probe.slide_accel(mode),
                                                                abs=1e-6)
        else:  # the load / limit: the box's tan a / mu, the ball's 2/7 tan a / mu
            creep = 1e6 * eps * math.atanh(math.tan(a) / mu)
            assert m["box_creep_umps"].value == pytest.approx(creep, rel=1e-4)
            creep = 1e6 * eps * math.atanh(2.0 / 7.0 * math.tan(a) / mu)
            assert m["ball_creep_umps"].value == pytest.approx(creep, rel=1e-4)
        for x in m.values():
            assert x.passed, x


def test_slide_accel_special_cases() -> None:
    """At the friction angle the box does not accelerate; frictionless it takes g sin a."""
    probe = Incline()
    at = Incline(values={"alpha_slide": math.atan(probe.p("mu"))})
    assert at.slide_accel("slide-elliptic") == pytest.approx(0.0, abs=1e-12)
    slick = Incline(values={"mu": 1e-300})
    a = probe.p("alpha_slide")
    assert slick.slide_accel("slide-elliptic") == pytest.approx(probe.p("g") * math.sin(a),
                                                                rel=1e-12)


# --- the probe's frames against MuJoCo's own ----------------------------------------------

def test_rotate_is_mujocos_quaternion_rotation() -> None:
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    v = rng.normal(size=(20, 3))
    ours = _rotate(q, v)
    for i in range(20):
        theirs = np.zeros(3)
        mujoco.mju_rotVecQuat(theirs, v[i], q[i])
        np.testing.assert_allclose(ours[i], theirs, atol=1e-14)


def test_ball_slip_is_mujocos_contact_velocity() -> None:
    """The ball turned and spinning every way, 0.3 mm into the table: the probe's slip is the
    contact's tangential velocity from efc_J qvel (elliptic rows: the contact frame's) to
    1e-12 m/s, so the lever (R + z) / 2 and the free joint's body-frame spin are MuJoCo's."""
    probe = Incline()
    mode = "elliptic"
    s = probe.setup(mode)
    model = mujoco.MjModel.from_xml_string(s.mjcf)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    qpos = np.array(s.qpos)
    quat = rng.normal(size=4)
    qpos[10:14] = quat / np.linalg.norm(quat)
    qpos[9] = probe.p("R") - 3e-4
    qvel = np.zeros(12)
    qvel[6:12] = rng.normal(size=6)
    qvel[8] = 0.0  # no normal velocity
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    ball = model.body("ball").id
    (i,) = [i for i in range(data.ncon)
            if ball in (model.geom_bodyid[data.contact[i].geom1],
                        model.geom_bodyid[data.contact[i].geom2])]
    adr = data.contact[i].efc_address
    jac = data.efc_J.reshape(data.nefc, model.nv)[adr + 1:adr + 3]
    theirs = jac @ qvel
    trace = ProbeTrace(time=np.zeros(1), qpos=qpos[None], qvel=qvel[None],
                       ncon=np.zeros(1, dtype=int), normal_N=np.zeros(1),
                       warnings=np.zeros((1, 8), dtype=int), ran={}, engine={})
    ours = probe.ball_slip(trace)[0]
    assert np.hypot(*ours) == pytest.approx(np.hypot(*theirs), abs=1e-12)


# --- MuJoCo's creep: its regularised friction, not the step --------------------------------

def test_elliptic_creep_is_mujocos_regularised_slip() -> None:
    """v = F / (b sum D_f) with F = M_box g sin a, b and D_f read from the settled state's
    efc_KBIP and efc_D: to 0.1 % (the window's mean holds the last of the settling, 2e-5)."""
    probe = Incline()
    trace = _run("elliptic")
    s = probe.setup("elliptic")
    model = mujoco.MjModel.from_xml_string(s.mjcf)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = trace.qpos[-1], trace.qvel[-1]
    mujoco.mj_forward(model, data)
    box = model.body("box").id
    d_sum, b = 0.0, set()
    for i in range(data.ncon):
        c = data.contact[i]
        if box in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            d_sum += data.efc_D[c.efc_address + 1]
            b.add(float(data.efc_KBIP[c.efc_address + 1, 1]))
    assert len(b) == 1 and d_sum > 0
    load = probe.p("M_box") * probe.p("g") * math.sin(probe.p("alpha"))
    predicted = 1e6 * load / (b.pop() * d_sum)
    assert _measured("elliptic")["box_creep_umps"].value == pytest.approx(predicted, rel=1e-3)


def test_elliptic_creep_falls_as_one_over_impratio() -> None:
    """impratio divides the friction rows' R exactly: the creep ratio is 10 to 0.1 %."""
    one, ten = _measured("elliptic"), _measured("elliptic-impratio10")
    for q in ("box_creep_umps", "ball_creep_umps"):
        assert one[q].value / ten[q].value == pytest.approx(10.0, rel=1e-3)


def test_must_meet_with_noslip_and_when_sliding() -> None:
    """RK4 at 0.5 ms: the elliptic cone with noslip holds both bodies (the creep is 0.01 um/s
    or less, against 16.7), and the slides meet a = g (sin - mu cos) and 5/7 g sin."""
    for mode in ("elliptic-noslip", "elliptic-impratio10-noslip", "slide-pyramidal",
                 "slide-elliptic"):
        for m in _measured(mode, "RK4", 0.0005).values():
            assert m.passed, (mode, m)


def test_must_not_meet_the_creep_without_noslip() -> None:
    """MuJoCo's friction has no stick state: at the defaults the elliptic cone holds the box's
    load at v = F / (b sum D_f), 508 um/s, 30x the tolerance, and a smaller step or a
    higher-order integrator does not change it (the contact model's, not the step's: RK4 at
    0.5 ms within 0.1 %)."""
    default = _measured("elliptic")
    rk4 = _measured("elliptic", "RK4", 0.0005)
    for q in ("box_creep_umps", "ball_creep_umps"):
        assert not default[q].passed
        assert default[q].value > 10 * CREEP_TOL_UMPS
        assert rk4[q].value == pytest.approx(default[q].value, rel=1e-3)
    assert default["ball_roll_accel_mps2"].passed  # the roll is right, creep and all


def test_pyramidal_noslip_holds_the_ball_not_the_box() -> None:
    """The docstring's finding: noslip with the pyramidal cone stops the ball's one contact
    (0.003 um/s) but the box on four walks down (463 um/s at the defaults)."""
    m = _measured("pyramidal-noslip")
    assert m["ball_creep_umps"].passed
    assert m["ball_creep_umps"].value < 0.1
    assert not m["box_creep_umps"].passed


def test_fast_slide_hops() -> None:
    """The docstring's limit: at alpha_slide = 0.61 rad the sliding box leaves the table (no
    contact at some rows after the settling, its centre over 1 mm above its rest)."""
    trace = _run("slide-elliptic", alpha_slide=0.61)
    after = trace.time >= SETTLE_S
    assert (trace.ncon[after] == 0).any()
    assert trace.qpos[after, 2].max() > Incline().p("H") + 1e-3


def test_defaults_run_every_mode_for_the_window() -> None:
    probe = Incline()
    for mode in probe.modes:
        assert probe.setup(mode).duration_s == pytest.approx(SETTLE_S + WINDOW_S)
    trace = _run("pyramidal")
    assert trace.ran["cone"] == "pyramidal" and trace.ran["noslip_iterations"] == 0
    trace = _run("elliptic-impratio10-noslip")
    assert trace.ran["cone"] == "elliptic" and trace.ran["impratio"] == pytest.approx(10.0)
    assert trace.ran["noslip_iterations"] == 10
    g = np.array(trace.ran["gravity_mps2"])
    assert math.atan2(g[0], -g[2]) == pytest.approx(probe.p("alpha"), abs=1e-12)


# --- bad input: one line ------------------------------------------------------------------

@pytest.mark.parametrize("values, says", [
    ({"alpha": 0.5}, "alpha below the friction angle"),
    ({"alpha_slide": 0.3}, "alpha_slide above the friction angle"),
    ({"alpha": 0.1, "alpha_slide": 0.78, "mu": 0.2}, "alpha_slide above the friction angle"),
    ({"mu": 0.0}, "mu > 0"),
    ({"R": -0.01}, "R > 0"),
    ({"g": math.nan}, "g > 0"),
])
def test_bad_parameters_are_one_line(values: dict, says: str) -> None:
    with pytest.raises(TippetopError) as err:
        Incline(values=values).setup("elliptic")
    assert says in str(err.value) and "\n" not in str(err.value)


def test_unknown_mode_is_one_line_with_a_suggestion() -> None:
    with pytest.raises(TippetopError, match="did you mean 'elliptic-noslip'"):
        Incline().setup("eliptic-noslip")


# --- slow: other releases -----------------------------------------------------------------

def _release_python(version: str) -> Path | None:
    from tippetop.mujoco_runner.envs import envs_root, ready_python

    for root in (envs_root(), Path.home() / ".cache" / "tippetop" / "envs"):
        python = ready_python(version, root)
        if python is not None:
            return python
    return None


@pytest.mark.slow
@pytest.mark.parametrize("version", ["2.3.7", "3.10.0"])
def test_other_releases_creep_the_same(version: str) -> None:
    """Every mode through the worker: each quantity as the installed MuJoCo's to 1e-4 relative
    (the docstring's "same digits" are 3; the releases' rounding differs at ~1e-6 in the
    pyramidal noslip walk and the noslip's 3e-5 um/s), so the same passes and failures."""
    python = _release_python(version)
    if python is None:
        pytest.skip(f"no managed environment for mujoco=={version}")
    probe = Incline()
    for mode in probe.modes:
        there = probe.measure(mode, run_in(str(python), _request(probe, mode)))
        here = _measured(mode)
        for m in there:
            assert m.value == pytest.approx(here[m.quantity.name].value, rel=1e-4), (mode, m)
            assert m.passed == here[m.quantity.name].passed
