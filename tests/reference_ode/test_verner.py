"""Verner's 9(8) pair (reference_ode/verner.py): tableau, order, interpolant, control, events.

The small problems with exact solutions are test_dop853.py's (decay, oscillator, guard, wall);
the tippe-top runs compare the method with DOP853 through ``simulate_ode``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest

from tippetop.reference_ode import dop853 as d
from tippetop.reference_ode import verner as v
from tippetop.reference_ode import verner_tableau as tab

from .test_dop853 import (
    T_GUARD,
    T_MARK,
    W,
    _osc_exact,
    _slope,
    decay_rhs,
    decay_watch,
    osc_guard_rhs,
    osc_rhs,
    osc_watch,
    wall_rhs,
)


@nb.njit(cache=True)
def kepler_rhs(y, p, dy):
    """Kepler's problem, r'' = -r / |r|^3 (GM = 1): nonlinear, so that every elementary
    differential enters; from pericentre (1 - e, 0) at speed sqrt((1 + e) / (1 - e)) the orbit
    has eccentricity e and period 2 pi, the state returning to the start."""
    r3 = (y[0] * y[0] + y[1] * y[1]) ** 1.5
    dy[0] = y[2]
    dy[1] = y[3]
    dy[2] = -y[0] / r3
    dy[3] = -y[1] / r3
    return 1.0


NS = tab.N_STAGES
A, B, C, E = tab.A[:NS, :NS], tab.B, tab.C[:NS], tab.E
B_HAT = B - E  # the embedded 8th-order weights


def _run(rhs, watch, y0, p, t_end, rtol, *, atol=1e-14, t_out=None, floor=-math.inf,
         max_steps=10**6, chunks=1):
    """Integrate to t_end in ``chunks`` calls of verner.run; (status, t, y, Y_out, stats)."""
    y = np.array(y0, dtype=float)
    t_out = np.array([t_end], dtype=float) if t_out is None else t_out
    Y = np.full((t_out.size, y.size), np.nan)
    stats = v.new_stats(y.size)
    t, i_out, status = 0.0, 0, d.STATUS_RUNNING
    for k in range(1, chunks + 1):
        status, t, i_out = v.run(rhs, watch, y, t, t_end * k / chunks, t_end,
                                 np.asarray(p, dtype=float), rtol, atol, max_steps, floor,
                                 t_out, Y, i_out, stats)
        if status != d.STATUS_RUNNING:
            break
    return status, t, y, Y, stats


def _osc_fixed_steps(h: float, n_steps: int) -> np.ndarray:
    y, _, _ = v.fixed_steps(osc_rhs, osc_watch, np.array([1.0, 0.0]), np.array([W, 0.0]), h,
                            n_steps)
    return y


def _osc_dense(h: float, xs: np.ndarray) -> np.ndarray:
    """One oscillator step of size h from (1, 0); the interpolant at the fractions xs."""
    p = np.array([W, 0.0])
    y0 = np.array([1.0, 0.0])
    _, _, K17 = v.fixed_steps(osc_rhs, osc_watch, y0.copy(), p, h, 1)
    K = np.ascontiguousarray(K17)
    F = np.empty((v.DEG, 2))
    v.dense_coeffs(osc_rhs, y0, h, p, K, F, np.empty(2))
    out = np.empty((xs.size, 2))
    for k, x in enumerate(xs):
        v.dense_eval(F, y0, float(x), out[k])
    return out


# ---------------------------------------------------------------- the tableau
# The coefficients are float64 roundings of Verner's exact values; |a_ij| <= 36, |b_i| <= 0.57,
# |b_i - b_hat_i| <= 2.7, so the sums below are exact to a few roundings of terms <= 36:
# ~1e-14 (measured <= 3.6e-15). A wrong digit shows far above TABLEAU_TOL: the next order's
# quadrature condition, which the pair need not meet, misses by 1.8e-6 (b) and 1.4e-5 (b_hat).
TABLEAU_TOL = 1e-13


def test_stage_row_sums_are_the_nodes_and_the_method_is_explicit() -> None:
    """sum_j a_ij = c_i for all 26 rows (stages, f(y_new), the interpolant's stages); a stage
    uses only earlier ones; sum b = sum b_hat = 1; the row of f(y_new) is b; c = 1 at 14, 15."""
    assert np.abs(tab.A.sum(axis=1) - tab.C).max() < TABLEAU_TOL
    assert np.all(np.triu(tab.A) == 0.0)
    assert np.array_equal(tab.A[NS, :NS], B) and tab.C[NS] == 1.0
    assert tab.C[14] == tab.C[15] == 1.0
    assert abs(B.sum() - 1.0) < TABLEAU_TOL and abs(B_HAT.sum() - 1.0) < TABLEAU_TOL


@pytest.mark.parametrize("k", range(1, 10))
def test_quadrature_order_conditions(k: int) -> None:
    """sum b_i c_i^(k-1) = 1/k for k = 1..9, and for b_hat up to k = 8."""
    assert abs(B @ C ** (k - 1) - 1.0 / k) < TABLEAU_TOL
    if k <= 8:
        assert abs(B_HAT @ C ** (k - 1) - 1.0 / k) < TABLEAU_TOL


def test_next_order_quadrature_conditions_fail() -> None:
    """The pair is 9(8), not more: the 10th (b) and 9th (b_hat) conditions miss."""
    assert abs(B @ C**9 - 1.0 / 10.0) > 1e-7
    assert abs(B_HAT @ C**8 - 1.0 / 9.0) > 1e-7


def test_tree_order_conditions() -> None:
    """Non-bushy trees of order 3 to 9: sum b_i Phi_i(t) = 1 / gamma(t) (b_hat to order 8)."""
    Ac = A @ C
    tall = C.copy()
    for _ in range(7):
        tall = A @ tall
    conditions = {
        "b.Ac = 1/6": (B @ Ac, 1 / 6),
        "b.(c*Ac) = 1/8": (B @ (C * Ac), 1 / 8),
        "b.(Ac)^2 = 1/20": (B @ Ac**2, 1 / 20),
        "b.A(c^7) = 1/72": (B @ (A @ C**7), 1 / 72),
        "b.(c^6*Ac) = 1/18": (B @ (C**6 * Ac), 1 / 18),
        "b.(c^3*A(c^4)) = 1/45": (B @ (C**3 * (A @ C**4)), 1 / 45),
        "b.(c^4*(Ac)^2) = 1/36": (B @ (C**4 * Ac**2), 1 / 36),
        "b.A(c*A(c^2)) = 1/90": (B @ (A @ (C * (A @ C**2))), 1 / 90),
        "b.AA(c^6) = 1/504": (B @ (A @ (A @ C**6)), 1 / 504),
        "b.A^7 c = 1/9!": (B @ tall, 1 / math.factorial(9)),
        "b_hat.(c^5*Ac) = 1/16": (B_HAT @ (C**5 * Ac), 1 / 16),
        "b_hat.A(c^6) = 1/56": (B_HAT @ (A @ C**6), 1 / 56),
    }
    for name, (value, expected) in conditions.items():
        assert abs(value - expected) < TABLEAU_TOL, name
    assert abs(B_HAT @ (A @ C**7) - 1 / 72) > 1e-7  # an order-9 tree b_hat need not meet


# The interpolant's weights b_i(x) are polynomials with coefficients up to 1.1e4 (cancelling):
# sums of ~20 such terms are exact to ~1e4 * 1e-16 * 20 = 2e-11; INTERP_TOL leaves 5x.
INTERP_TOL = 1e-10


def test_interpolant_conditions() -> None:
    """The 9th-order continuous extension over its 26 stages: b_i(1) = b_i (so it joins
    y_new) and 0 for f(y_new) and the extra stages; sum b_i(x) c_i^(k-1) = x^k / k for
    k = 1..9 and two non-bushy trees, at x = 0.3 and 0.8."""
    Cf, Af = tab.C, tab.A
    ones = np.ones(tab.INTERP_DEGREE)
    b1 = tab.R @ ones
    assert np.abs(b1[:NS] - B).max() < INTERP_TOL and np.abs(b1[NS:]).max() < INTERP_TOL
    for x in (0.3, 0.8):
        bx = tab.R @ x ** np.arange(1, tab.INTERP_DEGREE + 1)
        for k in range(1, 10):
            assert abs(bx @ Cf ** (k - 1) - x**k / k) < INTERP_TOL, (x, k)
        assert abs(bx @ (Af @ Cf) - x**3 / 6) < INTERP_TOL
        assert abs(bx @ (Af @ (Cf * (Af @ Cf**2))) - x**6 / 90) < INTERP_TOL


def _stability_boundary(b: np.ndarray) -> float:
    """Where |R(z)| first exceeds 1 on the negative real axis, R = 1 + sum_k z^k b.A^(k-1) 1
    the stability polynomial of the weights b (to 1e-4)."""
    coef, x = [1.0], np.ones(NS)
    for _ in range(NS):
        coef.append(b @ x)
        x = A @ x
    z = -np.arange(0.0, 8.0, 1e-4)
    unstable = np.abs(np.polynomial.polynomial.polyval(z, coef)) > 1.0
    return float(-z[np.argmax(unstable)])


def test_stiffness_threshold_sits_inside_the_real_stability_interval() -> None:
    """The real stability intervals are [-4.476, 0] for the 9th-order solution and
    [-3.879, 0] for the embedded one, whose amplified error estimate caps a stiff step.
    STIFF_HLAMBDA is inside, at 0.645 of the latter: between the tippe top's stiff steps
    (h lambda >= 2.69 measured) and its non-stiff ones (<= 2.14), see verner.py."""
    assert 4.47 < _stability_boundary(B) < 4.48
    embedded = _stability_boundary(B_HAT)
    assert 3.87 < embedded < 3.89
    assert 0.6 * embedded < v.STIFF_HLAMBDA < 0.7 * embedded


# ---------------------------------------------------------------- order and dense output
def test_fixed_step_order_is_nine() -> None:
    """One period of a Kepler orbit of eccentricity 1/2 in N fixed steps, N = 32 ... 128: the
    global error falls as h^9 or faster. Errors 8.1e-7 down to 1.7e-12 (far above round-off);
    the local slopes are 9.4-9.5 (measured: the h^10 term is not yet negligible there, Verner
    having made the 10th-order error coefficients small), the fitted one 9.43. An 8th-order
    method would fall below 9, and the 10th-order conditions fail (tests above): bound
    9.0 ... 9.9. (A linear problem is a poor probe: the stability polynomial's 10th
    coefficient misses 1/10! by only 2 %.)
    """
    ecc = 0.5
    y0 = np.array([1.0 - ecc, 0.0, 0.0, math.sqrt((1.0 + ecc) / (1.0 - ecc))])
    n_steps = np.array([32, 48, 64, 96, 128])
    errs = []
    for n in n_steps:
        y, _, _ = v.fixed_steps(kepler_rhs, decay_watch, y0.copy(), np.array([0.0]),
                                2.0 * math.pi / n, int(n))
        errs.append(float(np.abs(y - y0).max()))
    assert all(a > b for a, b in zip(errs, errs[1:], strict=False))
    assert 9.0 < _slope(1.0 / n_steps, errs) < 9.9


def test_interpolant_is_ninth_order() -> None:
    """The interpolant inside one step (x = 1/4, 1/2, 3/4) against the exact solution: a
    9th-order interpolant has a local error O(h^10): over h = 0.2 ... 0.05 (errors 1.2e-6 to
    2.2e-12, above round-off) the fitted slope is
    9.87 (measured); bound 10 +- 0.6. At the step's ends it reproduces y_old and y_new
    to the rounding of its weights' coefficients (up to 1.1e4, cancelling to O(1)):
    ~1e4 eps h |f| = 1.4e-12 here (measured 5e-12); bound 2e-11."""
    xs = np.array([0.25, 0.5, 0.75])
    hs = 0.2 / 2 ** (np.arange(5) / 2)
    errs = [float(np.abs(_osc_dense(h, xs) - _osc_exact(xs * h).T).max()) for h in hs]
    assert abs(_slope(hs, errs) - 10.0) < 0.6
    ends = _osc_dense(0.1, np.array([0.0, 1.0]))
    assert np.abs(ends[0] - [1.0, 0.0]).max() < 1e-15
    assert np.abs(ends[1] - _osc_fixed_steps(0.1, 1)).max() < 2e-11


# ---------------------------------------------------------------- adaptive runs
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


def test_adaptive_decay_error_tracks_rtol() -> None:
    """y' = -y to t = 5, atol negligible (1e-20): the largest relative error over 51 samples
    (interpolant) is 0.04 ... 1.2 rtol (measured) for rtol 1e-4 ... 1e-12: bound 10 rtol. It
    falls as rtol falls, by at least 10x per 100x of rtol (measured 16x to 200x)."""
    t_out = np.linspace(0.0, 5.0, 51)
    errs = []
    for rtol in RTOLS:
        status, t, _, Y, _ = _run(decay_rhs, decay_watch, [1.0], [1.0], 5.0, rtol, atol=1e-20,
                                  t_out=t_out)
        assert status == d.STATUS_OK and t == 5.0
        err = float(np.max(np.abs(Y[:, 0] - np.exp(-t_out)) / np.exp(-t_out)))
        assert err < 10.0 * rtol, rtol
        errs.append(err)
    assert all(b < a / 10.0 for a, b in zip(errs, errs[1:], strict=False))


def test_adaptive_oscillator_error_tracks_rtol() -> None:
    """Five periods of the oscillator: the largest error over 101 samples, relative to each
    component's amplitude (1 and w), is 0.28 ... 1.4 rtol (measured) for rtol 1e-4 ... 1e-12
    (atol 1e-14): bound 10 rtol. It falls by at least 10x per 100x of rtol."""
    t_out = np.linspace(0.0, 5.0, 101)
    exact = _osc_exact(t_out).T
    errs = []
    for rtol in RTOLS:
        status, _, _, Y, _ = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, rtol,
                                  t_out=t_out)
        assert status == d.STATUS_OK
        err = float(np.max(np.abs(Y - exact) / [1.0, W]))
        assert err < 10.0 * rtol, rtol
        errs.append(err)
    assert all(b < a / 10.0 for a, b in zip(errs, errs[1:], strict=False))


def test_chunked_run_resumes_exactly() -> None:
    """Seven calls carrying ``stats`` end in the same state, bit for bit, with the same steps
    as one call: each call only re-evaluates f at its start (6 more rhs)."""
    one = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9)
    seven = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9, chunks=7)
    assert one[0] == seven[0] == d.STATUS_OK
    assert np.array_equal(one[2], seven[2])
    assert one[4][d.S_NSTEPS] == seven[4][d.S_NSTEPS]
    assert seven[4][d.S_NRHS] - one[4][d.S_NRHS] == 6


def test_max_steps_status() -> None:
    status, t, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9,
                                  max_steps=5)
    assert status == d.STATUS_MAX_STEPS and stats[d.S_NSTEPS] == 5 and 0.0 < t < 5.0


def test_nan_rhs_ends_in_step_size_underflow() -> None:
    """y' = 1 that turns NaN at y = 1/2: the control shrinks the step until it underflows just
    short of t = 1/2 (within 1e-14: 10 ulp of t), with a finite state."""
    status, t, y, _, _ = _run(wall_rhs, decay_watch, [0.0], [0.5], 1.0, 1e-8)
    assert status == d.STATUS_STEP_TOO_SMALL
    assert 0.5 - 1e-14 < t <= 0.5
    assert np.isfinite(y).all()


def test_stiffness_detector() -> None:
    """y' = -k y: for k = 1 no step is flagged (h lambda = h k, measured 1.15 at most);
    for k = 1000 the steps are held at the stability border: 215 of 238 flagged (measured),
    bound more than half."""
    *_, calm = _run(decay_rhs, decay_watch, [1.0], [1.0], 5.0, 1e-6, atol=1e-12)
    assert calm[d.S_NSTIFF] == 0 and calm[d.S_HLAMBDA_MAX] < v.STIFF_HLAMBDA
    *_, stiff = _run(decay_rhs, decay_watch, [1.0], [1000.0], 1.0, 1e-6, atol=1e-12)
    assert stiff[d.S_NSTIFF] > 0.5 * stiff[d.S_NSTEPS]
    assert stiff[d.S_HLAMBDA_MAX] > v.STIFF_HLAMBDA


# ---------------------------------------------------------------- events
def test_mark_event_located_and_run_goes_on() -> None:
    """x = cos(2 pi t) first falls through 0 at t = 1/4: located on the interpolant to 1e-12
    at rtol 1e-12 (measured 1.1e-13; the interpolant's error ~1e-13 moves the root by
    ~1e-13 / |x'| = 2e-14). Only the first crossing is kept; the run carries on to t_end."""
    status, t, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 2.0, 1e-12)
    assert status == d.STATUS_OK and t == 2.0
    assert abs(stats[d.S_T_MARK] - T_MARK) < 1e-12


def test_no_mark_crossing_leaves_nan() -> None:
    *_, stats = _run(decay_rhs, decay_watch, [1.0], [1.0], 1.0, 1e-9)
    assert math.isnan(stats[d.S_T_MARK])


def test_guard_crossing_stops_the_run_there() -> None:
    """The guard x - 1/2 falls through 0 at t = 1/6: the run stops there with the guard
    status, t and x to 1e-12 (rtol 1e-12), the state put on the interpolant at that time, and
    the samples after it left unwritten."""
    t_out = np.array([0.0, 0.1, 0.2, 0.3])
    status, t, y, Y, _ = _run(osc_guard_rhs, osc_watch, [1.0, 0.0], [W, 0.5], 2.0, 1e-12,
                              t_out=t_out)
    assert status == d.STATUS_GUARD
    assert abs(t - T_GUARD) < 1e-12
    assert np.abs(y - _osc_exact(T_GUARD)).max() < 1e-10 * W
    assert abs(y[0] - 0.5) < 1e-12
    assert np.abs(Y[:2] - _osc_exact(t_out[:2]).T).max() < 1e-10 * W
    assert np.isnan(Y[2:]).all()


def test_guard_not_positive_at_start() -> None:
    status, t, y, _, stats = _run(osc_guard_rhs, osc_watch, [0.5, 0.0], [W, 0.5], 1.0, 1e-9)
    assert status == d.STATUS_GUARD and t == 0.0 and stats[d.S_NSTEPS] == 0
    assert np.array_equal(y, [0.5, 0.0])


def test_monitor_floor_stops_at_a_step_end() -> None:
    """The monitor v = -w sin(w t) first drops below -w/2 after t = 1/12: the run stops at the
    first step end below the floor and records that value as the smallest monitor."""
    status, t, y, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9,
                                  floor=-W / 2)
    assert status == d.STATUS_MONITOR
    assert t > 1.0 / 12.0 and y[1] < -W / 2
    assert stats[d.S_MONITOR_MIN] == y[1]


# ---------------------------------------------------------------- the tippe top
@pytest.mark.parametrize("law", ["friction.Lambda_mps=1e-6", "friction.law=coulomb"])
def test_stiff_fig3_rolls_with_vern9(law: str) -> None:
    """test_stiff.py's stiff scenarios with ode.method = vern9: Fig. 3 for 0.5 s at Lambda =
    1e-6 m/s, and with the exact Coulomb law's ramp (v_eps = 1e-5 m/s). The detector (h lambda
    > 2.5) starts one rolling phase early (the slip relaxes by ~0.05 s), theta(t) stays within
    test_stiff.THETA_TOL (1e-7 rad) of the law integrated throughout at rtol 1e-11 (DOP853;
    measured 1e-9 and 6e-9 rad, as DOP853's rolling runs), for under 2 % of the law's
    evaluations (measured 2 % and 0.4 %)."""
    from .test_stiff import THETA_TOL, _plan
    from .test_stiff import _run as run_plan

    fast = run_plan(_plan("fig3", law, "run.t_end_s=0.5", "ode.method=vern9"))
    tight = run_plan(_plan("fig3", law, "run.t_end_s=0.5"), stiff="off", rtol=1e-11)
    assert fast.method == "vern9" and fast.status == tight.status == "ok"
    assert fast.stiff == "rolling" and len(fast.rolling) == 1
    assert 0.0 < fast.rolling[0]["t_start"] < 0.1
    d_theta = np.abs(fast.table["theta"].to_numpy() - tight.table["theta"].to_numpy())
    assert d_theta.max() < THETA_TOL
    assert fast.n_rhs < 0.025 * tight.n_rhs


@pytest.mark.parametrize(("scene", "overrides"), [
    ("fig3", ("friction.Lambda_mps=1e-4",)), ("fig7b", ("run.t_end_s=10",))])
def test_detector_leaves_non_stiff_runs_alone(scene: str, overrides: tuple[str, ...]) -> None:
    """The runs with the largest h lambda that are not stiff (measured 2.14 on Fig. 3 at
    Lambda = 1e-4 m/s over 8 s, 1.83 on the catalogue's Fig. 7 (b) at the paper's 1e-2):
    no step flagged, no rolling phase."""
    from .test_stiff import _plan
    from .test_stiff import _run as run_plan

    res = run_plan(_plan(scene, *overrides, "ode.method=vern9"))
    assert res.status == "ok" and res.stiff_steps == 0 and res.rolling == []


def test_stem_run_with_vern9() -> None:
    """test_stem.py's Fig. 3 top with its stem, 4 s, with ode.method = vern9: the same contact
    phases as DOP853's run, the stem touching at the same time (to 1e-7 s: both locate it on
    their dense output at rtol 1e-9; measured 2.2e-9 s)."""
    from .test_stem import _run as run_stem

    _, dop = run_stem()
    _, ver = run_stem("ode.method=vern9")
    assert ver.method == "vern9" and ver.status == dop.status == "ok"
    assert [p["contact"] for p in ver.phases] == [p["contact"] for p in dop.phases]
    assert abs(ver.t_stem - dop.t_stem) < 1e-7
