"""MuJoCo executes a plan and decides nothing: what ran, read back, is what the plan said.

Every run reports what ran from the compiled model and from the top's contact at t = 0 (MuJoCo
has mixed the two geoms' values into it); the plan states the same before anything runs
(:meth:`MujocoPlan.what_runs`). A difference between plan and apply is a bug. Checked over the
catalogue's MuJoCo modes and over loaded tops, our own and a stranger's, and a plan read back
from its JSON runs to the same table, bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import mujoco_plan
from tippetop.models.modes import MODES
from tippetop.models.plan import RunPlan
from tippetop.mujoco_runner.run import simulate_plan

ROOT = Path(__file__).resolve().parents[2]
FILES = [ROOT / "examples" / "capsule_stem_top.xml",
         ROOT / "examples" / "cylinder_stem_ballast.xml",
         ROOT / "tests" / "data" / "tutorial_tippe_top.xml",
         ROOT / "tests" / "data" / "stranger" / "top.xml",
         # contact pairs with the friction rows' own solref (solreffriction)
         ROOT / "tests" / "data" / "group2_mu1_lift_free.xml"]
MUJOCO_MODES = [m for m, mode in MODES.items() if "mujoco" in mode.families]
pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")


def _ran(result) -> dict:
    return {k: v for k, v in result.ran.items() if k != "contact_source"}


@pytest.mark.parametrize("mode", MUJOCO_MODES)
@pytest.mark.parametrize("scene", ["fig3", "fig11_n060"])
def test_what_ran_is_what_the_plan_said(scene: str, mode: str) -> None:
    plan = mujoco_plan("run.t_end_s=0.02", *MODES[mode].mujoco, scene=scene)
    said = plan.what_runs()
    assert _ran(simulate_plan(plan)) == said


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
@pytest.mark.parametrize("extra", [(), ("mujoco.friction=paper", "mujoco.fit_paper_timestep=true"),
                                   ("mujoco.calibrated=true",), ("init.n0=90.0",)],
                         ids=["own", "paper", "calibrated", "state"])
def test_a_loaded_top_runs_what_its_plan_said(path: Path, extra: tuple[str, ...]) -> None:
    plan = mujoco_plan(f"top.mjcf={str(path)!r}", "run.t_end_s=0.02", *extra)
    said = plan.what_runs()
    assert _ran(simulate_plan(plan)) == said


@pytest.mark.parametrize(("scene", "over"), [
    ("fig3", ("mujoco.friction=paper",)),
    ("fig3", ("mujoco.friction=native",)),
    (None, (f"top.mjcf={str(FILES[3])!r}",)),
])
def test_a_plan_from_its_json_runs_the_same(scene: str | None, over: tuple[str, ...]) -> None:
    plan = mujoco_plan("run.t_end_s=0.05", *over, scene=scene)
    again = RunPlan.from_json(RunPlan("x", "mujoco", "paper", None, plan).to_json()).mujoco
    a, b = simulate_plan(plan), simulate_plan(again)
    assert a.table.equals(b.table) and a.message.split(" in ")[0] == b.message.split(" in ")[0]
    assert _ran(a) == _ran(b)
