"""The cost of a MuJoCo step is measured on the machine, per engine, kept in the run cache, and
estimates start from it.

Until runs on an engine (the MuJoCo installed here, or another spec through its worker) have
measured it, an estimate uses the default (``MUJOCO_STEP_S``) and says "not yet measured here";
a batch or a ``simulate`` then keeps its runs' median wall time per step for that engine,
blended into the figure kept, and the next estimate says "as measured here". Short runs, cached
runs and failed runs are not measured; a file that cannot be read or holds nonsense is the
default again.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tippetop.compare.measures.summary import measured_steps
from tippetop.compare.running import cost
from tippetop.compare.running.engines import plan_for
from tippetop.models.scene import load_scene


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("TIPPETOP_CACHE", str(folder))
    return folder


def test_the_default_until_measured_then_the_measured_figure_blended(cache: Path) -> None:
    assert cost.mujoco_step_s() == (cost.MUJOCO_STEP_S, False)
    assert cost.record_mujoco_runs([(20_000, 1.0)]) == pytest.approx(5e-5)  # first: as is
    assert cost.mujoco_step_s() == (pytest.approx(5e-5), True)
    # the median of a batch (1e-5, 2e-5, 9e-5 -> 2e-5), then halfway from the kept 5e-5
    kept = cost.record_mujoco_runs([(10_000, 0.1), (10_000, 0.2), (10_000, 0.9)])
    assert kept == pytest.approx(5e-5 + cost.LEARN_RATE * (2e-5 - 5e-5))
    assert cost.mujoco_step_s()[0] == pytest.approx(kept)
    doc = json.loads((cache / cost.STEP_COST_FILE).read_text())["engines"]["mujoco"]
    assert doc["runs"] == 3 and doc["last_median_s"] == pytest.approx(2e-5)


def test_each_engine_keeps_its_own_figure(cache: Path) -> None:
    # a worker's Python callback or MJX costs far more a step than the compiled stepper here
    cost.record_mujoco_runs([(20_000, 0.3)])  # 15 us here
    cost.record_mujoco_runs([(20_000, 20.0)], "mjx")  # 1 ms on MJX
    assert cost.mujoco_step_s() == (pytest.approx(15e-6), True)
    assert cost.mujoco_step_s("mjx") == (pytest.approx(1e-3), True)
    assert cost.mujoco_step_s("warp") == (cost.MUJOCO_STEP_S, False)
    plan = plan_for(load_scene("fig3", ["run.t_end_s=20"]), "mujoco", "native")  # 1e5 steps
    assert cost.expected_cost_s(plan, "mjx") == pytest.approx(cost.TASK_OVERHEAD_S + 100.0)
    on_mjx = plan_for(load_scene("fig3", ["run.t_end_s=20"]), "mjx", "native")
    assert cost.expected_cost_s(on_mjx) == pytest.approx(cost.TASK_OVERHEAD_S + 100.0)
    note = cost.long_run_note([plan, on_mjx], slots=2)
    assert note.startswith("tippetop: about 100 s of computing (")
    assert "1.0e+05 MuJoCo steps at ~15 us, as measured here" in note
    assert "1.0e+05 MuJoCo steps on mjx at ~1000 us, as measured here" in note


def test_the_estimate_uses_it_and_says_whether_it_was_measured(cache: Path) -> None:
    long = plan_for(load_scene("fig3", ["run.t_end_s=200"]), "mujoco", "paper")  # 1e7 steps
    assert cost.expected_cost_s(long) == pytest.approx(cost.TASK_OVERHEAD_S + 1e7 * 20e-6)
    assert "at ~20 us, not yet measured here" in cost.long_run_note([long])
    cost.record_mujoco_runs([(1_000_000, 40.0)])  # 40 us a step on a slow machine
    assert cost.expected_cost_s(long) == pytest.approx(cost.TASK_OVERHEAD_S + 1e7 * 40e-6)
    note = cost.long_run_note([long])
    assert note.startswith("tippetop: about 7 min of computing (")
    assert "1.0e+07 MuJoCo steps at ~40 us, as measured here" in note


@pytest.mark.parametrize("runs", [
    [],
    [(cost.MIN_MEASURED_STEPS - 1, 1.0)],  # too short: its fixed costs would dominate
    [(100_000, 0.0)],
    [(100_000, float("nan"))],
    [(100_000, 1e4)],  # 0.1 s a step: a suspended machine, not a step
])
def test_runs_that_say_nothing_about_a_step_are_not_kept(cache: Path, runs) -> None:
    assert cost.record_mujoco_runs(runs) is None
    assert not (cache / cost.STEP_COST_FILE).exists()
    assert cost.mujoco_step_s() == (cost.MUJOCO_STEP_S, False)


@pytest.mark.parametrize("text", ["{", "[]", '{"engines": []}',
                                  '{"engines": {"mujoco": 1e-5}}',
                                  '{"engines": {"mujoco": {"step_s": "fast"}}}',
                                  '{"engines": {"mujoco": {"step_s": true}}}',
                                  '{"engines": {"mujoco": {"step_s": -1}}}',
                                  '{"engines": {"mujoco": {"step_s": 5}}}',
                                  '{"mujoco_step_s": 1e-5}'])
def test_a_kept_figure_that_is_not_one_is_the_default(cache: Path, text: str) -> None:
    cache.mkdir()
    (cache / cost.STEP_COST_FILE).write_text(text)
    assert cost.mujoco_step_s() == (cost.MUJOCO_STEP_S, False)
    assert cost.record_mujoco_runs([(20_000, 1.0)]) == pytest.approx(5e-5)  # replaced


def test_no_usable_cache_folder_is_the_default_and_nothing_kept(tmp_path: Path,
                                                                monkeypatch) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("")
    monkeypatch.setenv("TIPPETOP_CACHE", str(a_file))
    assert cost.mujoco_step_s() == (cost.MUJOCO_STEP_S, False)
    assert cost.record_mujoco_runs([(20_000, 1.0)]) is None


def test_only_finished_runs_of_the_engine_are_measured() -> None:
    here = {"engine": "mujoco", "mode": "native", "status": "ok", "n_steps": 20_000,
            "wall_s": 0.3}
    assert measured_steps([here]) == [(20_000, 0.3)]
    others = [None, {**here, "engine": "mjx"}, {**here, "engine": "ode"},
              {**here, "status": "diverged"}, {**here, "n_steps": None}]
    assert measured_steps(others) == []
    assert measured_steps(others, "mjx") == [(20_000, 0.3)]  # each engine its own runs


def test_a_simulate_of_the_mujoco_here_keeps_what_its_steps_cost(tmp_path: Path) -> None:
    env_cache = tmp_path / "cache"
    args = [sys.executable, "-m", "tippetop.compare.cli", "simulate", "fig3", "--engine",
            "mujoco", "--mode", "paper", "--set", "run.t_end_s=0.5", "--json"]
    env = {**os.environ, "TIPPETOP_CACHE": str(env_cache)}
    r = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    run = json.loads(r.stdout)
    assert run["n_steps"] == 25_000  # 0.5 s at paper mode's 2e-5 s
    doc = json.loads((env_cache / cost.STEP_COST_FILE).read_text())["engines"]
    assert doc["mujoco"]["step_s"] == pytest.approx(run["wall_s"] / run["n_steps"])
    # the reference ODE has no step to measure: the figure stays as it was
    before = (env_cache / cost.STEP_COST_FILE).read_text()
    r = subprocess.run([*args[:5], "--engine", "ode", "--set", "run.t_end_s=0.5"],
                       capture_output=True,
                       text=True, env=env, timeout=300, check=False)
    assert r.returncode == 0 and (env_cache / cost.STEP_COST_FILE).read_text() == before


def test_a_batch_keeps_its_computed_runs_not_its_cached_ones(cache: Path) -> None:
    from tippetop.compare.running.runner import Task, run_tasks

    short = ("run.t_end_s=0.5", "mujoco.friction=paper")  # 25,000 steps each
    tasks = [Task("fig3", short, "mujoco"), Task("fig3", (*short, "init.n0=80"), "mujoco")]
    kept = cache / cost.STEP_COST_FILE
    res = run_tasks(tasks, workers=2, cache_dir=cache / "runs")
    assert all(r.error is None and not r.cached for r in res)
    per_step = sorted(r.summary["wall_s"] / r.summary["n_steps"] for r in res)
    assert json.loads(kept.read_text())["engines"]["mujoco"]["last_median_s"] == \
        pytest.approx(sum(per_step) / 2)  # the median of two
    before = kept.read_text()
    again = run_tasks(tasks, workers=2, cache_dir=cache / "runs")
    assert all(r.cached for r in again) and kept.read_text() == before
    # a worker's run is its engine's, kept apart: the installed MuJoCo's figure stays
    spec = f"mujoco@{sys.executable}"
    there = run_tasks([Task("fig3", short, spec)], workers=1,
                      cache_dir=cache / "runs")
    assert there[0].error is None
    engines = json.loads(kept.read_text())["engines"]
    assert engines["mujoco"] == json.loads(before)["engines"]["mujoco"]
    assert engines[spec]["step_s"] == pytest.approx(
        there[0].summary["wall_s"] / there[0].summary["n_steps"])
