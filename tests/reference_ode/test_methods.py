"""Every integration method of the reference on the paper's cases, and ``auto``'s choice.

Each method (``ode.method``: dop853, vern9, adams, taylor) must reproduce the paper's digits and
agree with the other formulation as the default does; ``auto`` must run the method and tolerances
its rule names (reference_ode/methods.py, measured with ``tippetop bench ode --sweep``), and
say what ran. The methods' own kernels are tested in test_dop853.py, test_verner.py and
test_adams.py and test_taylor.py; the stiff and stem cases under each in test_verner.py,
test_adams.py and test_taylor.py.
"""

from __future__ import annotations

import math

import pytest

from tests.conftest import run_scene_ode
from tippetop.models.errors import TippetopError
from tippetop.models.options import ODE_METHODS, OdeOptions, method_title
from tippetop.reference_ode.methods import (
    AUTO_RULE,
    AUTO_TAYLOR,
    METHODS,
    choose_method,
    get_method,
)

NAMED = tuple(m for m in ODE_METHODS if m != "auto")
#: Sec. 4.4 prints theta_asymp = 2.49 for n0 = 60 (two decimals); test_paper_cases.FIG11_TOL.
FIG11_N060_THETA = 2.49
FIG11_TOL = 0.01


def test_the_registry_is_the_options_list() -> None:
    assert tuple(METHODS) == NAMED
    assert all(METHODS[m].order >= 8 for m in NAMED)
    with pytest.raises(TippetopError, match="ode.method"):
        OdeOptions(method="rk45")


@pytest.mark.parametrize(("rtol", "method", "factor"), [
    (1e-3, "dop853", 1.0), (1e-4, "dop853", 1.0), (1e-5, "adams", 1e-3),
    (1e-9, "adams", 1e-3), (1e-10, "adams", 1e-3), (1e-11, "vern9", 1.0),
    (1e-14, "vern9", 1.0)])
def test_auto_follows_its_rule(rtol: float, method: str, factor: float) -> None:
    """The rule's boundaries (rtol 1e-4 and 1e-10) belong to the looser side's method."""
    assert choose_method(rtol) == (method, factor)
    m, f = get_method("auto", rtol)
    assert (m.name, f) == (method, factor)
    # where the Taylor method runs the problem, auto runs it at a tenth of every rtol
    assert choose_method(rtol, taylor=True) == AUTO_TAYLOR == ("taylor", 0.1)
    m, f = get_method("auto", rtol, taylor=True)
    assert (m.name, f) == AUTO_TAYLOR
    assert [lim for lim, _, _ in AUTO_RULE] == sorted((lim for lim, _, _ in AUTO_RULE),
                                                      reverse=True)
    for name in NAMED:  # a named method runs at the tolerances asked
        assert get_method(name, rtol) == (METHODS[name], 1.0)


def test_a_run_says_the_method_and_the_tolerances_that_ran() -> None:
    res = run_scene_ode("fig3", "run.t_end_s=0.5")  # the scene's rtol 1e-9: auto runs Taylor
    assert res.method == "taylor (order 12)"  # the order it ran at rtol 1e-10
    assert res.rtol == pytest.approx(1e-10) and res.atol == pytest.approx(1e-13)
    res = run_scene_ode("fig3", "run.t_end_s=0.5", "ode.formulation=paper")  # not Taylor's
    assert res.method == "adams"
    assert res.rtol == pytest.approx(1e-12) and res.atol == pytest.approx(1e-15)
    res = run_scene_ode("fig3", "run.t_end_s=0.5", "ode.method=dop853")
    assert res.method == "dop853" and res.rtol == pytest.approx(1e-9)


@pytest.mark.parametrize("method", NAMED)
def test_each_method_reproduces_fig11_n060(method: str) -> None:
    """Sec. 4.4, n0 = 60: theta_asymp 2.49 (test_paper_cases' tolerance and reasons)."""
    from tippetop.compare.measures.series import theta_asymp

    res = run_scene_ode("fig11_n060", f"ode.method={method}")
    assert res.status == "ok" and res.method == method_title(method, res.rtol)
    assert theta_asymp(res.table) == pytest.approx(FIG11_N060_THETA, abs=FIG11_TOL)


@pytest.mark.parametrize("method", NAMED)
def test_each_method_agrees_with_the_paper_formulation_on_fig3(method: str) -> None:
    """Fig. 3 inverts; the vector formulation under each method against the paper formulation
    under DOP853 (the paper's own equations, another state and right-hand side), both at the
    scene's rtol 1e-9: t_invert and the final theta within 1e-8 (test_paper_cases' bound for
    the default; measured 1e-9 s and 7e-10 rad for DOP853, and each method's own error at
    rtol 1e-9 on this top is below 1e-8: 7.7e-10 DOP853, ~1e-9 vern9, ~2e-9 adams, 2.3e-11
    taylor, from the work-precision sweep)."""
    res = run_scene_ode("fig3", f"ode.method={method}")
    paper = run_scene_ode("fig3", "ode.formulation=paper", "ode.method=dop853")
    assert res.status == paper.status == "ok"
    assert res.t_invert is not None and paper.t_invert is not None
    assert abs(res.t_invert - paper.t_invert) < 1e-8
    assert abs(res.table["theta"].iloc[-1] - paper.table["theta"].iloc[-1]) < 1e-8
    assert math.isfinite(res.cpu_s) and res.cpu_s >= 0.0


# ---------------------------------------------------------------- each method against DOP853
#: theta agreement with DOP853, both at rtol 1e-12 (atol 1e-15), at every sample (rad), and of
#: t_invert (s). At rtol 1e-12 each method is within ~1e-11 of the converged answer (DOP853 at
#: rtol 1e-13 and the sweep's truth, bench ode --sweep): measured Adams 4e-12 rad and 2e-13 s
#: (Fig. 11), 2e-12 and 2e-13 s (Fig. 3); Verner 2.6e-13 rad and 6e-14 s from DOP853 (Fig. 11);
#: Taylor 1e-13 (Fig. 11) and 1e-14 rad (Fig. 3); DOP853 itself ~1e-13 rad and 1.4e-11 s.
#: 1e-10 leaves ~10x; a method off by an order (a wrong coefficient) misses by far more.
TOP_TOL = 1e-10
#: What each method is for, in its own count against DOP853's (the ratio's bound): Adams's
#: evaluations (measured 6 % on Fig. 11, 16 % on Fig. 3), Verner's evaluations (56 %, Fig. 11:
#: 1.11M against 1.99M), the Taylor method's steps (6 % and 19 %).
COST = {"adams": ("n_rhs", 0.2), "vern9": ("n_rhs", 1.0), "taylor": ("n_steps", 0.3)}


def _top_case(case: str):
    from tippetop.models.params import FrictionParams, InitialState, TopParams
    from tippetop.models.resolve import resolve_plan
    from tippetop.models.scene import load_scene

    if case == "fig11":
        return (TopParams.from_ratios(1.0, 0.15), FrictionParams(),
                InitialState(theta0=0.01, n0=60.0), 60.0)
    pl = resolve_plan(load_scene("fig3", []), "ode").ode
    return pl.top, pl.friction, pl.init, pl.t_end_s


@pytest.mark.parametrize("case", ["fig11", "fig3"])
@pytest.mark.parametrize("method", sorted(COST))
def test_each_method_agrees_with_dop853_on_the_tops(method: str, case: str) -> None:
    """The Fig. 11 top (A/C = 1, a/R = 0.15, theta0 = 0.01, n0 = 60 rad/s, 60 s) and Fig. 3 at
    rtol 1e-12: theta at every sample (each method's dense output) and the inversion (located
    on it) against DOP853's, and the method's cost in its own count."""
    import numpy as np

    from tippetop.reference_ode.solve import simulate_ode

    top, fr, init, t_end = _top_case(case)
    runs = {m: simulate_ode(top, fr, init, t_end_s=t_end, sample_dt_s=0.01,
                            options=OdeOptions(method=m, rtol=1e-12, atol=1e-15))
            for m in ("dop853", method)}
    ref, res = runs["dop853"], runs[method]
    assert res.method == method_title(method, 1e-12) and res.status == ref.status == "ok"
    assert np.abs(res.table["theta"].to_numpy() - ref.table["theta"].to_numpy()).max() < TOP_TOL
    assert res.t_invert is not None and abs(res.t_invert - ref.t_invert) < TOP_TOL
    count, bound = COST[method]
    assert getattr(res, count) < bound * getattr(ref, count)
