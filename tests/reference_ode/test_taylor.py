"""The Taylor method (reference_ode/taylor.py, taylor_jet.py): its jet, its order, the top.

The jet is checked three ways: its first coefficients are the compiled right-hand side (the
same equations, written with three identities of the exact solution: |q| constant, k' = w x k,
k . kd = 0); every coefficient to the order is checked by the series' error, which must shrink
as h^(P+1) against a tight DOP853 solution (a wrong k-th coefficient leaves an error of order
h^k); and, where heyoka is installed, coefficient by coefficient against heyoka's jet of the
same system (reference_ode/taylor_peer.py). Then the method on the tops: the paper's digits
and the other formulation are test_methods.py's, the inversion and the samples against DOP853
here, the stiff top's hand-over, chunks, and what it does not run.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tippetop.models.errors import TippetopError
from tippetop.models.options import FORMULATIONS as FORMULATION_NAMES
from tippetop.models.options import OdeOptions, method_title, taylor_order, taylor_runs
from tippetop.models.params import FRICTION_LAWS, FrictionParams, InitialState, TopParams
from tippetop.models.resolve import resolve_plan
from tippetop.models.scene import load_scene
from tippetop.reference_ode import dop853 as d
from tippetop.reference_ode import taylor
from tippetop.reference_ode.params_array import pack_params
from tippetop.reference_ode.solve import initial_state_vector, simulate_ode
from tippetop.reference_ode.taylor_jet import (
    JET_VARS,
    N_ROWS,
    ROW_N,
    SUM_ORDERS,
    Constants,
    by_depth,
    jet_system,
    op_lines,
    rate_line,
)
from tippetop.reference_ode.top import FORMULATIONS

#: Two tops: a sphere's inertia (A = C, the symmetric jet) and A/C = 0.8 (the general one).
TOPS = {"sym": TopParams.from_ratios(1.0, 0.15), "gen": TopParams.from_ratios(0.8, 0.3)}


def _states(top: TopParams, n: int = 10) -> list[np.ndarray]:
    rng = np.random.default_rng(11)
    out = []
    for _ in range(n):
        y = initial_state_vector(top, InitialState(theta0=rng.uniform(0.1, 3.0), n0=60.0))
        y[2:4] = rng.normal(0.0, 0.05, 2)  # a slip of a few cm/s
        y[8:11] += rng.normal(0.0, 5.0, 3)
        out.append(y)
    return out


def _jet(order: int, p: np.ndarray, y: np.ndarray) -> np.ndarray:
    T = np.zeros((N_ROWS, order + 1))
    taylor.kernel(order, taylor.is_symmetric(p)).jet(y, p, T)
    return T


@pytest.mark.parametrize("kind", ["sym", "gen"])
def test_the_jet_starts_with_the_rhs(kind: str) -> None:
    """Coefficient 1 is f(y), coefficient 0 of N the rhs's guard: 1e-12 of the largest rate
    (the same terms, some reassociated and the identities used: a few ulp, ~1e-15; a wrong
    term is at least ~1e-6 of |f| at these states)."""
    top = TOPS[kind]
    p = pack_params(top, FrictionParams())
    assert taylor.is_symmetric(p) == (kind == "sym")
    for y in _states(top):
        dy = np.empty(11)
        N = FORMULATIONS["vector"].rhs(y.copy(), p, dy)
        T = _jet(8, p, y)
        np.testing.assert_array_equal(T[:11, 0], y)
        assert np.max(np.abs(T[:11, 1] - dy)) <= 1e-12 * np.max(np.abs(dy))
        assert abs(T[ROW_N, 0] - N) <= 1e-12 * abs(N)


@pytest.mark.parametrize(("kind", "order"), [("sym", 8), ("gen", 8), ("sym", 12)])
def test_the_series_has_its_order(kind: str, order: int) -> None:
    """The series summed at h and at h/2 against DOP853 at rtol 1e-14 from the same state: the
    error ratio is 2^(P+1) for a jet right to order P (P = 8: 512). Measured 463 (sym, 8), 500
    (gen, 8) and 8406 (sym, 12; 2^13 = 8192) at these steps, whose errors (5e-5..5e-9) stand far
    above the truth's (~1e-14); a wrong coefficient k <= P gives 2^k at most (half the ratio).
    Bounds: 0.6 and 1.6 of 2^(P+1)."""
    top = TOPS[kind]
    p = pack_params(top, FrictionParams())
    form = FORMULATIONS["vector"]
    y0 = _states(top, 1)[0]
    T = _jet(order, p, y0)
    h = {("sym", 8): 0.02, ("gen", 8): 0.01, ("sym", 12): 0.04}[(kind, order)]
    errs = []
    for hh in (h, h / 2):
        series = np.array([np.polyval(T[i, ::-1], hh) for i in range(11)])
        y = y0.copy()
        status, t, _ = d.dop853_run(form.rhs, form.watch, y, 0.0, hh, hh, p, 1e-14, 1e-17,
                                    10**6, -math.inf, np.empty(0), np.empty((0, 11)), 0,
                                    d.new_stats())
        assert status == d.STATUS_OK
        errs.append(np.max(np.abs(series - y)[8:11]))
    ratio = errs[0] / errs[1]
    assert 0.6 * 2 ** (order + 1) < ratio < 1.6 * 2 ** (order + 1), (errs, ratio)


@pytest.mark.parametrize("kind", ["sym", "gen"])
def test_the_jet_is_heyokas(kind: str) -> None:
    """Coefficient by coefficient against heyoka's jet of the same system at order 12: 1e-10
    of each order's largest coefficient (measured <= 5e-14: the recurrences differ in
    association and in the identities; a wrong term moves a coefficient by far more)."""
    pytest.importorskip("heyoka")
    import heyoka as hy

    from tippetop.reference_ode.taylor_peer import vector_system

    top = TOPS[kind]
    p = pack_params(top, FrictionParams())
    for y in _states(top, 3):
        ta = hy.taylor_adaptive(vector_system(p), y.copy(), tol=1e-10, compact_mode=True)
        order = int(ta.order)
        ta.step(write_tc=True)
        T = _jet(12, p, y)
        for k in range(min(order, 12) + 1):
            ref = ta.tc[:, k]
            assert np.max(np.abs(T[:11, k] - ref)) <= 1e-10 * max(np.max(np.abs(ref)), 1e-300)


class _Values(dict):
    """Every name a statement reads, a random number in [0.5, 1.5] (the same for both forms)."""

    def __init__(self) -> None:
        super().__init__(math=math)
        self.rng = np.random.default_rng(5)

    def __missing__(self, name: str) -> float:
        self[name] = float(self.rng.uniform(0.5, 1.5))
        return self[name]


@pytest.mark.parametrize("symmetric", [True, False])
def test_the_sums_in_either_order_are_the_same_sums(symmetric: bool) -> None:
    """The latency order (the kernel's) gives every product, square, power, quotient and rate
    the value the index order gives, at random inputs in [0.5, 1.5]: 1e-12 (rounding of up to 13
    terms near 1: ~1e-15; a term lost or doubled in the regrouping moves it by >= 0.25), and
    puts the terms of the newest coefficient (index k) last, which is its point
    (benchmarks/bench_jet_sums.py)."""
    ops, rate = jet_system(symmetric)
    values = _Values()
    for k in range(13):
        for nm, kind, args in ops:
            got = []
            for sums in ("plain", "latency"):
                env = _Values()
                env.update(values)
                for line in op_lines(nm, kind, args, k, Constants(), sums):
                    exec(line, {}, env)  # noqa: S102 - the generator's own statements
                values.update({n: v for n, v in env.items() if n not in values})
                got.append(env[f"{nm}_{k}"])
            assert abs(got[0] - got[1]) <= 1e-12 * max(1.0, abs(got[0])), (nm, k, got)
            if kind in ("mul", "powm", "div") and k >= 2:
                rhs = op_lines(nm, kind, args, k, Constants(), "latency")[-1]
                newest = f"{args[1 if kind == 'div' else 0]}_{k}"
                tail = rhs.rsplit(")", 1)[-1] if kind == "mul" else rhs.rsplit(") + ", 1)[-1]
                assert newest in tail, (nm, k, rhs)
        for v in JET_VARS:
            got = []
            for sums in ("plain", "latency"):
                env = _Values()
                env.update(values)
                exec(rate_line(v, k, rate, Constants(), sums), {}, env)  # noqa: S102
                got.append(env[f"{v}_{k + 1}"])
            assert abs(got[0] - got[1]) <= 1e-12 * max(1.0, abs(got[0])), (v, k, got)
    # the latency jet's operations in depth order (by_depth): the same terms, the latest last
    ordered, ordered_rate = by_depth(ops, rate)
    for (nm, kind, args), (nm2, kind2, args2) in zip(ops, ordered, strict=True):
        assert (nm, kind) == (nm2, kind2)
        if kind == "lin":
            assert sorted(args[0]) == sorted(args2[0]) and args[1] == args2[1]
        else:
            assert sorted(map(str, args)) == sorted(map(str, args2))
    assert {v: sorted(t) for v, t in rate.items()} == {v: sorted(t) for v, t in
                                                       ordered_rate.items()}
    vpx = next(args for nm, kind, args in ordered if nm == "vpx")
    assert vpx[0][-1][1] == "kdx"  # the term of this order's product last, the state's first
    with pytest.raises(ValueError, match="expected a sum order of latency, plain"):
        op_lines("a1", "mul", ("wx", "kx"), 3, Constants(), "fast")
    assert SUM_ORDERS == ("latency", "plain")


def test_the_order_follows_the_tolerance() -> None:
    """The rule (models.options.TAYLOR_ORDERS) and what a run and a plan say of it."""
    assert taylor_order(1e-3) == 7 and taylor_order(1e-4) == 7
    assert taylor_order(9e-5) == 9 and taylor_order(1e-5) == 9
    assert taylor_order(9e-6) == 10 and taylor_order(1e-6) == 10
    assert taylor_order(9e-7) == 12 and taylor_order(1e-13) == 12
    assert method_title("taylor", 1e-4) == "taylor (order 7)"
    assert method_title("adams", 1e-4) == "adams"
    pl = resolve_plan(load_scene("fig3", ["ode.method=taylor", "ode.rtol=1e-5"]), "ode").ode
    assert pl.what_runs()["method"] == "taylor (order 9)"
    res = simulate_ode(pl.top, pl.friction, pl.init, t_end_s=0.2, options=pl.options)
    assert res.method == "taylor (order 9)"


# ---------------------------------------------------------------- the tippe top
def test_a_run_in_chunks_is_one_run() -> None:
    """The method keeps no history and its steps end at t_end only: the chunks a progress
    display asks for (solve.N_CHUNKS) change no step, so the tables are equal bit for bit."""
    pl = resolve_plan(load_scene("fig3", ["run.t_end_s=2.0", "ode.method=taylor"]), "ode").ode

    def go(progress=None):
        return simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s,
                            sample_dt_s=pl.sample_dt_s, options=pl.options, progress=progress)

    one, chunked = go(), go(lambda t: None)
    assert one.method == chunked.method == "taylor (order 12)"
    np.testing.assert_array_equal(one.states, chunked.states)
    assert one.n_steps == chunked.n_steps


def test_stiff_fig3_hands_over_and_rolls() -> None:
    """Fig. 3 at Lambda = 1e-6 m/s for 0.5 s (test_stiff's short scenario): the Taylor method
    flags the steps where the law relaxes the slip 1000x faster than the top turns, hands the
    run to DOP853 (at 0.047 s, measured), whose detector starts the one rolling phase DOP853's
    own run does (within 0.01 s; measured the same time), and theta agrees with the law at
    rtol 1e-11 within test_stiff's THETA_TOL (1e-7)."""
    pl = resolve_plan(load_scene("fig3", ["friction.Lambda_mps=1e-6", "run.t_end_s=0.5"]),
                      "ode").ode

    def go(method, stiff="auto", rtol=1e-9):
        opts = replace(pl.options, method=method, rtol=rtol, atol=rtol * 1e-3)
        return simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s,
                            sample_dt_s=pl.sample_dt_s, options=opts, stiff=stiff)

    fast = go("taylor")
    dop = go("dop853")
    tight = go("dop853", stiff="off", rtol=1e-11)
    assert fast.status == "ok" and fast.stiff == "rolling" and len(fast.rolling) == 1
    assert fast.method.startswith("taylor (order 12) at rtol 1e-09, then dop853")
    assert abs(fast.rolling[0]["t_start"] - dop.rolling[0]["t_start"]) < 0.01
    d_theta = np.abs(fast.table["theta"].to_numpy() - tight.table["theta"].to_numpy())
    assert d_theta.max() < 1e-7


def test_the_kernel_stops_on_stiff_steps_when_asked() -> None:
    """Lambda = 1e-6 m/s: the slip's relaxation outruns the turning by far more than 1000x once
    the slip is small; S_STIFF_STOP = 5 stops there. The paper's Lambda (1 cm/s) flags none."""
    top = TopParams.from_ratios(1.0, 0.1)
    form = FORMULATIONS["vector"]
    for lam, stop, expect_status in ((1e-6, 5.0, d.STATUS_STIFF), (1e-6, math.inf, d.STATUS_OK),
                                     (1e-2, 5.0, d.STATUS_OK)):
        p = pack_params(top, FrictionParams(Lambda_mps=lam))
        y = initial_state_vector(top, InitialState(theta0=0.1, n0=100.0))
        stats = taylor.new_stats(y.size)
        stats[d.S_STIFF_STOP] = stop
        status, t, _ = taylor.run(form.rhs, form.watch, y, 0.0, 0.05, 0.05, p, 1e-9, 1e-12,
                                  10**7, -math.inf, np.array([0.0]), np.empty((1, y.size)), 0,
                                  stats)
        assert status == expect_status
        if expect_status == d.STATUS_STIFF:
            assert stats[d.S_NSTIFF] == stop and t < 0.05
        elif lam == 1e-2:
            assert stats[d.S_NSTIFF] == 0


def test_a_lost_contact_stops_where_n_falls_to_zero() -> None:
    """The guard N found on its series: a top tilted fast (theta_dot0 = 80 rad/s) leaves the
    table (at 0.0124 s, measured under DOP853); the stop agrees with DOP853's within 1e-9 s
    (both locate on their dense outputs to 2^-60 of a step; their states differ by ~1e-12 at
    rtol 1e-12 over so short a run)."""
    top = TopParams.from_ratios(1.0, 0.3)
    init = InitialState(theta0=1.0, n0=20.0, thetadot0=80.0)
    runs = [simulate_ode(top, FrictionParams(), init, t_end_s=1.0,
                         options=OdeOptions(method=m, rtol=1e-12, atol=1e-15))
            for m in ("dop853", "taylor")]
    ref, res = runs
    assert ref.status == res.status == "contact_lost"
    assert abs(ref.t_final - res.t_final) < 1e-9


def test_what_it_does_not_run() -> None:
    """A stem, another law or the paper's formulation: asked for by name, one line saying why;
    under auto, the rule for the other methods runs (and is said)."""
    for overrides in (["friction.law=coulomb"], ["ode.formulation=paper"]):
        with pytest.raises(TippetopError, match="got 'taylor'"):
            pl = resolve_plan(load_scene("fig3", [*overrides, "ode.method=taylor",
                                                  "run.t_end_s=0.1"]), "ode").ode
            simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s,
                         options=pl.options)
        pl = resolve_plan(load_scene("fig3", [*overrides, "run.t_end_s=0.1"]), "ode").ode
        res = simulate_ode(pl.top, pl.friction, pl.init, t_end_s=pl.t_end_s, options=pl.options)
        assert res.method.startswith("adams")  # AUTO_RULE at the scene's rtol 1e-9
    s = load_scene("fig3", ["run.t_end_s=0.1"])
    with pytest.raises(TippetopError, match="with no stem"):
        simulate_ode(s.top, s.friction, s.init, t_end_s=0.1,
                     options=replace(s.ode, method="taylor"), stem=s.stem)
    assert taylor.unsupported(FORMULATIONS["vector"].rhs,
                              pack_params(TOPS["sym"], FrictionParams(law="viscous"))) is not None


@pytest.mark.parametrize("law", FRICTION_LAWS)
@pytest.mark.parametrize("formulation", FORMULATION_NAMES)
def test_the_plan_and_the_kernel_agree_on_what_it_runs(formulation: str, law: str) -> None:
    """Which scenes run the method is decided from the plan's inputs (models.options); the
    kernel checks the compiled rhs and the packed parameters. The two must say the same for
    every formulation and law (a plan saying taylor for a run that falls back would report
    what did not run)."""
    p = pack_params(TOPS["gen"], FrictionParams(law=law))
    kernel_runs = taylor.unsupported(FORMULATIONS[formulation].rhs, p) is None
    assert taylor_runs(formulation, law, stem=False) == kernel_runs
    assert not taylor_runs(formulation, law, stem=True)
