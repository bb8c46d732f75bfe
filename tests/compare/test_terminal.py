"""What a person reads: values with units, and a progress bar weighted by each run's cost.

``fmt`` turns one value into text: ``None`` is ``-``, NaN is ``undefined (NaN)``, a float has
four significant digits (a relative drift two, in scientific notation), an integer has
thousands separators, a boolean is ``yes`` or ``no``; ``fmt_value`` adds the unit that a key's
name implies (``t_invert`` -> s, ``theta_*`` -> rad, ``*_J`` -> J, ``rel_diff`` -> %).
``table`` lines up rows of text in columns, numbers right-aligned.
"""

from __future__ import annotations

import io
import math

import pytest

from tippetop.compare.presentation.terminal import (
    MISSING,
    fmt,
    fmt_duration,
    fmt_percent,
    fmt_value,
    table,
    unit_of,
)
from tippetop.compare.running.cost import expected_cost_s, schedule_s
from tippetop.compare.running.progress import WorkProgress


# ---------------------------------------------------------------- values
@pytest.mark.parametrize(
    ("value", "unit", "text"),
    [
        (None, "", MISSING),
        (None, "rad", MISSING),
        (True, "", "yes"),
        (False, "", "no"),
        (400000, "", "400,000"),
        (2.329259, "s", "2.329 s"),
        (3.104172, "rad", "3.104 rad"),
        (0.1 + 0.2, "", "0.3"),  # never 0.30000000000000004
        (18.0, "s", "18 s"),
        (2e-5, "s", "2e-5 s"),
        (1.284282e-09, "", "1.284e-9"),
        (1.284282e-09, "relative", "1.3e-9"),
        (0.0, "relative", "0"),
        (0.0083333, "%", "+0.833 %"),
        ([0.0005, 1.0], "", "5e-4, 1"),
        ([], "", "none"),
        ("inverted", "", "inverted"),
    ],
)
def test_fmt(value: object, unit: str, text: str) -> None:
    assert fmt(value, unit) == text


def test_nan_and_inf_are_said_not_printed_as_python_does() -> None:
    assert "NaN" in fmt(math.nan) and fmt(math.nan) != "nan"
    assert "NaN" in fmt(math.nan, "rad") and "rad" not in fmt(math.nan, "rad")
    assert fmt(math.inf, "s") == "inf" and fmt(-math.inf) == "-inf"
    assert fmt_percent(math.nan) == fmt(math.nan)


def test_no_float_is_shown_with_more_than_four_significant_digits() -> None:
    for x in (math.pi, 1 / 3, 2 / 3 * 1e-7, 123456.789, 9.99999e5, 0.0012345678):
        text = fmt(x)
        digits = "".join(c for c in text.split("e")[0] if c.isdigit()).lstrip("0")
        assert len(digits) <= 6 and len(text) <= 10, text  # 123457: an integer part is kept


@pytest.mark.parametrize(
    ("key", "unit"),
    [("t_invert", "s"), ("wall_s", "s"), ("theta_asymp", "rad"), ("theta_s", "rad"),
     ("theta_trend_rad_s", "rad/s"), ("n1", "rad/s"), ("measured", "rad/s"),
     ("energy_dissipated_J", "J"), ("max_penetration_m", "m"), ("gravity_mps2", "m/s^2"),
     ("J_rel_drift", "relative"), ("energy_rise_rel", "relative"), ("rel_diff", "%"),
     ("engine", ""), ("n_steps", "")],
)
def test_units_follow_the_key(key: str, unit: str) -> None:
    assert unit_of(key) == unit


def test_fmt_value_says_what_none_means_and_reads_durations_and_phases() -> None:
    assert fmt_value("t_invert", None).startswith("never")
    assert fmt_value("theta_c", None) == MISSING
    assert fmt_value("wall_s", 0.0247803) == "24.78 ms"  # four digits, as every number
    assert fmt_value("wall_s", 125.3) == "2 min 05 s"
    assert fmt_duration(3725) == "1 h 02 min"
    assert fmt_value("phases", [{"contact": "ball", "t_start": 0.0, "t_end": 2.5},
                                {"contact": "stem", "t_start": 2.5, "t_end": 8.0}]) == \
        "ball 0-2.5 s, stem 2.5-8 s"
    assert fmt_value("solref", [0.0005, 1.0]) == "5e-4 s, 1"
    assert fmt_value("rel_diff", -0.25) == "-25 %"


def test_table_right_aligns_numbers_and_keeps_missing_cells() -> None:
    text = table(("mode", "t_invert"), [("ode/paper", "2.329 s"), ("mujoco/native", "12.5 s"),
                                       ("x", MISSING)])
    lines = text.splitlines()
    assert lines[0].startswith("mode") and len({len(s) for s in lines}) == 1
    assert lines[1].endswith("2.329 s") and lines[2].endswith(" 12.5 s")
    assert lines[3].endswith(MISSING)
    assert table(("a", "b"), [("1", "2")], header=False) == "1  2"


# ---------------------------------------------------------------- cost of a run
def test_a_mujoco_run_weighs_far_more_than_an_ode_run_of_the_same_scene(
        tmp_path, monkeypatch) -> None:
    """The weights come from the plans: MuJoCo's steps (t_end / timestep) times a per-step
    cost; the reference ODE a little per simulated second. Fig. 3 over 8 s: paper mode runs
    400,000 steps at 2e-5 s, native mode 40,000 at 2e-4 s (the calibrated timestep)."""
    from tippetop.compare.running.cost import TASK_OVERHEAD_S
    from tippetop.compare.running.engines import plan_for
    from tippetop.models.scene import load_scene

    # a fresh cache: the default cost of a step, not what this machine's runs measured
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    scene = load_scene("fig3")
    ode = expected_cost_s(plan_for(scene, "ode"))
    paper = expected_cost_s(plan_for(scene, "mujoco", "paper"))
    native = expected_cost_s(plan_for(scene, "mujoco", "native"))
    assert paper > 20 * ode and native > 2 * ode
    # beyond the fixed cost of a run, ten times the steps, four times the simulated time
    assert (paper - TASK_OVERHEAD_S) / (native - TASK_OVERHEAD_S) == pytest.approx(10)
    short = expected_cost_s(plan_for(load_scene("fig3", ["run.t_end_s=2"]), "mujoco",
                                                "paper"))
    assert (paper - TASK_OVERHEAD_S) / (short - TASK_OVERHEAD_S) == pytest.approx(4)


def test_schedule_runs_pending_work_on_the_first_free_worker() -> None:
    assert schedule_s([], [1, 1, 1, 1], 2) == 2
    assert schedule_s([3], [1, 1], 2) == 3  # the long run ends last; the short ones beside it
    assert schedule_s([], [10, 1, 1, 1], 2) == 10
    assert schedule_s([], [1, 1, 1, 10], 2) == pytest.approx(11.0)
    assert schedule_s([2, 2, 2], [], 2) == 4  # more running than workers


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_cheap_runs_done_first_do_not_make_the_batch_look_half_done() -> None:
    """The issue's sweep: 6 reference runs and 6 MuJoCo runs. With a count of runs the bar
    stood at 6/12 = 50 % for minutes; weighted by cost it shows the MuJoCo work still to do,
    moves while the MuJoCo runs report their simulated time, and its ETA comes down with it."""
    clock = _Clock()
    costs = [0.4] * 6 + [26.0] * 6
    p = WorkProgress("sweep", costs, slots=2, clock=clock, enabled=False)
    for i in range(6):
        clock.t += 0.2
        p.finished(i)
    assert p.fraction() < 0.02  # not 50 %
    eta0 = p.eta_s()
    assert eta0 == pytest.approx(78, rel=0.2)  # 6 x 26 s of work on 2 workers
    for step in range(1, 11):  # the two MuJoCo runs going report every second
        clock.t += 1.0
        p.reached(6, step / 26)
        p.reached(7, step / 26)
    assert p.fraction() == pytest.approx((2.4 + 20) / (2.4 + 156), rel=0.02)
    assert p.eta_s() == pytest.approx(eta0 - 10, rel=0.1)


def test_eta_follows_the_measured_speed() -> None:
    """Runs twice as slow as the cost model says: the ETA doubles once that is measured."""
    clock = _Clock()
    p = WorkProgress("compare", [10.0, 10.0], slots=2, clock=clock, enabled=False)
    assert p.eta_s() == pytest.approx(10)
    for step in range(1, 11):
        clock.t += 2.0
        p.reached(0, step / 20)
        p.reached(1, step / 20)
    assert p.fraction() == pytest.approx(0.5)
    assert p.eta_s() == pytest.approx(20, rel=0.25)  # 5 s of model work left at half speed


def test_worker_start_up_does_not_count_as_slow_work() -> None:
    clock = _Clock()
    p = WorkProgress("sweep", [10.0, 10.0], slots=2, clock=clock, enabled=False)
    clock.t = 8.0  # workers importing their engines: nothing reported yet
    p.tick()
    assert p.eta_s() == pytest.approx(10)
    assert "starting, then about 0:10" in p.line()
    clock.t = 9.0
    p.reached(0, 0.1)
    p.reached(1, 0.1)
    assert p.eta_s() < 12


def test_while_the_workers_compile_the_bar_says_so_and_how_long() -> None:
    # the nightly: "0% ... about 0:12" for 51 s while code compiled. With the compile
    # estimate the bar says what it waits for, counts it down, then gives the runs' own ETA
    clock = _Clock()
    p = WorkProgress("nightly", [10.0, 10.0], slots=2, clock=clock, enabled=False,
                     compile_s=18.0)
    assert "compiling, about 0:18 more, then about 0:10" in p.line()
    clock.t = 12.0
    p.tick()
    assert "compiling, about 0:06 more, then about 0:10" in p.line()
    clock.t = 25.0  # longer than said: still compiling, no negative countdown
    p.tick()
    assert "compiling, then about 0:10" in p.line()
    clock.t = 26.0
    p.reached(0, 0.1)
    p.reached(1, 0.1)
    assert "compiling" not in p.line() and "left" in p.line()


def test_nothing_to_compile_is_starting_as_before() -> None:
    clock = _Clock()
    p = WorkProgress("sweep", [10.0], clock=clock, enabled=False, compile_s=0.0)
    clock.t = 3.0
    p.tick()
    assert "starting, then about" in p.line() and "compiling" not in p.line()


class _Tty(io.StringIO):
    encoding = "utf-8"

    def isatty(self) -> bool:
        return True


def test_the_bar_is_drawn_on_a_terminal_only() -> None:
    quiet = io.StringIO()
    p = WorkProgress("sweep", [1.0, 1.0], stream=quiet)
    p.finished(0)
    p.draw(force=True)
    p.close()
    assert quiet.getvalue() == ""
    tty = _Tty()
    p = WorkProgress("sweep", [1.0, 3.0], stream=tty, note="2 from the cache",
                     min_interval_s=0.0)
    p.finished(0)
    text = tty.getvalue()
    assert text.startswith("\rsweep") and " 25%" in text and "1/2 runs (2 from the cache)" in text
    assert "elapsed" in text and "left" in text
    p.close()
    assert tty.getvalue().endswith("\r")


def test_run_tasks_is_quiet_when_stderr_is_not_a_terminal(capsys: pytest.CaptureFixture) -> None:
    from tippetop.compare.running.runner import Task, run_tasks

    res = run_tasks([Task("fig3", ("run.t_end_s=0.05",), "ode")], workers=1, use_cache=False)
    assert res[0].error is None
    assert capsys.readouterr().err == ""


def test_a_mujoco_run_reports_how_far_it_got() -> None:
    """In a worker (here in-process) a MuJoCo run says the fraction of its simulated time done,
    under its key, the last report at the end (the bar's share of that run)."""
    from tippetop.compare.running import tasks

    seen: list[tuple[str, float]] = []
    before = tasks.set_reporter(lambda key, f: seen.append((key, f)))
    try:
        out = tasks.execute(tasks.Task("fig3", ("run.t_end_s=0.1",), "mujoco", "native"), "k")
        assert "summary" in out
        tasks.execute(tasks.Task("fig3", ("run.t_end_s=0.05",), "ode"), "k2")
    finally:
        tasks.set_reporter(before)
    assert seen and {k for k, _ in seen} == {"k"}  # the reference is too quick to report
    assert seen[-1][1] == pytest.approx(1.0, abs=0.02)
