"""Your own models in the nightly: ``model = "top.xml"`` catalogue cases and ``--models FILE``.

A small catalogue in ``tests/data/nightly_models`` names a model file of its own (``mytop.xml``,
written as a newcomer would: MuJoCo's default friction, mu = 1, and its default 2 ms Euler
step) relative to itself, with a stored baseline (``baselines/models.json``). The runs are
0.5 s long (the catalogue's ``set``) or in the reference ODE only, in this process (``--workers
1``) with a private run cache, so the file takes seconds.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest

from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.nightly.catalogue import (
    MODEL_METRICS,
    load_catalogue,
    model_hash,
    select_cases,
)
from tippetop.models.errors import TippetopError
from tippetop.models.scene import override_texts

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "nightly_models"
STRANGER = ROOT / "tests" / "data" / "stranger" / "top.xml"
IDS = {"models/mytop[ode/paper]", "models/mytop[mujoco/file]", "models/mytop[mujoco/paper]"}


def run_nightly(*args: str) -> tuple[int, str, str]:
    """``tippetop nightly ARGS`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = nightly_command.main(list(args))
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run cache of this file's own (the runs repeat: most come from it)."""
    return tmp_path_factory.mktemp("cache")


@pytest.fixture
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cache_dir: Path) -> Path:
    """A copy of the test catalogue, its model file and its baseline, with the run cache."""
    monkeypatch.setenv("TIPPETOP_CACHE", str(cache_dir))
    copy = tmp_path / "nightly_models"
    shutil.copytree(DATA, copy)
    return copy


def _args(data: Path, out: Path, *extra: str) -> list[str]:
    return ["--catalogue", str(data / "catalogue.toml"), "--profile", "models",
            "--baseline", str(data / "baselines"), "--out", str(out), "--workers", "1",
            "--cache", *extra]


def _results(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())


def _record(results: dict, case_id: str) -> dict:
    return next(r for r in results["cases"] if r["id"] == case_id)


# --------------------------------------------------------------------------- the catalogue
def test_a_model_case_runs_its_file_as_matrix_runs_an_mjcf_top() -> None:
    cat = load_catalogue(DATA / "catalogue.toml")
    cases = {c.id: c for c in cat.cases}
    assert set(cases) == IDS  # file in MuJoCo only; paper in MuJoCo and the reference
    top = f"top.mjcf={json.dumps(str(DATA / 'mytop.xml'))}"
    for c in cases.values():
        texts = override_texts(c.overrides)
        assert c.model == str(DATA / "mytop.xml") and c.scene == "mytop.xml"
        assert c.scene_arg is None and texts[0] == top
        assert "run.t_end_s=0.5" in texts
        assert c.metrics == MODEL_METRICS and "matches_expect" not in c.metrics
    # the paper's law in MuJoCo at the largest timestep it fits, as 'tippetop matrix' runs it
    assert override_texts(cases["models/mytop[mujoco/paper]"].overrides)[-1] == \
        "mujoco.fit_paper_timestep=true"
    for other in ("models/mytop[mujoco/file]", "models/mytop[ode/paper]"):
        assert not any("fit_paper" in o for o in override_texts(cases[other].overrides))


def test_the_model_hash_follows_the_content_not_the_folder(tmp_path: Path) -> None:
    copy = tmp_path / "a" / "stranger"
    shutil.copytree(STRANGER.parent, copy)
    sha, files = model_hash(STRANGER)
    assert files == ["top.xml", "floor.xml", "meshes/knob.obj"]  # includes and assets
    assert model_hash(copy / "top.xml")[0] == sha
    for name in ("floor.xml", "meshes/knob.obj", "top.xml"):
        f = copy / name
        before = f.read_bytes()
        f.write_bytes(before + b"\n")
        assert model_hash(copy / "top.xml")[0] != sha, name
        f.write_bytes(before)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda s: s.replace('model = "mytop.xml"', 'model = "nothere.xml"'), "no such file"),
    (lambda s: s.replace('model = "mytop.xml"', 'model = "notop.xml"'),
     "notop.xml: expected exactly one body with a free joint, got 0 free joints"),
    (lambda s: s.replace('model = "mytop.xml"', 'model = "mytop.xml"\nscene = "fig3"'),
     "got both"),
    (lambda s: s.replace('kind = "run"', 'kind = "sweep"\nn0 = "30:60:15"'),
     "expected kind = 'run'"),
    (lambda s: s.replace('profiles = ["models"]',
                         'profiles = ["models"]\nmetrics = ["outcome", "matches_expect"]'),
     "no [expect] to match"),
])
def test_a_bad_model_case_is_one_line_exit_2_before_any_run(data: Path, tmp_path: Path,
                                                            edit, message: str) -> None:
    (data / "notop.xml").write_text('<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>'
                                    "</worldbody></mujoco>\n")
    cat = data / "catalogue.toml"
    cat.write_text(edit(cat.read_text()))
    code, out, err = run_nightly(*_args(data, tmp_path / "out"))
    assert code == 2 and message in err and err.count("\n") == 1, err
    assert "catalogue catalogue.toml: case 'mytop'" in err
    assert not (tmp_path / "out").exists() and out == ""


# --------------------------------------------------------------------------- the baseline
def test_the_model_case_passes_against_its_stored_baseline(data: Path, tmp_path: Path) -> None:
    stored = json.loads((DATA / "baselines" / "models.json").read_text())["cases"]
    code, out, err = run_nightly(*_args(data, tmp_path / "out"))
    assert code == 0, out + err
    res = _results(tmp_path / "out")
    assert {r["id"] for r in res["cases"]} == IDS
    c = res["counts"]
    assert c["checks"] == 3 * len(MODEL_METRICS) == c["checks_pass"]
    assert res["verdict"] == "OK" and "result: OK" in out and not res["model_changed"]
    for case_id in IDS:
        rec = _record(res, case_id)
        model = rec["model"]
        assert model["file"] == str(data / "mytop.xml") and model["given"] == "mytop.xml"
        assert model["sha256"] == model["baseline_sha256"] == stored[case_id]["model_sha256"]
        assert model["changed"] is False and model["origin"] == "catalogue"
        assert rec["category"] == "models" and rec["status"] == "pass"
        assert rec["expect"] == {} and "matches_expect" not in rec["metrics"]
    # in the report and the junit file like the scenes
    html = (tmp_path / "out" / "report.html").read_text()
    assert "<h3 id='models'>Model files</h3>" in html and "as in its baseline" in html
    assert "models/mytop[mujoco/file]" in html  # in every check's table
    junit = (tmp_path / "out" / "junit.xml").read_text()
    assert 'name="nightly.models.models"' in junit


def test_a_perturbed_baseline_value_is_a_regression(data: Path, tmp_path: Path) -> None:
    bfile = data / "baselines" / "models.json"
    doc = json.loads(bfile.read_text())
    edits = {("models/mytop[mujoco/file]", "theta_asymp"): lambda v: v + 0.5,
             ("models/mytop[ode/paper]", "outcome"): lambda v: "inverted"}
    for (case_id, metric), edit in edits.items():
        doc["cases"][case_id][metric] = edit(doc["cases"][case_id][metric])
    bfile.write_text(json.dumps(doc))
    code, out, err = run_nightly(*_args(data, tmp_path / "out"))
    assert code == 1, out + err
    assert "result: REGRESSION" in out
    res = _results(tmp_path / "out")
    assert res["counts"]["checks_fail"] == len(edits)
    for case_id, metric in edits:
        assert f"{case_id} {metric} regressed" in out
        rec = _record(res, case_id)
        assert rec["status"] == "fail"
        assert [ch["metric"] for ch in rec["checks"] if ch["status"] == "fail"] == [metric]


def test_a_changed_model_file_is_said_not_compared(data: Path, tmp_path: Path) -> None:
    model = data / "mytop.xml"
    # twice the stem's mass: the top, and so its values, change
    model.write_text(model.read_text().replace('mass="0.0002"', 'mass="0.0004"'))
    code, out, err = run_nightly(*_args(data, tmp_path / "out"))
    assert code == 0, out + err
    assert "MODEL FILE CHANGED" in out and "the model file changed since its baseline" in out
    res = _results(tmp_path / "out")
    assert res["counts"]["checks_fail"] == 0 and "REGRESSIONS:" not in out
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Model files changed since their baselines" in html
    assert "changed since its baseline: not compared" in html
    assert set(res["model_changed"]) == IDS
    for case_id in IDS:
        rec = _record(res, case_id)
        assert rec["model"]["changed"] is True and rec["status"] == "new"
        assert rec["model"]["sha256"] != rec["model"]["baseline_sha256"]
        assert all(ch["status"] == "new" and "model file changed" in ch["message"]
                   for ch in rec["checks"])
    # the file's A/C moved: at least one value would have been compared with another top's
    moved = [ch for r in res["cases"] for ch in r["checks"]
             if ch["metric"] == "energy_lost" and ch["value"] != ch["baseline"]]
    assert moved
    # --update-baseline stores the new file's values and hash; the next run compares again
    code, out, err = run_nightly(*_args(data, tmp_path / "update"), "--update-baseline")
    assert code == 0, out + err
    stored = json.loads((data / "baselines" / "models.json").read_text())["cases"]
    assert {stored[i]["model_sha256"] for i in IDS} == {model_hash(model)[0]}
    code, out, err = run_nightly(*_args(data, tmp_path / "again"))
    assert code == 0 and "MODEL FILE CHANGED" not in out, out + err
    assert _results(tmp_path / "again")["counts"]["checks_pass"] == 3 * len(MODEL_METRICS)


# --------------------------------------------------------------------------- --models
def test_models_option_adds_a_case_said_new_then_stored(data: Path, tmp_path: Path) -> None:
    args = [*_args(data, tmp_path / "first"), "--engines", "ode", "--models", str(STRANGER)]
    code, out, err = run_nightly(*args)
    assert code == 0, out + err
    res = _results(tmp_path / "first")
    rec = _record(res, "models/top[ode/paper]")
    assert rec["status"] == "new" and rec["model"]["baseline_sha256"] is None
    assert rec["metrics"] == list(MODEL_METRICS) and rec["model"]["origin"] == "--models"
    assert all("no baseline yet" in ch["message"] for ch in rec["checks"])
    assert "NEW (no baseline yet" in out and f"models/top[ode/paper]: all {len(MODEL_METRICS)}" \
        in out
    assert res["models"] == [str(STRANGER)]
    assert _record(res, "models/mytop[ode/paper]")["status"] == "pass"  # the catalogue's too

    args[args.index(str(tmp_path / "first"))] = str(tmp_path / "update")
    code, out, err = run_nightly(*args, "--update-baseline")
    assert code == 0, out + err
    stored = json.loads((data / "baselines" / "models.json").read_text())["cases"]
    entry = stored["models/top[ode/paper]"]
    assert entry["model_sha256"] == model_hash(STRANGER)[0]
    assert entry["model_origin"] == "--models" and set(MODEL_METRICS) <= set(entry)

    args[args.index(str(tmp_path / "update"))] = str(tmp_path / "again")
    code, out, err = run_nightly(*args)
    assert code == 0 and "NEW" not in out, out + err
    assert _record(_results(tmp_path / "again"), "models/top[ode/paper]")["status"] == "pass"

    # a rebaseline of the catalogue alone keeps what --models stored
    code, out, err = run_nightly(*_args(data, tmp_path / "catalogue"), "--engines", "ode",
                                 "--update-baseline")
    assert code == 0, out + err
    stored = json.loads((data / "baselines" / "models.json").read_text())["cases"]
    assert stored["models/top[ode/paper]"] == entry


def test_models_option_names_are_unique_and_cases_filters_them(tmp_path: Path) -> None:
    cat = load_catalogue(DATA / "catalogue.toml")
    other = tmp_path / "mine" / "top.xml"
    other.parent.mkdir()
    other.write_text((DATA / "mytop.xml").read_text())
    mytop = DATA / "mytop.xml"
    cases = select_cases(cat, "models", ("ode",), models=[STRANGER, other, mytop, STRANGER])
    assert [c.id for c in cases] == [
        "models/mytop[ode/paper]",  # the catalogue's
        "models/top[ode/paper]", "models/mine-top[ode/paper]",  # the folder makes it unique
        "models/nightly_models-mytop[ode/paper]"]  # the catalogue has a 'mytop' already
    # globs that name no file's case leave them in; one that does narrows them
    ids = [c.id for c in select_cases(cat, "models", ("ode",), ["paper/*"], models=[STRANGER])]
    assert ids == ["models/top[ode/paper]"]
    ids = [c.id for c in select_cases(cat, "models", ("ode", "mujoco"), ["models/top[*"],
                                      models=[STRANGER])]
    assert sorted(ids) == ["models/top[mujoco/file]", "models/top[mujoco/paper]",
                           "models/top[ode/paper]"]
    # --modes: the files run in those modes, on the engines that can run each
    ids = [c.id for c in select_cases(cat, "models", ("ode", "mujoco"), ["models/top[*"],
                                      ("native", "coulomb"), models=[STRANGER])]
    assert sorted(ids) == ["models/top[mujoco/native]", "models/top[ode/coulomb]"]


@pytest.mark.parametrize(("make", "message"), [
    (lambda d: d / "nothere.xml", "--models: expected an MJCF top file, got"),
    (lambda d: (d / "bad.xml", (d / "bad.xml").write_text("<mujoco><worldbody>"))[0],
     "expected a valid MJCF document"),
])
def test_a_missing_or_bad_model_file_is_one_line_exit_2_nothing_written(
        data: Path, tmp_path: Path, make, message: str) -> None:
    path = make(tmp_path)
    bfile = data / "baselines" / "models.json"
    before = bfile.read_bytes()
    code, out, err = run_nightly(*_args(data, tmp_path / "out"), "--update-baseline",
                                 "--models", str(path))
    assert code == 2 and message in err and err.count("\n") == 1, err
    assert str(path) in err or path.name in err
    assert not (tmp_path / "out").exists() and out == ""
    assert bfile.read_bytes() == before


def test_select_cases_refuses_a_missing_model() -> None:
    cat = load_catalogue(DATA / "catalogue.toml")
    with pytest.raises(TippetopError, match="no such file"):
        select_cases(cat, "models", models=["/nowhere/top.xml"])
