"""Many MuJoCo runs on threads (mujoco_runner.batch) equal their single runs bit for bit.

Every comparison here is ``==`` on floats, with no tolerance: each run is stepped on its own
thread by the single run's own stepping (the compiled stepper, on its own mjData), and paper
mode's callback reads only the mjData it is given, so the same floating-point operations run in
the same order as in the single run. Any difference is a bug (a callback reading another
simulation's state, a lost N, a wrong start), not rounding: == on every sample's qpos and qvel,
and on the tables, windows, contacts and messages.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests.conftest import mujoco_plan
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner import friction_callback
from tippetop.mujoco_runner.batch import iter_simulate_plans, simulate_plans
from tippetop.mujoco_runner.friction_callback import PaperFriction
from tippetop.mujoco_runner.results import MujocoResult
from tippetop.mujoco_runner.run import simulate_plan
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.state import initial_qpos_qvel

#: Short: a tenth of a second is 5000 paper-mode steps, through the first nutation.
T_END = ("run.t_end_s=0.1",)


@pytest.fixture(autouse=True)
def _no_leftover_callback():
    yield
    assert friction_callback._install_count == 0, "a batch left the callback installed"


def _plan(scene: str, *overrides: str):
    return mujoco_plan(*T_END, *overrides, scene=scene)


def _timing_free(message: str) -> str:
    """A run's one line without its wall time (' in 0.12 s' at the end)."""
    return re.sub(r" in [0-9.e+-]+ s$", "", message)


def _assert_same(batched: MujocoResult, alone: MujocoResult) -> None:
    assert batched.status == alone.status
    assert _timing_free(batched.message) == _timing_free(alone.message)
    assert batched.n_steps == alone.n_steps
    assert batched.ran == alone.ran
    assert batched.warnings == alone.warnings
    assert batched.contacts.tobytes() == alone.contacts.tobytes()
    assert batched.windows.ints.tobytes() == alone.windows.ints.tobytes()
    assert batched.windows.floats.tobytes() == alone.windows.floats.tobytes()
    assert batched.max_penetration_m == alone.max_penetration_m
    assert batched.contact_energy_bound_J == alone.contact_energy_bound_J
    assert list(batched.table.columns) == list(alone.table.columns)
    # bit for bit: the same bytes, NaN where the single run has NaN
    assert batched.table.to_numpy().tobytes() == alone.table.to_numpy().tobytes()


@pytest.mark.parametrize("friction", ["paper", "native"])
def test_a_batch_on_two_threads_equals_single_runs(friction: str) -> None:
    # fig3's top at four spins and, in paper mode, another mu (another law in one batch)
    overrides = [(f"init.n0={n0}",) for n0 in (40.0, 75.0, 100.0, 140.0)]
    overrides.append(("init.n0=90.0", "friction.mu=0.3"))
    plans = [_plan("fig3", f"mujoco.friction={friction}", *o) for o in overrides]
    batched = simulate_plans(plans, nthread=2)
    for plan, res in zip(plans, batched, strict=True):
        _assert_same(res, simulate_plan(plan))
    # the runs did differ (a batch that ran one simulation five times would pass the above)
    assert len({r.table.to_numpy().tobytes() for r in batched}) == len(plans)


def test_paper_mode_in_a_batch_applies_the_law() -> None:
    # The failure the issue names: a callback that reads one armed mjData is frictionless in a
    # batch's threads. Here the friction force the table reports is the callback's own last
    # output in each simulation, and the trajectory differs from the frictionless one.
    plan = _plan("fig3", "mujoco.friction=paper")
    frictionless = _plan("fig3", "mujoco.friction=paper", "effects.sliding=false")
    with_law, without = simulate_plans([plan, frictionless], nthread=2)
    assert with_law.ran["friction_law"] == "modified_coulomb"
    assert without.ran["friction_law"] == "none"
    # The friction power the table reports is the callback's own output in each simulation.
    # The law gives P = -mu N v^2 / sqrt(v^2 + Lambda^2) at the slip v; the callback's N lags
    # the table's by one evaluation (a few %), so half of it is a bound that a frictionless
    # run (P = 0) or another simulation's force cannot meet by accident.
    t = with_law.table
    v2 = (t["vPX"] ** 2 + t["vPY"] ** 2).to_numpy()
    law_power = 0.1 * t["N"].to_numpy() * v2 / np.sqrt(v2 + 0.01 ** 2)
    assert (-t["P_fric"].to_numpy()[1:] > 0.5 * law_power[1:]).all()
    assert (without.table["P_fric"] == 0.0).all()
    assert not np.array_equal(with_law.table["theta"], without.table["theta"])


def test_recorded_states_equal_a_loop_over_mjdata(monkeypatch) -> None:
    # The state each sample records is that of one MjData stepped alone with the harness's
    # PaperFriction and plain mj_step, on every sample: qpos and qvel ==.
    from tippetop.mujoco_runner import batch as mjb

    plans = [_plan("fig3", "mujoco.friction=paper", f"init.n0={n0}") for n0 in (50.0, 120.0)]
    kept = {}
    original = mjb._result

    def keep(sim, record, *args):
        kept[sim.index] = (record.qpos.copy(), record.qvel.copy())
        return original(sim, record, *args)

    monkeypatch.setattr(mjb, "_result", keep)
    simulate_plans(plans, nthread=2)
    for i, plan in enumerate(plans):
        tm = build_model(plan)
        data = mujoco.MjData(tm.model)
        data.qpos[:7], data.qvel[:6] = initial_qpos_qvel(tm, plan.init)
        assert (tuple(data.qpos[:7]), tuple(data.qvel[:6])) == (plan.start_qpos,
                                                                plan.start_qvel)
        qpos, qvel = [], []
        with PaperFriction(tm, data, plan.law):
            mujoco.mj_forward(tm.model, data)
            mujoco.mj_forward(tm.model, data)
            for row in range(plan.n_intervals + 1):
                if row:
                    mujoco.mj_step(tm.model, data, plan.steps_per_sample)
                qpos.append(data.qpos.copy())
                qvel.append(data.qvel.copy())
        assert kept[i][0].tobytes() == np.array(qpos).tobytes()
        assert kept[i][1].tobytes() == np.array(qvel).tobytes()


def test_other_tops_each_run_on_their_own_model() -> None:
    # Different tops (A/C, a/R) on the threads at once: each equals its single run.
    plans = [_plan("fig3", "mujoco.friction=paper"), _plan("fig6", "mujoco.friction=paper"),
             _plan("fig3", "mujoco.friction=paper", "top.A_over_C=0.95")]
    for plan, res in zip(plans, simulate_plans(plans, nthread=2), strict=True):
        _assert_same(res, simulate_plan(plan))


def test_failed_runs_in_a_batch_fail_as_alone_and_the_others_run_on(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to ./MUJOCO_LOG.TXT
    plans = [
        _plan("fig3", "mujoco.friction=paper"),
        # |qvel| above MuJoCo's bound: it warns (from a batch thread) and resets the state
        _plan("fig3", "mujoco.friction=paper", "init.n0=1e11"),
        # a step at the contact's time constant: the ball sinks (found by the sample checks)
        _plan("fig3", "mujoco.friction=paper", "effects.sliding=false",
              "mujoco.integrator=Euler", "mujoco.timestep_s=0.02", "run.t_end_s=1"),
        # a plan this MuJoCo cannot run as it says (its text and its values disagree; a step
        # the law cannot follow is refused earlier, when the plan is made): refused before
        # running, as alone
        replace(_plan("fig3", "mujoco.friction=paper"), timestep_s=1e-4),
        _plan("fig3", "mujoco.friction=native", "init.n0=70.0"),
        # explicit Euler on an A != C top: unstable, it keeps stepping past the energy check
        _plan("fig3", "mujoco.friction=paper", "effects.sliding=false", "top.A_over_C=1.25",
              "top.a_over_R=0.15", "top.C_factor=0.8", "init.n0=1000", "run.t_end_s=2",
              "mujoco.integrator=Euler", "mujoco.timestep_s=0.005", "run.sample_dt_s=0.005"),
    ]
    out = dict(iter_simulate_plans(plans, nthread=2))
    assert sorted(out) == list(range(len(plans)))
    assert isinstance(out[3], TippetopError)
    with pytest.raises(TippetopError) as alone:
        simulate_plan(plans[3])
    assert str(out[3]) == str(alone.value)
    assert "MuJoCo warning mjWARN_BADQVEL" in out[1].message
    assert "the ball sank" in out[2].message
    for i in (0, 1, 2, 4, 5):
        _assert_same(out[i], simulate_plan(plans[i]))
    assert [out[i].ok for i in (0, 1, 2, 4, 5)] == [True, False, False, True, False]


def test_progress_reports_each_simulation() -> None:
    # on threads a run reports every PROGRESS_INTERVAL_S of its stepping: 2 s is ~0.3 s
    t_end = "run.t_end_s=2.0"
    plans = [_plan("fig3", "mujoco.friction=native", f"init.n0={n0}", t_end)
             for n0 in (60.0, 90.0)]
    seen: dict[int, list[float]] = {}
    ticks = []
    import tippetop.mujoco_runner.batch as mjb

    before = mjb.TICK_S
    mjb.TICK_S = 0.0  # report after every sample
    try:
        results = dict(iter_simulate_plans(
            plans, nthread=2, progress=lambda i, f: seen.setdefault(i, []).append(f),
            tick=lambda: ticks.append(1)))
    finally:
        mjb.TICK_S = before
    assert sorted(results) == [0, 1] and all(r.ok for r in results.values())
    assert sorted(seen) == [0, 1] and ticks
    for fractions in seen.values():
        assert fractions == sorted(fractions) and 0.0 <= fractions[0]
        assert 0.0 < fractions[-1] <= 1.0


EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.xml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_loaded_tops_with_keyframes_and_stems_equal_single_runs(path: Path,
                                                                ) -> None:
    # The example tops: a file's keyframe as the start (mj_resetDataKeyframe) or the scene's
    # spin, a stem the law also acts at (paper mode) or MuJoCo's contact (native), in one call.
    plans = []
    for mode in ("paper", "native"):
        # paper mode on a stemmed top needs a step its law can follow (the files' are longer)
        step = ["mujoco.timestep_s=0.0002"] if mode == "paper" and "stem" in path.stem else []
        for start in ([], ["init.n0=120.0"]):
            with warnings.catch_warnings():  # the files' stems and origins: warned of
                warnings.simplefilter("ignore")
                plans.append(mujoco_plan(f"top.mjcf={str(path)!r}", "run.t_end_s=0.3",
                                         f"mujoco.friction={mode}", *step, *start))
    assert plans[0].keyframe is not None and plans[1].keyframe is None
    for plan, res in zip(plans, simulate_plans(plans, nthread=2), strict=True):
        _assert_same(res, simulate_plan(plan))


def test_runs_of_other_timesteps_and_samplings_run_together() -> None:
    # compare's modes: paper at dt = 2e-5 s (50 steps a sample), native at 2e-4 s (5 steps),
    # native elliptic sampled every 2 ms (10 steps), implicitfast: on the threads at once
    plans = [_plan("fig3", "mujoco.friction=paper"), _plan("fig3", "mujoco.friction=native"),
             _plan("fig3", "mujoco.friction=native", "mujoco.cone=elliptic",
                   "run.sample_dt_s=0.002"),
             _plan("fig3", "mujoco.friction=paper", "effects.sliding=false"),
             _plan("fig3", "mujoco.friction=native", "mujoco.integrator=implicitfast")]
    assert sorted(p.steps_per_sample for p in plans) == [5, 5, 10, 50, 50]
    for plan, res in zip(plans, simulate_plans(plans, nthread=2), strict=True):
        _assert_same(res, simulate_plan(plan))


def _workers_alive() -> list[str]:
    import threading

    return [t.name for t in threading.enumerate() if t.name.startswith("tippetop-mujoco-")]


def test_stopping_the_runs_stops_and_joins_the_threads() -> None:
    # The caller stops after the first result (a command that failed fast, or Ctrl-C between
    # results): the workers stop at their next progress report and are joined at once.
    import time

    plans = [_plan("fig3", "mujoco.friction=native", f"init.n0={n0}", "run.t_end_s=0.2")
             for n0 in (60.0, 70.0)]
    plans += [_plan("fig3", "mujoco.friction=native", f"init.n0={n0}", "run.t_end_s=30")
              for n0 in (80.0, 90.0)]
    runs = iter_simulate_plans(plans, nthread=2)
    next(runs)
    start = time.perf_counter()
    runs.close()
    # a 30-s run takes ~4 s; stopped, it ends within a progress interval (0.2 s) and a chunk
    assert time.perf_counter() - start < 1.5
    assert _workers_alive() == []


def test_ctrl_c_while_the_threads_step_is_raised_and_they_are_joined() -> None:
    plans = [_plan("fig3", "mujoco.friction=native", f"init.n0={n0}", "run.t_end_s=30")
             for n0 in (80.0, 90.0)]

    def interrupt() -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        list(iter_simulate_plans(plans, nthread=2, tick=interrupt))
    assert _workers_alive() == []


def test_an_error_in_a_thread_is_raised_in_the_caller(monkeypatch) -> None:
    from tippetop.mujoco_runner import batch as mjb

    def broken(*args, **kwargs):
        raise RuntimeError("out of memory, say")

    monkeypatch.setattr(mjb, "step_top_model", broken)
    plans = [_plan("fig3", "mujoco.friction=native", f"init.n0={n0}") for n0 in (60.0, 70.0)]
    with pytest.raises(RuntimeError, match="out of memory, say"):
        simulate_plans(plans, nthread=2)
    assert _workers_alive() == []
