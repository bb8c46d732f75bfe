"""``tippetop mjcf``: the file written is the model a run steps, and stepping it IS the run.

The written file is loaded with plain MuJoCo (``mujoco.MjModel.from_xml_path``), reset to its
keyframe and stepped with ``mj_step``; its theta(t) is compared with ``tippetop simulate``'s on
the same scene and settings. Tolerance: 1e-12 rad, though the two are expected to be bit
identical (the same compiled model, the same initial state, the same ``mj_step``). A model that
differs at all does not stay within it: MuJoCo's own XML writer (``MjSpec.to_xml``) prints 6
significant digits, and the Fig. 3 top stepped from that file departs by more than 1e-9 rad
within 0.5 s (checked below), so 1e-12 separates "the run's model" from "almost the run's".
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd
import pytest

from tippetop.compare.cli import main
from tippetop.compare.running.mjcf_export import KEYFRAME, model_differences

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
#: fig3 in MuJoCo's native friction, over a short run (0.5 s, 2500 RK4 steps).
NATIVE = ["fig3", "--engine", "mujoco", "--set", 'mujoco.friction="native"', "--set",
          "run.t_end_s=0.5"]
THETA_TOL = 1e-12  # rad; see the module docstring


def theta_of(qpos: np.ndarray) -> np.ndarray:
    """The tilt of a generated top's body z axis (its symmetry axis), rad, for (n, 7) qpos.

    As tippetop's table defines it: the quaternion normalised, k = R e_z, theta = atan2(|k_h|,
    k_z).
    """
    q = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    w, x, y, z = q.T
    kx, ky, kz = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
    return np.arctan2(np.hypot(kx, ky), kz)


def step_file(path: Path, n_samples: int, sample_dt_s: float) -> np.ndarray:
    """qpos at each sample of the file stepped by plain MuJoCo from its tippetop keyframe."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, KEYFRAME))
    steps = round(sample_dt_s / m.opt.timestep)
    out = [d.qpos.copy()]
    for _ in range(n_samples - 1):
        mujoco.mj_step(m, d, steps)
        out.append(d.qpos.copy())
    return np.array(out)


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def native(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """fig3 native: the file written, and simulate's summary and table of the same run."""
    folder = tmp_path_factory.mktemp("mjcf")
    xml, table = folder / "fig3.xml", folder / "fig3.parquet"
    assert main(["mjcf", *NATIVE, "--out", str(xml)]) == 0
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["simulate", *NATIVE, "--out", str(table), "--json"]) == 0
    return {"xml": xml, "summary": json.loads(buf.getvalue()),
            "table": pd.read_parquet(table)}


def test_native_file_stepped_by_plain_mujoco_is_the_run(native: dict) -> None:
    table, summary = native["table"], native["summary"]
    qpos = step_file(native["xml"], len(table), summary["sample_dt_s"])
    theta = theta_of(qpos)
    assert len(table) == 501 and summary["n_steps"] == 2500
    err = float(np.max(np.abs(theta - table["theta"].to_numpy())))
    assert err <= THETA_TOL, err
    assert err == 0.0  # bit-identical, as measured; a failure here alone means rounding
    assert np.ptp(theta) > 0.01  # the top moved (not a trivially equal pair of still tops)


def test_the_files_options_and_contact_are_what_ran(native: dict) -> None:
    s = native["summary"]
    m = mujoco.MjModel.from_xml_path(str(native["xml"]))
    ball = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "ball")
    integrator = mujoco.mjtIntegrator(int(m.opt.integrator)).name.removeprefix("mjINT_")
    assert m.opt.timestep == s["timestep_s"]
    assert integrator.lower() == s["integrator"].lower()
    assert {0: "pyramidal", 1: "elliptic"}[int(m.opt.cone)] == s["cone"]
    assert m.opt.impratio == s["impratio"]
    assert m.opt.noslip_iterations == s["noslip_iterations"]
    assert -m.opt.gravity[2] == s["gravity_mps2"]
    assert m.geom_condim[ball] == s["condim"] == 3
    assert m.geom_friction[ball, 0] == s["mu"]
    assert list(m.geom_solref[ball]) == s["solref"]
    assert list(m.geom_solimp[ball]) == s["solimp"]
    assert m.nuserdata == 0  # the harness's callback block is left out


def test_mujocos_own_xml_writer_would_not_do(native: dict) -> None:
    """Why the file is written with repr(), which parses back to the same double: MuJoCo's own
    XML writer (``MjSpec.to_xml``/``mj_saveLastXML``) prints 6 significant digits, and the run
    departs by far more than THETA_TOL from that file (the test above can fail)."""
    spec = mujoco.MjSpec.from_file(str(native["xml"]))
    spec.compile()
    rounded = native["xml"].with_name("rounded.xml")
    rounded.write_text(spec.to_xml())
    table, summary = native["table"], native["summary"]
    theta = theta_of(step_file(rounded, len(table), summary["sample_dt_s"]))
    assert np.max(np.abs(theta - table["theta"].to_numpy())) > 1e-9


@pytest.mark.parametrize(("name", "extra", "n_keys"), [
    # its own two keyframes, friction on contact pairs: started from its keyframe 'slow'
    ("cylinder_stem_ballast", ["--keyframe", "slow"], 3),
    # the stem's collisions turned off on the compiled model (its midphase tree keeps it)
    ("capsule_stem_top", ["--set", "effects.stem=false"], 2),
])
def test_a_loaded_file_with_the_calibrated_settings_is_the_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, extra: list[str],
        n_keys: int) -> None:
    """A user's file with the native mode's settings written back onto its geoms and pairs."""
    args = ["--mjcf", str(EXAMPLES / f"{name}.xml"), *extra, "--engine", "mujoco", "--mode",
            "native",
            "--set", "run.t_end_s=0.3"]
    xml, table = tmp_path / "c.xml", tmp_path / "c.parquet"
    rc, out, err = run_cli(capsys, "mjcf", *args, "--out", str(xml), "--json")
    assert rc == 0, err
    res = json.loads(out)
    assert res["keyframe"] == KEYFRAME and res["mode"] == "native"
    rc, out, err = run_cli(capsys, "simulate", *args, "--out", str(table), "--json")
    assert rc == 0, err
    summary, tab = json.loads(out), pd.read_parquet(table)
    m = mujoco.MjModel.from_xml_path(str(xml))
    assert m.nkey == n_keys and res["keyframe_index"] == n_keys - 1  # the file's, then ours
    assert m.opt.timestep == summary["timestep_s"] and m.opt.impratio == summary["impratio"]
    qpos = step_file(xml, len(tab), summary["sample_dt_s"])
    q = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    assert np.max(np.abs(q - tab[["qw", "qx", "qy", "qz"]].to_numpy())) <= THETA_TOL
    assert np.ptp(tab["theta"]) > 1e-3  # it moved


def test_paper_mode_says_the_law_is_not_in_the_file(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    xml = tmp_path / "p.xml"
    rc, out, err = run_cli(capsys, "mjcf", "fig3", "--engine", "mujoco", "--mode", "paper",
                           "--out", str(xml), "--json")
    assert rc == 0, err
    res = json.loads(out)
    assert res["mode"] == "paper" and res["friction_in_file"] is False
    assert "callback" in res["note"] and res["ran"]["condim"] == 1
    assert err.count("\n") == 1 and "paper mode" in err and "frictionless" in err
    text = xml.read_text()
    assert text.startswith("<!--") and "PAPER MODE" in text.split("-->")[0]
    m = mujoco.MjModel.from_xml_path(str(xml))
    assert set(m.geom_condim[(m.geom_contype != 0) | (m.geom_conaffinity != 0)]) == {1}


@pytest.mark.parametrize(("argv", "says"), [
    (["nosuchscene"], "scene"),
    (["fig3", "--engine", "ode"], "--engine"),
    (["fig3", "--set", "init.n0=oops"], "init.n0"),
    # a step the paper's law cannot be followed with: a run refuses it, and so does its file
    (["fig3", "--engine", "mujoco", "--mode", "paper", "--set", "mujoco.timestep_s=0.01"],
     "mujoco.timestep_s"),
])
def test_bad_input_is_one_line_exit_2_and_no_file(tmp_path: Path, argv: list[str], says: str,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out_file = tmp_path / "m.xml"
    rc, out, err = run_cli(capsys, "mjcf", *argv, "--out", str(out_file))
    assert rc == 2 and err.count("\n") == 1 and says in err, err
    assert not out_file.exists() and list(tmp_path.iterdir()) == []


def test_an_existing_out_needs_force_and_a_missing_folder_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mine = tmp_path / "mine.xml"
    mine.write_text("<mujoco/>\n")
    rc, _, err = run_cli(capsys, "mjcf", "fig3", "--out", str(mine))
    assert rc == 2 and err.count("\n") == 1 and "--force" in err
    assert mine.read_text() == "<mujoco/>\n"
    missing = tmp_path / "no" / "m.xml"
    rc, _, err = run_cli(capsys, "mjcf", "fig3", "--out", str(missing))
    assert rc == 2 and err.count("\n") == 1 and "folder" in err and not missing.parent.exists()
    rc, _, err = run_cli(capsys, "mjcf", "fig3", "--out", str(mine), "--force")
    assert rc == 0, err
    assert mujoco.MjModel.from_xml_path(str(mine)).nkey == 1
    assert {p.name for p in tmp_path.iterdir()} == {"mine.xml"}  # no temporary file left


def test_model_differences_sees_one_changed_value() -> None:
    """The command's self-check (the file against the run's model) can fail."""
    xml = ('<mujoco><worldbody><body><freejoint/><geom size="0.1" mass="{m}"/></body>'
           "</worldbody></mujoco>")
    a = mujoco.MjModel.from_xml_string(xml.format(m=repr(1 / 3)))
    b = mujoco.MjModel.from_xml_string(xml.format(m="0.333333"))
    assert model_differences(a, a) == []
    assert "body_mass" in model_differences(a, b)
    assert not math.isclose(a.body_mass[1], b.body_mass[1], rel_tol=1e-12)
