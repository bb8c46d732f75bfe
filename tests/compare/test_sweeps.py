"""Thresholds measured by bisection, sweeps against theta_s(n0), the cache, and Dask."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from tippetop.compare.measures import theory
from tippetop.compare.results.sweep import SweepResult
from tippetop.compare.results.threshold import ThresholdResult
from tippetop.compare.running.runner import Task, run_tasks, strip_timing
from tippetop.compare.studies.sweep import parse_range, run_sweep
from tippetop.compare.studies.threshold import measure_threshold
from tippetop.models.errors import TippetopError
from tippetop.models.scene import load_scene


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))


def test_fig9a_n1_measured_in_the_reference() -> None:
    """The Fig. 9 (a) top (A/C = 1, a/R = 0.15) from theta0 = 0.01 over 60 s: the bisection on
    n0 for where theta = 0 turns unstable lands on the paper's printed n1 = 34.4 rad/s, within
    half a unit of its last digit (0.05 rad/s). Measured 34.384, bracket [34.352, 34.416]: 0.09 %
    above the theory's 34.352 (eq. zeroStability4). The 60-s horizon's bias (the growth rate
    vanishes at n1, so a run just above it may not leave the vertical in time) is smaller than
    the bracket's 0.5 % width, not the 3 % once assumed; the bound on the relative difference
    is that width."""
    res = measure_threshold(None, "ode", "n1", method="bisect")
    assert abs(res.measured - 34.4) <= 0.05
    lo, hi = res.bracket
    assert lo <= res.measured <= hi and (hi - lo) / res.measured <= 0.005
    assert abs(res.rel_diff) <= 0.005
    assert res.n_runs == len(res.runs) >= 4
    # the bracket's ends keep their sides over 120 s: the answer is not the horizon's
    assert res.horizon_check.low_crossed is False
    assert res.horizon_check.high_crossed is True
    assert res.converged and not res.depends_on_horizon and res.warning is None
    # the result says itself as the command's JSON and reads itself back
    data = res.to_json()
    assert list(data)[:3] == ["which", "engine", "scene"] and list(data)[-1] == "mode"
    assert data["horizon_check"]["horizon_s"] == 120.0 and data["rates"] == []
    assert ThresholdResult.from_json(json.loads(json.dumps(data))) == res


def test_a_threshold_that_depends_on_the_run_length_says_so() -> None:
    """n_c of the Fig. 6 top by bisection over its 12-s horizon: near n_c a run approaches
    theta = pi ever more slowly. Runs still moving at their end are continued over 24 and 48 s;
    some never settle, and they are reported (``settled`` false, ``unsettled_n0``), not taken
    as outcomes of a converged answer. Over 24 s the bracket's low end inverts as well: the
    answer moves with the horizon, so it is not 'converged' and says why. (Measured: 58.3
    rad/s against the theory's 54.3; 72.7 without continuing the runs.)"""
    res = measure_threshold("fig6", "ode", "nc", method="bisect")
    assert res.bracket_converged
    assert res.depends_on_horizon and not res.converged
    assert res.horizon_check.horizon_s == 24.0 and res.horizon_check.low_crossed
    assert "depends on the run length" in res.warning
    assert not res.settled and res.unsettled_n0
    assert all(r["t_end_s"] > 12.0 for r in res.runs if r["n0"] in res.unsettled_n0)


def test_threshold_refuses_a_group_one_top() -> None:
    with pytest.raises(TippetopError, match="Group I"):
        measure_threshold("fig7a", "ode", "n1", method="bisect")


def test_fig9a_sweep_on_the_theory_curve() -> None:
    """The Fig. 9 (a) sweep: theta_asymp falls on theta_s(n0) within 0.01 rad at every n0 at
    least 10 % away from n1 and n4; closer to them the approach to the steady state is slower
    than the 60-s horizon (the paper: 'near n1 and n4 it takes longer'; at 35 and 65 rad/s the
    runs are 0.28 and 0.09 rad short). Measured at the checked points: at most 2.7e-3 rad (the
    nutation left near pi at 70-85 rad/s; 7e-4 at the intermediate angles), as for Fig. 11."""
    top = load_scene("fig11_n060").top
    n1, n4 = theory.n1(top), theory.n4(top)
    res = run_sweep("fig11_n060", parse_range("25:85:5"), [("ode", "paper", ())])
    checked = 0
    for row in res.table.itertuples():
        if min(abs(row.n0 / n1 - 1), abs(row.n0 / n4 - 1)) < 0.10:
            continue
        assert row.theta_asymp == pytest.approx(theory.theta_s(top, row.n0), abs=0.01), row.n0
        checked += 1
    assert checked >= 8


def test_second_identical_sweep_computes_nothing() -> None:
    first = run_sweep("fig7b", [20.0, 30.0], [("ode", None, ())], ("run.t_end_s=1",))
    second = run_sweep("fig7b", [20.0, 30.0], [("ode", None, ())], ("run.t_end_s=1",))
    assert first.computed == 2 and first.cached == 0
    assert second.computed == 0 and second.cached == 2
    assert second.table["theta_asymp"].tolist() == first.table["theta_asymp"].tolist()
    # a changed scene is computed again, the unchanged point is not
    third = run_sweep("fig7b", [20.0, 31.0], [("ode", None, ())], ("run.t_end_s=1",))
    assert third.computed == 1 and third.cached == 1
    # the result says itself as the command's JSON and reads itself back, the theory's curve
    # recomputed from its top over the same n0 range
    back = SweepResult.from_json(json.loads(json.dumps(third.to_json())), third.top)
    assert back.to_json() == third.to_json() and back.scene == third.scene
    assert back.theory["theta_s"].tolist() == third.theory["theta_s"].tolist()


def test_parse_range() -> None:
    assert parse_range("30:80:10") == [30.0, 40.0, 50.0, 60.0, 70.0, 80.0]
    for bad in ("30:80", "a:b:c", "80:30:10", "0:1:0", "0:1e9:1"):
        with pytest.raises(TippetopError):
            parse_range(bad)


@pytest.mark.slow  # about 40 s on 2 cores (a LocalCluster starts): default suite near 10 min
def test_dask_cluster_gives_the_local_results() -> None:
    """The same tasks on a Dask LocalCluster (2 worker processes) give the local results,
    bit for bit except the wall time."""
    distributed = pytest.importorskip("distributed")
    tasks = [Task("fig7b", ("run.t_end_s=0.5", f"init.n0={n0}"), "ode") for n0 in (20.0, 40.0)]
    local = run_tasks(tasks, use_cache=False, workers=1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = run_tasks(tasks, use_cache=False, scheduler=cluster.scheduler_address)
    for a, b in zip(local, remote, strict=True):
        assert strip_timing(a.summary) == strip_timing(b.summary)
        assert a.table.equals(b.table)
    assert not math.isnan(local[0].summary["theta_asymp"])
