"""A plan is data: every value resolved, the MJCF it compiles, exact JSON, nothing left to decide.

Over every catalogue scene in every mode, and over MJCF tops of our own and of a stranger's
(defaults classes, a floor of higher priority, solmix weights, an explicit pair, an included
file, a mesh found through meshdir): the plan holds every value the run uses, round-trips
through JSON exactly, compiles to a model that holds its values, and states the ball's contact
with the table as MuJoCo makes it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tippetop.models.errors import TippetopError
from tippetop.models.modes import MODES
from tippetop.models.plan import PLAN_FORMAT, MujocoPlan, RunPlan
from tippetop.models.resolve import resolve_plan
from tippetop.models.scene import catalogue_names, load_scene
from tippetop.mujoco_runner.settings import build_model
from tippetop.mujoco_runner.state import file_top
from tippetop.mujoco_runner.stepping import start_data

ROOT = Path(__file__).resolve().parents[2]
FILES = [ROOT / "examples" / "paper_loaded_sphere.xml",
         ROOT / "examples" / "capsule_stem_top.xml",
         ROOT / "examples" / "cylinder_stem_ballast.xml",
         ROOT / "tests" / "data" / "tutorial_tippe_top.xml",
         ROOT / "tests" / "data" / "stranger" / "top.xml"]
pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")


def _plan(scene: str | None, run: str, *overrides: str) -> RunPlan:
    """The plan of ``run``: an engine (its scene's mode), or ``ENGINE/MODE``."""
    engine, _, mode = run.partition("/")
    s = load_scene(scene, list(overrides))
    loaded = file_top(s.top_mjcf) if s.top_mjcf is not None else None
    return resolve_plan(s, engine, mode or None, file_top=loaded)


def _catalogue() -> list[tuple[str, str]]:
    return [(name, f"{family}/{mode}") for name in catalogue_names()
            for mode, m in MODES.items() for family in m.families]


def _files() -> list[tuple[Path, str, tuple[str, ...]]]:
    out = []
    for f in FILES:
        for mode in ("mujoco", "mujoco/native", "mujoco/file", "ode"):
            out.append((f, mode, ()))
        out.append((f, "mujoco/paper", ("mujoco.fit_paper_timestep=true",)))
        out.append((f, "mujoco", ("init.n0=150", "init.theta0=0.2")))  # a state, no keyframe
    out.append((FILES[2], "mujoco", ("init.keyframe='slow'", "effects.stem=false")))
    return out


@pytest.mark.parametrize(("scene", "mode"), _catalogue())
def test_every_catalogue_plan_round_trips_through_json_exactly(scene: str, mode: str) -> None:
    plan = _plan(scene, mode)
    text = plan.to_json()
    assert json.loads(text)["format"] == PLAN_FORMAT
    again = RunPlan.from_json(text)
    assert again == plan
    assert again.to_json() == text  # and writes the same text again


@pytest.mark.parametrize(("path", "mode", "over"), _files(),
                         ids=lambda v: v.parent.name + "/" + v.name if isinstance(v, Path)
                         else None)
def test_a_loaded_tops_plan_round_trips_and_holds_every_value(path: Path, mode: str,
                                                             over: tuple[str, ...]) -> None:
    plan = _plan(None, mode, f"top.mjcf={str(path)!r}", "run.t_end_s=1.0", *over)
    assert RunPlan.from_json(plan.to_json()) == plan
    if plan.mujoco is not None:
        _complete(plan.mujoco)


def _complete(p: MujocoPlan) -> None:
    """Nothing left for an engine to fill in, and the model it compiles holds the values."""
    for name in ("timestep_s", "integrator", "cone", "impratio", "noslip_iterations",
                 "gravity_mps2", "sample_dt_s", "steps_per_sample", "n_intervals", "mjcf"):
        assert getattr(p, name) is not None, name
    assert p.contacts and p.ball_contact is not None
    assert p.sample_dt_s == p.steps_per_sample * p.timestep_s
    # the start is a keyframe of the text, or the free joint's state: exactly one of them
    assert (p.keyframe is None) == (len(p.start_qpos) == 7 and len(p.start_qvel) == 6)
    assert (p.law is None) == (p.paper_max_timestep_s is None) or p.friction == "paper"
    build_model(p)  # raises if the compiled model does not hold the plan's values


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
@pytest.mark.parametrize("mode", ["mujoco", "mujoco/native", "mujoco/paper"])
def test_the_plan_states_the_ball_table_contact_as_mujoco_makes_it(path: Path,
                                                                    mode: str) -> None:
    # MuJoCo mixes the two geoms' values into the contact (mj_contactParam: priority, then the
    # larger condim and friction, solmix-weighted solref and solimp) or takes a pair's; the
    # plan's ball_contact must be the contact MuJoCo builds at t = 0, to the last bit
    over = ("mujoco.fit_paper_timestep=true",) if mode == "mujoco/paper" else ()
    p = _plan(None, mode, f"top.mjcf={str(path)!r}", "run.t_end_s=0.1", *over).mujoco
    top_model = build_model(p)
    model = top_model.model
    data = start_data(top_model, p)
    mujoco.mj_forward(model, data)
    ball, con = top_model.ball_geom_id, None
    for i in range(data.ncon):
        c = data.contact[i]
        other = c.geom2 if c.geom1 == ball else c.geom1 if c.geom2 == ball else None
        if other is not None and model.body_weldid[model.geom_bodyid[other]] == 0:
            con = c
            break
    assert con is not None, "the ball starts on the table"
    want = p.ball_contact
    assert (int(con.dim), tuple(con.friction), tuple(con.solref), tuple(con.solimp)) == (
        want.condim, want.contact_friction, want.solref, want.solimp)


def test_the_stranger_file_mixes_by_priority_and_keeps_its_pair() -> None:
    # the floor has priority 1: the ball's contact takes the floor's values alone (mu 0.3, not
    # the shell's 0.8), and so does the friction law's mu; the stem's explicit pair with the
    # floor keeps its own five coefficients
    p = _plan(None, "mujoco", f"top.mjcf={str(FILES[4])!r}").mujoco
    assert p.ball_contact.friction == (0.3, 0.3, 0.005, 0.0001, 0.0001)
    assert p.ball_contact.source == "geoms floor and shell"
    assert _plan(None, "mujoco/paper", f"top.mjcf={str(FILES[4])!r}",
                 "mujoco.fit_paper_timestep=true").mujoco.law.mu == 0.3
    pair = next(c for c in p.contacts if c.element == "pair")
    assert pair.friction == (0.5, 0.5, 0.01, 0.001, 0.001) and pair.solref == (0.003, 1.0)
    # a native scene value goes to every contact element: geoms and the pair
    q = _plan(None, "mujoco", f"top.mjcf={str(FILES[4])!r}", "mujoco.mu=0.2").mujoco
    assert {c.friction[0] for c in q.contacts} == {0.2}
    assert next(c for c in q.contacts if c.element == "pair").friction[:2] == (0.2, 0.2)


def test_the_plans_mjcf_compiles_anywhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                         ) -> None:
    # the stranger's file includes another and finds a mesh through meshdir, both relative to
    # its folder: the plan's text inlines the include and makes the folders absolute, so it
    # compiles from another working folder to the model the file itself compiles to
    p = _plan(None, "mujoco", f"top.mjcf={str(FILES[4])!r}").mujoco
    assert "<include" not in p.mjcf and 'name="floor"' in p.mjcf
    monkeypatch.chdir(tmp_path)
    from_text = mujoco.MjModel.from_xml_string(p.mjcf)
    direct = mujoco.MjModel.from_xml_path(str(FILES[4]))
    for name in ("geom_size", "mesh_vert", "body_inertia", "body_ipos", "geom_friction",
                 "pair_friction", "geom_priority", "key_qpos"):
        assert np.array_equal(getattr(from_text, name), getattr(direct, name)), name
    assert from_text.opt.timestep == direct.opt.timestep
    assert list(tmp_path.iterdir()) == []


def test_a_plan_whose_text_disagrees_with_its_values_is_refused() -> None:
    from dataclasses import replace

    p = _plan("fig3", "mujoco/native").mujoco
    with pytest.raises(TippetopError, match="^mjcf: expected the compiled model to hold the "
                       "plan's values, got timestep_s 0.0002, the plan's 0.0001"):
        build_model(replace(p, timestep_s=1e-4))


@pytest.mark.parametrize(("text", "says"), [
    ("[]", "plan format: expected 'tippetop-plan/1' or 'tippetop-plan/2', got 'list'"),
    ('{"format": "tippetop-plan/0"}', "plan format: expected 'tippetop-plan/1' or "
     "'tippetop-plan/2', got "
     "'tippetop-plan/0'"),
    ("{not json", "plan: expected JSON"),
])
def test_json_that_is_not_a_plan_is_one_line(text: str, says: str) -> None:
    with pytest.raises(TippetopError) as info:
        RunPlan.from_json(text)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_a_plan_with_a_field_changed_or_added_is_refused() -> None:
    data = json.loads(_plan("fig3", "mujoco/paper").to_json())
    data["mujoco"]["timestep_s"] = "fast"
    with pytest.raises(TippetopError, match="^plan.mujoco.timestep_s: expected a number"):
        RunPlan.from_json(json.dumps(data))
    data = json.loads(_plan("fig3", "ode").to_json())
    data["ode"]["rtol2"] = 1e-3
    with pytest.raises(TippetopError, match=r"^plan.ode: expected the fields of OdePlan, got "
                       r"\['rtol2'\]"):
        RunPlan.from_json(json.dumps(data))


def test_paper_modes_timestep_rule_is_the_plans() -> None:
    # the tutorial top (mu = 1, its own 2 ms step): the law relaxes the slip in 0.166 ms
    tut = f"top.mjcf={str(FILES[3])!r}"
    with pytest.raises(TippetopError, match=r"^mujoco\.timestep_s: expected at most 0\.000166 "
                       r"s .* or mujoco.fit_paper_timestep = true"):
        _plan(None, "mujoco/paper", tut)
    p = _plan(None, "mujoco/paper", tut, "mujoco.fit_paper_timestep=true").mujoco
    assert p.timestep_s == 1e-4 and p.paper_max_timestep_s == pytest.approx(1.66e-4, rel=0.01)
    assert p.notes == ("ran at dt = 0.0001 s, not the file's 0.002 s: the paper's law at mu = 1 "
                       "relaxes the slip in 0.166 ms on this top, which a longer step cannot "
                       "follow",)
    # a step the scene sets itself is never changed
    with pytest.raises(TippetopError, match=r"^mujoco\.timestep_s: expected at most"):
        _plan(None, "mujoco/paper", tut, "mujoco.fit_paper_timestep=true",
              "mujoco.timestep_s=0.001")


def test_plans_hold_no_path_relative_to_the_working_folder(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    p = _plan(None, "mujoco", f"top.mjcf={os.path.relpath(FILES[0])!r}").mujoco
    assert p.source is not None and os.path.isabs(p.source)
