"""Both engines run the plan, and the summary says what ran.

The two bugs of the three-place scene resolution each have a test here: paper mode ignored
``effects.sliding = false``, and a loaded MJCF top ignored ``mujoco.timestep_s`` and
``mujoco.integrator`` while the summary echoed them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import run_mujoco
from tippetop.compare.running.engines import plan_for, run_engine, run_plan
from tippetop.models.mjcf import MjcfContact, MjcfOption, make_mjcf
from tippetop.models.params import TopParams
from tippetop.models.scene import load_scene

T_END = 0.5  # s: a quarter of Fig. 3's rise, enough for friction to move the top visibly


def _run(engine: str, *overrides: str):
    return run_engine(load_scene("fig3", ["run.t_end_s=0.5", *overrides]), engine,
                      progress=False)


def test_paper_mode_without_sliding_applies_no_friction() -> None:
    off = _run("mujoco", "mujoco.friction=paper", "effects.sliding=false")
    on = _run("mujoco", "mujoco.friction=paper")
    assert off.status == on.status == "ok"
    assert off.summary["friction_law"] == "none" and on.summary["friction_law"] != "none"
    # A frictionless table pushes only along e_z: the centre of mass cannot move sideways
    # from its start at rest (x = y = 0); 1e-12 m is round-off over 25,000 RK4 steps. With
    # friction on, the same start slides by about a millimetre.
    assert np.max(np.hypot(off.table["x"], off.table["y"])) < 1e-12
    assert np.max(np.hypot(on.table["x"], on.table["y"])) > 1e-4
    # ... and the friction power is zero, not just small
    assert np.all(off.table["P_fric"] == 0.0)
    # It follows the frictionless reference: only the soft contact separates them. Paper mode
    # agrees with the reference to ~2e-4 rad over 6 s with friction (README); without it the
    # error left is the contact's (ball sinking < 1 um): 1e-3 rad bounds it over 0.5 s.
    ode = _run("ode", "effects.sliding=false")
    theta_ode = np.interp(off.table["t"], ode.table["t"], ode.table["theta"])
    assert np.max(np.abs(off.table["theta"] - theta_ode)) < 1e-3
    # the frictionless and the frictional runs differ by far more than that
    assert np.max(np.abs(on.table["theta"] - off.table["theta"])) > 1e-2


@pytest.fixture(scope="module")
def mjcf_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A top written as a file with options that no scene default has."""
    xml = make_mjcf(TopParams.from_ratios(1.0, 0.1), contact=MjcfContact(friction_mode="paper"),
                    option=MjcfOption(timestep_s=5e-5, integrator="implicitfast"))
    path = tmp_path_factory.mktemp("mjcf") / "top.xml"
    path.write_text(xml)
    return path


def test_a_loaded_top_runs_its_own_timestep_and_integrator(mjcf_file: Path) -> None:
    scene = load_scene("fig3", [f"top.mjcf={str(mjcf_file)!r}", "run.t_end_s=0.1",
                                "mujoco.friction=paper"])
    run = run_plan(plan_for(scene, "mujoco"), progress=False)
    assert (run.summary["timestep_s"], run.summary["integrator"]) == (5e-5, "implicitfast")
    assert run.summary["n_steps"] == round(0.1 / 5e-5)
    # and the summary is true: this is the run of a model written with the file's settings
    # (its own contact too), bit for bit
    same_args = ("run.t_end_s=0.1", "run.sample_dt_s=1e-3", "mujoco.friction='paper'",
                 "mujoco.timestep_s=5e-5", "mujoco.solref=[0.02, 1.0]")
    same = run_mujoco(*same_args, "mujoco.integrator='implicitfast'")
    assert np.array_equal(run.table["theta"].to_numpy(), same.table["theta"].to_numpy())
    # ... which the integrator does change: RK4 at the same dt ends 4.6e-5 rad away
    rk4 = run_mujoco(*same_args, "mujoco.integrator='RK4'")
    assert np.max(np.abs(run.table["theta"].to_numpy() - rk4.table["theta"].to_numpy())) > 1e-6


def test_a_loaded_top_runs_the_timestep_and_integrator_it_is_given(mjcf_file: Path) -> None:
    scene = load_scene("fig3", [f"top.mjcf={str(mjcf_file)!r}", "run.t_end_s=0.1",
                                "mujoco.friction=paper", "mujoco.timestep_s=1e-4",
                                "mujoco.integrator=Euler"])
    run = run_plan(plan_for(scene, "mujoco"), progress=False)
    s = run.summary
    assert (s["timestep_s"], s["integrator"], s["n_steps"]) == (1e-4, "Euler", 1000)
    # and it is the run of a model written with those settings, bit for bit
    same = run_mujoco("run.t_end_s=0.1", "run.sample_dt_s=1e-3", "mujoco.friction='paper'",
                      "mujoco.timestep_s=1e-4", "mujoco.integrator='Euler'",
                      "mujoco.solref=[0.02, 1.0]")
    assert np.array_equal(run.table["theta"].to_numpy(), same.table["theta"].to_numpy())


def test_the_summary_reports_what_ran_and_what_was_not_used() -> None:
    mj = _run("mujoco", "mujoco.friction=native", "mujoco.cone=elliptic", "ode.rtol=1e-6",
              "run.t_end_s=0.05")
    s = mj.summary
    assert s["condim"] == 3 and s["friction_law"] == "mujoco_contact"
    assert s["unused"] == ["ode.rtol"]
    for key in ("timestep_s", "integrator", "impratio", "mu", "solref", "solimp"):
        assert s[key] is not None, key
    ode = _run("ode", "mujoco.cone=pyramidal", "run.t_end_s=0.05")
    assert ode.summary["unused"] == ["mujoco.cone"]
    assert (ode.summary["friction_law"], ode.summary["formulation"]) == ("modified_coulomb",
                                                                         "vector")


def _slide_deceleration(mode: str, angle_deg: float) -> float:
    """The top, upright and not spinning, slid at 0.5 m/s along ``angle_deg`` from the table's
    x axis: the centre's deceleration over 10-90 ms (the ball still slips; rolling would start
    at about 0.14 s), in units of mu g."""
    a = math.radians(angle_deg)
    scene = load_scene("fig3", ["init.theta0=0.0", "init.n0=0.0", f"init.uOX={0.5 * math.cos(a)!r}",
                                f"init.uOY={0.5 * math.sin(a)!r}", "run.t_end_s=0.1",
                                "run.sample_dt_s=0.001"])
    run = run_engine(scene, "mujoco", mode, progress=False)
    t = run.table["t"].to_numpy()
    speed = np.hypot(np.gradient(run.table["x"].to_numpy(), t),
                     np.gradient(run.table["y"].to_numpy(), t))
    keep = (t > 0.01) & (t < 0.09)
    return float(-np.polyfit(t[keep], speed[keep], 1)[0] / (run.summary["mu"] * 9.8))


def test_the_cone_setting_takes_effect() -> None:
    # MuJoCo's pyramidal cone bounds each of its edge directions, so a slip along a diagonal
    # of the table's axes gets at most mu N / sqrt(2); the elliptic cone gives mu N in every
    # direction (facts.md: a box decelerated at 0.70 mu g against ~1.0). The tippe top on its
    # calibrated native contact: measured 1.009 mu g elliptic at 0 and 45 degrees, 1.011 mu g
    # pyramidal along x, 0.711 mu g pyramidal along the diagonal. Bounds 0.03 mu g.
    assert _slide_deceleration("native-elliptic", 45.0) == pytest.approx(1.0, abs=0.03)
    assert _slide_deceleration("native-pyramidal", 0.0) == pytest.approx(1.0, abs=0.03)
    assert _slide_deceleration("native-pyramidal", 45.0) == pytest.approx(
        1.0 / math.sqrt(2.0), abs=0.03)


def test_inversion_time_is_a_crossing_from_below() -> None:
    """MuJoCo's sampled t_invert means what the reference's located one means: theta crossing
    pi/2 upward. A start above pi/2 is not an inversion at t = 0."""
    import pandas as pd

    from tippetop.compare.measures.series import first_inversion_time

    t = np.arange(5) * 0.1
    assert first_inversion_time(pd.DataFrame({"t": t, "theta": [0.1, 1.0, 1.6, 2.0, 3.0]})) \
        == pytest.approx(0.2)
    assert first_inversion_time(pd.DataFrame({"t": t, "theta": [3.1, 2.5, 2.0, 1.8, 1.8]})) \
        is None
    assert first_inversion_time(pd.DataFrame({"t": t, "theta": [3.1, 1.2, 1.4, 1.7, 1.8]})) \
        == pytest.approx(0.3)


@pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")
def test_a_top_heavy_at_the_stem_starts_inverted_in_both_engines(tmp_path: Path) -> None:
    """A file whose centre of mass lies above the ball's centre (a heavy stem up, spun
    upright): in the paper's frame the top starts at theta = pi. Neither engine reports an
    inversion, and both start from the same paper state."""
    f = tmp_path / "heavy_stem.xml"
    f.write_text("""<mujoco>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body name="top" pos="0 0 0.02">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.02" mass="0.08"/>
      <geom name="knob" type="cylinder" pos="0 0 0.021" size="0.003 0.009" mass="0.04"/>
    </body>
  </worldbody>
  <keyframe><key qpos="0 0 0.02 1 0 0 0" qvel="0 0 0 0 0.5 150"/></keyframe>
</mujoco>""")
    scene = load_scene(None, [f"top.mjcf={str(f)!r}", "run.t_end_s=0.5"])
    ode = run_plan(plan_for(scene, "ode"), progress=False)
    mj = run_plan(plan_for(scene, "mujoco"), progress=False)
    assert plan_for(scene, "ode").init.theta0 == pytest.approx(math.pi)
    assert ode.summary["t_invert"] is None and mj.summary["t_invert"] is None
    assert float(mj.table["theta"].iloc[0]) == pytest.approx(math.pi, abs=1e-9)
