"""Issue 43, item 3: the MJCF block ``tippetop validate`` ends with pastes into the file as it is.

The block (:func:`~tippetop.compare.measures.summary.paste_block`) names the file's own geoms,
with one ``<pair>`` for each geom of the top that can touch the table, every number written
so that it reads back as the same double. A pair supersedes the dynamic contact of its two
geoms, so pasted inside the file's ``<mujoco>`` the contacts are the run's whatever the geoms'
own attributes say, and the second ``<option>`` sets only the attributes it names.

Three kinds of test. The block's text (names, comments, exact numbers). The block pasted into
each example, a stranger's file and two odd files (unnamed geoms, margins, heterogeneous
condim, the file's own pairs), stepped with plain ``mujoco.mj_step`` beside the document the
harness compiles for the same settings (``plan.mjcf``): the same qpos at every step, in the
calibrated settings, a tuning's fit and the lift-free family (seconds). And, slow, end to end:
``tippetop validate FILE --no-tune --json`` on the examples and the stranger's file, its
calibrated candidate's block pasted and stepped by a plain loop, against the run validate
reports.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from tippetop.compare.measures.summary import FileContacts, paste_block, paste_pairs
from tippetop.compare.running.tasks import Task
from tippetop.compare.studies.validate import plan_file_info
from tippetop.compare.tuning.calibrate.identify import lift_free_seeds
from tippetop.compare.tuning.calibrate.scoring import mujoco_defaults
from tippetop.models import mjcf_document
from tippetop.models.scene import Override
from tippetop.mujoco_runner.model import load_top

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.xml"))
#: A stranger's file: a hull, a handle and a lead weight on a body "spinner", the ground
#: "ground", MuJoCo's default mu = 1 and 2 ms Euler step, comments.
STRANGER = ROOT / "tests" / "data" / "stranger" / "paste_spinner.xml"

#: An odd top: an unnamed floor with a margin and a gap, a ball of condim 4 with its own
#: torsional friction, an unnamed stem of condim 3 (the tuning keeps each geom's own condim:
#: its pairs differ).
ODD_UNNAMED = """<mujoco model="odd unnamed">
  <option timestep="0.001"/>
  <worldbody>
    <light pos="0 0 1"/>
    <geom type="plane" size="0.3 0.3 0.01" margin="0.0004" gap="0.0001"/>
    <body name="top" pos="0 0 0.02">
      <freejoint/>
      <geom name="orb" type="sphere" size="0.02" mass="0.010" condim="4"
            friction="0.6 0.02 0.0001"/>
      <geom type="capsule" fromto="0 0 0.012 0 0 0.03" size="0.004" mass="0.0005"/>
      <geom type="cylinder" size="0.017 0.002" pos="0 0 -0.008" mass="0.016" contype="0"
            conaffinity="0"/>
    </body>
  </worldbody>
  <keyframe>
    <key qpos="0 0 0.02 0.99875026 0.04997917 0 0" qvel="0 0 0 0 0 150"/>
  </keyframe>
</mujoco>
"""
#: An odd top with its own pairs: the ball's with a margin and its own solreffriction, a
#: floor of higher priority, the stem's contact dynamic (the geoms' values mixed).
ODD_PAIRS = """<mujoco model="odd pairs">
  <option timestep="0.0005" cone="elliptic" integrator="implicitfast"/>
  <worldbody>
    <geom name="deck" type="plane" size="0.3 0.3 0.01" priority="1" friction="0.4 0.01 0.001"/>
    <body name="top" pos="0 0 0.02">
      <freejoint/>
      <geom name="orb" type="sphere" size="0.02" mass="0.010"/>
      <geom name="peg" type="capsule" fromto="0 0 0.012 0 0 0.03" size="0.004" mass="0.0005"
            solmix="3"/>
      <geom name="lead" type="cylinder" size="0.017 0.002" pos="0 0 -0.008" mass="0.016"
            contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <contact>
    <pair geom1="orb" geom2="deck" friction="0.3 0.3 0.005 0.0001 0.0001" margin="0.0003"
          solreffriction="-1 -5"/>
  </contact>
  <keyframe>
    <key qpos="0 0 0.02 0.99875026 0.04997917 0 0" qvel="0 0 0 0 0 150"/>
  </keyframe>
</mujoco>
"""


def _loaded(path: Path) -> tuple[tuple[Any, ...], dict[str, Any]]:
    over = (Override.of("top.mjcf", str(path)),)
    return over, plan_file_info(over)


def _paste(text: str, block: str) -> str:
    """``text`` with ``block`` pasted before ``</mujoco>``, as its comments ask.

    The block as it is; where a comment asks, first the file's own pairs it replaces removed
    and its unnamed geoms given the names its pairs use (as a user does by hand).
    """
    removed = re.search(r"remove the file's own pairs? of (.*?): the pairs below", block)
    named = re.findall(r'add name="([^"]+)" to the \w+\'s geom \(the \w+, the (\d+)\w\w geom '
                       r"of (<worldbody>|body [^)]+)\)", block)
    if removed or named:
        root = mjcf_document.parse(text)  # the examples' comments hold "--"
        if removed:
            couples = [frozenset(c.split(" and ")) for c in removed.group(1).split(", of ")]
            for contact in root.iter("contact"):
                for pair in list(contact.findall("pair")):
                    if frozenset((pair.get("geom1"), pair.get("geom2"))) in couples:
                        contact.remove(pair)
        for name, nth, where in named:
            holder = (root.find("worldbody") if where == "<worldbody>" else
                      next(b for b in root.iter("body")
                           if b.get("name") == where.removeprefix("body ")))
            assert holder is not None
            holder.findall("geom")[int(nth) - 1].set("name", name)
        text = mjcf_document.to_text(root)
    assert text.count("</mujoco>") == 1
    return text.replace("</mujoco>", f"{block}\n</mujoco>")


def _step(model: mujoco.MjModel, key: int | None, steps: int, track: int | None = None
          ) -> tuple[np.ndarray, bool]:
    """qpos after every step of a plain ``mj_step`` loop from keyframe ``key``.

    With ``track`` (a geom id): whether that geom ever touched anything (the stem's contact
    exercised).
    """
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, key or 0)
    out = np.empty((steps, model.nq))
    touched = False
    for i in range(steps):
        mujoco.mj_step(model, data)
        out[i] = data.qpos
        if track is not None and not touched and data.ncon:
            touched = bool((data.contact.geom[:data.ncon] == track).any())
    return out, touched


# ---------------------------------------------------------------- the block's text
def test_the_block_names_the_files_own_geoms() -> None:
    """Measured on the capsule example before issue 43: BALL/TABLE and ``<geom ...``."""
    over, loaded = _loaded(ROOT / "examples" / "capsule_stem_top.xml")
    plan = Task(None, over, "mujoco", "native").plan().mujoco
    ran = plan.what_runs()
    block = paste_block(ran, loaded["contacts"], keeps_dims=False)
    assert "BALL" not in block and "TABLE" not in block and "..." not in block
    root = ET.fromstring(f"<mujoco>{block}</mujoco>")
    assert [(p.get("geom1"), p.get("geom2")) for p in root.iter("pair")] == [
        ("shell", "floor"), ("stem", "floor")]
    option = root.find("option")
    assert option is not None and float(option.get("timestep", "nan")) == ran["timestep_s"]
    # every number reads back as the double that ran (0.3 * 0.106 / 0.1 is not 0.318)
    for pair in root.iter("pair"):
        assert float(pair.get("friction", "").split()[0]) == ran["mu"]
        assert [float(v) for v in pair.get("solimp", "").split()] == ran["solimp"]


def test_the_files_own_pairs_are_replaced_and_said_so() -> None:
    over, loaded = _loaded(ROOT / "examples" / "cylinder_stem_ballast.xml")
    ran = Task(None, over, "mujoco", "native").plan().mujoco.what_runs()
    block = paste_block(ran, loaded["contacts"], keeps_dims=False)
    lines = [line for line in block.splitlines() if "remove" in line]
    assert lines == ["<!-- remove the file's own pairs of ball and table, of stem and table: "
                     "the pairs below replace them (two pairs of the same geoms make two "
                     "contacts) -->"]


def test_an_unnamed_geom_is_said_in_one_line(tmp_path: Path) -> None:
    """MuJoCo's tutorial top has an unnamed floor: the pairs name it, one line says how."""
    over, loaded = _loaded(ROOT / "tests" / "data" / "tutorial_tippe_top.xml")
    ran = Task(None, over, "mujoco", "native").plan().mujoco.what_runs()
    block = paste_block(ran, loaded["contacts"], keeps_dims=False)
    said = [line for line in block.splitlines() if "unnamed" in line]
    assert said == ['<!-- unnamed geoms: add name="table" to the table\'s geom (the plane, '
                    "the 1st geom of <worldbody>): the pairs below name them so -->"]
    odd = tmp_path / "odd.xml"
    odd.write_text(ODD_UNNAMED)
    over, loaded = _loaded(odd)
    ran = Task(None, over, "mujoco", "native").plan().mujoco.what_runs()
    said = [line for line in paste_block(ran, loaded["contacts"]).splitlines()
            if "unnamed" in line]
    assert said == ['<!-- unnamed geoms: add name="table" to the table\'s geom (the plane, the '
                    '1st geom of <worldbody>); add name="stem" to the stem\'s geom (the capsule, '
                    "the 2nd geom of body top): the pairs below name them so -->"]


def test_a_generated_top_says_which_names_to_use() -> None:
    ran = {"timestep_s": 2e-4, "integrator": "RK4", "cone": "elliptic", "impratio": 1.0,
           "condim": 3, "mu": 0.1, "solref": [0.002, 1.0], "solimp": [0.9, 0.95, 0.001, 0.5, 2],
           "solreffriction": [-1.0, -2.6]}
    block = paste_block(ran, None)
    comments = [line for line in block.splitlines() if line.startswith("<!--")]
    assert comments == ["<!-- no file was read: tippetop's own top names its geoms ball, stem "
                        "and table; in a file, the geom attributes go on its geoms that touch "
                        "the table and on the table's, and a pair names its own -->"]
    assert '<pair geom1="ball" geom2="table"' in block
    assert paste_block({**ran, "timestep_s": None}, None) == ""


# ---------------------------------------------------------------- pasted and stepped
def _candidates(mu: float) -> dict[str, tuple[str | None, tuple[Any, ...], bool]]:
    """(mode, overrides, keeps_dims) of the calibrated run, a fit's and a lift-free one's."""
    fit = mujoco_defaults(mu)
    lift = lift_free_seeds(mu)[0]
    return {"calibrated": ("native", (), False),
            "fit": (None, fit.overrides(2e-4, "RK4"), True),
            "lift-free": (None, lift.overrides(2e-4, "RK4"), True)}


#: The stranger's file of the tuning's tests: defaults classes, a floor of higher priority in
#: an included file, solmix, its own pair for the stem, a mesh found through meshdir.
STRANGER_INCLUDES = ROOT / "tests" / "data" / "stranger" / "top.xml"
FILES = {**{p.stem: p for p in EXAMPLES}, "stranger": STRANGER,
         "stranger_includes": STRANGER_INCLUDES, "odd_unnamed": ODD_UNNAMED,
         "odd_pairs": ODD_PAIRS}


@pytest.mark.parametrize("which", ["calibrated", "fit", "lift-free"])
@pytest.mark.parametrize("name", sorted(FILES))
def test_the_pasted_block_steps_as_the_harness_runs(name: str, which: str,
                                                    tmp_path: Path) -> None:
    """Pasted into the file, the block gives the model the harness compiles for the same
    settings: the same qpos at every step of 1.2 s (6000 steps; the stem's contact within it
    in the capsule example's calibrated run) of a plain ``mj_step`` loop from the file's
    keyframe. Expected bit for bit (the same doubles, the same contacts in the same order):
    the tolerance, 1e-12 m or rad, is only the rule that no float is compared with ==."""
    source = FILES[name]
    if isinstance(source, str):
        path = tmp_path / f"{name}.xml"
        path.write_text(source)
    else:  # its folder copied: the pasted file beside it finds its includes and meshes
        shutil.copytree(source.parent, tmp_path / "files")
        path = tmp_path / "files" / source.name
    over, loaded = _loaded(path)
    mode, extra, keeps = _candidates(float(loaded["mu"]))[which]
    plan = Task(None, (*over, *extra), "mujoco", mode).plan().mujoco
    assert plan is not None
    ran = plan.what_runs()
    block = paste_block(ran, loaded["contacts"], keeps_dims=keeps)
    target = path.with_name("pasted.xml")
    target.write_text(_paste(path.read_text(), block))
    model = mujoco.MjModel.from_xml_path(str(target))
    # every contact of the top with the table is a pair: MuJoCo's own, then the block's
    assert model.npair == len(paste_pairs(ran, loaded["contacts"], keeps_dims=keeps)) >= 1
    steps = round(1.2 / plan.timestep_s)
    stem = next((c.index for c in loaded["contacts"].contacts if c.role == "stem"), None)
    harness, _ = _step(mujoco.MjModel.from_xml_string(plan.mjcf), plan.keyframe, steps)
    mine, stem_touched = _step(model, plan.keyframe, steps, stem)
    gap = float(np.max(np.abs(harness - mine)))
    assert gap <= 1e-12, f"{name}/{which}: qpos departs by {gap:g}"
    if (name, which) == ("capsule_stem_top", "calibrated"):
        assert stem_touched  # the stem's pair is exercised, not only the ball's


# ---------------------------------------------------------------- end to end, slow
def _plain_run(xml: str, key: int, steps: int) -> dict[str, Any]:
    """A plain ``mj_step`` loop's inversion, stem contact and final tilt, as the harness
    measures them: at the state after each step k (time k dt) the axis's z and whether a geom
    of the top other than the ball touches, read on a second mjData (the stepped one only
    steps)."""
    top = load_top(xml)
    model = mujoco.MjModel.from_xml_string(xml)
    data, look = mujoco.MjData(model), mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, key)
    dt = float(model.opt.timestep)
    body, ball, axis = top.body_id, top.ball_geom_id, np.asarray(top.axis_body, dtype=float)
    out: dict[str, Any] = {"t_invert": None, "t_stem": None}
    prev_kz = None
    for k in range(steps + 1):
        if k:
            mujoco.mj_step(model, data)
        look.qpos[:], look.qvel[:] = data.qpos, data.qvel
        mujoco.mj_fwdPosition(model, look)
        axis_world = look.xmat[body].reshape(3, 3) @ axis
        kz = float(axis_world[2])
        if out["t_invert"] is None and prev_kz is not None and prev_kz > 0.0 >= kz:
            out["t_invert"] = k * dt
        prev_kz = kz
        if out["t_stem"] is None and any(
                ball not in (c.geom1, c.geom2) and body in (model.geom_bodyid[c.geom1],
                                                            model.geom_bodyid[c.geom2])
                for c in look.contact[:look.ncon]):
            out["t_stem"] = k * dt
    out["theta_final"] = math.atan2(math.hypot(axis_world[0], axis_world[1]), axis_world[2])
    return out


@pytest.mark.slow
@pytest.mark.parametrize("path", [*EXAMPLES, STRANGER], ids=lambda p: p.stem)
def test_validates_answer_pasted_runs_as_validate_verified(path: Path, tmp_path: Path) -> None:
    """``validate FILE --no-tune``: its calibrated candidate's block (the answer where one is
    pasted), pasted into the file as its comments say and stepped by a plain loop for the
    run's steps from the file's first keyframe, turns over, touches its stem and ends at the
    tilt validate's ``mujoco/native`` run reports. The harness runs the document the block
    reproduces bit for bit (test above) with ``mj_step``: the event times are the same step
    (1e-9 s, far below a step of 2e-4 s) and the final tilt the same double (measured: equal).
    Its tolerance, 1e-12 rad, resolves a single rounding: mu written as 0.318 where
    0.31799999999999995 ran (one ulp) moves the capsule example's final tilt by 2e-14 rad and
    the stranger's (mu = 1.06 for 1.0599999999999998) by 7e-11 rad."""
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "validate", str(path),
                           "--no-tune", "--json"], capture_output=True, text=True, cwd=ROOT,
                          timeout=900)
    assert proc.returncode in (0, 1), proc.stderr
    res = json.loads(proc.stdout)
    ans = res["answer"]
    calibrated = next(c for c in ans["candidates"] if c["name"] == "calibrated")
    if ans["source"] == "calibrated":
        assert ans["mjcf"] == calibrated["mjcf"]
    run = res["runs"]["mujoco/native"]
    assert run["status"] == "ok", run
    pasted = _paste(path.read_text(), calibrated["mjcf"])
    (tmp_path / "pasted.xml").write_text(pasted)  # kept to look at when it fails
    mine = _plain_run(pasted, 0, int(run["n_steps"]))
    for key in ("t_invert", "t_stem"):
        if run[key] is None:
            assert mine[key] is None, (key, mine[key])
        else:
            assert mine[key] is not None and abs(mine[key] - run[key]) <= 1e-9, (key, mine, run)
    assert abs(mine["theta_final"] - run["theta_final"]) <= 1e-12, (mine, run["theta_final"])


def test_file_contacts_read_every_geom() -> None:
    model = mujoco.MjModel.from_xml_string(ODD_UNNAMED)
    fc = FileContacts.of_model(model, ())
    assert fc.geom_names == ("", "orb", "", "")
    assert fc.geom_margins[0] == (0.0004, 0.0001) and fc.geom_places[3] == (
        "the cylinder, the 3rd geom of body top")
