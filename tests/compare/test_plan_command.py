"""``tippetop plan`` prints what would run; ``tippetop simulate --plan`` runs exactly that.

A plan is made once (the scene resolved for an engine) and executed unchanged: the plan's JSON
is the plan the run makes in-process, its people form says what ran in the very lines a run's
summary says it with, and a run of the plan's JSON gives the summary of ``simulate`` of the
same scene, bit for bit (the wall time and the message that quotes it aside).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tippetop.compare import cli
from tippetop.compare.running.engines import plan_for
from tippetop.models.plan import RunPlan
from tippetop.models.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
STRANGER = ROOT / "tests" / "data" / "stranger" / "top.xml"
SHORT = ("--set", "run.t_end_s=0.05")
CASES = [
    ("fig3", "ode", ()),
    ("fig3", "mujoco/paper", ()),
    ("fig3", "mujoco/native", ()),
    ("fig8a", "mujoco/native-condim4", ()),
    (None, "mujoco", ("--mjcf", str(ROOT / "examples" / "cylinder_stem_ballast.xml"),
                      "--keyframe", "slow")),
    (None, "mujoco/paper", ("--mjcf", str(STRANGER), "--set",
                            "mujoco.fit_paper_timestep=true")),
    (None, "ode", ("--mjcf", str(STRANGER))),
]
pytestmark = pytest.mark.filterwarnings("ignore::tippetop.mujoco_runner.model.TopModelWarning")


def _main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _args(scene: str | None, engine: str, extra: tuple[str, ...]) -> list[str]:
    """The command line of a case's run: ``engine`` is an engine or ``ENGINE/MODE``."""
    engine, _, mode = engine.partition("/")
    return [*([scene] if scene else []), "--engine", engine, *(["--mode", mode] if mode else []),
            *SHORT, *extra]


def _block(text: str, head: str) -> list[str]:
    """The indented lines under ``head`` (the what-ran block)."""
    lines = text.splitlines()
    i = lines.index(head)
    out = []
    for line in lines[i + 1:]:
        if not line.startswith("  "):
            break
        out.append(" ".join(line.split()))  # the column width differs between the two
    return out


@pytest.mark.parametrize(("scene", "engine", "extra"), CASES)
def test_plan_json_is_the_plan_a_run_makes(scene, engine, extra, capsys) -> None:
    code, out, _ = _main(["plan", *_args(scene, engine, extra), "--json"], capsys)
    assert code == 0
    assert json.loads(out)["format"] == "tippetop-plan/2"
    over = list(SHORT[1::2])
    if "--mjcf" in extra:
        over.append(f"top.mjcf={str(Path(extra[extra.index('--mjcf') + 1]))!r}")
    if "--keyframe" in extra:
        over.append(f"init.keyframe={extra[extra.index('--keyframe') + 1]!r}")
    over += [v for k, v in zip(extra[::2], extra[1::2], strict=True) if k == "--set"]
    name, _, mode = engine.partition("/")
    assert RunPlan.from_json(out) == plan_for(load_scene(scene, over), name, mode or None)


@pytest.mark.parametrize(("scene", "engine", "extra"), CASES)
def test_plan_says_what_runs_in_the_lines_a_run_says_it_ran(scene, engine, extra, capsys
                                                           ) -> None:
    code, said, _ = _main(["plan", *_args(scene, engine, extra)], capsys)
    assert code == 0
    code, ran, _ = _main(["simulate", *_args(scene, engine, extra)], capsys)
    assert code == 0
    will, did = _block(said, "what will run:"), _block(ran, "what ran:")
    assert will  # not vacuous
    if engine.startswith("mujoco"):
        assert will == did
    else:  # the reference's run adds its rolling phases (found while integrating) to them
        assert [line for line in did if not line.startswith("rolling ")] == will


@pytest.mark.parametrize(("scene", "engine", "extra"), CASES)
def test_simulate_plan_is_simulate_bit_for_bit(scene, engine, extra, tmp_path, capsys) -> None:
    plan = tmp_path / "plan.json"
    code, _, _ = _main(["plan", *_args(scene, engine, extra), "--out", str(plan)], capsys)
    assert code == 0 and plan.is_file()
    code, out, _ = _main(["simulate", "--plan", str(plan), "--json"], capsys)
    assert code == 0
    code, direct, _ = _main(["simulate", *_args(scene, engine, extra), "--json"], capsys)
    assert code == 0
    a, b = json.loads(out), json.loads(direct)
    for d in (a, b):  # the wall time, and the message that quotes it
        d.pop("wall_s")
        d["message"] = d["message"].split(" in ")[0]
    assert a == b


@pytest.mark.parametrize(("argv", "says"), [
    (["simulate", "fig3", "--plan", "plan.json"], "--plan: expected the plan alone (it says "
     "what runs), got SCENE beside it"),
    (["simulate", "--plan", "plan.json", "--set", "init.n0=3"], "got --set beside it"),
    (["simulate", "--plan", "missing.json"], "--plan: expected an existing plan file"),
    (["simulate", "--plan", "notjson.json"], "plan: expected JSON"),
    (["simulate", "--plan", "other.json"], "plan format: expected 'tippetop-plan/1' or "
     "'tippetop-plan/2', got 'tippetop-sweep/1'"),
    (["simulate", "--plan", "plan.json", "--engine", "mujoco"], "got --engine beside it"),
    (["plan", "fig3", "--engine", "ode", "--mode", "file"], "expected a mode the reference ODE "
     "runs"),
    (["plan", "--mjcf", str(ROOT / "tests" / "data" / "tutorial_tippe_top.xml"), "--engine",
      "mujoco", "--mode", "paper"], "mujoco.timestep_s: expected at most 0.000166 s"),
    (["plan", "fig3", "--out", "taken.json"], "--out: expected a path that does not exist"),
])
def test_bad_input_is_one_line_and_writes_nothing(argv, says, tmp_path, monkeypatch,
                                                  capsys) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "plan.json").write_text(load_and_json())
    (tmp_path / "notjson.json").write_text("{plan")
    (tmp_path / "other.json").write_text('{"format": "tippetop-sweep/1"}')
    (tmp_path / "taken.json").write_text("keep")
    before = sorted(p.name for p in tmp_path.iterdir())
    code, out, err = _main(argv, capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("tippetop: error: ") and says in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "taken.json").read_text() == "keep"


def load_and_json() -> str:
    return plan_for(load_scene("fig3", ["run.t_end_s=0.01"]), "ode").to_json()


def test_plan_says_each_contacts_solimp_width_in_metres(capsys) -> None:
    """solimp's third value is a depth: the "what will run" line says "0.001 m" and the contact
    lines said a bare "0.001"; counts have their thousands separated as simulate's."""
    code, out, _ = _main(["plan", "fig3", "--engine", "mujoco", "--mode", "native"], capsys)
    assert code == 0
    assert "40,000 steps of 2e-4 s, a sample every 5 steps (8,001 rows)" in out.splitlines()[0]
    contacts = [line for line in out.splitlines() if line.startswith("contact ")]
    assert len(contacts) == 2, out
    # the calibrated settings' (models/calibrated_native.toml), their width in metres
    from tippetop.models.calibrated import calibrated_native_settings
    from tippetop.models.numbers import number_text

    cal = calibrated_native_settings()
    d0 = number_text(cal["solimp"][0])
    solref = f"{number_text(cal['solref'][0], 's')}, {number_text(cal['solref'][1])}"
    for line in contacts:
        assert line.endswith(f"solref {solref}, solimp {d0}, 0.95, 0.001 m, 0.5, 2"), line
    # the same words as the what-will-run line above them
    (said,) = [line for line in out.splitlines() if line.strip().startswith("solimp ")]
    assert said.split(None, 1)[1] == f"{d0}, 0.95, 0.001 m, 0.5, 2"
