"""The one resolution of a scene into a run plan: its rules, each with the case that shows it."""

from __future__ import annotations

from pathlib import Path

import pytest

from tippetop.models.calibrated import calibrated_native_settings
from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import MUJOCO_DEFAULT_ROLLING
from tippetop.models.params import TopParams
from tippetop.models.plan import (
    PAPER_SOLREF,
    FileTop,
    default_sample_dt,
    resolve_plan,
    sample_interval,
)
from tippetop.models.scene import load_scene

FILE_TOP = FileTop(TopParams.from_ratios(1.0, 0.15))


def plan(engine: str, *overrides: str, scene: str | None = "fig3", file_top=None):
    return resolve_plan(load_scene(scene, list(overrides)), engine, file_top=file_top)


# ---------------------------------------------------------------- effects
def test_sliding_off_removes_friction_in_every_engine() -> None:
    off = "effects.sliding=false"
    assert plan("ode", off).ode.friction.law == "none"
    paper = plan("mujoco", off, "mujoco.friction=paper").mujoco
    assert paper.law is None and paper.condim == 1
    native = plan("mujoco", off, "mujoco.friction=native").mujoco
    assert native.mu == 0.0 and native.condim == 1
    # and with sliding on, each engine gets the scene's law
    assert plan("ode").ode.friction.law == "modified_coulomb"
    assert plan("mujoco", "mujoco.friction=paper").mujoco.law.law == "modified_coulomb"


@pytest.mark.parametrize("engine,mode", [("ode", "paper"), ("mujoco", "paper")])
def test_torsion_is_refused_where_it_cannot_run(engine: str, mode: str) -> None:
    with pytest.raises(TippetopError, match="^effects: .* expected torsional = false"):
        plan(engine, "effects.torsional=true", f"mujoco.friction={mode}")


def test_native_condim_follows_the_effects() -> None:
    nat = "mujoco.friction=native"
    assert plan("mujoco", nat).mujoco.condim == 3
    p = plan("mujoco", nat, "effects.torsional=true").mujoco
    assert (p.condim, p.rolling) == (4, 0.0) and p.torsional > 0
    p = plan("mujoco", nat, "effects.torsional=true", "effects.rolling=true",
             "effects.rolling_mu=0.002").mujoco
    assert (p.condim, p.rolling) == (6, 0.002)
    p = plan("mujoco", nat, "effects.rolling=true").mujoco
    assert p.rolling == MUJOCO_DEFAULT_ROLLING


# ---------------------------------------------------------------- paper and native settings
def test_paper_mode_is_frictionless_and_stiff_unless_told() -> None:
    p = plan("mujoco", "mujoco.friction=paper").mujoco
    assert (p.condim, p.mu, p.solref) == (1, 0.0, PAPER_SOLREF)
    assert plan("mujoco", "mujoco.friction=paper",
                "mujoco.solref=[0.01, 1]").mujoco.solref == (0.01, 1.0)
    # mujoco.mu replaces the law's mu in paper mode
    assert plan("mujoco", "mujoco.friction=paper", "mujoco.mu=0.3").mujoco.law.mu == 0.3
    with pytest.raises(TippetopError, match="^mujoco.condim: expected 1 in paper mode"):
        plan("mujoco", "mujoco.friction=paper", "mujoco.condim=3")


def test_native_mode_takes_the_calibration_for_what_the_scene_does_not_set() -> None:
    cal = calibrated_native_settings()
    assert cal, "models/calibrated_native.toml must ship [settings]"
    p = plan("mujoco", "mujoco.friction=native").mujoco
    assert (p.cone, p.impratio, p.mu, p.timestep_s, p.integrator) == (
        cal["cone"], cal["impratio"], cal["mu"], cal["timestep_s"], cal["integrator"])
    assert p.solref == tuple(cal["solref"]) and p.solimp == tuple(cal["solimp"])
    p = plan("mujoco", "mujoco.friction=native", "mujoco.cone=elliptic", "mujoco.mu=0.5").mujoco
    assert (p.cone, p.mu, p.impratio) == ("elliptic", 0.5, cal["impratio"])
    # the calibration fitted mu for the reference's mu = 0.1: another law's mu scales with it
    p = plan("mujoco", "mujoco.friction=native", "friction.mu=0.3").mujoco
    assert p.mu == pytest.approx(3.0 * cal["mu"], rel=1e-15)


# ---------------------------------------------------------------- a loaded MJCF top
def test_a_loaded_top_keeps_its_file_settings_unless_the_scene_sets_them() -> None:
    mjcf = "top.mjcf=\"/nonexistent/top.xml\""  # the plan does not open it: file_top is given
    p = plan("mujoco", mjcf, "mujoco.friction=native", file_top=FILE_TOP).mujoco
    assert p.top == FILE_TOP.top and p.mjcf == Path("/nonexistent/top.xml")
    assert (p.timestep_s, p.integrator, p.cone, p.impratio, p.condim, p.mu, p.solref,
            p.solimp, p.sample_dt_s) == (None,) * 9
    p = plan("mujoco", mjcf, "mujoco.friction=native", "mujoco.timestep_s=1e-4",
             "mujoco.integrator=Euler", "effects.torsional=true", file_top=FILE_TOP).mujoco
    assert (p.timestep_s, p.integrator, p.condim, p.cone) == (1e-4, "Euler", 4, None)
    assert p.sample_dt_s == pytest.approx(1e-3, rel=1e-12)  # 10 steps: the timestep is known
    paper = plan("mujoco", mjcf, "mujoco.friction=paper", file_top=FILE_TOP).mujoco
    assert (paper.condim, paper.solref, paper.timestep_s) == (1, None, None)
    assert plan("ode", mjcf, file_top=FILE_TOP).ode.top == FILE_TOP.top


def test_a_loaded_top_needs_its_parameters() -> None:
    with pytest.raises(TypeError, match="file_top"):
        plan("ode", "top.mjcf=\"/nonexistent/top.xml\"")


# ---------------------------------------------------------------- sampling
def test_sampling() -> None:
    assert default_sample_dt(8.0) == 1e-3
    assert default_sample_dt(60.0) == 60.0 / 20_000
    assert sample_interval(8.0, None, 3e-4) == pytest.approx(9e-4)  # nearest whole number
    assert sample_interval(8.0, 2e-3, 2e-4) == pytest.approx(2e-3)
    with pytest.raises(TippetopError, match="^run.sample_dt_s: expected a whole multiple of "
                       "the timestep 0.002 s, got 0.001"):
        sample_interval(8.0, 1e-3, 2e-3)
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
