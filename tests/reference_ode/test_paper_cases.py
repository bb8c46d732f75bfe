"""The paper's simulated cases reproduced by the default (vector) formulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.conftest import run_scene_ode
from tippetop.compare import theory
from tippetop.compare.metrics import theta_asymp
from tippetop.models.scene import load_scene

# Fig. 11: theta_asymp printed in Sec. 4.4 for n0 = 30 ... 80 rad/s.
FIG11 = {30: 0.0, 40: 0.92, 50: 1.67, 60: 2.49, 70: math.pi, 80: math.pi}
# The tolerance. The paper prints two decimals (+-0.005) and says the runs reach these
# within about 60 s; the residual nutation and the slow approach near n1 and n4 (n0 = 40, 60)
# leave a few 1e-3 rad in the 60-s runs' last 10 %.
FIG11_TOL = 0.03


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

    Started at theta0 = 0.1, theta must never exceed that start by more than the nutation
    amplitude (< 0.05 rad here), and ends closer to 0 than it started.
    """
    s = load_scene("fig7a")
    assert theory.group(s.top) == "I"
    t = run_scene_ode("fig7a").table
    assert t["theta"].max() < s.init.theta0 + 0.05
    assert theta_asymp(t) < s.init.theta0


def test_group_three_settles_at_theta_s_below_theta_f() -> None:
    """Fig. 8 (a): Group III rises to the intermediate steady state, below theta_f.

    The theory's theta_s is evaluated for the run's own Jellett constant (theta0 = 0.1, not 0:
    n_equiv = J0 / (C (R - a))). Tolerance 0.03 rad as for Fig. 11.
    """
    s = load_scene("fig8a")
    top = s.top
    res = run_scene_ode("fig8a")
    J0 = float(res.table["J"].iloc[0])
    n_equiv = J0 / (top.C_kgm2 * (top.R_m - top.a_m))
    expected = theory.theta_s(top, n_equiv)
    got = theta_asymp(res.table)
    assert got == pytest.approx(expected, abs=0.03)
    assert got < theory.theta_f(top)
    assert res.t_invert is not None  # it does pass pi/2 (theta_s = 1.87 > pi/2)


@pytest.mark.parametrize("name", ["fig6", "fig7b", "fig8b", "fig11_n030"])
def test_below_n1_stays_upright(name: str) -> None:
    """Figs. 6, 7 (b), 8 (b) and Fig. 11 at 30 rad/s: n0 < n1 (or Group I): stays upright."""
    s = load_scene(name)
    n1 = theory.n1(s.top)
    assert n1 is None or s.init.n0 < n1
    t = run_scene_ode(name).table
    assert t["theta"].max() < max(s.init.theta0, 0.01) + 0.05
    assert theta_asymp(t) < 0.05


@pytest.mark.parametrize("name", ["fig3", "fig4"])
def test_fig3_fig4_invert(name: str) -> None:
    """Figs. 3 and 4: the Group II top at n0 = 100 > n_c turns over; by about 3 s (facts.md)."""
    res = run_scene_ode(name)
    assert res.t_invert is not None and res.t_invert < 4.0
    assert theta_asymp(res.table) > 3.0


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
    from tippetop.compare.metrics import classify_outcome, outcome_of_angle

    s = load_scene(name)
    got = classify_outcome(run_scene_ode(name).table)
    assert got == s.expect["outcome"]
    assert outcome_of_angle(theory.theta_s(s.top, s.init.n0)) == got
