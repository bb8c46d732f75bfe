"""The variable-order Adams PECE kernel (reference_ode/adams.py): the dop853 contract.

The small problems with exact solutions are dop853's (tests/reference_ode/test_dop853.py),
compiled here again: decay y' = -k y; the oscillator x' = v, v' = -w^2 x from (1, 0) with
w = 2 pi (its mark x first falls through 0 at t = 1/4, its monitor is v; ``osc_guard_rhs``
has the guard x - 1/2, through 0 at t = 1/6); ``wall_rhs``, y' = 1 turning NaN at y = p[0].
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction

import numba as nb
import numpy as np

from tippetop.models.params import FrictionParams, InitialState, TopParams
from tippetop.models.resolve import resolve_plan
from tippetop.models.scene import load_scene
from tippetop.reference_ode import adams as a
from tippetop.reference_ode import dop853 as d
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.solve import initial_state_vector, simulate_ode
from tippetop.reference_ode.top import FORMULATIONS

W = 2.0 * math.pi
T_MARK = 0.25
T_GUARD = 1.0 / 6.0
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


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
    dy[0] = 1.0 if y[0] < p[0] else math.nan
    return 1.0


def _osc_exact(t):
    t = np.asarray(t, dtype=float)
    return np.array([np.cos(W * t), -W * np.sin(W * t)])


def _run(rhs, watch, y0, p, t_end, rtol, *, atol=1e-14, t_out=None, floor=-math.inf,
         max_steps=10**6, chunks=1, stats=None):
    """Integrate to t_end in ``chunks`` calls of :func:`adams.run`; (status, t, y, Y, stats)."""
    y = np.array(y0, dtype=float)
    t_out = np.array([t_end], dtype=float) if t_out is None else t_out
    Y = np.full((t_out.size, y.size), np.nan)
    stats = a.new_stats(y.size) if stats is None else stats
    t, i_out, status = 0.0, 0, d.STATUS_RUNNING
    for k in range(1, chunks + 1):
        status, t, i_out = a.run(rhs, watch, y, t, t_end * k / chunks, t_end,
                                 np.asarray(p, dtype=float), rtol, atol, max_steps, floor,
                                 t_out, Y, i_out, stats)
        if status != d.STATUS_RUNNING:
            break
    return status, t, y, Y, stats


# ---------------------------------------------------------------- the method
def _pece_radius(k: int, z: float) -> float:
    """Spectral radius of one equal step of the PECE pair on y' = lambda y, z = h lambda:
    p = y_n + z sum_{i<k} gamma_i nabla^i y_n (Adams-Bashforth in backward differences,
    gamma_i the exact rationals), y_{n+1} = p + gamma_k z (p - sum_{i<k} nabla^i y_n)."""
    gam = [Fraction(1)]
    for i in range(1, k + 1):
        gam.append(1 - sum(gam[j] / (i + 1 - j) for j in range(i)))
    pred = np.zeros(k)
    ext = np.zeros(k)
    for i in range(k):
        for j in range(i + 1):
            c = (-1) ** j * math.comb(i, j)
            pred[j] += z * float(gam[i]) * c
            ext[j] += c
    pred[0] += 1.0
    M = np.eye(k, k, -1)
    M[0] = pred + float(gam[k]) * z * (pred - ext)
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def test_stability_boundaries_of_the_table() -> None:
    """STAB_BOUNDARY (the stiffness threshold's scale): stable on (-0.99 b, 0) sampled at 200
    points, unstable at -1.01 b (the table has 3-4 digits). Order 1 is Heun's method: 2."""
    for k in range(1, a.MAX_ORDER + 1):
        b = a.STAB_BOUNDARY[k]
        assert max(_pece_radius(k, -x) for x in np.linspace(1e-3, 0.99, 200) * b) <= 1 + 1e-9
        assert _pece_radius(k, -1.01 * b) > 1.0, k
    assert a.STAB_BOUNDARY[1] == 2.0


def test_decay_error_tracks_rtol() -> None:
    """y' = -y to t = 5 (atol 1e-20): the largest relative error over 51 dense samples is
    0.1 ... 3 rtol (measured) for rtol 1e-4 ... 1e-12: bound 20 rtol (the error is per unit
    step, as Shampine-Gordon's, so it may add up over the 5 time units). It falls as rtol does,
    by at least 10x per 100x."""
    t_out = np.linspace(0.0, 5.0, 51)
    errs = []
    for rtol in RTOLS:
        status, t, _, Y, _ = _run(decay_rhs, decay_watch, [1.0], [1.0], 5.0, rtol, atol=1e-20,
                                  t_out=t_out)
        assert status == d.STATUS_OK and t == 5.0
        err = float(np.max(np.abs(Y[:, 0] - np.exp(-t_out)) / np.exp(-t_out)))
        assert err < 20.0 * rtol, rtol
        errs.append(err)
    assert all(b < a_ / 10.0 for a_, b in zip(errs, errs[1:], strict=False))


def test_oscillator_error_tracks_rtol() -> None:
    """Five periods: the largest error over 101 dense samples relative to the amplitudes
    (1, w) is 1 ... 8 rtol (measured) for rtol 1e-4 ... 1e-12: bound 50 rtol (error per unit
    step over 5 time units). It falls by at least 10x per 100x of rtol."""
    t_out = np.linspace(0.0, 5.0, 101)
    exact = _osc_exact(t_out).T
    errs = []
    for rtol in RTOLS:
        status, _, _, Y, _ = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, rtol,
                                  t_out=t_out)
        assert status == d.STATUS_OK
        err = float(np.max(np.abs(Y - exact) / [1.0, W]))
        assert err < 50.0 * rtol, rtol
        errs.append(err)
    assert all(b < a_ / 10.0 for a_, b in zip(errs, errs[1:], strict=False))


def test_the_order_reaches_twelve() -> None:
    """At rtol 1e-13 on the oscillator (20 periods, read after each of 2000 chunks, which
    resume exactly) the order of the accepted steps reaches 12, and most chunks end at order
    >= 10 (a smooth problem at a tight tolerance wants the highest orders)."""
    y = np.array([1.0, 0.0])
    stats = a.new_stats(2)
    t, orders = 0.0, []
    for c in range(1, 2001):
        _, t, _ = a.run(osc_rhs, osc_watch, y, t, 20.0 * c / 2000, 20.0, np.array([W, 0.0]),
                        1e-13, 1e-16, 10**6, -math.inf, np.empty(0), np.empty((0, 2)), 0, stats)
        orders.append(int(stats[a.A_KOLD]))
    assert max(orders) == a.MAX_ORDER
    assert np.mean(np.array(orders) >= 10) > 0.5
    assert np.abs(y - _osc_exact(20.0)).max() < 1e-9 * W


# ---------------------------------------------------------------- the contract
def test_chunked_run_resumes_exactly() -> None:
    """Seven calls carrying ``stats`` (the whole history) take the same steps as one call and
    end in the same state, bit for bit; each call only re-evaluates f at its start."""
    one = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9)
    seven = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9, chunks=7)
    assert one[0] == seven[0] == d.STATUS_OK
    assert np.array_equal(one[2], seven[2])
    assert one[4][d.S_NSTEPS] == seven[4][d.S_NSTEPS]
    assert one[4][d.S_NREJECT] == seven[4][d.S_NREJECT]
    assert seven[4][d.S_NRHS] - one[4][d.S_NRHS] == 6


def test_new_stats_starts_with_dop853s_slots() -> None:
    s = a.new_stats(11)
    assert np.array_equal(s[:d.N_STATS], d.new_stats(11), equal_nan=True)
    assert s.size > d.N_STATS + 16 * 11


def test_restart_with_s_h_zero() -> None:
    """``stats[S_H] = 0`` between calls: the next step is a fresh order-1 step, and the run
    stays accurate (10 rtol, as above) to its end."""
    y = np.array([1.0, 0.0])
    stats = a.new_stats(2)
    p = np.array([W, 0.0])
    args = (np.empty(0), np.empty((0, 2)), 0, stats)
    _, t, _ = a.run(osc_rhs, osc_watch, y, 0.0, 1.3, 5.0, p, 1e-9, 1e-14, 10**6, -math.inf,
                    *args)
    assert stats[a.A_KOLD] > 4
    stats[d.S_H] = 0.0
    n_steps = stats[d.S_NSTEPS]
    _, t, _ = a.run(osc_rhs, osc_watch, y, t, math.nextafter(t, 9.0), 5.0, p, 1e-9, 1e-14,
                    10**6, -math.inf, *args)  # one step
    assert stats[d.S_NSTEPS] == n_steps + 1 and stats[a.A_KOLD] == 1
    status, t, _ = a.run(osc_rhs, osc_watch, y, t, 5.0, 5.0, p, 1e-9, 1e-14, 10**6, -math.inf,
                         *args)
    assert status == d.STATUS_OK and t == 5.0
    assert np.abs(y - _osc_exact(5.0)).max() < 10 * 1e-9 * W


def test_max_steps_status() -> None:
    status, t, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9,
                                  max_steps=5)
    assert status == d.STATUS_MAX_STEPS and stats[d.S_NSTEPS] == 5 and 0.0 < t < 5.0


def test_nan_rhs_ends_in_step_size_underflow() -> None:
    """y' = 1 turning NaN at y = 1/2: NaN estimates are rejected, the step halves until it
    underflows (10 ulp of t) just short of t = 1/2, with a finite state."""
    status, t, y, _, _ = _run(wall_rhs, decay_watch, [0.0], [0.5], 1.0, 1e-8)
    assert status == d.STATUS_STEP_TOO_SMALL
    assert 0.5 - 1e-14 < t <= 0.5
    assert np.isfinite(y).all()


def test_mark_event_located_and_run_goes_on() -> None:
    """x = cos(2 pi t) first falls through 0 at t = 1/4: located on the dense output to 1e-12
    at rtol 1e-12 (the interpolant's error ~1e-12 moves the root by ~1e-12 / |x'| = 2e-13);
    the run carries on to t_end."""
    status, t, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 2.0, 1e-12)
    assert status == d.STATUS_OK and t == 2.0
    assert abs(stats[d.S_T_MARK] - T_MARK) < 1e-12


def test_guard_crossing_stops_the_run_there() -> None:
    """The guard x - 1/2 through 0 at t = 1/6: the run stops there (t and x to 1e-12 at rtol
    1e-12), the state on the dense output, the later samples unwritten."""
    t_out = np.array([0.0, 0.1, 0.2, 0.3])
    status, t, y, Y, _ = _run(osc_guard_rhs, osc_watch, [1.0, 0.0], [W, 0.5], 2.0, 1e-12,
                              t_out=t_out)
    assert status == d.STATUS_GUARD
    assert abs(t - T_GUARD) < 1e-12
    assert abs(y[0] - 0.5) < 1e-12
    assert np.abs(y - _osc_exact(T_GUARD)).max() < 1e-10 * W
    assert np.abs(Y[:2] - _osc_exact(t_out[:2]).T).max() < 1e-10 * W
    assert np.isnan(Y[2:]).all()


def test_guard_not_positive_at_start() -> None:
    status, t, y, _, stats = _run(osc_guard_rhs, osc_watch, [0.5, 0.0], [W, 0.5], 1.0, 1e-9)
    assert status == d.STATUS_GUARD and t == 0.0 and stats[d.S_NSTEPS] == 0
    assert np.array_equal(y, [0.5, 0.0])


def test_monitor_floor_stops_at_a_step_end() -> None:
    """v = -w sin(w t) first drops below -w/2 after t = 1/12: the run stops at the first step
    end below the floor; with no floor the smallest monitor is -w to within the step ends'
    spacing (above -w (1 + 1e-8), 10x the rtol)."""
    status, t, y, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9,
                                  floor=-W / 2)
    assert status == d.STATUS_MONITOR
    assert t > 1.0 / 12.0 and y[1] < -W / 2
    assert stats[d.S_MONITOR_MIN] == y[1]
    status, _, _, _, stats = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-9)
    assert status == d.STATUS_OK
    assert -W * (1.0 + 1e-8) <= stats[d.S_MONITOR_MIN] < -0.9 * W


def test_dense_output_samples() -> None:
    """500 samples over 5 periods at rtol 1e-12: within 1e-10 of the amplitude (the steps'
    own error is ~1e-12 relative, the interpolant of order k+1 adds its own of the same
    size; 1e-10 leaves 10x over the measured 1e-11)."""
    t_out = np.linspace(0.0, 5.0, 500)
    _, _, _, Y, _ = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, 1e-12, t_out=t_out)
    assert np.max(np.abs(Y - _osc_exact(t_out).T) / [1.0, W]) < 1e-10


def test_stiffness_detector() -> None:
    """y' = -k y: k = 1 flags no step; k = 1000 flags 229 of 711 steps (measured): every
    order-1..4 step, whose h k sits at its order's boundary; SG's order choice also runs orders
    5-9 at 0.84 of theirs, unflagged, as the detector looks only at orders <= 4 (so that the
    oscillator, at high orders with h |lambda| past their small real-axis boundaries, is not
    flagged: none at rtol 1e-4 ... 1e-12, measured). Bound: a quarter of the steps."""
    *_, calm = _run(decay_rhs, decay_watch, [1.0], [1.0], 5.0, 1e-6, atol=1e-12)
    assert calm[d.S_NSTIFF] == 0
    *_, stiff = _run(decay_rhs, decay_watch, [1.0], [1000.0], 1.0, 1e-6, atol=1e-12)
    assert stiff[d.S_NSTIFF] > 0.25 * stiff[d.S_NSTEPS]
    assert stiff[d.S_HLAMBDA_MAX] > a.STAB_BOUNDARY[1]
    for rtol in (1e-4, 1e-9, 1e-12):
        *_, osc = _run(osc_rhs, osc_watch, [1.0, 0.0], [W, 0.0], 5.0, rtol)
        assert osc[d.S_NSTIFF] == 0


def test_the_kernel_stops_on_stiff_steps_when_asked() -> None:
    """test_stiff's hook under Adams: Lambda = 1e-6 m/s, S_STIFF_STOP = 5 stops there."""
    top = TopParams.from_ratios(1.0, 0.1)
    p = pack_params(top, FrictionParams(Lambda_mps=1e-6))
    form = FORMULATIONS["vector"]
    for stop, expect_status in ((5.0, d.STATUS_STIFF), (math.inf, d.STATUS_OK)):
        y = initial_state_vector(top, InitialState(theta0=0.1, n0=100.0))
        stats = a.new_stats(y.size)
        stats[d.S_STIFF_STOP] = stop
        status, t, _ = a.run(form.rhs, form.watch, y, 0.0, 0.05, 0.05, p, 1e-9, 1e-12, 10**7,
                             -math.inf, np.array([0.0]), np.empty((1, y.size)), 0, stats)
        assert status == expect_status
        if stop < math.inf:
            assert stats[d.S_NSTIFF] == stop and t < 0.05


# ---------------------------------------------------------------- the tippe top
def test_stiff_fig3_rolls_under_adams() -> None:
    """Fig. 3 at Lambda = 1e-6 m/s for 0.5 s (test_stiff's short scenario): Adams's detector
    starts the one rolling phase DOP853's does (at 0.047 s, measured: the same 16 flagged
    steps), and theta agrees with the law at rtol 1e-11 within test_stiff's THETA_TOL (1e-7;
    measured 1.2e-10, as DOP853's)."""
    pl = resolve_plan(load_scene("fig3", ["friction.Lambda_mps=1e-6", "run.t_end_s=0.5"]),
                      "ode").ode

    def go(method, stiff="auto", rtol=1e-9):
        opts = replace(pl.options, method=method, rtol=rtol, atol=rtol * 1e-3)
        return simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s,
                            sample_dt_s=pl.sample_dt_s, options=opts, stiff=stiff)

    fast = go("adams")
    dop = go("dop853")
    tight = go("dop853", stiff="off", rtol=1e-11)
    assert fast.status == "ok" and fast.stiff == "rolling" and len(fast.rolling) == 1
    assert abs(fast.rolling[0]["t_start"] - dop.rolling[0]["t_start"]) < 0.01
    d_theta = np.abs(fast.table["theta"].to_numpy() - tight.table["theta"].to_numpy())
    assert d_theta.max() < 1e-7


def test_stem_run_under_adams() -> None:
    """Fig. 3 with its stem for 4 s (test_stem's run): the same contact phases as DOP853's,
    the stem's touch at the same time within 1e-7 s (both at rtol 1e-9; measured 3e-9 s) and
    theta at the end within 1e-6 rad (measured 2e-8 after ten impacts)."""
    s = load_scene("fig3", ["run.t_end_s=4.0"])
    runs = [simulate_ode(s.top, s.friction, s.init, t_end_s=4.0,
                         options=replace(s.ode, method=m), stem=s.stem)
            for m in ("dop853", "adams")]
    ref, res = runs
    assert res.status == ref.status == "ok"
    assert [p["contact"] for p in res.phases] == [p["contact"] for p in ref.phases]
    assert abs(res.t_stem - ref.t_stem) < 1e-7
    assert abs(res.table["theta"].iloc[-1] - ref.table["theta"].iloc[-1]) < 1e-6
