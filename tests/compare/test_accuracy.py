"""Work-precision data of the reference ODE (compare/studies/accuracy/), on a short Fig. 3 run."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tippetop.compare.results.accuracy import AccuracyResult
from tippetop.compare.running.options import RunOptions
from tippetop.compare.studies import accuracy as acc
from tippetop.compare.studies.accuracy.mujoco_study import predict_steps_wall
from tippetop.models.errors import TippetopError

T_END_S = 1.0  # Fig. 3 cut to 1 s: through the first nutation dips towards theta = 0
TOLS = (1e-6, 1e-8, 1e-10)
METHODS = ("dop853-compiled/vector", "scipy-DOP853")


@functools.cache
def _df() -> pd.DataFrame:
    return acc.ode_work_precision("fig3", t_end_s=T_END_S, tolerances=TOLS, methods=METHODS,
                                  budget_s=60.0)


def _errors(method: str) -> pd.Series:
    df = _df()
    rows = df[df["method"] == method].sort_values("rtol", ascending=False)
    assert (rows["status"] == "ok").all(), rows["status"].tolist()
    return rows.set_index("rtol")["theta_max_err"]


def test_one_row_per_method_and_tolerance() -> None:
    df = _df()
    assert list(df.columns) == list(acc.ACCURACY_COLUMNS)
    assert len(df) == len(METHODS) * len(TOLS)
    assert set(df["engine"]) == {"ode"} and set(df["scene"]) == {"fig3"}
    assert (df["atol"] == acc.ATOL_PER_RTOL * df["rtol"]).all()
    assert (df["n_rhs"] > 0).all() and (df["wall_s"] > 0).all()
    assert np.isfinite(df[["theta_max_err", "final_state_err", "J_drift"]].to_numpy()).all()


def test_compiled_error_is_proportional_to_rtol() -> None:
    """The compiled DOP853's max theta error falls as rtol tightens, with a fitted slope of
    log(error) against log(rtol) in [0.7, 1.3].

    DOP853's controller keeps each step's local error near rtol, so the global error is about
    proportional to rtol (slope 1, "tolerance proportionality") whatever the order of the
    method. Measured: 1.05e-7, 2.0e-9, 1.8e-11 rad at rtol 1e-6, 1e-8, 1e-10, slope 0.94 (0.9
    on the full 8-s run, 1.0 on Fig. 11); +-0.3 leaves room for that scene dependence, while a
    broken error estimate (slope 8/7, or a controller that saturates, slope ~0) falls outside.
    """
    err = _errors("dop853-compiled/vector")
    assert (np.diff(err.to_numpy()) < 0).all()
    slope = np.polyfit(np.log10(err.index.to_numpy()), np.log10(err.to_numpy()), 1)[0]
    assert 0.7 < slope < 1.3, slope


def test_scipy_dop853_scores_like_the_compiled_one() -> None:
    """scipy's DOP853 is the same tableau and step control on the same right-hand side: its
    errors equal the compiled ones to 1e-3 relative (measured 4e-5: the step sequences agree
    up to floating-point order), and it needs the same evaluations to 5 % (the compiled count
    includes its 3 dense-output stages per sampled step, which scipy counts too, and its first
    step's extra evaluation)."""
    ours, theirs = _errors("dop853-compiled/vector"), _errors("scipy-DOP853")
    assert np.allclose(theirs.to_numpy(), ours.to_numpy(), rtol=1e-3)
    df = _df()
    n = df.pivot(index="rtol", columns="method", values="n_rhs")
    assert np.allclose(n["scipy-DOP853"], n["dop853-compiled/vector"], rtol=0.05)


def test_reference_is_the_most_accurate() -> None:
    """The reference (compiled DOP853, vector, rtol 1e-14) differs from its own 10x looser
    sibling by less than every point's error from it: it is more accurate than any point, so
    the errors measure the points and not the reference."""
    df = _df()
    ref = df.attrs["reference"]
    assert ref["method"] == "dop853-compiled/vector" and ref["rtol"] == acc.REFERENCE_RTOL
    assert ref["floor"] < df["theta_max_err"].min() / 10


def test_over_budget_points_are_recorded_not_dropped() -> None:
    """With a budget no run can meet, the loosest tolerance still runs (nothing to
    extrapolate from) and every tighter one is a 'skipped: over budget' row."""
    df = acc.ode_work_precision("fig3", t_end_s=0.2, tolerances=TOLS,
                                methods=("dop853-compiled/vector",), budget_s=1e-9)
    assert df["status"].tolist() == ["ok", acc.STATUS_SKIPPED, acc.STATUS_SKIPPED]
    assert df["theta_max_err"].iloc[1:].isna().all()


def test_a_failing_method_is_recorded_with_its_reason() -> None:
    """theta0 = 0: the paper formulation refuses to start (it is singular there); the row says
    so and carries no error numbers, while the vector formulation completes."""
    from tippetop.models.scene import load_scene

    scene = load_scene("fig3", ["init.theta0=0.0", "run.t_end_s=0.2"])
    df = acc.ode_work_precision(scene, tolerances=(1e-6,),
                                methods=("dop853-compiled/vector", "dop853-compiled/paper"))
    vec, pap = df.iloc[0], df.iloc[1]
    assert vec["status"] == "ok" and vec["theta_max_err"] < 1e-12
    assert pap["status"].startswith("failed: init.theta0") and "singular" in pap["status"]
    assert math.isnan(pap["theta_max_err"])


def _row(method: str, rtol: float, wall: float, err: float, status: str = "ok") -> dict:
    return {"engine": "ode", "scene": "s", "method": method, "formulation": "vector",
            "rtol": rtol, "atol": 1e-3 * rtol, "timestep_s": math.nan, "t_end_s": 2.0,
            "wall_s": wall, "wall_per_sim_s": wall / 2.0, "n_rhs": 1000, "n_steps": 10,
            "theta_max_err": err, "theta_final_err": err, "n_final_rel_err": err,
            "Omega_final_err": err, "final_state_err": err, "J_drift": 0.0, "status": status}


def test_pareto_picks_the_cheapest_qualifying_point() -> None:
    """Hand-made points: for 1e-2 the cheapest point under it (B at 0.1 s, not the more
    accurate A at 0.3 s); for 1e-4 only A qualifies (the cheaper C is not 'ok'); nothing
    reaches 1e-6."""
    df = pd.DataFrame([
        _row("A", 1e-6, 0.3, 1e-5),
        _row("B", 1e-3, 0.1, 5e-3),
        _row("B", 1e-2, 0.05, 2e-2),
        _row("C", 1e-8, 0.01, math.nan, status="failed: step_too_small"),
        _row("D", 1e-4, 0.2, 1e-3),
    ])
    got = acc.pareto_table(df, thresholds=(1e-2, 1e-4, 1e-6))
    assert [(e["threshold"], e["method"], e["rtol"]) for e in got] == [
        (1e-2, "B", 1e-3), (1e-4, "A", 1e-6), (1e-6, None, None)]
    assert got[0]["wall_per_sim_s"] == pytest.approx(0.05)
    assert got[0]["text"].startswith("to get theta right to 0.01 rad, use B at rtol 0.001; "
                                     "it costs 0.05 s per simulated second")
    assert got[2]["text"] == "to get theta right to 1e-06 rad: none reached"
    front = acc.pareto_front(df)
    assert front["method"].tolist() == ["B", "B", "D", "A"]


def test_run_accuracy_writes_csv_figure_and_table(tmp_path: Path) -> None:
    out = tmp_path / "acc"
    summary = acc.run_accuracy(("fig3",), out, t_end_s=0.5,
                               ode=acc.OdeGrid(tolerances=(1e-6, 1e-8),
                                               methods=("dop853-compiled/vector",
                                                        "dop853-compiled/paper"),
                                               stiff=False))
    csv = pd.read_csv(out / "accuracy_ode.csv")
    assert list(csv.columns) == list(acc.ACCURACY_COLUMNS)
    assert len(csv) == 4 and summary.n_points == 4 and summary.n_ok == 4
    png = out / "accuracy_ode_fig3.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "pareto_ode.md").read_text()
    assert "to get theta right to 0.0001 rad, use dop853-compiled/" in md
    assert "rtol 1e-14" in md
    assert [e.threshold for e in summary.pareto] == [1e-2, 1e-4, 1e-6]
    # the result reads back from its JSON, which keeps the dictionary's keys
    data = summary.to_json()
    assert AccuracyResult.from_json(data) == summary
    assert list(data) == ["csv", "figures", "pareto_md", "references", "pareto", "n_points",
                          "n_ok", "n_skipped", "n_failed", "engines", "report"]
    assert data["engines"]["ode"]["figures"] == [str(png)] and data["csv"] == str(
        out / "accuracy_ode.csv")
    assert list(data["pareto"][0]) == ["engine", "scene", "threshold", "method", "setting",
                                       "rtol", "timestep_s", "wall_s", "wall_per_sim_s",
                                       "n_rhs_per_sim_s", "n_steps_per_sim_s",
                                       "theta_max_err", "text", "best_theta_max_err",
                                       "best_method", "best_setting"]
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporary files
    before = csv.to_csv()
    with pytest.raises(TippetopError, match="--force"):
        acc.run_accuracy(("fig3",), out, t_end_s=0.5,
                         ode=acc.OdeGrid(tolerances=(1e-6,), methods=("dop853-compiled/vector",)))
    assert pd.read_csv(out / "accuracy_ode.csv").to_csv() == before


def test_run_accuracy_puts_the_stiff_case_on_its_own_frontier(tmp_path: Path) -> None:
    """With the ODE, the study also writes Fig. 3 at Lambda = 1e-6 m/s: the reference with its
    rolling phases against the law throughout, both scored against the law at rtol 1e-11."""
    out = tmp_path / "acc"
    res = acc.run_accuracy(("fig3",), out, t_end_s=0.3,
                           ode=acc.OdeGrid(tolerances=(1e-6,),
                                           methods=("dop853-compiled/vector",)))
    assert res.engines["stiff"].n_ok == 2  # one point per method: rolling and the law
    stiff = pd.read_csv(out / "accuracy_ode_stiff.csv")
    assert set(stiff["scene"]) == {"fig3_Lambda1e-06"}
    by = stiff.set_index("method")
    # the point of the rolling phases: far fewer evaluations (the law is held at its explicit
    # stability limit: ~700x over the whole 8 s, bench_stiff.py) for an error that stays small
    # (the reduced model departs from the law by O(Lambda^2): 2e-9 rad measured over 8 s; 1e-6
    # rad leaves room for rtol 1e-6 itself)
    assert by.loc["dop853-compiled/vector", "n_rhs"] * 20 < by.loc[
        "dop853-compiled/vector-law", "n_rhs"]
    assert by.loc["dop853-compiled/vector", "theta_max_err"] < 1e-6
    assert (out / "accuracy_ode_fig3_Lambda1e-06.png").read_bytes()[:4] == b"\x89PNG"
    assert "Lambda" in (out / "pareto_ode_stiff.md").read_text()


# ------------------------------------------------------------------ MuJoCo half
MJ_T_END_S = 0.5  # Fig. 3 cut to 0.5 s: theta falls from 0.1 while nutating
MJ_TIMESTEPS = (1e-3, 5e-4, 2.5e-4)


@functools.cache
def _mj() -> pd.DataFrame:
    return acc.mujoco_work_precision("fig3", t_end_s=MJ_T_END_S, integrators=("RK4", "Euler"),
                                     modes=("paper",), timesteps=MJ_TIMESTEPS, budget_s=60.0,
                                     workers=1)


def _mj_errors(method: str) -> pd.Series:
    df = _mj()
    rows = df[df["method"] == method].sort_values("timestep_s", ascending=False)
    assert (rows["status"] == "ok").all(), rows["status"].tolist()
    return rows.set_index("timestep_s")["theta_max_err"]


def test_mujoco_rows_share_the_ode_columns() -> None:
    """One row per (integrator, mode, timestep) in the ODE's columns: engine 'mujoco', method
    'INTEGRATOR/MODE', the timestep and the steps set, the ODE-only columns NaN."""
    df = _mj()
    assert list(df.columns) == list(acc.ACCURACY_COLUMNS)
    assert len(df) == 2 * len(MJ_TIMESTEPS)
    assert set(df["engine"]) == {"mujoco"} and set(df["scene"]) == {"fig3"}
    assert set(df["formulation"]) == {"paper"}
    assert df["rtol"].isna().all() and df["atol"].isna().all() and df["n_rhs"].isna().all()
    assert (df["n_steps"] == np.round(MJ_T_END_S / df["timestep_s"])).all()
    assert (df["wall_s"] > 0).all()
    assert np.isfinite(df[["theta_max_err", "final_state_err", "J_drift"]].to_numpy()).all()
    assert df.attrs["reference"]["rtol"] == acc.REFERENCE_RTOL


def test_mujoco_rk4_paper_mode_error_is_first_order_in_dt() -> None:
    """RK4 in paper mode: max |theta - theta_ref| falls as dt falls, with a fitted order (slope
    of log error against log dt) in [0.7, 1.4].

    First order, not RK4's fourth: the friction callback uses the normal force of the previous
    dynamics evaluation (mujoco_runner/friction_callback.py), an O(dt) error that dominates.
    Measured on 0-0.5 s of Fig. 3: 1.2e-3, 6.5e-4, 3.4e-4 rad at dt = 1e-3, 5e-4, 2.5e-4 s,
    order 0.92 (the same 0.9-1.0 over the full 8 s down to dt = 1e-4, where MuJoCo's soft
    contact floors it near 1e-4 rad). A fourth-order error or a stalled one (order ~0) falls
    outside the bound.
    """
    err = _mj_errors("RK4/paper")
    assert (np.diff(err.to_numpy()) < 0).all(), err.tolist()
    order = np.polyfit(np.log10(err.index.to_numpy()), np.log10(err.to_numpy()), 1)[0]
    assert 0.7 < order < 1.4, (err.tolist(), order)
    assert err.iloc[-1] < 1e-3


def test_mujoco_integrator_setting_takes_effect() -> None:
    """Euler and RK4 rows at the same timestep are different runs: Euler's own O(dt)
    truncation error adds to the O(dt) lag error both share, so its theta error is larger at
    every dt (measured 1.62x, 1.55x, 1.51x on these 0.5 s; the README's ~100x is over the full
    8 s, where Euler's error grows through the rise). Bound 1.3x; the same run under two labels
    would give exactly 1."""
    ratio = _mj_errors("Euler/paper") / _mj_errors("RK4/paper")
    assert len(ratio) == len(MJ_TIMESTEPS)
    assert (ratio > 1.3).all(), ratio.tolist()


def test_mujoco_euler_error_also_falls_with_dt() -> None:
    """Euler in paper mode is first order too (measured 2.0e-3, 1.0e-3, 5.1e-4 rad): each
    halving of dt at least 1.5x smaller."""
    err = _mj_errors("Euler/paper").to_numpy()
    assert (err[:-1] / err[1:] > 1.5).all(), err


def test_too_large_euler_step_is_recorded_not_dropped() -> None:
    """Native Euler at dt = 0.05 s (one step per 0.05-s sample): the ball sinks through the
    table within the first sample; the row says 'diverged: ...' with the runner's reason and
    carries no error numbers. Paper mode refuses that step before running (longer than the
    law's slip relaxation time, 2.54 ms on Fig. 3): 'failed: ...' with the reason. At
    dt = 2e-3 s both complete and are recorded as they are."""
    from tippetop.models.scene import load_scene

    s = load_scene("fig3", ["run.t_end_s=0.5", "run.sample_dt_s=0.05"])
    df = acc.mujoco_work_precision(s, integrators=("Euler",), modes=("native", "paper"),
                                   timesteps=(0.05, 0.002), workers=1)
    native, paper = df[df["formulation"] == "native"], df[df["formulation"] == "paper"]
    assert native["timestep_s"].tolist() == [0.05, 0.002]
    big, ok = native.iloc[0], native.iloc[1]
    assert big["status"].startswith("diverged: by t = 0.05 s"), big["status"]
    assert "sank" in big["status"] and "reduce timestep_s" in big["status"]
    assert math.isnan(big["theta_max_err"]) and big["n_steps"] >= 1
    assert ok["status"] == "ok" and ok["theta_max_err"] > 0
    refused, ran = paper.iloc[0], paper.iloc[1]
    assert refused["status"].startswith("failed: mujoco.timestep_s: expected at most 0.00254 s")
    assert math.isnan(refused["theta_max_err"]) and refused["n_steps"] == 0
    assert ran["status"] == "ok" and ran["theta_max_err"] > 0


def test_mujoco_over_budget_points_are_recorded_not_dropped() -> None:
    """With a budget no run can meet, the largest timestep still runs (nothing to extrapolate
    from) and every smaller one is a 'skipped: over budget' row with no numbers."""
    df = acc.mujoco_work_precision("fig3", t_end_s=0.1, integrators=("RK4",), modes=("paper",),
                                   timesteps=(1e-3, 5e-4, 2.5e-4), budget_s=1e-9, workers=1)
    assert df["status"].tolist() == ["ok", acc.STATUS_SKIPPED, acc.STATUS_SKIPPED]
    assert df["theta_max_err"].iloc[1:].isna().all()
    assert (df["n_steps"].iloc[1:] == 0).all()


def test_mujoco_run_over_the_hard_limit_is_stopped() -> None:
    """A run still going after HARD_LIMIT_FACTOR budgets of wall time is stopped at the
    runner's next progress call (every 0.2 s) and recorded as failed; the smaller timesteps
    are then skipped. (2 s at dt = 2e-5 s takes 1.2 s of wall time here, 2026-11-28, so the
    call at 0.2 s finds it running; at dt = 1e-4 s, 0.26 s, it sometimes ended first.)"""
    df = acc.mujoco_work_precision("fig3", t_end_s=2.0, integrators=("RK4",), modes=("paper",),
                                   timesteps=(2e-5, 1e-5), budget_s=1e-9, workers=1)
    assert df["status"].iloc[0].startswith("failed: stopped after"), df["status"].iloc[0]
    assert df["wall_s"].iloc[0] < 1.0 and math.isnan(df["theta_max_err"].iloc[0])
    assert df["status"].iloc[1] == acc.STATUS_SKIPPED


def test_mujoco_wall_time_prediction() -> None:
    """The prediction: a fixed part plus a part proportional to the steps, fitted on the last
    two completed runs; one run scales its whole wall time (an overestimate); only diverged
    runs scale by the steps they took; nothing to go on gives None."""
    p = predict_steps_wall
    assert p([], 1000) is None
    assert p([(100, 1.0, True)], 1000) == pytest.approx(10.0)
    # 1 s fixed + 1 ms per step
    assert p([(1000, 2.0, True), (2000, 3.0, True)], 10_000) == pytest.approx(11.0)
    # noisy timings (wall fell): back to scaling the last run
    assert p([(1000, 2.0, True), (2000, 1.9, True)], 4000) == pytest.approx(3.8)
    assert p([(50, 0.5, False)], 1000) == pytest.approx(10.0)


def test_mujoco_pareto_text() -> None:
    """MuJoCo entries say which integrator, timestep and mode; an unreached threshold gives
    the best error achieved and where."""
    rows = [_row("RK4/paper", math.nan, 1.0, 5e-4), _row("Euler/paper", math.nan, 0.5, 5e-3),
            _row("Euler/native", math.nan, 0.1, 0.2)]
    for r, dt, mode in zip(rows, (1e-4, 1e-4, 1e-3), ("paper", "paper", "native"), strict=True):
        r.update(engine="mujoco", timestep_s=dt, formulation=mode, rtol=math.nan,
                 atol=math.nan, n_rhs=math.nan, n_steps=round(2.0 / dt))
    got = acc.pareto_table(pd.DataFrame(rows), thresholds=(1e-2, 1e-4))
    assert got[0]["text"] == ("to get theta right to 0.01 rad, use Euler at dt = 0.0001 s in "
                              "paper mode; it costs 0.25 s per simulated second (theta error "
                              "5.0e-03 rad)")
    assert got[0]["n_steps_per_sim_s"] == pytest.approx(1e4)
    assert got[1]["method"] is None
    assert got[1]["text"] == ("to get theta right to 0.0001 rad: not reached (best error "
                              "5.0e-04 rad, RK4 at dt = 0.0001 s in paper mode)")


def test_run_accuracy_both_engines(tmp_path: Path) -> None:
    """Both engines into one folder, the MuJoCo series on two processes: the ODE files as
    before, plus accuracy_mujoco.csv (the same columns), a MuJoCo figure per scene and
    pareto_mujoco.md, which names the friction-model floor of native mode."""
    out = tmp_path / "acc"
    res = acc.run_accuracy(("fig3",), out, t_end_s=0.3, engines=("ode", "mujoco"),
                           ode=acc.OdeGrid(tolerances=(1e-6,),
                                           methods=("dop853-compiled/vector",), stiff=False),
                           mujoco=acc.MujocoGrid(integrators=("RK4", "Euler"),
                                                 modes=("paper", "native"),
                                                 timesteps=(1e-3, 5e-4)),
                           run=RunOptions(workers=2))
    ode = pd.read_csv(out / "accuracy_ode.csv")
    mj = pd.read_csv(out / "accuracy_mujoco.csv")
    assert list(ode.columns) == list(mj.columns) == list(acc.ACCURACY_COLUMNS)
    assert len(ode) == 1 and len(mj) == 8
    assert set(mj["method"]) == {"RK4/paper", "RK4/native", "Euler/paper", "Euler/native"}
    assert (mj["status"] == "ok").all(), mj["status"].tolist()
    for name in ("accuracy_ode_fig3.png", "accuracy_mujoco_fig3.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (out / "pareto_mujoco.md").read_text()
    assert "# MuJoCo: accuracy against cost" in md and "not the paper's law" in md
    assert "to get theta right to 0.01 rad, use " in md
    assert "| RK4/native |" in md
    assert res.engines["mujoco"].n_points == 8 and res.n_points == 9
    assert res.csv == str(out / "accuracy_ode.csv")
    assert {e.engine for e in res.pareto} == {"ode", "mujoco"}
    assert "fig3 [mujoco]: to get theta right to 0.01 rad" in res.report
    assert AccuracyResult.from_json(res.to_json()) == res
    assert not list(out.glob(".*.tmp"))
    with pytest.raises(TippetopError, match="--force"):
        acc.run_accuracy(("fig3",), out, engines=("mujoco",), t_end_s=0.3)


def test_bench_accuracy_engines_option(capsys: pytest.CaptureFixture[str],
                                       tmp_path: Path) -> None:
    """The command runs both engines by default; an unknown engine is one line and exit 2,
    before any work."""
    from tippetop.compare.cli import build_parser, main

    args = build_parser().parse_args(["bench", "accuracy"])
    assert args.engines == "ode,mujoco" and args.budget_s is None
    code = main(["bench", "accuracy", "fig3", "--engines", "ode,bullet", "--out",
                 str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "'bullet'" in err and "--engines" in err
    assert not (tmp_path / "x").exists()


def test_the_peers_run_in_the_accuracy_study(monkeypatch: pytest.MonkeyPatch) -> None:
    """numbalsoda's DOP853 is the same method on the same right-hand side as the reference's
    kernel: at the same tolerance it needs the same evaluations to within 5 % (the two differ
    in the initial step and in details of the step control) and reaches an error of the same
    order: a global error is a sum of local errors over a step sequence, so a different
    sequence moves it by a small factor (measured 6e-10 against 1.6e-9 rad at rtol 1e-8;
    both far below the 1e-6 rad the study's thresholds start at, and far above the rtol-1e-14
    reference's ~1e-13 floor). LSODA completes with an error consistent with its tolerance."""
    pytest.importorskip("numbalsoda")
    assert set(acc.PEER_METHODS) <= set(acc.default_methods())
    df = acc.ode_work_precision("fig3", t_end_s=0.5, tolerances=(1e-8,),
                                methods=("dop853-compiled/vector", "numbalsoda-DOP853",
                                         "numbalsoda-LSODA"))
    assert (df["status"] == "ok").all(), df["status"].tolist()
    by = df.set_index("method")
    ours, peer = by.loc["dop853-compiled/vector"], by.loc["numbalsoda-DOP853"]
    assert abs(peer["n_rhs"] - ours["n_rhs"]) <= 0.05 * ours["n_rhs"]
    assert ours["theta_max_err"] / 5 < peer["theta_max_err"] < 5 * ours["theta_max_err"]
    assert max(ours["theta_max_err"], peer["theta_max_err"]) < 1e-7
    assert by.loc["numbalsoda-LSODA", "theta_max_err"] < 1e-4
    # without numbalsoda: the peers leave the defaults, and asked for, they say why
    import tippetop.compare.studies.accuracy.ode_study as ode_study

    monkeypatch.setattr(ode_study, "numbalsoda_missing", lambda: "numbalsoda is not installed")
    assert not set(acc.PEER_METHODS) & set(acc.default_methods())
    df = acc.ode_work_precision("fig3", t_end_s=0.2, tolerances=(1e-6,),
                                methods=("numbalsoda-DOP853",))
    assert df["status"].tolist() == ["failed: numbalsoda is not installed"]
