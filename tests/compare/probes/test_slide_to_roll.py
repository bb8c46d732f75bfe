"""slide-to-roll: Coulomb's t = 2 v0 / (7 mu g) and 5 v0 / 7, and the paper's law's own ODE."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tippetop.compare.probes.slide_to_roll import SLIP_FRACTION, SlideToRoll
from tippetop.compare.probes.study import run_probes
from tippetop.models.engines import parse_engine

MUJOCO = [parse_engine("mujoco")]


def _ball(probe: SlideToRoll, law: str) -> object:
    """solve_ivp (DOP853, rtol 1e-12) of the ball's v and R w under ``law``, N = M g.

    Coulomb: friction mu M g while the ball slides (u > 0), to the event u = 0 (terminal).
    """
    mu, g, lam = probe.p("mu"), probe.p("g"), probe.p("Lambda")

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        u = y[0] - y[1]
        f = mu * g * (1.0 if law == "coulomb" else u / np.hypot(u, lam))
        return [-f, 2.5 * f]  # dv/dt = -F/M, R dw/dt = F R^2 / I = 5/2 F/M

    def rolls(_t: float, y: np.ndarray) -> float:
        return y[0] - y[1]

    rolls.terminal = True  # type: ignore[attr-defined]
    return solve_ivp(rhs, (0.0, 0.8), [probe.p("v0"), 0.0], method="DOP853", rtol=1e-12,
                     atol=1e-14, dense_output=True,
                     events=rolls if law == "coulomb" else None)


def test_coulombs_roll_time_and_speed_against_the_ball_integrated() -> None:
    # the sliding ball integrated to the event u = 0: its time and speed to 1e-10
    probe = SlideToRoll()
    sol = _ball(probe, "coulomb")
    t_roll = float(sol.t_events[0][0])
    assert t_roll == pytest.approx(probe.t_roll(), rel=1e-10)
    assert float(sol.y_events[0][0][0]) == pytest.approx(5 / 7 * probe.p("v0"), rel=1e-10)


def test_the_paper_laws_slip_against_its_ode_integrated() -> None:
    # the closed form P(u0) - P(u) = 7/2 mu g t against DOP853 at rtol 1e-12: 1e-9 relative
    probe = SlideToRoll()
    sol = _ball(probe, "paper")
    t = np.linspace(0.0, 0.8, 401)
    v, rw = sol.sol(t)
    # where the slip has decayed to ~1e-16 the integration is left with its own ~1e-11
    np.testing.assert_allclose(probe.paper_slip(t), v - rw, rtol=1e-8, atol=5e-11)
    u_end = SLIP_FRACTION * probe.p("v0")
    t_end = probe.paper_time(u_end)
    assert float(np.subtract(*sol.sol(t_end))) == pytest.approx(u_end, rel=1e-8)
    # v = 5 v0 / 7 + 2 u / 7 at every slip
    np.testing.assert_allclose(v, 5 / 7 * probe.p("v0") + 2 / 7 * (v - rw), rtol=1e-10)


def test_mujoco_meets_both_laws_at_a_small_rk4_step() -> None:
    res = run_probes(["slide-to-roll"], MUJOCO, integrator="RK4", timestep_s=0.0005,
                     use_cache=False)
    assert {r.mode for r in res.rows} == {"pyramidal", "elliptic", "paper"}
    assert all(r.passed for r in res.rows), [(r.mode, r.quantity, r.error) for r in res.rows]
    # the paper's law: only the integrator's error is left, O(dt) in the event's time
    paper = next(r for r in res.rows if r.mode == "paper" and r.quantity == "roll_time_s")
    assert abs(paper.error) < 1e-3


def test_euler_at_20_ms_misses_the_paper_laws_slide() -> None:
    # Euler's first-order error in the slip's decay: ~dt (20 ms) late, beyond 0.01 s
    res = run_probes(["slide-to-roll"], MUJOCO, modes=["paper"], integrator="Euler",
                     timestep_s=0.02, use_cache=False)
    late = next(r for r in res.rows if r.quantity == "roll_time_s")
    assert not late.passed and late.error > 0.01


def test_the_paper_mode_is_mujoco_cs_alone() -> None:
    # MJX and Warp have no Python passive callback: the worker refuses the law before it
    # imports them (here a worker of this interpreter), and the mode is a failed row, said
    import sys

    from tippetop.compare.probes.study import run_one

    run = run_one(SlideToRoll(), "paper", parse_engine("mjx"), integrator=None,
                  timestep_s=None, cache=None, python=sys.executable)
    assert run.rows and all(not r.passed and r.reason == "not run: the paper's law is MuJoCo "
                            "C's passive callback here, not mjx's" for r in run.rows)
