"""The one resolution of a scene into a run plan: its rules, each with the case that shows it."""

from __future__ import annotations

from pathlib import Path

import pytest

from tippetop.models.calibrated import calibrated_native_settings
from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import MUJOCO_DEFAULT_ROLLING
from tippetop.models.plan import default_sample_dt, sample_grid
from tippetop.models.resolve import PAPER_SOLREF, resolve_plan
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner.state import file_top

ROOT = Path(__file__).resolve().parents[2]
#: examples/paper_loaded_sphere.xml: the paper's Fig. 3 top written by hand (RK4 at 2e-4 s,
#: an elliptic cone, MuJoCo's default contact softness, mu 0.1 on the ball and the floor)
FILE = ROOT / "examples" / "paper_loaded_sphere.xml"
MJCF = f"top.mjcf={str(FILE)!r}"


@pytest.fixture(scope="module")
def loaded():
    return file_top(FILE)


def plan(engine: str, *overrides: str, scene: str | None = "fig3", file_top=None):
    return resolve_plan(load_scene(scene, list(overrides)), engine, file_top=file_top)


def ball(p):
    """The ball's contact with the table as MuJoCo makes it, as a summary reports it."""
    return p.ball_contact.acting()


# ---------------------------------------------------------------- effects
def test_sliding_off_removes_friction_in_every_engine() -> None:
    off = "effects.sliding=false"
    assert plan("ode", off).ode.friction.law == "none"
    paper = plan("mujoco", off, "mujoco.friction=paper").mujoco
    assert paper.law is None and ball(paper)["condim"] == 1
    native = plan("mujoco", off, "mujoco.friction=native").mujoco
    assert {c.friction[0] for c in native.contacts} == {0.0} and ball(native)["condim"] == 1
    # and with sliding on, each engine gets the scene's law
    assert plan("ode").ode.friction.law == "modified_coulomb"
    assert plan("mujoco", "mujoco.friction=paper").mujoco.law.law == "modified_coulomb"


@pytest.mark.parametrize("engine,mode", [("ode", "paper"), ("mujoco", "paper")])
def test_torsion_is_refused_where_it_cannot_run(engine: str, mode: str) -> None:
    with pytest.raises(TippetopError, match="^effects: .* expected torsional = false"):
        plan(engine, "effects.torsional=true", f"mujoco.friction={mode}")


def test_native_condim_follows_the_effects() -> None:
    nat = "mujoco.friction=native"
    assert ball(plan("mujoco", nat).mujoco)["condim"] == 3
    p = ball(plan("mujoco", nat, "effects.torsional=true").mujoco)
    assert (p["condim"], p["rolling"]) == (4, None) and p["torsional"] > 0
    p = ball(plan("mujoco", nat, "effects.torsional=true", "effects.rolling=true",
                  "effects.rolling_mu=0.002").mujoco)
    assert (p["condim"], p["rolling"]) == (6, 0.002)
    p = ball(plan("mujoco", nat, "effects.rolling=true").mujoco)
    assert p["rolling"] == MUJOCO_DEFAULT_ROLLING


# ---------------------------------------------------------------- paper and native settings
def test_paper_mode_is_frictionless_and_stiff_unless_told() -> None:
    p = plan("mujoco", "mujoco.friction=paper").mujoco
    assert {(c.condim, c.friction, c.solref) for c in p.contacts} == {
        (1, (0.0, 0.0, 0.0), PAPER_SOLREF)}
    assert ball(plan("mujoco", "mujoco.friction=paper",
                     "mujoco.solref=[0.01, 1]").mujoco)["solref"] == [0.01, 1.0]
    # mujoco.mu replaces the law's mu in paper mode
    assert plan("mujoco", "mujoco.friction=paper", "mujoco.mu=0.3").mujoco.law.mu == 0.3
    with pytest.raises(TippetopError, match="^mujoco.condim: expected 1 in paper mode"):
        plan("mujoco", "mujoco.friction=paper", "mujoco.condim=3")


def test_native_mode_takes_the_calibration_for_what_the_scene_does_not_set() -> None:
    cal = calibrated_native_settings()
    assert cal, "models/calibrated_native.toml must ship [settings]"
    p = plan("mujoco", "mujoco.friction=native").mujoco
    assert (p.cone, p.impratio, ball(p)["mu"], p.timestep_s, p.integrator) == (
        cal["cone"], cal["impratio"], cal["mu"], cal["timestep_s"], cal["integrator"])
    assert ball(p)["solref"] == list(cal["solref"]) and ball(p)["solimp"] == list(cal["solimp"])
    p = plan("mujoco", "mujoco.friction=native", "mujoco.cone=elliptic", "mujoco.mu=0.5").mujoco
    assert (p.cone, ball(p)["mu"], p.impratio) == ("elliptic", 0.5, cal["impratio"])
    # the calibration fitted mu for the reference's mu = 0.1: another law's mu scales with it
    p = plan("mujoco", "mujoco.friction=native", "friction.mu=0.3").mujoco
    assert ball(p)["mu"] == pytest.approx(3.0 * cal["mu"], rel=1e-15)


# ---------------------------------------------------------------- a loaded MJCF top
def test_a_loaded_top_keeps_its_file_settings_unless_the_scene_sets_them(loaded) -> None:
    p = plan("mujoco", MJCF, "mujoco.friction=native", file_top=loaded).mujoco
    assert p.top == loaded.top and p.source == str(FILE)
    # every value resolved: the file's own, read into the plan (impratio, noslip and gravity
    # are MuJoCo's defaults, which the file leaves: 1, 0 and 9.81 m/s^2)
    assert (p.timestep_s, p.integrator, p.cone, p.impratio, p.noslip_iterations,
            p.gravity_mps2) == (2e-4, "RK4", "elliptic", 1.0, 0, (0.0, 0.0, -9.81))
    assert p.contacts == loaded.contacts
    assert ball(p) == {"condim": 3, "mu": 0.1, "torsional": None, "rolling": None,
                       "solref": [0.02, 1.0], "solreffriction": None,
                       "solimp": [0.9, 0.95, 0.001, 0.5, 2.0]}
    assert p.sample_dt_s == pytest.approx(1e-3, rel=1e-12) and p.steps_per_sample == 5
    p = plan("mujoco", MJCF, "mujoco.friction=native", "mujoco.timestep_s=1e-4",
             "mujoco.integrator=Euler", "effects.torsional=true", file_top=loaded).mujoco
    assert (p.timestep_s, p.integrator, ball(p)["condim"], p.cone) == (
        1e-4, "Euler", 4, "elliptic")
    assert p.steps_per_sample == 10
    paper = plan("mujoco", MJCF, "mujoco.friction=paper", file_top=loaded).mujoco
    assert (ball(paper)["condim"], ball(paper)["solref"], paper.timestep_s) == (
        1, [0.02, 1.0], 2e-4)
    assert plan("ode", MJCF, file_top=loaded).ode.top == loaded.top


def test_a_loaded_top_needs_its_parameters() -> None:
    with pytest.raises(TypeError, match="file_top"):
        plan("ode", "top.mjcf=\"/nonexistent/top.xml\"")


# ---------------------------------------------------------------- sampling
def test_sampling() -> None:
    assert default_sample_dt(8.0) == 1e-3
    assert default_sample_dt(60.0) == 60.0 / 20_000
    assert sample_grid(8.0, None, 3e-4) == (pytest.approx(9e-4), 3, 8888)  # nearest whole
    assert sample_grid(8.0, 2e-3, 2e-4) == (pytest.approx(2e-3), 10, 4000)
    with pytest.raises(TippetopError, match="^run.sample_dt_s: expected a whole multiple of "
                       "the timestep 0.002 s, got 0.001"):
        sample_grid(8.0, 1e-3, 2e-3)
    with pytest.raises(TippetopError, match="^run.t_end_s: expected >= the sample interval"):
        sample_grid(1e-4, None, 2e-4)
    assert plan("ode").ode.sample_dt_s == 1e-3
    assert plan("ode", "run.sample_dt_s=0.01").ode.sample_dt_s == 0.01


# ---------------------------------------------------------------- unused keys
@pytest.mark.parametrize(("engine", "overrides", "unused"), [
    ("ode", ("mujoco.cone=pyramidal", "ode.rtol=1e-8"), ("mujoco.cone",)),
    ("mujoco", ("ode.rtol=1e-8", "init.n0=50"), ("ode.rtol",)),
    ("ode", ("friction.law=coulomb", "friction.Lambda_mps=0.02"), ("friction.Lambda_mps",)),
    ("ode", ("effects.sliding=false", "friction.mu=0.3"), ("friction.mu",)),
    ("mujoco", ("mujoco.friction=paper", "mujoco.cone=pyramidal"), ("mujoco.cone",)),
    # native mode scales the calibrated mu by the scene's friction.mu: it is read
    ("mujoco", ("mujoco.friction=native", "friction.mu=0.3"), ()),
    ("mujoco", ("mujoco.friction=native", "mujoco.mu=0.3"), ()),
    ("mujoco", ("mujoco.friction=native", "effects.torsional_mu=0.01"),
     ("effects.torsional_mu",)),
])
def test_set_keys_the_engine_does_not_read_are_listed(engine: str, overrides: tuple[str, ...],
                                                      unused: tuple[str, ...]) -> None:
    assert plan(engine, *overrides).unused == unused


def test_physics_ignores_names_and_unused_keys() -> None:
    a = plan("ode")
    b = plan("ode", "mujoco.cone=pyramidal", "scene.name=other")
    assert a.physics() == b.physics()
    assert a.physics() != plan("ode", "init.n0=90").physics()
