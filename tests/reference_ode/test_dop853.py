"""The generic DOP853 kernel on its own: tableau, order, dense output, error control, events.

The right-hand sides are small problems with exact solutions, compiled in this module and
passed to the kernel as first-class functions (``reference_ode.top`` does the same for the
tippe top):

* decay: y' = -k y, y(t) = exp(-k t) (p = [k]);
* oscillator: x' = v, v' = -w^2 x from (1, 0): x = cos(w t), v = -w sin(w t), with w = 2 pi
  (period 1). Its mark is x (first falls through 0 at t = 1/4), its monitor v.
  ``osc_guard_rhs`` is the same system with the guard x - 1/2 (falls through 0 at t = 1/6).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest

from tippetop.reference_ode import dop853 as d

W = 2.0 * math.pi  # oscillator angular frequency: period 1
T_MARK = 0.25  # x = cos(w t) first falls through 0
T_GUARD = 1.0 / 6.0  # x = cos(w t) first falls to 1/2


# ---------------------------------------------------------------- test problems (compiled)
@nb.njit(cache=True)
def decay_rhs(y, p, dy):
    dy[0] = -p[0] * y[0]
    return 1.0


@nb.njit(cache=True)
def decay_watch(y, p):
    return 1.0, y[0]


@nb.njit(cache=True)
def osc_rhs(y, p, dy):
    dy[0] = y[1]
    dy[1] = -p[0] * p[0] * y[0]
    return 1.0


@nb.njit(cache=True)
def osc_guard_rhs(y, p, dy):
    dy[0] = y[1]
    dy[1] = -p[0] * p[0] * y[0]
    return y[0] - p[1]


@nb.njit(cache=True)
def osc_watch(y, p):
    return y[0], y[1]


@nb.njit(cache=True)
def wall_rhs(y, p, dy):
    """y' = 1 below y = p[0], NaN at and above it: a right-hand side that breaks down."""
    dy[0] = 1.0 if y[0] < p[0] else math.nan
    return 1.0


# ---------------------------------------------------------------- helpers
def _osc_exact(t: np.ndarray | float) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    return np.array([np.cos(W * t), -W * np.sin(W * t)])


def _run(rhs, watch, y0, p, t_end, rtol, *, atol=1e-14, t_out=None, floor=-math.inf,
         max_steps=10**6, chunks=1):
    """Integrate to t_end in ``chunks`` calls; (status, t, y, Y_out, stats)."""
    y = np.array(y0, dtype=float)
    t_out = np.array([t_end], dtype=float) if t_out is None else t_out
    Y = np.full((t_out.size, y.size), np.nan)
    stats = d.new_stats()
    t, i_out, status = 0.0, 0, d.STATUS_RUNNING
    for k in range(1, chunks + 1):
        status, t, i_out = d.dop853_run(rhs, watch, y, t, t_end * k / chunks, t_end,
                                        np.asarray(p, dtype=float), rtol, atol, max_steps, floor,
                                        t_out, Y, i_out, stats)
        if status != d.STATUS_RUNNING:
            break
    return status, t, y, Y, stats


def _osc_fixed_steps(h: float, n_steps: int) -> np.ndarray:
    """The oscillator's state after ``n_steps`` steps of size ``h`` from (1, 0), no control."""
    y, _, _ = d.fixed_steps(osc_rhs, osc_watch, np.array([1.0, 0.0]), np.array([W, 0.0]), h,
                            n_steps)
    return y


def _osc_dense(h: float, xs: np.ndarray) -> np.ndarray:
    """One oscillator step of size ``h`` from (1, 0); the dense output at the fractions xs
    (``dense_coeffs`` and ``dense_eval`` on the kernel's stage buffer of that step)."""
    p = np.array([W, 0.0])
    y0 = np.array([1.0, 0.0])
    y_new, _, K16 = d.fixed_steps(osc_rhs, osc_watch, y0.copy(), p, h, 1)
    K = np.ascontiguousarray(K16)
    F = np.empty((7, 2))
    ytmp = np.empty(2)
    d.dense_coeffs(osc_rhs, y0, y_new, K[d.N_STAGES].copy(), h, p, K, F, ytmp)
    out = np.empty((xs.size, 2))
    for k, x in enumerate(xs):
        d.dense_eval(F, y0, float(x), out[k])
    return out


def _slope(h: np.ndarray, err: list[float]) -> float:
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


# ---------------------------------------------------------------- the tableau
# The coefficients are stored to double precision and are at most 44 in size (|b_i| <= 5.8), so
# the sums below are exact up to ~10 roundings of such terms: ~1e-14. TABLEAU_TOL leaves 10x;
# a wrong digit in any coefficient shows far above it (the order-9 quadrature condition, which
# an 8th-order method need not meet, misses by 2.7e-5).
TABLEAU_TOL = 1e-13


def test_tableau_is_scipys_to_the_bit() -> None:
    """The coefficients written into ``dop853_tableau`` (so that a run does not import scipy)
    are scipy's DOP853 coefficients exactly: every entry equal, same shapes and dtype."""
    from scipy.integrate._ivp import dop853_coefficients as ref

    from tippetop.reference_ode import dop853_tableau as tab

    for name in ("A", "B", "C", "E3", "E5", "D"):
        ours, theirs = getattr(tab, name), getattr(ref, name)
        assert ours.dtype == theirs.dtype and ours.shape == theirs.shape, name
        assert np.array_equal(ours, theirs), name
    assert (tab.N_STAGES, tab.N_STAGES_EXTENDED, tab.INTERPOLATOR_POWER) == (
        ref.N_STAGES, ref.N_STAGES_EXTENDED, ref.INTERPOLATOR_POWER)


def test_the_integrator_does_not_import_scipy_integrate() -> None:
    """A fresh process that imports the reference ODE (kernel, formulations, solve) has not
    imported ``scipy.integrate`` (~0.4 s of every run's start-up). (numba itself imports the
    bare ``scipy`` package, ~20 ms.)"""
    import subprocess
    import sys

    code = ("import sys; import tippetop.reference_ode.solve; "
            "print('scipy.integrate' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[-1] == "False"


def test_stage_row_sums_are_the_nodes() -> None:
    """sum_j a_ij = c_i for the 12 stages and the 3 extra dense-output stages; sum b = 1."""
    assert np.abs(d.A.sum(axis=1) - d.C).max() < TABLEAU_TOL
    assert np.abs(d.A_EXTRA.sum(axis=1) - d.C_EXTRA).max() < TABLEAU_TOL
    assert abs(d.B.sum() - 1.0) < TABLEAU_TOL
    # explicit: a stage uses only earlier stages
    assert np.all(np.triu(d.A) == 0.0)


@pytest.mark.parametrize("k", range(1, 9))
def test_quadrature_order_conditions(k: int) -> None:
    """sum_i b_i c_i^(k-1) = 1/k for k = 1..8 (the bushy trees)."""
    assert abs(d.B @ d.C ** (k - 1) - 1.0 / k) < TABLEAU_TOL


def test_order_nine_quadrature_condition_fails() -> None:
    """The method is of order 8, not 9: sum b_i c_i^8 misses 1/9 (by 2.7e-5), so the
    conditions above are not met by accident of the tolerance."""
    assert abs(d.B @ d.C**8 - 1.0 / 9.0) > 1e-6


def test_tree_order_conditions() -> None:
    """A few non-bushy trees of order 3 to 8: sum b_i Phi_i(t) = 1 / gamma(t)."""
    A, B, C = d.A, d.B, d.C
    Ac = A @ C
    tall = C.copy()
    for _ in range(6):
        tall = A @ tall
    conditions = {
        "b.Ac = 1/6": (B @ Ac, 1 / 6),
        "b.(c*Ac) = 1/8": (B @ (C * Ac), 1 / 8),
        "b.A(c^2) = 1/12": (B @ (A @ C**2), 1 / 12),
        "b.AAc = 1/24": (B @ (A @ Ac), 1 / 24),
        "b.A(c^6) = 1/56": (B @ (A @ C**6), 1 / 56),
        "b.(c^5*Ac) = 1/16": (B @ (C**5 * Ac), 1 / 16),
        "b.(c^3*A(c^3)) = 1/32": (B @ (C**3 * (A @ C**3)), 1 / 32),
        "b.A^6 c = 1/8!": (B @ tall, 1 / math.factorial(8)),
    }
    for name, (value, expected) in conditions.items():
        assert abs(value - expected) < TABLEAU_TOL, name


# ---------------------------------------------------------------- order and dense output
def test_fixed_step_order_is_eight() -> None:
    """One oscillator period in N fixed steps, N = 8 ... 45: the global error falls as h^8.

    The errors run from 3.6e-7 down to 3.7e-13, far above round-off (~1e-15 per step); the
    fitted slope is 7.99 (measured), the bound 8 +- 0.5 tells order 8 from 7 or 9.
    """
    n_steps = np.array([8, 11, 16, 22, 32, 45])
    errs = [float(np.abs(_osc_fixed_steps(1.0 / n, int(n)) - [1.0, 0.0]).max())
            for n in n_steps]
    assert all(a > b for a, b in zip(errs, errs[1:], strict=False))
    assert abs(_slope(1.0 / n_steps, errs) - 8.0) < 0.5


def test_dense_output_is_seventh_order() -> None:
    """The dense output inside one step (x = 1/4, 1/2, 3/4 of it) against the exact solution.

    A 7th-order interpolant has a local error O(h^8): over h = 0.1 ... 0.025 (errors 2.4e-8 to
    3.3e-13, far above round-off) the fitted slope is 8.05 (measured); bound 8 +- 0.5. At the
    step's ends it reproduces y_old and y_new (to rounding: 1e-15).
    """
    xs = np.array([0.25, 0.5, 0.75])
    hs = 0.1 / 2 ** (np.arange(5) / 2)
    errs = [float(np.abs(_osc_dense(h, xs) - _osc_exact(xs * h).T).max()) for h in hs]
    assert abs(_slope(hs, errs) - 8.0) < 0.5
    ends = _osc_dense(0.1, np.array([0.0, 1.0]))
    assert np.abs(ends[0] - [1.0, 0.0]).max() < 1e-15
    assert np.abs(ends[1] - _osc_fixed_steps(0.1, 1)).max() < 1e-14


# ---------------------------------------------------------------- adaptive runs
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


def test_adaptive_decay_error_tracks_rtol() -> None:
    """y' = -y to t = 5, atol negligible (1e-20): the largest relative error over 51 samples
    (dense output) is 1.1 ... 2.6 rtol (measured) for rtol 1e-4 ... 1e-12: bound 10 rtol. It
    falls as rtol falls, by at least 10x per 100x of rtol (measured ~100x)."""
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
    component's amplitude (1 and w), is 2.2 ... 2.5 rtol (measured) for rtol 1e-4 ... 1e-12
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
    """Seven calls carrying ``stats`` (the step size) end in the same state, bit for bit, with
    the same steps as one call: each call only re-evaluates f at its start (6 more rhs)."""
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
    """y' = 1 that turns NaN at y = 1/2: every step reaching past it has a NaN error estimate;
    the control must shrink the step (not accept it, not hang) until it underflows just short
    of t = 1/2 (within 1e-14: the underflow is 10 ulp of t), with a finite state."""
    status, t, y, _, _ = _run(wall_rhs, decay_watch, [0.0], [0.5], 1.0, 1e-8)
    assert status == d.STATUS_STEP_TOO_SMALL
    assert 0.5 - 1e-14 < t <= 0.5
    assert np.isfinite(y).all()


def test_stiffness_detector() -> None:
    """y' = -k y: for k = 1 no step is flagged (h lambda = h k < 1, measured 0.99 at most); for
    k = 1000 the steps are held at the stability border: 150 of 176 flagged (measured), bound
    more than half."""
    *_, calm = _run(decay_rhs, decay_watch, [1.0], [1.0], 5.0, 1e-6, atol=1e-12)
    assert calm[d.S_NSTIFF] == 0 and calm[d.S_HLAMBDA_MAX] < d.STIFF_HLAMBDA
    *_, stiff = _run(decay_rhs, decay_watch, [1.0], [1000.0], 1.0, 1e-6, atol=1e-12)
    assert stiff[d.S_NSTIFF] > 0.5 * stiff[d.S_NSTEPS]
    assert stiff[d.S_HLAMBDA_MAX] > d.STIFF_HLAMBDA


# ---------------------------------------------------------------- events
def test_mark_event_located_and_run_goes_on() -> None:
    """x = cos(2 pi t) first falls through 0 at t = 1/4: located on the dense output to
    1e-12 at rtol 1e-12 (measured 2e-14; the bisection resolves 2^-60 of a step, the dense
    output's error ~1e-13 moves the root by ~1e-13 / |x'| = 2e-14). Only the first crossing is
    kept, and the run carries on to t_end."""
    status, t, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 2.0, 1e-12)
    assert status == d.STATUS_OK and t == 2.0
    assert abs(stats[d.S_T_MARK] - T_MARK) < 1e-12


def test_no_mark_crossing_leaves_nan() -> None:
    *_, stats = _run(decay_rhs, decay_watch, [1.0], [1.0], 1.0, 1e-9)
    assert math.isnan(stats[d.S_T_MARK])


def test_guard_crossing_stops_the_run_there() -> None:
    """The guard x - 1/2 falls through 0 at t = 1/6: the run stops there with the guard
    status, t to 1e-12 and x to 1e-12 (rtol 1e-12; measured 1e-14 and 1e-16), the state put on
    the dense output at that time, and the samples after it left unwritten."""
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
    """A start with the guard already <= 0 stops at once, no step taken."""
    status, t, y, _, stats = _run(osc_guard_rhs, osc_watch, [0.5, 0.0], [W, 0.5], 1.0, 1e-9)
    assert status == d.STATUS_GUARD and t == 0.0 and stats[d.S_NSTEPS] == 0
    assert np.array_equal(y, [0.5, 0.0])


def test_monitor_floor_stops_at_a_step_end() -> None:
    """The monitor v = -w sin(w t) first drops below -w/2 after t = 1/12: the run stops at the
    first step end below the floor with the monitor status, and records that value as the
    smallest monitor; with the floor at -inf the same run only records (min v = -w to within
    the step ends' spacing)."""
    status, t, y, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9,
                                  floor=-W / 2)
    assert status == d.STATUS_MONITOR
    assert t > 1.0 / 12.0 and y[1] < -W / 2
    assert stats[d.S_MONITOR_MIN] == y[1]
    status, _, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9)
    assert status == d.STATUS_OK
    assert -W * (1.0 + 1e-8) <= stats[d.S_MONITOR_MIN] < -0.9 * W  # 1e-8: 10x the rtol


# ---------------------------------------------------------------- on-disk cache
_CACHE_WARM = """
from tippetop.models.options import OdeOptions
from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.reference_ode.solve import simulate_ode
for form in ("vector", "paper"):
    simulate_ode(TopParams.from_ratios(1.0, 0.1), FrictionParams(), InitialState(theta0=0.1),
                 t_end_s=0.01, options=OdeOptions(formulation=form, method="dop853"))
"""
_CACHE_PROBE = _CACHE_WARM + """
import json
import numba
from tippetop.reference_ode import dop853, top
out = {}
for mod in (dop853, dop853.kernel(), top):
    for name, fn in vars(mod).items():
        if isinstance(fn, numba.core.registry.CPUDispatcher) and fn.__module__ == mod.__name__:
            out[name] = [sum(fn.stats.cache_hits.values()), sum(fn.stats.cache_misses.values())]
print(json.dumps(out))
"""


def test_second_process_compiles_nothing() -> None:
    """The kernel takes its functions as function pointers so that its compiled code can be
    cached (a kernel specialised on a dispatcher argument never is; see docs/design.md), and
    is written by the driver to a module of its own in the cache (reference_ode/driver.py). A
    process running both formulations must load every function from the cache and compile
    none. This process runs them first, so that the cache is warm (and written if it was
    cold)."""
    import json
    import subprocess
    import sys

    exec(_CACHE_WARM, {})
    proc = subprocess.run([sys.executable, "-c", _CACHE_PROBE], capture_output=True, text=True,
                          check=True)
    stats = json.loads(proc.stdout.strip().splitlines()[-1])
    assert stats["run"][0] == 1 and stats["vector_rhs"][0] >= 1
    assert stats["paper_rhs"][0] >= 1
    assert all(misses == 0 for _, misses in stats.values()), stats
