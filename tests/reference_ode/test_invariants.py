"""Conservation and dissipation laws that any correct solution obeys."""

from __future__ import annotations

import numpy as np
import pytest

from tests.conftest import run_ode
from tippetop.compare.measures import theory
from tippetop.compare.measures.series import energy_rise, jellett_drift
from tippetop.models.params import TopParams

LAWS = ["modified_coulomb", "coulomb", "viscous", "coulomb_viscous"]


@pytest.mark.parametrize("law", LAWS)
def test_jellett_conserved_at_rtol_1e10(law: str) -> None:
    """J = -L . X_P is exact for any contact force through P (eq. 2.10).

    At rtol 1e-10 it must hold to 1e-8 relative (the issue's bound; facts.md reports 1e-9 with a
    tight DOP853): the Fig. 3 start (theta0 = 0.1, n0 = 100), which inverts, for every law.
    """
    res = run_ode(1.0, 0.1, law=law, t_end_s=4.0, theta0=0.1, n0=100.0)
    assert res.status == "ok"
    assert jellett_drift(res.table) < 1e-8


def test_jellett_initial_value_matches_the_paper() -> None:
    """J0 = C n0 (R cos theta0 - a) + A Omega0 R sin^2 theta0 (eq. 4.21), to rounding."""
    top = TopParams.from_ratios(1.0, 0.1)
    res = run_ode(1.0, 0.1, law="modified_coulomb", t_end_s=0.01, theta0=0.3, n0=80.0,
                  Omega0=7.0)
    expected = theory.jellett_from_spin(top, 80.0, theta0=0.3, Omega0=7.0)
    assert res.table["J"].iloc[0] == pytest.approx(expected, rel=1e-13)


@pytest.mark.parametrize("law", LAWS)
def test_energy_never_rises(law: str) -> None:
    """dE/dt = F . v_P <= 0 (eq. 4.9): E is non-increasing on every sample, to 1e-8 of E0.

    The bound is 100x the run's rtol (1e-10) times E0: what the integrator's local error can
    show, far below the physical decrease (about 1e-3 of E0 per second). That the decrease is
    the friction's work, and not a loss from anywhere else, is test_energy_balance's claim.
    """
    res = run_ode(1.0, 0.1, law=law, t_end_s=4.0, theta0=0.1, n0=100.0)
    E0 = res.table["E"].iloc[0]
    assert energy_rise(res.table) <= 100 * 1e-10 * E0
    assert res.table["E"].iloc[-1] < E0 * (1 - 1e-3)


@pytest.mark.parametrize("law", LAWS)
def test_energy_balance(law: str) -> None:
    """E(t) - E(0) equals the integral of the friction power F . v_P (work-energy theorem).

    Integrated by the trapezoid rule on 10-us samples over the first second, which resolve the
    fastest slip transient (the viscous laws' M / c ~ 10 ms); the quadrature error is then
    O(dt^2 P'') < 1e-3 of the energy lost. A wrong gyroscopic or constraint term breaks this
    at O(1).
    """
    res = run_ode(1.0, 0.1, law=law, t_end_s=1.0, theta0=0.1, n0=100.0, sample_dt_s=1e-5)
    t = res.table
    work = np.concatenate([[0.0], np.cumsum(0.5 * (t["P_fric"].to_numpy()[1:]
                                                   + t["P_fric"].to_numpy()[:-1])
                                            * np.diff(t["t"].to_numpy()))])
    lost = t["E"].iloc[0] - t["E"].iloc[-1]
    assert np.max(np.abs((t["E"] - t["E"].iloc[0]) - work)) < 1e-3 * lost


def test_frictionless_conserves_energy() -> None:
    """With no friction the energy is a constant of motion: to 1e-9 relative at rtol 1e-10."""
    res = run_ode(1.0, 0.1, law="none", t_end_s=2.0, theta0=0.5, n0=60.0, Omega0=3.0)
    E = res.table["E"].to_numpy()
    assert np.max(np.abs(E / E[0] - 1)) < 1e-9


def test_contact_constraint_normal_force() -> None:
    """N = M (g + a (theta_dot^2 cos theta + theta_ddot sin theta)) (Sec. 2), with theta_ddot
    from a central difference of the sampled theta_dot (error O(dt^2), dt = 1 ms): agrees to
    1e-4 of Mg away from theta = 0, where theta_dot is smooth."""
    res = run_ode(1.0, 0.15, law="modified_coulomb", t_end_s=2.0, theta0=1.0, n0=60.0)
    t = res.table
    top = TopParams.from_ratios(1.0, 0.15)
    dt = t["t"].diff().iloc[1]
    thdd = (t["theta_dot"].shift(-1) - t["theta_dot"].shift(1)) / (2 * dt)
    N = top.M_kg * (top.g_mps2 + top.a_m * (t["theta_dot"] ** 2 * np.cos(t["theta"])
                                           + thdd * np.sin(t["theta"])))
    err = (N - t["N"]).iloc[1:-1].abs().max()
    assert err < 1e-4 * top.M_kg * top.g_mps2


def test_upright_start_stays_exactly_upright() -> None:
    """theta0 = 0 exactly, no perturbation: k = e_z, w = n e_z is an exact equilibrium (the
    vertical spin state, eq. 4.4). The vector formulation keeps theta = 0 and the paper-frame
    quantities (Omega, xi, slip and velocity in the rotating frame) are NaN, not garbage."""
    res = run_ode(1.0, 0.15, law="modified_coulomb", t_end_s=2.0, theta0=0.0, n0=60.0)
    t = res.table
    assert res.status == "ok"
    assert (t["theta"] == 0.0).all()
    for col in ("Omega", "xi", "vPX", "vPY", "uOX", "uOY"):
        assert t[col].isna().all(), col
    assert t["n"].iloc[-1] == pytest.approx(60.0, rel=1e-12)
    assert np.isfinite(t[["J", "E", "N", "x", "y", "theta_dot"]].to_numpy()).all()


def test_initial_observables_match_the_initial_state() -> None:
    """The table's first row is the requested initial state, in both formulations (1e-12)."""
    init = dict(theta0=0.7, thetadot0=0.3, Omega0=4.0, n0=55.0, uOX=0.01, uOY=-0.02)
    for form in ("vector", "paper"):
        row = run_ode(1.0, 0.15, t_end_s=0.01, formulation=form, **init).table.iloc[0]
        got = [row["theta"], row["theta_dot"], row["Omega"], row["n"], row["uOX"], row["uOY"]]
        assert got == pytest.approx(list(init.values()), rel=1e-12, abs=1e-14), form
