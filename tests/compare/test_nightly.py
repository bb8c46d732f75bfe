"""The nightly regression: baselines, tolerances, exit codes, results.json and junit.xml.

Most tests run a tiny catalogue (short reference-ODE runs only, a 20-s threshold bisection and
a 3-point sweep) in this process (``--workers 1``) with a private run cache, so the whole file
takes well under a minute. One test runs a subset of the shipped quick profile against the
baselines stored in the repository.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tippetop.compare import nightly
from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.measures.tolerances import TOLERANCES, Tolerance, compare_value
from tippetop.compare.nightly import load_catalogue, select_cases
from tippetop.compare.results.nightly import NightlyResult
from tippetop.compare.results.threshold import ThresholdResult
from tippetop.models.errors import TippetopError
from tippetop.models.modes import MODES
from tippetop.models.scene import catalogue_names

TINY = """
[profiles.tiny]
description = "test profile: short ODE runs"

[profiles.other]
description = "never run by the tests"

[[case]]
name = "fig3-short"
category = "paper"
kind = "run"
scene = "fig3"
set = ["run.t_end_s=4"]
engines = ["ode"]
modes = ["paper", "viscous"]
profiles = ["tiny"]
metrics = ["outcome", "matches_expect", "theta_asymp", "t_invert", "J_rel_drift",
           "energy_monotone", "energy_lost", "status"]

[[case]]
name = "fig7b-short"
category = "groups"
kind = "run"
scene = "fig7b"
set = ["run.t_end_s=2"]
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny", "other"]
metrics = ["outcome", "theta_asymp", "J_rel_drift"]

[[case]]
name = "fig3"
category = "paper"
kind = "run"
scene = "fig3"
engines = ["mujoco"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["outcome", "theta_asymp"]

[[case]]
name = "n1-20s"
category = "thresholds"
kind = "threshold"
scene = "fig11_n060"
set = ["run.t_end_s=20"]
which = "n1"
rel_tol = 0.1
max_rounds = 4
points_per_round = 2
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["measured", "converged"]

[[case]]
name = "fig9a-tiny"
category = "sweeps"
kind = "sweep"
scene = "fig11_n060"
set = ["run.t_end_s=20"]
n0 = "30:60:15"
figure = "Fig. 9"
label = "(a)"
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["theta_asymp_vs_n0", "outcomes_vs_n0"]
"""

FIG3 = "paper/fig3-short[ode/paper]"
MUJOCO_ID = "paper/fig3[mujoco/paper]"


def run_nightly(*args: str) -> tuple[int, str, str]:
    """``tippetop nightly ARGS`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = nightly_command.main(list(args))
        except SystemExit as exc:  # an option refused by the parser (--scheduler's port)
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The tiny catalogue, its baselines made by --update-baseline, and a private run cache."""
    root = tmp_path_factory.mktemp("nightly")
    cat = root / "tiny.toml"
    cat.write_text(TINY)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TIPPETOP_CACHE", str(root / "cache"))
        code, out, err = run_nightly(
            "--catalogue", str(cat), "--profile", "tiny", "--engines", "ode",
            "--baseline", str(root / "baselines"), "--update-baseline",
            "--out", str(root / "first"), "--workers", "1", "--cache")
    assert code == 0, out + err
    return {"root": root, "catalogue": cat, "baselines": root / "baselines",
            "first": root / "first", "cache": root / "cache", "stdout": out}


@pytest.fixture
def cached(tiny: dict, monkeypatch: pytest.MonkeyPatch) -> dict:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tiny["cache"]))
    return tiny


def _args(t: dict, out: Path, baselines: Path | None = None,
          *extra: str) -> list[str]:
    return ["--catalogue", str(t["catalogue"]), "--profile", "tiny", "--engines", "ode",
            "--baseline", str(baselines or t["baselines"]), "--out", str(out), "--workers", "1",
            "--cache", *extra]


def _results(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())


def _check(results: dict, case_id: str, metric: str) -> dict:
    rec = next(r for r in results["cases"] if r["id"] == case_id)
    return next(ch for ch in rec["checks"] if ch["metric"] == metric)


# --------------------------------------------------------------------------- baselines, exit 0
def test_update_baseline_writes_the_ode_cases(tiny: dict) -> None:
    base = json.loads((tiny["baselines"] / "tiny.json").read_text())
    ids = set(base["cases"])
    assert FIG3 in ids and "thresholds/n1-20s[ode/paper]" in ids
    assert "sweeps/fig9a-tiny[ode/paper]" in ids
    assert MUJOCO_ID not in ids  # --engines ode: the MuJoCo case did not run
    assert set(base["cases"][FIG3]) == {"outcome", "matches_expect", "theta_asymp",
                                        "t_invert", "J_rel_drift", "energy_monotone",
                                        "energy_lost", "status"}
    assert "baseline updated" in tiny["stdout"]
    assert base["environment"]["packages"]["numpy"]
    # the first run had no baseline: every check was "new", nothing failed
    res = _results(tiny["first"])
    assert res["counts"]["checks_new"] == res["counts"]["checks"] > 0
    assert res["baseline_update"]["added"] == len(ids)


def test_results_json_reads_back_as_a_nightly_result(tiny: dict) -> None:
    """results.json is NightlyResult.to_json(), key for key in its order, and reads back."""
    data = _results(tiny["first"])
    res = NightlyResult.from_json(data)
    assert res.profile == "tiny" and res.engines == ("ode",) and res.history is not None
    assert res.baseline_update is not None and res.report_error is None
    assert list(res.to_json()) == list(data) and res.to_json() == data
    assert NightlyResult.from_json(res.to_json()) == res


def test_a_failed_report_is_said_in_results_json(cached: dict, tmp_path: Path) -> None:
    """No history (no key), the report's error last, and the verdict says the report failed."""
    from tippetop.compare.nightly.suite import NightlyOptions
    from tippetop.compare.nightly.suite import run_nightly as run_suite

    def no_report(*_args: object) -> None:
        raise RuntimeError("no report")

    opts = NightlyOptions(profile="tiny", catalogue=cached["catalogue"],
                          baseline_dir=cached["baselines"], out=str(tmp_path / "out"),
                          engines=("ode",), workers=1, cache=True, no_history=True)
    said: list[str] = []
    code = run_suite(opts, write_report=no_report, log=lambda s: None, echo=said.append)
    data = _results(tmp_path / "out")
    res = NightlyResult.from_json(data)
    assert code == 1 and "history" not in data and list(data)[-1] == "report_error"
    assert res.report_error == "RuntimeError: no report" and res.history is None
    assert res.verdict == "ERROR (report failed)" and "ERROR (report failed)" in said[0]
    assert res.to_json() == data


def test_untouched_baselines_exit_0_and_are_not_written(cached: dict,
                                                        tmp_path: Path) -> None:
    bfile = cached["baselines"] / "tiny.json"
    before = (bfile.read_bytes(), bfile.stat().st_mtime_ns)
    code, out, err = run_nightly(*_args(cached, tmp_path / "out"))
    assert code == 0, out + err
    assert (bfile.read_bytes(), bfile.stat().st_mtime_ns) == before
    res = _results(tmp_path / "out")
    c = res["counts"]
    assert c["checks_pass"] == c["checks"] and c["checks_fail"] == c["checks_new"] == 0
    assert res["verdict"] == "OK" and "result: OK" in out
    for name in ("results.json", "junit.xml", "report.html"):
        assert (tmp_path / "out" / name).is_file()
    # every check records its value, baseline and tolerance
    chk = _check(res, FIG3, "theta_asymp")
    assert chk["value"] == chk["baseline"]
    assert chk["tolerance"]["text"] == TOLERANCES["theta_asymp"].describe()
    assert res["environment"]["python"] and "git_commit" in res["environment"]


# --------------------------------------------------------------------------- regressions
@pytest.mark.parametrize(("case_id", "metric", "edit"), [
    (FIG3, "theta_asymp", lambda v: v + 0.5),
    (FIG3, "outcome", lambda v: "upright" if v != "upright" else "inverted"),
    ("thresholds/n1-20s[ode/paper]", "measured", lambda v: 1.5 * v),
    ("sweeps/fig9a-tiny[ode/paper]", "theta_asymp_vs_n0", lambda v: {**v, "45": v["45"] + 0.4}),
])
def test_injected_regression_exits_1_and_names_the_metric(
        cached: dict, tmp_path: Path, case_id: str, metric: str, edit) -> None:
    bdir = tmp_path / "baselines"
    shutil.copytree(cached["baselines"], bdir)
    doc = json.loads((bdir / "tiny.json").read_text())
    old = doc["cases"][case_id][metric]
    doc["cases"][case_id][metric] = edit(old)
    (bdir / "tiny.json").write_text(json.dumps(doc))
    code, out, err = run_nightly(*_args(cached, tmp_path / "out", bdir))
    assert code == 1, out + err
    # the summary names the case and the metric
    assert f"{case_id} {metric} regressed" in out and "result: REGRESSION" in out
    # results.json: that metric failed with both values, and nothing else did
    res = _results(tmp_path / "out")
    chk = _check(res, case_id, metric)
    assert chk["status"] == "fail"
    assert chk["baseline"] == doc["cases"][case_id][metric] and chk["value"] == old
    assert res["counts"]["checks_fail"] == 1
    # junit.xml: one <failure> naming the metric and both values
    root = ET.parse(tmp_path / "out" / "junit.xml").getroot()
    failures = [(tc, f) for tc in root.iter("testcase") for f in tc.findall("failure")]
    assert len(failures) == 1
    tc, fail = failures[0]
    assert tc.get("name") == metric and case_id.split("/")[1] in tc.get("classname")
    assert metric in fail.get("message") and "baseline" in fail.get("message")
    if isinstance(old, float):
        assert f"{old:.6g}" in fail.get("message")
        assert f"{doc['cases'][case_id][metric]:.6g}" in fail.get("message")
    # the baseline file was not touched
    assert json.loads((bdir / "tiny.json").read_text()) == doc


def test_missing_case_is_new_not_a_regression(cached: dict, tmp_path: Path) -> None:
    bdir = tmp_path / "baselines"
    shutil.copytree(cached["baselines"], bdir)
    doc = json.loads((bdir / "tiny.json").read_text())
    del doc["cases"]["groups/fig7b-short[ode/paper]"]
    (bdir / "tiny.json").write_text(json.dumps(doc))
    code, out, err = run_nightly(*_args(cached, tmp_path / "out", bdir))
    assert code == 0, out + err
    assert "NEW" in out and "groups/fig7b-short[ode/paper]: all 3 metrics" in out
    res = _results(tmp_path / "out")
    rec = next(r for r in res["cases"] if r["id"] == "groups/fig7b-short[ode/paper]")
    assert rec["status"] == "new" and res["counts"]["checks_new"] == 3
    root = ET.parse(tmp_path / "out" / "junit.xml").getroot()
    assert len(list(root.iter("skipped"))) == 3


def test_update_baseline_restores_merges_and_drops(cached: dict,
                                                   tmp_path: Path) -> None:
    """--update-baseline rewrites what ran, keeps what was filtered out (the MuJoCo case under
    --engines ode) and drops ids that left the profile."""
    bdir = tmp_path / "baselines"
    shutil.copytree(cached["baselines"], bdir)
    doc = json.loads((bdir / "tiny.json").read_text())
    good = doc["cases"][FIG3]["theta_asymp"]
    doc["cases"][FIG3]["theta_asymp"] = good + 1.0
    doc["cases"][MUJOCO_ID] = {"outcome": "inverted", "theta_asymp": 3.1}
    doc["cases"]["paper/gone[ode/paper]"] = {"outcome": "upright"}
    (bdir / "tiny.json").write_text(json.dumps(doc))
    code, out, err = run_nightly(*_args(cached, tmp_path / "out", bdir, "--update-baseline"))
    assert code == 0, out + err  # regressions are accepted when updating
    assert f"baseline updated: {bdir / 'tiny.json'}" in out
    new = json.loads((bdir / "tiny.json").read_text())["cases"]
    assert new[FIG3]["theta_asymp"] == good
    assert new[MUJOCO_ID] == {"outcome": "inverted", "theta_asymp": 3.1}
    assert "paper/gone[ode/paper]" not in new
    # the run still reports what it found against the old values
    assert _check(_results(tmp_path / "out"), FIG3, "theta_asymp")["status"] == "fail"


# --------------------------------------------------------------------------- outputs
def test_output_folder_is_not_written_over_without_force(cached: dict,
                                                         tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    code, stdout, err = run_nightly(*_args(cached, out))
    assert code == 2 and "--force" in err and "not empty" in err
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    code, stdout, err = run_nightly(*_args(cached, out), "--force")
    assert code == 0, stdout + err
    assert (out / "results.json").is_file() and (out / "mine.txt").read_text() == "keep"
    # an empty existing folder is fine without --force
    (tmp_path / "empty").mkdir()
    assert run_nightly(*_args(cached, tmp_path / "empty"))[0] == 0


def test_default_output_folder_is_new_and_timestamped(cached: dict, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    args = _args(cached, tmp_path / "x")
    i = args.index("--out")
    code, out, err = run_nightly(*args[:i], *args[i + 2:], "--cases", "groups/*")
    assert code == 0, out + err
    (folder,) = [p for p in tmp_path.iterdir() if p.name.startswith("nightly-")]
    assert len(folder.name) == len("nightly-20250101-120000") and f"output: {folder}" in out


def test_junit_xml_parses_and_counts_match(cached: dict) -> None:
    res = _results(cached["first"])
    root = ET.parse(cached["first"] / "junit.xml").getroot()
    assert root.tag == "testsuites"
    cases = list(root.iter("testcase"))
    assert int(root.get("tests")) == len(cases) == res["counts"]["checks"]
    for tag, key in (("failure", "checks_fail"), ("error", "checks_error"),
                     ("skipped", "checks_new")):
        n = sum(len(tc.findall(tag)) for tc in cases)
        assert n == res["counts"][key]
    suites = root.findall("testsuite")
    assert {s.get("name") for s in suites} == {f"nightly.tiny.{c}" for c in
                                                ("paper", "groups", "thresholds", "sweeps")}
    for s in suites:
        assert int(s.get("tests")) == len(s.findall("testcase"))
        assert s.find("properties/property[@name='profile']").get("value") == "tiny"


def test_junit_xml_reads_with_junitparser(cached: dict) -> None:
    junitparser = pytest.importorskip("junitparser")
    xml = junitparser.JUnitXml.fromfile(str(cached["first"] / "junit.xml"))
    res = _results(cached["first"])
    assert sum(s.tests for s in xml) == res["counts"]["checks"]
    assert sum(s.skipped for s in xml) == res["counts"]["checks_new"]


def test_case_that_cannot_run_is_an_error_and_exits_1(cached: dict,
                                                      tmp_path: Path) -> None:
    """A bisection that cannot run (n_c of a Group III top) is reported as that case's error."""
    cat = tmp_path / "bad.toml"
    cat.write_text(TINY.replace('set = ["run.t_end_s=20"]\nwhich = "n1"',
                                'set = ["run.t_end_s=20", "top.A_over_C=1.25"]\nwhich = "nc"'))
    args = _args(cached, tmp_path / "out")
    args[1] = str(cat)
    code, out, err = run_nightly(*args, "--cases", "thresholds/*")
    assert code == 1, out + err
    assert "ERRORS" in out and "thresholds/n1-20s[ode/paper]" in out
    res = _results(tmp_path / "out")
    assert res["counts"]["cases_error"] == 1 and res["verdict"] == "ERROR"
    root = ET.parse(tmp_path / "out" / "junit.xml").getroot()
    assert len(list(root.iter("error"))) == 2  # measured and converged


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(("extra", "message"), [
    (["--profile", "nope"], "--profile"),
    (["--engines", "ode,bullet"], "--engines"),
    (["--cases", "nothing/*"], "at least one case"),
    (["--scheduler", "localhost:8786"], "--scheduler"),
])
def test_bad_input_exits_2(cached: dict, tmp_path: Path, extra: list[str],
                           message: str) -> None:
    args = _args(cached, tmp_path / "out")
    if extra[0] in args:
        i = args.index(extra[0])
        args[i + 1] = extra[1]
    else:
        args += extra
    code, out, err = run_nightly(*args)
    assert code == 2 and message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_missing_baseline_folder_exits_2(cached: dict, tmp_path: Path) -> None:
    code, out, err = run_nightly(*_args(cached, tmp_path / "out", tmp_path / "nowhere"))
    assert code == 2 and "--baseline" in err


@pytest.mark.parametrize(("edit", "message"), [
    (lambda s: s.replace('kind = "sweep"', 'kind = "sweep"\ncolour = "red"'), "unknown key"),
    (lambda s: s.replace('"theta_asymp_vs_n0", ', '"theta_asymp", '), "metrics"),
    (lambda s: s.replace('modes = ["paper"]\nprofiles = ["tiny", "other"]',
                         'modes = ["paper-magic"]\nprofiles = ["tiny", "other"]'), "modes"),
    (lambda s: s.replace('engines = ["ode"]\nmodes = ["paper"]\nprofiles = ["tiny", "other"]',
                         'engines = ["ode"]\nmodes = ["native"]\nprofiles = ["tiny", "other"]'),
     "expected modes the engines ode can run, got 'native'"),
    (lambda s: s.replace('engines = ["ode"]\nmodes = ["paper"]\nprofiles = ["tiny", "other"]',
                         'engines = ["bullet"]\nmodes = ["paper"]\nprofiles = ["tiny", "other"]'),
     "engines: expected a list of ode and mujoco"),
    (lambda s: s.replace('profiles = ["tiny", "other"]', 'profiles = ["tiny", "nightly"]'),
     "profiles"),
    (lambda s: s + s[s.index("[[case]]"):s.index("[[case]]", s.index("[[case]]") + 1)],
     "unique case ids"),
])
def test_catalogue_errors_name_the_problem(tmp_path: Path, edit, message: str) -> None:
    cat = tmp_path / "cat.toml"
    cat.write_text(edit(TINY))
    with pytest.raises(TippetopError, match=message):
        load_catalogue(cat)


# --------------------------------------------------------------------------- tolerances
def test_compare_value_rules() -> None:
    assert compare_value(1.01, 1.0, Tolerance("abs", 0.02))[0]
    assert not compare_value(1.03, 1.0, Tolerance("abs", 0.02))[0]
    assert compare_value(1.019, 1.0, Tolerance("rel", 0.02))[0]
    assert not compare_value(1.03, 1.0, Tolerance("rel", 0.02))[0]
    assert compare_value(5e-7, 1e-9, Tolerance("rel", 0.02, floor=1e-6))[0]  # floor
    growth = TOLERANCES["J_rel_drift"]
    assert compare_value(1e-12, 1e-9, growth)[0]  # shrinking always passes
    assert compare_value(9e-9, 1e-12, growth)[0]  # below the floor
    assert compare_value(9e-6, 1e-6, growth)[0]
    assert not compare_value(2e-5, 1e-6, growth)[0]  # more than 10x the baseline
    assert compare_value("inverted", "inverted", Tolerance("exact"))[0]
    assert not compare_value(True, False, Tolerance("exact"))[0]
    assert compare_value(None, None, Tolerance("abs", 0.1))[0]
    ok, msg = compare_value(None, 2.3, Tolerance("abs", 0.1, unit="s"))
    assert not ok and "none vs baseline 2.3 s" in msg
    ok, msg = compare_value({"30": 0.0, "45": 1.3}, {"30": 0.0, "45": 1.0},
                            Tolerance("abs", 0.05))
    assert not ok and msg.startswith("n0 = 45:")
    ok, msg = compare_value({"30": 0.0, "60": 2.5}, {"30": 0.01}, Tolerance("abs", 0.05))
    assert ok and "1 point(s) without baseline" in msg


def test_every_metric_has_a_tolerance_with_a_reason() -> None:
    for kind_metrics in nightly.KIND_METRICS.values():
        for m in kind_metrics:
            tol = TOLERANCES[m]
            assert tol.kind in ("exact", "abs", "rel", "growth") and len(tol.why) > 20


# --------------------------------------------------------------------------- shipped catalogue
def test_shipped_catalogue_covers_the_issue() -> None:
    cat = load_catalogue()
    assert set(cat.profiles) == {"quick", "full", "stress"}
    for prof in ("quick", "full"):
        cases = select_cases(cat, prof)
        ode_scenes = {c.scene for c in cases if c.kind == "run" and c.run == "ode/paper"
                      and not c.set}
        assert ode_scenes == set(catalogue_names())  # every paper scene in the reference
        for key in ("fig3", "fig7a"):
            assert {c.run for c in cases if c.scene == key and not c.set} >= {
                "ode/paper", "mujoco/paper"}
        thresholds = {c.engine for c in cases if c.kind == "threshold"}
        assert thresholds == {"ode", "mujoco"}  # at least one bisection per engine
        friction = {c.run for c in cases if c.category == "friction"}
        assert friction >= {"ode/coulomb", "ode/viscous", "ode/coulomb_viscous",
                            "mujoco/native-condim4", "mujoco/native-condim6",
                            "mujoco/native-pyramidal"}
        for c in cases:
            if c.kind == "probe":  # a probe's own modes and quantities (issue 44)
                from tippetop.compare.probes import probe_class, probe_metric

                assert c.mode in probe_class(c.scene).modes
                assert all(probe_metric(m).tolerance is not None for m in c.metrics)
                continue
            assert c.mode in MODES and all(m in TOLERANCES for m in c.metrics)
        # every probe runs in the profile (issue 44: a probes category, in quick)
        from tippetop.compare.probes import probe_names

        assert {c.scene for c in cases if c.kind == "probe"} == set(probe_names())
    quick_sweeps = {(c.figure, c.label) for c in select_cases(cat, "quick") if c.kind == "sweep"}
    assert ("Fig. 9", "(a)") in quick_sweeps
    full_sweeps = {(c.figure, c.label) for c in select_cases(cat, "full") if c.kind == "sweep"}
    assert full_sweeps >= {("Fig. 9", x) for x in ("(a)", "(b)", "(c)", "(d)")} | {
        ("Fig. 10", "(a)"), ("Fig. 10", "(b)")}
    assert 0 < len(select_cases(cat, "stress")) <= 12
    # the ODE-only selection the tests use
    assert all(c.engine == "ode" for c in select_cases(cat, "quick", ("ode",)))


@pytest.mark.parametrize("profile", ["quick", "full"])
def test_repository_baselines_cover_every_ode_case(profile: str) -> None:
    path = nightly.BASELINE_DIR / f"{profile}.json"
    stored = json.loads(path.read_text())["cases"]
    for c in select_cases(load_catalogue(), profile, ("ode",)):
        assert c.id in stored, f"{c.id}: run 'tippetop nightly --profile {profile} " \
                               f"--engines ode --update-baseline'"
        assert set(c.metrics) <= set(stored[c.id])


def test_quick_subset_matches_the_repository_baselines(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The stored quick baselines still hold for a few reference cases (the default --baseline
    folder). If the reference ODE changed on purpose, update them with --update-baseline."""
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    code, out, err = run_nightly("--profile", "quick", "--engines", "ode", "--cases",
                                 "paper/fig3[*,paper/fig7b[*,friction/fig3[ode/viscous],groups/groupI*",
                                 "--out", str(tmp_path / "out"), "--workers", "1")
    assert code == 0, out + err
    res = _results(tmp_path / "out")
    assert res["counts"]["checks_pass"] == res["counts"]["checks"] >= 20
    assert res["baseline_file"] == str(nightly.BASELINE_DIR / "quick.json")


# --------------------------------------------------------------------------- engine specs
def test_engine_specs_keep_their_own_baselines(tiny: dict, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """``--engines mujoco,mujoco@PYTHON``: the MuJoCo case on both, each with its own file.

    The same MuJoCo in a worker (``mujoco@`` this interpreter) runs the case as
    ``paper/fig3[mujoco@.../paper]``; its baseline goes to ``tiny@<engine>.json``, not
    into ``tiny.json``; a second run compares each with its own (no check is new). The
    threshold case is not run on the other spec, and says so.
    """
    import sys

    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    here = f"mujoco@{sys.executable}"
    base = tmp_path / "baselines"
    cat = tmp_path / "short.toml"
    # the tiny catalogue's paper-mode fig3, cut to 0.5 s (the worker's Python callback is slow)
    cat.write_text(TINY.replace('engines = ["mujoco"]\nmodes = ["paper"]',
                                'set = ["run.t_end_s=0.5"]\nengines = ["mujoco"]\n'
                                'modes = ["paper"]'))
    args = ["--catalogue", str(cat), "--profile", "tiny", "--engines",
            f"mujoco,{here}", "--cases", "paper/fig3[*", "--baseline", str(base),
            "--workers", "1", "--cache"]
    code, out, err = run_nightly(*args, "--update-baseline", "--out", str(tmp_path / "a"))
    assert code == 0, out + err
    from tippetop.compare.nightly.suite import spec_slug

    own = base / f"tiny@{spec_slug(here)}.json"
    main_ids = set(json.loads((base / "tiny.json").read_text())["cases"])
    spec_ids = set(json.loads(own.read_text())["cases"])
    there = f"paper/fig3[{here}/paper]"
    assert main_ids == {MUJOCO_ID} and spec_ids == {there}
    code, out, err = run_nightly(*args, "--out", str(tmp_path / "b"))
    assert code == 0, out + err
    res = _results(tmp_path / "b")
    assert res["counts"]["checks_new"] == 0 and res["counts"]["checks_fail"] == 0
    by = {r["id"]: r for r in res["cases"]}
    assert by[there]["engine"] == here and by[there]["mode"] == "paper"
    # the verdict table has a column for the other engine
    assert {r["run"] for r in res["crossval"]} == {"mujoco/paper", f"{here}/paper"}
    # the same MuJoCo in a worker: the same values to the bit
    assert by[MUJOCO_ID]["values"] == by[there]["values"]


def test_a_missing_spec_baseline_is_one_line(tiny: dict, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setenv("TIPPETOP_CACHE", str(tiny["cache"]))
    code, out, err = run_nightly(
        "--catalogue", str(tiny["catalogue"]), "--profile", "tiny", "--engines",
        f"ode,mujoco@{sys.executable}", "--baseline", str(tiny["baselines"]),
        "--out", str(tmp_path / "out"), "--workers", "1")
    assert code == 2 and err.count("\n") == 1 and "tiny@mujoco_" in err, err
    assert not (tmp_path / "out").exists()


def test_thresholds_and_the_atlas_go_on_another_spec(monkeypatch) -> None:
    from tippetop.compare.nightly import running
    from tippetop.compare.nightly.suite import cases_on_specs, engine_specs

    cat = load_catalogue(None)
    kinds, specs = engine_specs(("ode", "mujoco", "mujoco==3.3.7"))
    assert kinds == ("ode", "mujoco") and specs == ["mujoco", "mujoco==3.3.7"]
    picked = select_cases(cat, "full", kinds)
    cases, skipped = cases_on_specs(picked, specs)
    mj = [c for c in picked if c.family == "mujoco"]
    assert any(c.kind == "threshold" for c in mj) and any(c.kind == "atlas" for c in mj)
    # every kind runs on any engine: each MuJoCo case once more, on the release
    assert len(cases) == len(picked) + len(mj) and skipped == []
    assert any(c.kind == "atlas" and c.engine == "mujoco==3.3.7" for c in cases)
    # a threshold case on the release measures on it: its spec goes to the measurement
    on = next(c for c in cases if c.kind == "threshold" and c.engine == "mujoco==3.3.7")
    assert on.id.endswith(f"[mujoco==3.3.7/{on.mode}]")
    seen = {}

    def fake(*args, **kw):
        seen.update(kw)
        return ThresholdResult("n1", on.engine, on.mode, "fig11_n060", "growth", 34.3, 34.35,
                               None, (), (), 2.0, True, True)

    monkeypatch.setattr(running, "measure_threshold", fake)
    running._run_threshold(running.CaseRun(on), scheduler=None, workers=1, use_cache=False,
                           log=lambda s: None)
    assert seen["mode"] == on.mode and on.engine == "mujoco==3.3.7"
    with pytest.raises(TippetopError, match="--engines: expected a comma-separated list of "
                       "ode and engine specs"):
        engine_specs(("ode", "bullet"))
