"""MuJoCo executes a plan and decides nothing: what ran, read back, is what the plan said.

Every run reports what ran from the compiled model and from the top's contact at t = 0 (MuJoCo
has mixed the two geoms' values into it); the plan states the same before anything runs
(:meth:`MujocoPlan.what_runs`). A difference between plan and apply is a bug. Checked over the
catalogue's MuJoCo modes and over loaded tops, our own and a stranger's, and a plan read back
from its JSON runs to the same table, bit for bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
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
STRANGER_G2 = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"
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


#: The lift-free contact of tests/data/group2_mu1_lift_free.xml, as --set keys (issue 30)
LIFT_FREE = ("mujoco.friction=native", "mujoco.cone=elliptic", "mujoco.impratio=300",
             "mujoco.solref=[-100000,-632]", "mujoco.solimp=[0.0001,0.0001,0.1,0.5,2]",
             "mujoco.mu=1.0", "mujoco.timestep_s=0.0002", "mujoco.integrator=RK4")


@pytest.mark.parametrize("where", ["generated", "file", "unnamed geoms"])
def test_solreffriction_writes_a_pair_per_top_table_contact(where: str, tmp_path: Path) -> None:
    """MuJoCo takes solreffriction only on an explicit pair: the plan adds one for every geom
    of the top that can touch the table (named in the document where it had no name), and
    what ran, read back from the contact, is what the plan said."""
    unnamed = tmp_path / "unnamed.xml"
    text = STRANGER_G2.read_text(encoding="utf-8")
    for name in ("floor", "ball", "ballast", "stem"):
        text = text.replace(f'name="{name}" ', "")
    unnamed.write_text(text, encoding="utf-8")
    top = {"generated": (), "file": (f"top.mjcf={str(STRANGER_G2)!r}",),
           "unnamed geoms": (f"top.mjcf={str(unnamed)!r}",)}[where]
    plan = mujoco_plan("run.t_end_s=0.02", *top, *LIFT_FREE,
                       "mujoco.solreffriction=[-1,-2.6]",
                       scene="fig3" if where == "generated" else None)
    pairs = [c for c in plan.contacts if c.element == "pair"]
    tops = [c for c in plan.contacts if c.role in ("ball", "stem") and c.collides]
    assert len(pairs) == len(tops) >= 1
    assert all(p.solreffriction == (-1.0, -2.6) for p in pairs)
    ran = _ran(simulate_plan(plan))
    assert ran == plan.what_runs() and ran["solreffriction"] == [-1.0, -2.6]


def test_solreffriction_set_by_hand_and_by_the_plan_run_alike() -> None:
    """The hand-written pairs of tests/data/group2_mu1_lift_free.xml and the pairs the plan
    writes from mujoco.solreffriction on the same top (the stranger's group2 file) are one
    contact: theta over 0.5 s agrees to 1e-9 rad (two documents, one compiled model; measured
    0), and both turn the same way."""
    a = simulate_plan(mujoco_plan(f"top.mjcf={str(FILES[4])!r}", "run.t_end_s=0.5"))
    b = simulate_plan(mujoco_plan(f"top.mjcf={str(STRANGER_G2)!r}", "run.t_end_s=0.5",
                                  *LIFT_FREE, "mujoco.solreffriction=[-1,-2.6]"))
    assert len(a.table) == len(b.table)
    assert np.max(np.abs(a.table["theta"].to_numpy() - b.table["theta"].to_numpy())) < 1e-9


@pytest.mark.parametrize(("extra", "expected"), [
    (("mujoco.cone=pyramidal",), "mujoco.solreffriction: expected an elliptic cone"),
    (("mujoco.cone=elliptic", "mujoco.solreffriction=[0.002,-1]"),
     "mujoco.solreffriction: expected two finite numbers, both > 0"),
])
def test_solreffriction_outside_an_elliptic_cone_is_one_line(extra, expected) -> None:
    from tippetop.models.errors import TippetopError

    with pytest.raises(TippetopError, match=expected):
        mujoco_plan("mujoco.friction=native", "mujoco.solreffriction=[0.002,1]", *extra,
                    scene="fig3")
