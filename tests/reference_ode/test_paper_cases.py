"""The paper's simulated cases reproduced by the default (vector) formulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.conftest import run_scene_ode
from tippetop.compare.measures import theory
from tippetop.compare.measures.series import classify_outcome, theta_asymp
from tippetop.models.scene import load_scene

# Fig. 11: theta_asymp printed in Sec. 4.4 for n0 = 30 ... 80 rad/s.
FIG11 = {30: 0.0, 40: 0.92, 50: 1.67, 60: 2.49, 70: math.pi, 80: math.pi}
# The paper prints two decimals (+-0.005) and says the runs reach these within about 60 s;
# the residual nutation near pi (n0 = 70, 80) and the slow approach near n1 and n4 (n0 = 40,
# 60) leave a few 1e-3 rad in the 60-s runs' last 10 %: measured at most 2.7e-3 against the
# printed values (n0 = 70) and 3.9e-3 against the theory's theta_s for each run's own Jellett
# constant (n0 = 60). 0.005 + 0.005.
FIG11_TOL = 0.01


@pytest.mark.parametrize("n0", sorted(FIG11))
def test_fig11_theta_asymp(n0: int) -> None:
    res = run_scene_ode(f"fig11_n0{n0}")
    assert res.status == "ok"
    assert theta_asymp(res.table) == pytest.approx(FIG11[n0], abs=FIG11_TOL)


def test_fig11_inversion_time_shrinks_with_spin() -> None:
    """Sec. 4.4: the larger n0, the faster the rise. t_invert exists only where theta > pi/2."""
    times = {n0: run_scene_ode(f"fig11_n0{n0}").t_invert for n0 in FIG11}
    assert times[30] is None and times[40] is None
    assert times[50] > times[60] > times[70] > times[80] > 0


def test_group_one_stays_upright() -> None:
    """Fig. 7 (a): Group I, n0 = 100: theta = 0 is stable for any spin (eq. 4.12).

    Started at theta0 = 0.1 < theta_c = 0.84 with theta_dot0 = Omega0 = 0, the start is the top
    of the first nutation and v~_PY < 0 only lowers the later ones: theta never exceeds theta0
    (measured: the maximum is theta0 itself; bound 1e-6 rad), and the tilt decays: theta_asymp
    at 12 s is 0.030, bound half the start.
    """
    s = load_scene("fig7a")
    assert theory.group(s.top) == "I" and s.init.theta0 < theory.theta_c(s.top)
    t = run_scene_ode("fig7a").table
    assert t["theta"].max() <= s.init.theta0 + 1e-6
    assert theta_asymp(t) < 0.5 * s.init.theta0


def test_group_three_settles_at_theta_s_below_theta_f() -> None:
    """Fig. 8 (a): Group III rises to the intermediate steady state, below theta_f.

    The theory's theta_s is evaluated for the run's own Jellett constant (theta0 = 0.1, not 0:
    n_equiv = J0 / (C (R - a))). Tolerance as for Fig. 11 (measured 4.0e-4 rad at 60 s).
    """
    s = load_scene("fig8a")
    top = s.top
    res = run_scene_ode("fig8a")
    J0 = float(res.table["J"].iloc[0])
    n_equiv = J0 / (top.C_kgm2 * (top.R_m - top.a_m))
    expected = theory.theta_s(top, n_equiv)
    got = theta_asymp(res.table)
    assert got == pytest.approx(expected, abs=FIG11_TOL)
    assert got < theory.theta_f(top)
    assert res.t_invert is not None  # it does pass pi/2 (theta_s = 1.87 > pi/2)


@pytest.mark.parametrize("name", ["fig6", "fig7b", "fig8b", "fig11_n030"])
def test_below_n1_stays_upright(name: str) -> None:
    """Figs. 6, 7 (b), 8 (b) and Fig. 11 at 30 rad/s: n0 < n1 (or Group I): stays upright.

    As for Fig. 7 (a): theta never exceeds its start (measured: the maximum is theta0; bound
    1e-6 rad) and the tilt decays to less than half of it (theta_asymp / theta0 measured 0.31,
    0.27, 0.10 and 0.04).
    """
    s = load_scene(name)
    n1 = theory.n1(s.top)
    assert n1 is None or s.init.n0 < n1
    t = run_scene_ode(name).table
    assert t["theta"].max() <= s.init.theta0 + 1e-6
    assert theta_asymp(t) < 0.5 * s.init.theta0


@pytest.mark.parametrize("name", ["fig3", "fig4"])
def test_fig3_fig4_invert(name: str) -> None:
    """Figs. 3 and 4: the Group II top at n0 = 100 > n_c turns over (theta_s = pi). The
    inversion time and the final angle against the paper's own equations (the paper
    formulation) for the same scene, to 1e-8 (s, rad): measured 9.9e-10 s and 6.6e-10 rad
    (fig3), 3.4e-9 s and 4.8e-10 rad (fig4) at the scenes' rtol 1e-9."""
    s = load_scene(name)
    assert s.init.n0 > theory.n_c(s.top) and theory.theta_s(s.top, s.init.n0) == math.pi
    res = run_scene_ode(name)
    paper = run_scene_ode(name, "ode.formulation=paper")
    assert res.status == paper.status == "ok"
    assert res.t_invert is not None
    assert abs(res.t_invert - paper.t_invert) < 1e-8
    assert abs(res.table["theta"].iloc[-1] - paper.table["theta"].iloc[-1]) < 1e-8


def test_fig3_xi_reaches_the_xi_minus_curve() -> None:
    """Sec. 3.3: once the top rises, xi fluctuates about xi_minus (|xi/xi0| << 1).

    Between theta = 1 and 2.5 rad the mean of xi / xi0 is within 0.02 of the mean of
    xi_minus / xi0 (xi_minus / xi0 is about -0.002 here), and far from the start value 1.
    """
    t = run_scene_ode("fig3").table
    xi0 = float(t["xi"].dropna().iloc[0])
    mid = t[(t["theta"] > 1.0) & (t["theta"] < 2.5)]
    assert len(mid) > 100
    assert abs(np.mean(mid["xi"] / xi0) - np.mean(mid["xi_minus"] / xi0)) < 0.02


@pytest.mark.parametrize("name", ["fig3", "fig4", "fig6", "fig7a", "fig7b", "fig8a", "fig8b",
                                  *[f"fig11_n0{n}" for n in FIG11]])
def test_outcome_matches_the_scene_and_the_theory(name: str) -> None:
    """Each catalogue scene's final state is the one the paper reports (its ``expect.outcome``)
    and the one the theory predicts from theta_s, classified the same way."""
    from tippetop.compare.measures.series import outcome_of_angle

    s = load_scene(name)
    got = classify_outcome(run_scene_ode(name).table)
    assert got == s.expect["outcome"]
    assert outcome_of_angle(theory.theta_s(s.top, s.init.n0)) == got


def _group_one_outcome(theta0: float, Omega0: float) -> str:
    """The Fig. 7 (Group I) top started spinning about the vertical (psi_dot0 = 0: n0 =
    Omega0 cos theta0), 20 s of the reference."""
    res = run_scene_ode("fig7a", "run.t_end_s=20", f"init.theta0={theta0!r}",
                        f"init.Omega0={Omega0!r}", f"init.n0={Omega0 * math.cos(theta0)!r}")
    assert res.status == "ok"
    return classify_outcome(res.table)


@pytest.mark.parametrize("Omega0", [100.0, 200.0])
def test_group_one_theta_c_separates_upright_from_inverted(Omega0: float) -> None:
    """Sec. 3.2 (i): a Group I top spun with psi_dot0 ~ 0 and a large Omega0 turns over if
    theta0 > theta_c (0.841 rad here, ThetaCritical) and returns to the vertical if
    theta0 < theta_c, the sign of v~_PY.

    Measured (bisection on theta0, 20 s runs): the separatrix lies above theta_c, by 0.221 rad
    at Omega0 = 100 rad/s and 0.119 at 200 (0.110 at 300; beyond about 400 rad/s the top
    leaves the table at once): the argument neglects u_OY, and the claim holds with a margin
    that shrinks as Omega0 grows. So: every start below theta_c (by 0.03 and 0.3 rad) stays
    upright; theta_c + 0.3 turns over; and theta_c + 0.03 still stays upright at these spins.
    """
    tc = theory.theta_c(load_scene("fig7a").top)
    for theta0 in (tc - 0.3, tc - 0.03, tc + 0.03):
        assert _group_one_outcome(theta0, Omega0) == "upright", theta0 - tc
    assert _group_one_outcome(tc + 0.3, Omega0) == "inverted"


def test_group_one_separatrix_approaches_theta_c_as_Omega0_grows() -> None:
    """The separatrix of the previous test, located by bisection to 0.005 rad: above theta_c
    at both spins, and closer to it at Omega0 = 200 than at 100 rad/s (measured theta_c +
    0.221 and + 0.119): the paper's 'sufficiently large Omega0'."""
    tc = theory.theta_c(load_scene("fig7a").top)

    def separatrix(Omega0: float) -> float:
        lo, hi = tc - 0.3, tc + 0.6
        while hi - lo > 0.005:
            mid = 0.5 * (lo + hi)
            if _group_one_outcome(mid, Omega0) == "inverted":
                hi = mid
            else:
                lo = mid
        return 0.5 * (lo + hi)

    at_100, at_200 = separatrix(100.0), separatrix(200.0)
    assert tc < at_200 < at_100
