"""roll-resistance: the rolling law's closed form, and MuJoCo's condim-6 rolling ball on it.

- The closed form a = mu_r g / (R (1 + k)) = 5/7 mu_r g / R is checked against scipy's
  solve_ivp of the ball's translation and spin (a stiff no-slip tangential force, a steeply
  smoothed Coulomb rolling torque), and the probe's measure() is fed that solution.
- The cones' share of the rolling torque is checked against the cones themselves: the
  pyramid's edges n +- mu_i e_i (scipy's linprog) and the ellipse (a root of its boundary).
- RK4 at 1 ms and MuJoCo's default (Euler at 2 ms) meet the law with the elliptic cone; the
  pyramidal cone falls short of it (MuJoCo's, measured: 0.94 of the pyramid's law).
- Euler at 20 ms must not (the tangential friction no longer holds the ball rolling), nor may
  a ball rolled below the soft friction's relaxation (v0 = 0.3 m/s).
- Slow: the default on MuJoCo 3.10.0 through the worker.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, linprog

from tippetop.compare.probes import probe_class
from tippetop.compare.probes.roll_resistance import RollResistance
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner.probe_run import ProbeRequest, ProbeTrace, run_here, run_in

ELLIPTIC, PYRAMIDAL = "condim6-elliptic", "condim6-pyramidal"


def _request(probe: RollResistance, mode: str, integrator: str | None = None,
             timestep_s: float | None = None) -> ProbeRequest:
    s = probe.setup(mode)
    return ProbeRequest(s.mjcf, s.body, s.qpos, s.qvel, s.duration_s,
                        integrator or s.integrator, timestep_s or s.timestep_s)


def _reference(probe: RollResistance, torque_N_m: float, dt: float = 0.002) -> ProbeTrace:
    """M dv/dt = F, I dw/dt = -F R - T tanh(w / 1e-3), F = -(M / 1e-5 s)(v - R w): Radau at
    rtol 1e-11 on a 2 ms grid (the slip settles at a * 1e-5 s ~ 4e-6 m/s in ~1e-5 s)."""
    s = probe.setup(ELLIPTIC)
    M, R = probe.p("M"), probe.p("R")
    inertia = probe.k() * M * R * R
    stiff = M / 1e-5

    def rhs(_t, y):
        v, w = y
        F = -stiff * (v - R * w)
        return [F / M, (-F * R - torque_N_m * np.tanh(w / 1e-3)) / inertia]

    t = np.linspace(0.0, s.duration_s, int(round(s.duration_s / dt)) + 1)
    sol = solve_ivp(rhs, (0.0, s.duration_s), [s.qvel[0], s.qvel[4]], method="Radau",
                    t_eval=t, rtol=1e-11, atol=1e-12)
    assert sol.success
    n = len(t)
    qpos = np.tile(np.array(s.qpos), (n, 1))
    qvel = np.zeros((n, 6))
    qvel[:, 0], qvel[:, 4] = sol.y
    return ProbeTrace(time=t, qpos=qpos, qvel=qvel, ncon=np.ones(n, dtype=int),
                      normal_N=np.full(n, M * probe.p("g")),
                      warnings=np.zeros((n, 8), dtype=int), ran={"integrator": "Radau"},
                      engine={"implementation": "scipy"})


def _one(measured):
    assert len(measured) == 1
    return measured[0]


def _window_slope(trace: ProbeTrace, v0: float) -> float:
    v = trace.qvel[:, 0]
    sel = (v <= 0.8 * v0) & (v >= 0.2 * v0)
    return -float(np.polyfit(trace.time[sel], v[sel], 1)[0])


def test_registered_under_its_name() -> None:
    assert probe_class("roll-resistance") is RollResistance


def test_closed_form_matches_the_rolling_ode_integrated() -> None:
    """With T = mu_r M g the integrated ball decelerates at 5/7 mu_r g / R = 0.350357 m/s^2
    (the law without the cone's share) to 1e-6 relative: the slip's lag (~4e-6 m/s, constant
    once settled) does not change the slope, and Radau at rtol 1e-11 is good to ~1e-9."""
    probe = RollResistance()
    law = 5.0 / 7.0 * probe.p("mu_r") * probe.p("g") / probe.p("R")
    assert probe.k() == pytest.approx(0.4, rel=1e-12)
    for mode in RollResistance.modes:
        assert probe.decel(mode) / probe.cone_share(mode) == pytest.approx(law, rel=1e-12)
    ref = _reference(probe, probe.p("mu_r") * probe.p("M") * probe.p("g"))
    assert _window_slope(ref, probe.p("v0")) == pytest.approx(law, rel=1e-6)
    slip = ref.qvel[:, 0] - probe.p("R") * ref.qvel[:, 4]
    assert np.max(np.abs(slip)) < 1e-5


def test_cone_share_is_the_cones_own() -> None:
    """The largest rolling torque T with the tangential force F = T / (R (1 + k)) that keeps
    the ball rolling, over mu_r N, found from each cone as MuJoCo documents it, to 1e-9:
    the pyramid as the convex hull of its 10 edges n +- mu_i e_i (a linear program over the
    edges' weights), the ellipse as the root of (F / mu)^2 + (T / mu_r)^2 = N^2."""
    probe = RollResistance()
    mu, mu_r, R, k = probe.p("mu"), probe.p("mu_r"), probe.p("R"), probe.k()
    c = 1.0 / (R * (1.0 + k))  # F = c T
    N = 1.0
    # edges' components: (normal, t1, t2, torsion, roll1, roll2), weights w >= 0
    coeffs = [mu, mu, 0.005, mu_r, mu_r]
    edges = []
    for i, m in enumerate(coeffs):
        for sign in (1.0, -1.0):
            e = np.zeros(6)
            e[0], e[1 + i] = 1.0, sign * m
            edges.append(e)
    E = np.array(edges).T  # 6 x 10
    # maximise roll2 (about the axis the ball rolls on) with t1 = c * roll2, the rest zero
    a_eq = np.vstack([E[0], E[1] - c * E[5], E[2], E[3], E[4]])
    b_eq = np.array([N, 0.0, 0.0, 0.0, 0.0])
    lp = linprog(-E[5], A_eq=a_eq, b_eq=b_eq, bounds=[(0, None)] * 10, method="highs")
    assert lp.status == 0
    pyramid = float(E[5] @ lp.x) / (mu_r * N)
    assert probe.cone_share(PYRAMIDAL) == pytest.approx(pyramid, abs=1e-9)
    ellipse = brentq(lambda T: (c * T / mu) ** 2 + (T / mu_r) ** 2 - N * N, 0.0, mu_r * N,
                     xtol=1e-15) / (mu_r * N)
    assert probe.cone_share(ELLIPTIC) == pytest.approx(ellipse, abs=1e-9)
    # the defaults' figures the docstring states
    assert probe.cone_share(ELLIPTIC) == pytest.approx(0.99936, abs=1e-5)
    assert probe.cone_share(PYRAMIDAL) == pytest.approx(0.96552, abs=1e-5)


def test_measure_reads_the_exact_rolling_as_exact() -> None:
    """Fed the ball integrated under the cone's own torque, each mode reads its deceleration
    as exact to 1e-6 of it (3.5e-7 m/s^2, four decades below the 3.5e-3 tolerance)."""
    probe = RollResistance()
    for mode in RollResistance.modes:
        torque = probe.cone_share(mode) * probe.p("mu_r") * probe.p("M") * probe.p("g")
        m = _one(probe.measure(mode, _reference(probe, torque)))
        assert m.quantity.name == "roll_decel_mps2"
        assert abs(m.error) < 1e-6 * m.exact and m.passed and m.note == "", m
        curve = probe.curve(mode, _reference(probe, torque))
        rolling = curve.exact > 0.01
        assert np.max(np.abs(curve.value[rolling] - curve.exact[rolling])) < 1e-5


def test_rk4_at_a_small_step_meets_the_elliptic_law_and_not_the_pyramids() -> None:
    """RK4 at 1 ms: the elliptic cone meets its law (measured +0.06 %); the pyramidal cone
    MUST fall short of even the pyramid's share, 0.966 of the law (measured 0.94 of it): its
    rolling torque relaxes from ~1 m/s and the ball slips by centimetres per second. A
    release that fixes that fails this test, which is the point: it would have moved."""
    probe = RollResistance()
    m = _one(probe.measure(ELLIPTIC, run_here(_request(probe, ELLIPTIC, "RK4", 0.001))))
    assert m.passed, m
    trace = run_here(_request(probe, PYRAMIDAL, "RK4", 0.001))
    m = _one(probe.measure(PYRAMIDAL, trace))
    assert not m.passed and m.value < 0.97 * m.exact, m
    slip = trace.qvel[:, 0] - probe.p("R") * trace.qvel[:, 4]
    assert np.max(np.abs(slip)) > 0.01


def test_default_meets_the_elliptic_law() -> None:
    """MuJoCo's default, Euler at 2 ms: the elliptic cone within 1 % (measured +0.1 %); the
    pyramidal cone short of it as at RK4 (the same model: the step is not the cause)."""
    probe = RollResistance()
    s = probe.setup(ELLIPTIC)
    assert (s.integrator, s.timestep_s) == ("Euler", 0.002)
    assert _one(probe.measure(ELLIPTIC, run_here(_request(probe, ELLIPTIC)))).passed
    m = _one(probe.measure(PYRAMIDAL, run_here(_request(probe, PYRAMIDAL))))
    assert not m.passed and m.value < 0.97 * m.exact, m


def test_euler_at_a_large_step_fails_the_law() -> None:
    """Euler at 20 ms MUST fail the elliptic law: the step is the friction's time constant
    (MuJoCo raises it to 2 h), so the tangential friction no longer keeps the ball rolling
    (it slips at ~0.1 m/s against ~2 mm/s at 2 ms) and the deceleration is no longer the
    rolling torque's (measured +3 %)."""
    probe = RollResistance()
    trace = run_here(_request(probe, ELLIPTIC, "Euler", 0.02))
    m = _one(probe.measure(ELLIPTIC, trace))
    assert not m.passed, m
    slip = trace.qvel[:, 0] - probe.p("R") * trace.qvel[:, 4]
    assert np.max(np.abs(slip)) > 0.05


def test_a_ball_rolled_below_the_relaxation_fails_the_law() -> None:
    """v0 = 0.3 m/s MUST fail: the window (0.24 to 0.06 m/s) is below the 0.1-0.2 m/s under
    which MuJoCo's soft rolling friction is viscous, not mu_r N (measured 0.71 of the law
    elliptic, 0.34 pyramidal)."""
    probe = RollResistance(values={"v0": 0.3})
    for mode in RollResistance.modes:
        m = _one(probe.measure(mode, run_here(_request(probe, mode))))
        assert not m.passed and m.value < 0.8 * m.exact, (mode, m)


@pytest.mark.parametrize("key, value", [("mu_r", 0.0), ("v0", -1.0), ("M", math.inf)])
def test_a_bad_parameter_is_one_line(key: str, value: float) -> None:
    with pytest.raises(TippetopError) as err:
        RollResistance(values={key: value}).setup(ELLIPTIC)
    text = str(err.value)
    assert "\n" not in text and f"roll-resistance.{key}: expected" in text
    assert repr(value) in text


def test_an_unknown_mode_is_one_line() -> None:
    with pytest.raises(TippetopError) as err:
        RollResistance().setup("condim6-eliptic")
    text = str(err.value)
    assert "\n" not in text and ELLIPTIC in text and "did you mean" in text


def _release_python(version: str) -> Path | None:
    from tippetop.mujoco_runner.envs import envs_root, ready_python

    for root in (envs_root(), Path.home() / ".cache" / "tippetop" / "envs"):
        python = ready_python(version, root)
        if python is not None:
            return python
    return None


@pytest.mark.slow
def test_default_on_3_10_matches_the_installed_release() -> None:
    """MuJoCo 3.10.0 through the worker, its default: the elliptic law met, the pyramid short
    of it, each value the installed release's to 1e-4 relative: the same model and solver,
    but the two builds round differently and the ball's chatter (contacts made and lost)
    carries that over 3,400 steps (measured 1e-6); 1e-4 is 1 % of the tolerance."""
    python = _release_python("3.10.0")
    if python is None:
        pytest.skip("no managed environment for mujoco==3.10.0")
    probe = RollResistance()
    for mode in RollResistance.modes:
        there = _one(probe.measure(mode, run_in(str(python), _request(probe, mode))))
        here = _one(probe.measure(mode, run_here(_request(probe, mode))))
        assert there.passed == (mode == ELLIPTIC), (mode, there)
        assert there.value == pytest.approx(here.value, rel=1e-4)
