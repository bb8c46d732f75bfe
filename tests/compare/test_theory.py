"""compare.analysis.theory against the paper's printed numbers, and against its own consistency
relations.

Printed numbers are checked to half a unit of their last printed digit (n1 = 34.4 -> 0.05).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tippetop.compare.measures import theory as th
from tippetop.models.params import TopParams


def top(A_over_C: float, a_over_R: float, C_factor: float = 1.0) -> TopParams:
    return TopParams.from_ratios(A_over_C, a_over_R, C_factor)


FIG9 = {
    "a": top(1.00, 0.15),
    "b": top(0.95, 0.15),
    "c": top(0.95, 0.125),
    "d": top(0.95, 0.10),
}
FIG10 = {"a": top(1.25, 0.025, 0.8), "b": top(1.25, 0.15, 0.8)}
FIG7 = top(0.85, 0.10)


def half_unit(printed: str) -> float:
    """Half a unit of the last printed digit of ``printed``."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return 0.5 * 10.0**-decimals


def assert_printed(value: float | None, printed: str) -> None:
    assert value is not None
    assert abs(value - float(printed)) <= half_unit(printed), (value, printed)


# --------------------------------------------------------------------------------------------
# The paper's printed numbers
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("key", "n1", "n4", "nc_is"),
    [
        ("a", "34.4", "62.9", "n4"),
        ("b", "42.1", "54.5", "n4"),
        ("c", "45.7", "49.4", "n4"),
        ("d", "51.4", "44.4", "n1"),
    ],
)
def test_fig9_critical_spins(key: str, n1: str, n4: str, nc_is: str) -> None:
    t = FIG9[key]
    assert th.group(t) == "II"
    assert_printed(th.n1(t), n1)
    assert_printed(th.n4(t), n4)
    expected_nc = th.n4(t) if nc_is == "n4" else th.n1(t)
    assert th.n_c(t) == expected_nc
    # The paper's Sec. 4.3: n4 > n1 exactly when A/C > r_c.
    assert (th.n4(t) > th.n1(t)) == (t.A_over_C > th.r_c(t))


def test_fig9_rc_and_theta_d() -> None:
    assert_printed(th.r_c(FIG9["c"]), "0.94")
    assert_printed(th.r_c(FIG9["d"]), "0.96")
    assert_printed(th.theta_d(FIG9["c"]), "1.89")
    # (a): A/C = 1, (d): A/C < r_c, (b): r_c < A/C < 1 but F'(1) < 0, F monotone -> no theta_d.
    for key in ("a", "b", "d"):
        assert th.theta_d(FIG9[key]) is None
    t = FIG9["b"]
    assert th.r_c(t) < t.A_over_C < 1.0
    assert th.D(t, 1.0) > 0.0


def test_fig6_n1() -> None:
    t = top(1.00, 0.10)
    assert th.group(t) == "II"
    assert_printed(th.n1(t), "36")


@pytest.mark.parametrize(("key", "n1", "theta_f"), [("a", "13.3", "1.67"), ("b", "23.5", "2.21")])
def test_fig10_group_iii(key: str, n1: str, theta_f: str) -> None:
    t = FIG10[key]
    assert th.group(t) == "III"
    assert_printed(th.n1(t), n1)
    assert_printed(th.theta_f(t), theta_f)
    assert math.pi / 2 < th.theta_f(t) < math.pi
    for f in (th.n3, th.n4, th.n_c, th.theta_c, th.theta_d):
        assert f(t) is None


def test_fig11_theta_s_curve() -> None:
    t = FIG9["a"]
    n0 = np.arange(30.0, 81.0, 10.0)
    got = th.theta_s_curve(t, n0)
    expected = np.array([0.0, 0.92, 1.67, 2.49, math.pi, math.pi])
    assert got.shape == n0.shape
    # to half a unit of the printed digit (0.005); the closest call is n0 = 60: 2.4949 for 2.49
    np.testing.assert_allclose(got, expected, rtol=0, atol=half_unit("2.49"))
    assert got[0] == 0.0 and got[-2] == math.pi and got[-1] == math.pi


def test_group_i_example_fig7() -> None:
    t = FIG7
    assert th.group(t) == "I"
    # (ThetaCritical): theta_c = arccos(a / (R (1 - A/C))) = arccos(0.1 / 0.15) = arccos(2/3)
    tc = th.theta_c(t)
    assert tc == pytest.approx(math.acos(2.0 / 3.0), rel=1e-12)

    # ... where the reduced slip v~_PY = sin(theta) (a + R (A/C - 1) cos(theta)) (VPYTilde)
    # changes sign: theta falls below theta_c and rises above it
    def v_py(theta: float) -> float:
        return math.sin(theta) * (t.a_m + t.R_m * (t.A_over_C - 1.0) * math.cos(theta))

    assert v_py(tc - 1e-6) < 0.0 < v_py(tc + 1e-6)
    assert abs(v_py(tc)) < 1e-12 * t.R_m
    assert th.n1(t) is None and th.n_c(t) is None
    assert th.theta_f(t) is None and th.theta_d(t) is None
    for n0 in (1.0, 50.0, 500.0, 1e5):
        assert th.theta_s(t, n0) == 0.0
        assert th.H_sign_zero(t, n0) == -1
        assert th.D_sign_at_theta_s(t, n0) is None


# --------------------------------------------------------------------------------------------
# Consistency relations
# --------------------------------------------------------------------------------------------

INTERMEDIATE_CASES = [
    (FIG9["a"], [35.0, 40.0, 50.0, 60.0, 62.5]),
    (FIG9["b"], [42.5, 45.0, 50.0, 54.0]),
    (FIG9["c"], [45.8, 47.0, 49.0]),
    (FIG10["a"], [13.5, 20.0, 50.0, 200.0]),
    (FIG10["b"], [24.0, 30.0, 100.0, 1000.0]),
]


@pytest.mark.parametrize(("t", "spins"), INTERMEDIATE_CASES)
def test_root_solves_F_equals_kappa(t: TopParams, spins: list[float]) -> None:
    for n0 in spins:
        ts = th.theta_s(t, n0)
        assert 0.0 < ts < math.pi
        kap = th.kappa(t, th.jellett_from_spin(t, n0))
        assert th.F(t, math.cos(ts)) == pytest.approx(kap, rel=1e-9)
        # Appendix B: the intermediate state is stable, D(x_s) > 0.
        assert th.D(t, math.cos(ts)) > 0.0
        assert th.D_sign_at_theta_s(t, n0) == 1


def test_kappa_at_n1_and_n4_are_F_at_the_ends() -> None:
    for t in FIG9.values():
        assert th.kappa(t, th.jellett_from_spin(t, th.n1(t))) == pytest.approx(
            th.F(t, 1.0), rel=1e-12
        )
        assert th.kappa(t, th.jellett_from_spin(t, th.n4(t))) == pytest.approx(
            th.F(t, -1.0), rel=1e-12
        )
    assert th.F(FIG9["c"], -1.0) > th.F(FIG9["c"], 1.0)
    assert th.F(FIG9["d"], -1.0) < th.F(FIG9["d"], 1.0)


def test_theta_s_continuous_and_increasing_fig9a() -> None:
    t = FIG9["a"]
    v1, v4 = th.n1(t), th.n4(t)
    n0 = np.linspace(v1, v4, 2001)[1:-1]
    ts = th.theta_s_curve(t, n0)
    assert np.all(np.diff(ts) > 0.0)
    assert np.max(np.diff(ts)) < 0.05
    assert th.theta_s(t, v1 * (1 + 1e-9)) < 1e-3
    assert th.theta_s(t, v4 * (1 - 1e-9)) > math.pi - 1e-3
    assert th.theta_s(t, v1) == 0.0
    assert th.theta_s(t, v4) == math.pi
    assert th.D_sign_at_theta_s(t, v1 * 0.9) is None
    assert th.D_sign_at_theta_s(t, v4 * 1.1) is None


def test_theta_s_jumps_to_theta_d_fig9c() -> None:
    t = FIG9["c"]
    v1, v4, td = th.n1(t), th.n4(t), th.theta_d(t)
    assert th.theta_s(t, v1 * (1 - 1e-9)) == 0.0
    assert th.theta_s(t, v1 * (1 + 1e-9)) == pytest.approx(td, abs=1e-3)
    ts = th.theta_s_curve(t, np.linspace(v1, v4, 52)[1:-1])
    assert np.all((ts > td) & (ts < math.pi))
    assert np.all(np.diff(ts) > 0.0)
    assert th.theta_s(t, v4 * (1 + 1e-9)) == math.pi


def test_no_intermediate_state_below_rc_fig9d() -> None:
    t = FIG9["d"]
    v1 = th.n1(t)
    assert th.theta_s(t, v1 * (1 - 1e-9)) == 0.0
    assert th.theta_s(t, v1 * (1 + 1e-9)) == math.pi
    assert th.D_sign_at_theta_s(t, v1 * 1.1) is None


def test_group_iii_theta_s_approaches_theta_f() -> None:
    for t in FIG10.values():
        tf = th.theta_f(t)
        ts = th.theta_s_curve(t, th.n1(t) * np.array([1.01, 2.0, 10.0, 100.0, 1e4]))
        assert np.all(np.diff(ts) > 0.0)
        assert np.all(ts < tf)
        assert tf - ts[-1] < 1e-3


def test_theta_s_sign_of_spin_irrelevant() -> None:
    t = FIG9["a"]
    assert th.theta_s(t, -50.0) == th.theta_s(t, 50.0)


def test_H_sign_zero_flips_at_n1() -> None:
    for t in (*FIG9.values(), *FIG10.values()):
        v1 = th.n1(t)
        assert th.H_sign_zero(t, v1 * (1 - 1e-6)) == -1
        assert th.H_sign_zero(t, v1 * (1 + 1e-6)) == 1
        assert th.H_sign_zero(t, v1) == 0
        assert th.H_sign_zero(t, -v1 * (1 + 1e-6)) == 1


def test_H_sign_pi_flips_at_n3() -> None:
    for t in (*FIG9.values(), FIG7):
        v3 = th.n3(t)
        assert v3 >= th.n2(t)
        assert th.H_sign_pi(t, -v3 * (1 - 1e-6)) == 1
        assert th.H_sign_pi(t, -v3 * (1 + 1e-6)) == -1
        assert th.H_sign_pi(t, v3 * (1 + 1e-6)) == -1
        assert th.H_sign_pi(t, v3) == 0
    for t in FIG10.values():  # Group III: unstable at pi for every spin
        assert th.H_sign_pi(t, 1e6) == 1


@pytest.mark.parametrize(("t", "spins"), INTERMEDIATE_CASES)
def test_E1_stationary_and_minimal_at_theta_s(t: TopParams, spins: list[float]) -> None:
    h = 1e-5
    scale = t.M_kg * t.g_mps2 * t.a_m  # size of the gravity term's theta-derivative
    for n0 in spins:
        J = th.jellett_from_spin(t, n0)
        ts = th.theta_s(t, n0)
        e_minus, e_0, e_plus = th.E1(t, np.array([ts - h, ts, ts + h]), J)
        assert abs((e_plus - e_minus) / (2 * h)) < 1e-6 * scale
        assert (e_plus - 2 * e_0 + e_minus) / h**2 > 0.0  # stable: a minimum (Appendix C)
        # ... and the derivative is not small away from the steady state.
        off = ts - 0.2 if ts > 0.3 else ts + 0.2
        d_off = (th.E1(t, off + h, J) - th.E1(t, off - h, J)) / (2 * h)
        assert abs(d_off) > 1e-3 * scale


def test_E1_matches_paper_form_and_vectorises() -> None:
    t = FIG9["b"]
    theta = np.linspace(0.0, math.pi, 7)
    J = th.jellett_from_spin(t, 45.0)
    eta = np.cos(theta)
    G = 1 - eta**2 + (t.C_kgm2 / t.A_kgm2) * (eta - t.a_over_R) ** 2
    expected = J**2 / (2 * t.A_kgm2 * t.R_m**2 * G) + t.M_kg * t.g_mps2 * t.R_m * (
        1 - t.a_over_R * eta
    )
    np.testing.assert_allclose(th.E1(t, theta, J), expected, rtol=1e-14)
    assert isinstance(th.E1(t, 0.3, J), float)


def test_xi_roots_and_conditioning() -> None:
    t = FIG9["a"]
    theta = np.linspace(0.0, 1.2, 25)  # R cos(theta) - a stays well away from 0
    J = th.jellett_from_spin(t, 60.0)
    xp, xm = th.xi_plus(t, theta, J), th.xi_minus(t, theta, J)
    c = t.R_m * np.cos(theta) - t.a_m
    h = t.R_m - t.a_m * np.cos(theta)
    amg = t.A_kgm2 * t.M_kg * t.g_mps2
    disc = J**2 + 4 * amg * c * h * t.a_m
    np.testing.assert_allclose(xp, (J + np.sqrt(disc)) / (2 * c), rtol=1e-14)
    np.testing.assert_allclose(xm, (J - np.sqrt(disc)) / (2 * c), rtol=1e-6)
    for xi in (xp, xm):  # both solve V(xi, theta, J) = 0 (EulerYYY)
        V = (J - xi * c) * xi + amg * t.a_m * h
        np.testing.assert_allclose(V, 0.0, atol=1e-12 * J**2)
    # J an array of theta's shape
    Js = np.full_like(theta, J)
    np.testing.assert_array_equal(th.xi_minus(t, theta, Js), xm)


def test_xi_minus_small_a_limit() -> None:
    t = TopParams.from_ratios(1.0, 1e-4)
    J = th.jellett_from_spin(t, 100.0)
    theta = np.array([0.0, 0.5, 1.0, 1.5])
    limit = -t.A_kgm2 * t.M_kg * t.g_mps2 * t.a_m * t.R_m / J
    np.testing.assert_allclose(th.xi_minus(t, theta, J), limit, rtol=1e-3)
    # The naive form loses most digits here; the stable form does not.
    tiny = TopParams.from_ratios(1.0, 1e-9)
    Jt = th.jellett_from_spin(tiny, 100.0)
    ref = -tiny.A_kgm2 * tiny.M_kg * tiny.g_mps2 * tiny.a_m * tiny.R_m / Jt
    assert th.xi_minus(tiny, 0.0, Jt) == pytest.approx(ref, rel=1e-6)


def test_xi_nan_where_no_real_root() -> None:
    t = FIG9["a"]
    # theta = pi, J = 0: R cos(theta) - a < 0 makes the discriminant negative.
    assert math.isnan(th.xi_plus(t, math.pi, 0.0))
    assert math.isnan(th.xi_minus(t, math.pi, 0.0))
    out = th.xi_minus(t, np.array([0.0, math.pi]), np.array([1e-3, 0.0]))
    assert np.isfinite(out[0]) and np.isnan(out[1])


# --------------------------------------------------------------------------------------------
# Borders, small helpers, summary
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("e", [0.025, 0.1, 0.125, 0.15, 0.3])
def test_group_borders(e: float) -> None:
    lower = top(1.0 - e, e)
    assert th.group(lower) == "I"
    assert th.n1(lower) is None
    assert th.theta_c(lower) == 0.0
    assert th.theta_s(lower, 1e4) == 0.0
    upper = top(1.0 + e, e)
    assert th.group(upper) == "III"
    assert th.theta_f(upper) == math.pi
    assert th.n3(upper) is None and th.n4(upper) is None
    assert th.group(top(1.0 - e * (1 - 1e-9), e)) == "II"
    assert th.group(top(1.0 + e * (1 - 1e-9), e)) == "II"
    assert th.group(top(1.0 + e * (1 + 1e-9), e)) == "III"


def test_zero_eccentricity() -> None:
    assert th.group(top(0.9, 0.0)) == "I"
    assert th.group(top(1.0, 0.0)) == "I"
    assert th.group(top(1.1, 0.0)) == "III"
    assert th.theta_c(top(0.9, 0.0)) == pytest.approx(math.pi / 2)
    assert th.theta_f(top(1.1, 0.0)) == pytest.approx(math.pi / 2)
    assert th.theta_c(top(1.0, 0.0)) is None
    assert th.n2(top(1.1, 0.0)) == 0.0
    assert th.r_c(top(1.1, 0.0)) == 1.0


@pytest.mark.parametrize("key", sorted(FIG9))
def test_F_at_the_ends_is_the_papers_closed_form(key: str) -> None:
    """Sec. 4.2.3: F(1) = (1 - a/R)^4 / (A/C - 1 + a/R) (the bound kappa > F(1) that n > n1
    gives) and F(-1) = (1 + a/R)^4 / (1 + a/R - A/C) (kappa < F(-1), the road to n4), written
    here from the paper's text, not from f1 and f2. To rounding (measured <= 6e-16)."""
    t = FIG9[key]
    e, r = t.a_over_R, t.A_over_C
    assert th.F(t, 1.0) == pytest.approx((1 - e) ** 4 / (r - 1 + e), rel=1e-14)
    assert th.F(t, -1.0) == pytest.approx((1 + e) ** 4 / (1 + e - r), rel=1e-14)


@pytest.mark.parametrize("key", sorted(FIG9))
def test_F_derivative_is_the_papers(key: str) -> None:
    """dF/dx from a central difference of ``F`` (h = 1e-4: truncation error h^2/6 times the
    third derivative, measured <= 3e-8 of max |dF/dx|; rounding 1e-12) equals (DerivG),
    dF/dx = -4 sqrt(f2) - f2 (A/C - 1) / f1^2, with f1 and f2 written from (f1), (f2); bound
    1e-6. Appendix B's form of the same derivative, -sqrt(f2) D / f1^2, holds for ``D`` to
    rounding (measured 4e-15; bound 1e-12)."""
    t = FIG9[key]
    e, r = t.a_over_R, t.A_over_C
    x = np.linspace(-0.9, 0.9, 7)
    h = 1e-4
    f1 = (r - 1.0) * x + e
    f2 = ((x - e) ** 2 + r * (1.0 - x * x)) ** 2
    paper = -4.0 * np.sqrt(f2) - f2 * (r - 1.0) / f1**2
    numeric = (th.F(t, x + h) - th.F(t, x - h)) / (2.0 * h)
    scale = np.max(np.abs(paper))
    assert np.max(np.abs(numeric - paper)) < 1e-6 * scale
    np.testing.assert_allclose(-np.sqrt(f2) * th.D(t, x) / f1**2, paper, rtol=0,
                               atol=1e-12 * scale)


def test_summary_keys_and_json() -> None:
    keys = {"group", "n1", "n2", "n3", "n4", "nc", "rc", "theta_c", "theta_f", "theta_d"}
    s = th.summary(FIG9["c"])
    assert set(s) == keys
    s_n0 = th.summary(FIG9["c"], n0=47.0)
    assert set(s_n0) == keys | {"theta_s"}
    assert s_n0["theta_s"] == th.theta_s(FIG9["c"], 47.0)
    assert s["group"] == "II" and s["nc"] == th.n4(FIG9["c"])
    for t in (*FIG9.values(), *FIG10.values(), FIG7):
        round_trip = json.loads(json.dumps(th.summary(t, n0=40.0)))
        assert all(v is None or isinstance(v, str | float) for v in round_trip.values())
    assert th.summary(FIG7)["n1"] is None


# --------------------------------------------------------------------------------------------
# The root finder: scipy's brentq, step for step, without importing scipy
# --------------------------------------------------------------------------------------------


def _root_problems() -> list[tuple[str, object, float, float]]:
    """Every bracketed root the theory solves, over tops of all three groups and many spins."""
    out: list[tuple[str, object, float, float]] = []
    tops = [*FIG9.values(), *FIG10.values(), FIG7, top(1.0, 0.1), top(1.1, 0.05),
            top(0.97, 0.12), top(0.99, 0.2), top(1.4, 0.3, 0.9)]
    for t in tops:
        if th.group(t) == "II" and th.r_c(t) < t.A_over_C < 1.0 and float(th.D(t, 1.0)) < 0:
            out.append(("D", lambda x, t=t: float(th.D(t, x)), -1.0, 1.0))
        n1 = th.n1(t)
        if n1 is None:
            continue
        for n0 in np.linspace(n1 * 1.01, n1 * 3.0, 7):
            kap = float(th.kappa(t, th.jellett_from_spin(t, n0)))
            def g(x: float, t: TopParams = t, kap: float = kap) -> float:
                return th._g(t, x, kap)

            if th.group(t) == "III":
                out.append(("g3", g, th._cos_crossing(t), 1.0))
            elif g(-1.0) > 0.0 > g(1.0):
                out.append(("g2", g, -1.0, 1.0))
    return out


def test_brentq_is_scipys_bit_for_bit() -> None:
    """th.brentq returns exactly scipy.optimize.brentq's float on every root the theory solves.

    Tolerance: none (equality of floats). The port repeats scipy's C iteration operation for
    operation in IEEE double precision, so any difference would be a transcription error;
    scipy is imported here only (the theory does not import it, test_startup checks that).
    """
    scipy_optimize = pytest.importorskip("scipy.optimize")
    problems = _root_problems()
    assert len(problems) > 30 and {k for k, *_ in problems} == {"D", "g2", "g3"}
    for _, f, lo, hi in problems:
        ours = th.brentq(f, lo, hi)
        theirs = scipy_optimize.brentq(f, lo, hi, xtol=th.ROOT_XTOL, rtol=th.ROOT_RTOL,
                                       maxiter=200)
        assert ours == theirs, (lo, hi, ours, theirs)
    # and on textbook functions, loose and tight tolerances (more extrapolation steps)
    for f, lo, hi in [(math.cos, 0.0, 3.0), (lambda x: x**3 - 2 * x - 5, 2.0, 3.0),
                      (lambda x: math.exp(x) - 10.0, -5.0, 5.0), (lambda x: x - 0.3, 0.0, 1.0)]:
        for xtol in (1e-3, 1e-8, 2e-12, 1e-15):
            assert th.brentq(f, lo, hi, xtol=xtol) == scipy_optimize.brentq(
                f, lo, hi, xtol=xtol, rtol=th.ROOT_RTOL, maxiter=200)


def test_brentq_refuses_an_unbracketed_root() -> None:
    with pytest.raises(ValueError, match="different signs"):
        th.brentq(lambda x: x * x + 1.0, -1.0, 1.0)
    assert th.brentq(lambda x: x, 0.0, 1.0) == 0.0  # a root at an end is returned as it is
