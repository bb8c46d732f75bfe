"""A MuJoCo run: the observables table, Jellett's constant, inversion, energy, divergence.

The default scene, the paper's Fig. 3 top (TopParams.from_ratios(1.0, 0.1), theta0 = 0.1,
n0 = 100 rad/s, mu = 0.1, Lambda = 0.01 m/s) at dt = 2e-5 s with RK4, on paper mode's stiff
contact (solref 0.5 ms, ``models.resolve.PAPER_SOLREF``: the ball sinks 0.27 um at rest),
against the reference ODE (rtol 1e-10) sampled at the same 1-ms times.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest

from tests.conftest import run_mujoco, run_ode
from tippetop.models.errors import TippetopError
from tippetop.models.observables import COLUMNS, EXTRA_COLUMNS
from tippetop.models.params import TopParams
from tippetop.mujoco_runner.checks import MAX_ENERGY_RISE

FIG3_TOP = TopParams.from_ratios(1.0, 0.1)
DT = 2e-5
# The paper-mode run to 3.5 s is shared by the J, inversion and energy tests (about 7 s wall).
PAPER_T_END = 3.5
PAPER = ("mujoco.friction='paper'", "run.sample_dt_s=1e-3", f"mujoco.timestep_s={DT!r}")
#: MuJoCo's own friction with the scene's settings (elliptic cone, solref 0.02 s), uncalibrated
NATIVE = ("mujoco.friction='native'", "mujoco.calibrated=false", "run.sample_dt_s=1e-3",
          f"mujoco.timestep_s={DT!r}")
NO_FRICTION = ("mujoco.friction='paper'", "effects.sliding=false")


@pytest.fixture(scope="module")
def paper_fig3():
    return run_mujoco(*PAPER, f"run.t_end_s={PAPER_T_END!r}")


def _ode_fig3(t_end_s: float):
    """The reference run of the same start, sampled at the same 1-ms times (cached)."""
    return run_ode(1.0, 0.1, t_end_s=t_end_s, theta0=0.1, n0=100.0, sample_dt_s=1e-3)


def _crossing(table: pd.DataFrame) -> float:
    """The time theta passes pi/2, interpolated linearly between the samples around it."""
    t, th = table["t"].to_numpy(), table["theta"].to_numpy() - math.pi / 2
    i = int(np.flatnonzero(th > 0)[0])
    return float(t[i - 1] - th[i - 1] * (t[i] - t[i - 1]) / (th[i] - th[i - 1]))


def _work(table: pd.DataFrame) -> np.ndarray:
    """The friction's work since t = 0: the trapezoid rule on the sampled P_fric (J)."""
    t, P = table["t"].to_numpy(), table["P_fric"].to_numpy()
    return np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(t))])


def _J_drift(table: pd.DataFrame, t_max: float = math.inf) -> float:
    J = table.loc[table.t <= t_max, "J"].to_numpy()
    return float(np.max(np.abs(J / J[0] - 1)))


def test_table_schema_and_initial_row(paper_fig3) -> None:
    result = paper_fig3
    assert result.ok, result.message
    table = result.table
    assert list(table.columns) == list(COLUMNS + EXTRA_COLUMNS)
    assert len(table) == round(PAPER_T_END / 1e-3) + 1
    np.testing.assert_allclose(table.t, np.arange(len(table)) * 1e-3, rtol=1e-12, atol=1e-15)
    assert result.n_steps == round(PAPER_T_END / DT)
    first = table.iloc[0]
    assert first.theta == pytest.approx(0.1, abs=1e-14)
    assert first.n == pytest.approx(100.0, rel=1e-14)
    assert first.theta_dot == pytest.approx(0.0, abs=1e-12)
    assert first.Omega == pytest.approx(0.0, abs=1e-10)
    assert first.xi == pytest.approx(FIG3_TOP.C_kgm2 * 100.0, rel=1e-14)
    # The centre of mass sits at h = R - a cos theta above the table, at the origin.
    assert first.z == pytest.approx(FIG3_TOP.R_m - FIG3_TOP.a_m * math.cos(0.1), rel=1e-14)
    assert first.x == pytest.approx(0.0, abs=1e-18)
    assert np.isfinite(table[list(COLUMNS)].drop(columns=["Omega"]).to_numpy()).all()


def test_paper_mode_conserves_jellett(paper_fig3) -> None:
    # The normal force acts through the sphere's centre and the friction at P, so the torque
    # about O is X_P x (N + F) and J = -L . X_P is conserved exactly (paper eq. 2.7), whatever
    # the contact's softness or the one-evaluation lag of N: only rounding and RK4's error
    # remain. Brief's bound 1e-4; measured ~1e-13 over 3.5 s.
    assert _J_drift(paper_fig3.table, 2.0) < 1e-9
    assert _J_drift(paper_fig3.table) < 1e-9


def test_paper_mode_inverts_fig3(paper_fig3) -> None:
    # Against the reference's event time (2.3292593 s): the sampled theta crosses pi/2 at the
    # same time, linearly interpolated between the 1-ms samples (the interpolation alone is
    # off by 2e-6 s). The engines' theta differ by at most ~2e-4 rad (README; measured here
    # 2.2e-4 over 3.5 s) and theta rises at ~2 rad/s through pi/2, so 1e-3 rad of gap would
    # move the crossing by 5e-4 s: the bound. Measured 1.1e-5 s.
    ode = _ode_fig3(PAPER_T_END)
    table = paper_fig3.table
    assert (table.theta > math.pi / 2).any(), f"not inverted: theta_end = {table.theta.iat[-1]}"
    assert abs(_crossing(table) - ode.t_invert) < 5e-4
    assert np.max(np.abs(table["theta"].to_numpy() - ode.table["theta"].to_numpy())) < 1e-3


def test_paper_mode_energy_never_rises(paper_fig3) -> None:
    # Friction only dissipates (P_fric <= 0); E leaves out the contact's elastic energy, whose
    # exchange with E when N changes is at most M g delta, with the static sink delta = 0.27 um
    # of this stiff contact: 4.6e-6 E0. Bound 1e-5 E0; measured 0 (1.2e-11 over 8 s).
    E = paper_fig3.table.E.to_numpy()
    assert np.max(E - np.minimum.accumulate(E)) < 1e-5 * E[0]


def test_paper_mode_work_energy_balance(paper_fig3) -> None:
    # E(t) - E(t0) = integral of the friction power over [t0, t] (the normal force does no
    # work on a rigid contact; gravity is in E). Trapezoid rule on the 1-ms samples, from
    # t0 = 10 ms: the first samples hold the contact forming from zero penetration (N rises
    # from 0 to M g in ~1 ms; a residual of 1.1e-6 J that 0.1-ms samples cut to 1.2e-7 J).
    # Error budget: the quadrature (the reference ODE's own table on the same samples closes
    # its balance to 4e-9 J) plus the contact's elastic energy M g delta = 4e-8 J. Bound
    # 1e-6 J, 5.6e-4 of the 1.8e-3 J that friction takes. Measured with the table's N:
    # 1.25e-5 J, growing through the rise, independent of dt (1e-5 ... 1e-4 s) and of the
    # sampling (the callback was not armed on the scratch mjData the runner reads N from);
    # with it armed: 5.3e-9 J.
    table = paper_fig3.table
    i0 = 10  # t = 10 ms
    residual = (table["E"].to_numpy() - table["E"].iat[i0]) - (_work(table) - _work(table)[i0])
    assert np.max(np.abs(residual[i0:])) < 1e-6


def test_paper_mode_normal_force_is_the_contact_impulse(paper_fig3) -> None:
    # The vertical momentum balance of the centre of mass: integral of N dt over [t0, t1] =
    # M g (t1 - t0) + M (zdot(t1) - zdot(t0)), with zdot = a sin(theta) theta_dot (z = R - a cos
    # theta; the contact's penetration rate adds an error of order 1e-8). Trapezoid rule on the 1-ms
    # samples from 10 ms (after the contact forms) to 3.5 s. The same check on the reference's
    # table closes to 1.7e-8 of M g (t1 - t0) (the quadrature); MuJoCo with N read with the
    # friction applied: 1.0e-8. Bound 1e-5. With the table's N: 4.6e-3 (5.2e-3 over the rise).
    table = paper_fig3.table
    top = FIG3_TOP
    t = table["t"].to_numpy()
    zdot = top.a_m * np.sin(table["theta"].to_numpy()) * table["theta_dot"].to_numpy()
    i0, i1 = 10, len(t) - 1
    impulse = np.trapezoid(table["N"].to_numpy()[i0:], t[i0:])
    weight = top.M_kg * top.g_mps2 * (t[i1] - t[i0])
    assert abs(impulse - weight - top.M_kg * (zdot[i1] - zdot[i0])) < 1e-5 * weight


def test_native_condim3_conserves_jellett() -> None:
    # MuJoCo applies the friction at the middle of the penetration, R - delta/2 below S
    # (delta ~ 0.4 mm at rest with the default solref), so J with the nominal R drifts by
    # ~ (delta/2R) * (relative change of L_z): measured 6.3e-7 over 2 s (no flip yet, L_z
    # changes little). Bound 1e-5: 16x the measurement, and far below what a torque off P
    # does (the torsional and rolling runs below drift by ~1).
    result = run_mujoco(*NATIVE, "mujoco.condim=3", "run.t_end_s=2.0")
    assert result.ok, result.message
    assert _J_drift(result.table) < 1e-5


@pytest.mark.parametrize("condim", [4, 6])
def test_native_torsional_rolling_break_jellett(condim: int) -> None:
    # Torsional/rolling torques are not through P: with MuJoCo's default coefficients the spin,
    # and J with it, is gone within 0.5 s (measured relative drift ~1.0).
    effects = ("effects.torsional=true",) + (("effects.rolling=true",) if condim == 6 else ())
    result = run_mujoco(*NATIVE, *effects, "run.t_end_s=0.5")
    assert result.ran["condim"] == condim
    assert result.ok, result.message
    assert _J_drift(result.table) > 0.1


def test_too_large_timestep_is_reported_as_diverged() -> None:
    # Explicit Euler at dt = 5 ms with n0 = 1000 rad/s: the gyroscopic term of a top with
    # A != C is unstable (the A = C Fig. 3 top has none, and Euler merely loses accuracy).
    # No sliding friction: paper mode refuses a step its law cannot follow (see
    # test_paper_timestep.py), and this failure is the integrator's, not the law's.
    result = run_mujoco(*NO_FRICTION, "top.A_over_C=1.25", "top.a_over_R=0.15",
                        "top.C_factor=0.8", "init.n0=1000.0", "run.t_end_s=2.0",
                        "run.sample_dt_s=5e-3", "mujoco.timestep_s=5e-3",
                        "mujoco.integrator='Euler'", "mujoco.solref=[0.02, 1.0]")
    assert result.status == "diverged" and not result.ok
    assert result.message.startswith("diverged by t = ")
    assert "timestep_s" in result.message and "\n" not in result.message
    assert len(result.table) < 2.0 / 5e-3  # stopped early; no rows after the failure
    assert np.isfinite(result.table[["theta", "n", "J", "E"]].to_numpy()).all()
    # the runner stops at the first sample whose energy rose by more than MAX_ENERGY_RISE of
    # E0 (friction and the contact can only dissipate): no tabulated row is past that
    E = result.table.E.to_numpy()
    assert (E <= E[0] * (1 + MAX_ENERGY_RISE)).all()


@pytest.mark.parametrize(
    ("A_over_C", "n0", "dt", "integrator", "fragment", "rows"),
    [
        # |qvel| above MuJoCo's 1e10 bound: MuJoCo warns and resets the state.
        (1.0, 1e11, DT, "RK4", "MuJoCo warning mjWARN_BADQVEL", 1),
        # Euler makes an A != C top hop off the table.
        (0.95, 1000.0, 5e-3, "Euler", "contact lost", 300),
        # dt at the contact's time constant: the ball falls through.
        (1.0, 100.0, 2e-2, "Euler", "the ball sank", 1),
    ],
)
def test_failures_are_reported_not_tabulated(A_over_C, n0, dt, integrator, fragment, rows,
                                             tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to ./MUJOCO_LOG.TXT
    # no sliding friction: these failures are the integration's and the contact's (paper mode
    # refuses a step its law cannot follow before running, test_paper_timestep.py); the
    # scene's contact (solref 0.02 s), not paper mode's stiff one
    result = run_mujoco(*NO_FRICTION, f"top.A_over_C={A_over_C!r}", f"init.n0={n0!r}",
                        "run.t_end_s=2.0", f"run.sample_dt_s={max(dt, 1e-3)!r}",
                        f"mujoco.timestep_s={dt!r}", f"mujoco.integrator={integrator!r}",
                        "mujoco.solref=[0.02, 1.0]")
    assert result.status == "diverged", result.message
    assert fragment in result.message and "\n" not in result.message
    assert 1 <= len(result.table) <= rows


def test_deterministic_and_reports_progress() -> None:
    reported: list[float] = []
    a = run_mujoco(*PAPER, "run.t_end_s=0.05", progress=reported.append)
    b = run_mujoco(*PAPER, "run.t_end_s=0.05")
    pd.testing.assert_frame_equal(a.table, b.table, check_exact=True)
    assert reported[0] == 0.0 and reported[-1] == pytest.approx(0.05)


@pytest.mark.parametrize(
    ("overrides", "what"),
    [
        (("run.sample_dt_s=1.5e-5",), "run.sample_dt_s"),
        (("run.sample_dt_s=1.00001e-3",), "run.sample_dt_s"),
        (("run.t_end_s=-1.0",), "run.t_end_s"),
        (("run.t_end_s=1e-5",), "run.t_end_s"),
        (("mujoco.friction='exact'",), "mujoco.friction"),
        (("mujoco.condim=3",), "mujoco.condim"),
    ],
)
def test_bad_run_arguments(overrides: tuple[str, ...], what: str) -> None:
    with pytest.raises(TippetopError, match=f"^{re.escape(what)}: expected "):
        run_mujoco(*PAPER, "run.t_end_s=0.01", *overrides)


@pytest.mark.slow
@pytest.mark.parametrize("dt", [2e-5, 1e-4])
def test_paper_mode_inverts_and_stays_inverted(dt: float) -> None:
    # Full 8 s (about 8 s wall at dt = 2e-5), against the reference sampled at the same times:
    # theta within 1e-3 rad all along (README: 2e-4 rad over 6 s; measured 2.2e-4 at both dt,
    # the contact's floor, and 1.3e-5 / 4.4e-6 rad at 8 s), the crossing of pi/2 within 5e-4 s
    # of the reference's event time (measured 1.1e-5 s and 5.0e-5 s; see
    # test_paper_mode_inverts_fig3 for the bound), and J exact (torques through P only).
    result = run_mujoco("mujoco.friction='paper'", "run.sample_dt_s=1e-3",
                        f"mujoco.timestep_s={dt!r}", "run.t_end_s=8.0")
    assert result.ok, result.message
    table = result.table
    ode = _ode_fig3(8.0)
    assert len(table) == len(ode.table)
    assert np.max(np.abs(table["theta"].to_numpy() - ode.table["theta"].to_numpy())) < 1e-3
    assert abs(_crossing(table) - ode.t_invert) < 5e-4
    assert _J_drift(table) < 1e-9
