"""Issue 23, "nothing silent, nothing OK that is not": what simulate and validate print.

Every number printed carries its unit (a relative quantity says so), a missing value says why
(never a Python ``None``), simulate's numbers have four significant digits, and validate names
the file's mu (not the calibrated settings' mu, which is scaled from it). The ``--json`` output
is not touched: a value that is None there stays null.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tippetop.compare.measures.friction_realised import realised_sentence
from tippetop.compare.measures.verdict import verdict
from tippetop.compare.presentation.terminal import (
    check_text,
    fmt_duration,
    fmt_rolling,
    fmt_stiff,
    fmt_value,
)
from tippetop.compare.studies.validate import show_setting, suggestion

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "paper_loaded_sphere.xml"
MU1 = ROOT / "tests" / "data" / "stranger" / "group2_mu1_implicitfast.xml"


def tippetop(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)


# ---------------------------------------------------------------- a verdict's check as text
def _event(name: str, value: float | None, passed: bool, note: str) -> dict[str, Any]:
    return {"check": name, "run": "mujoco/file", "engine": "mujoco", "mode": "file",
            "passed": passed, "value": value,
            "tolerance": "|dt| <= ...", "note": note}


def test_an_event_the_run_never_has_says_so_with_the_horizon() -> None:
    c = _event("t_invert", None, False, "turns over (theta = pi/2): the reference only")
    runs = {"mujoco/file": {"t_invert": None}, "ode/paper": {"t_invert": 2.329259}}
    assert check_text(c, 8.0, runs) == ("does not turn over within the run's 8 s; the "
                                        "reference turns over at 2.329 s")
    # without the runs (a tuning's verification) it still says who, and within what
    assert check_text(c, 8.0) == ("does not turn over within the run's 8 s; the reference "
                                  "turns over")
    only_mine = _event("t_stem", None, False, "the stem touches: this run only")
    assert check_text(only_mine, 4.0, {"mujoco/file": {"t_stem": 3.1}, "ode/paper": {}}) == (
        "touches its stem at 3.1 s; the reference does not touch its stem within the run's 4 s")
    neither = _event("t_stem", None, True, "neither the stem touches")
    assert "None" not in check_text(neither, 8.0) and "within the run's 8 s" in \
        check_text(neither, 8.0)


def test_an_event_time_is_said_in_seconds_from_the_reference() -> None:
    assert check_text(_event("t_invert", 1.2897, False, "")) == \
        "1.29 s later than the reference"
    assert check_text(_event("t_invert", -0.75512, False, "")) == \
        "0.7551 s earlier than the reference"


def test_drifts_and_rises_are_said_to_be_relative() -> None:
    j = {"check": "jellett_before_stem", "mode": "m", "passed": False, "value": 0.0648,
         "tolerance": "<= 0.001", "note": ""}
    assert check_text(j) == "0.065 (relative)"
    e = {**j, "check": "energy_never_rises", "value": 2.1e-3}
    assert check_text(e) == "0.0021 of E0"
    assert "None" not in check_text({**j, "value": None})
    assert check_text({**j, "check": "outcome", "value": "upright"}) == "upright"


# ---------------------------------------------------------------- values of simulate
def test_simulate_values_have_four_digits_and_say_what_is_relative() -> None:
    assert fmt_duration(11.8734) == "11.87 s"
    assert fmt_value("wall_s", 0.0057441) == "5.744 ms"
    assert fmt_value("J_rel_drift", 1.284e-9) == "1.3e-9 (relative)"
    assert fmt_value("energy_rise_rel", 0.0) == "0 of E0"
    assert fmt_value("rtol", 1e-9) == "1e-9 (relative)"
    assert fmt_value("solimp", [0.9, 0.95, 0.001, 0.5, 2.0]) == "0.9, 0.95, 0.001 m, 0.5, 2"


def test_the_stiff_line_agrees_with_the_rolling_phases() -> None:
    """The issue: ``stiff  rolling`` beside ``rolling  phases 0``. The treatment was there; the
    run never needed it: both lines say so."""
    none = {"phases": 0, "t_s": 0.0}
    assert fmt_stiff("rolling", none) == ("rolling phases where the law turns stiff: "
                                          "available, never entered")
    assert fmt_rolling(none) == "no rolling phase entered"
    some = {"phases": 2, "t_s": 3.95312}
    assert fmt_stiff("rolling", some).endswith("entered 2 times (3.953 s in all)")
    assert fmt_rolling(some) == "2 rolling phases, 3.953 s in all"
    assert fmt_stiff("off") == "off (the law throughout, as asked)"


def test_the_realised_law_has_four_digits_and_units() -> None:
    fr = {"mu_fit": 0.0872912, "Lambda_fit_mps": 0.00491234, "residual": 0.0038123,
          "half_mu_slip_mps": 0.0139123, "law_half_mu_slip_mps": 0.01 / 3 ** 0.5,
          "angle_rms_rad": 1.761, "creep_fraction": 0.05}
    text = realised_sentence("mujoco/file", fr)
    assert text.startswith("mujoco/file: the contact reaches half of mu N at a slip of "
                           "13.91 mm/s, the paper's law at 5.774 mm/s")
    assert "Lambda 4.912 mm/s" in text and "residual 0.0038 of |F_t|/N" in text
    assert "creeping 5 % of the time" in text


_NUMBER = re.compile(r"(?<![\w.^])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")
#: Keys of simulate whose numbers are counts, coefficients or ratios (no unit to give); a
#: method's name carries its order (``taylor (order 12)``) and, after a hand-over, the
#: tolerances it ran at.
_UNITLESS = {"n_rhs", "n_steps", "iterations", "condim", "noslip_iterations", "impratio",
             "law_mu", "mu", "version", "message", "friction_law", "formulation", "method"}
_UNIT = re.compile(r"^(?:s|rad|rad/s|m|m/s|m/s\^2|J|kg|mm/s|ms)(?![\w/^])|^%|^\(relative\)"
                   r"|^of (?:E0|\|F_t\|/N)|^\(absolute")


def _unitless_numbers(key: str, value: str) -> list[str]:
    """The numbers in ``value`` that no unit follows (``solref``'s dampratio and ``solimp``'s
    dimensionless parts aside; a ``mu`` is a coefficient, a ``condim`` a count)."""
    if key in _UNITLESS:
        return []
    value = re.sub(r"\b(mu|condim|condim below) \d[\d.e-]*", r"\1", value)
    if key in ("solref", "solimp"):
        return [] if re.search(r"\d s\b|\d m\b", value) else [value]
    if key == "phases":
        value = re.sub(r"(\d)-(\d)", r"\1 s-\2", value)
    bad = []
    for m in _NUMBER.finditer(value):
        if not _UNIT.match(value[m.end():].lstrip()):
            bad.append(m.group())
    return bad


@pytest.mark.parametrize("engine", ["ode", "mujoco"])
def test_simulate_prints_no_none_and_a_unit_after_each_number(engine: str) -> None:
    r = tippetop("simulate", "fig3", "--engine", engine, "--set", "run.t_end_s=0.5")
    assert r.returncode == 0, r.stderr
    assert "None" not in r.stdout and not re.search(r"\s-$", r.stdout, re.M), r.stdout
    for line in r.stdout.splitlines():
        key, _, value = line.strip().partition("  ")
        assert _unitless_numbers(key, value.strip()) == [], line
    if engine == "ode":  # the rolling-phase treatment ran and was never needed: said so
        stiff = next(x for x in r.stdout.splitlines() if x.startswith("stiff "))
        assert stiff.endswith("available, never entered"), stiff
    # the JSON contract is as it was: the same keys, None still null
    d = json.loads(tippetop("simulate", "fig3", "--engine", engine, "--set",
                            "run.t_end_s=0.5", "--json").stdout)
    assert d["t_stem"] is None and d["t_invert"] is None
    if engine == "ode":
        assert d["stiff"] == "rolling" and d["rolling_phases"] == {"phases": 0, "t_s": 0.0}


# ---------------------------------------------------------------- validate
def test_the_suggestion_names_the_files_mu_not_the_scaled_one() -> None:
    """A file at mu = 1: the calibrated settings' mu is 1.04 (their 0.104 at mu = 0.1, scaled);
    the sentence said "scaled to the file's mu = 1.04"."""
    base = {"status": "ok", "theta_final": 3.0, "t_invert": 2.0, "t_stem": None,
            "J_rel_drift": 1e-9, "energy_monotone": True, "energy_rise_rel": 0.0,
            "contact_energy_bound_J": 0.0, "phases": [], "error": None, "outcome": "inverted",
            "end_state": "inverted", "E0_J": 1.0, "integrator": "RK4", "timestep_s": 2e-4,
            "condim": 3, "cone": "pyramidal", "impratio": 1.0, "solref": [0.02, 1.0],
            "solimp": [0.9, 0.95, 0.001, 0.5, 2.0]}
    runs = {"mujoco/file": {**base, "mu": 1.0}, "ode/paper": {**base, "engine": "ode"},
            "mujoco/paper": {**base, "mu": 1.0},
            "mujoco/native": {**base, "mu": 1.04, "t_invert": 1.0}}
    checks = verdict(runs, "inverted")
    note = suggestion(runs["mujoco/native"], checks, runs["mujoco/file"], file_mu=1.0)["note"]
    assert "the file's mu = 1," in note and "the file's mu = 1.04" not in note, note
    assert "MuJoCo's contact mu = 1.04" in note and "mu = 0.104 to follow the law's 0.1" in note
    # the file's run's mu when the file's is not given; the same mu said once
    same = suggestion({**runs["mujoco/native"], "mu": 1.0}, checks, runs["mujoco/file"])["note"]
    assert "scaled to the file's mu = 1:" in same and "1.04" not in same, same
    assert show_setting("timestep_s", 0.002) == "0.002 s"
    assert show_setting("solref", [0.02, 1.0]) == "[0.02 s, 1]"


def _departs(stdout: str) -> dict[tuple[str, str], str]:
    """``departs:`` lines -> (mode, check) -> the value as printed."""
    out = {}
    for line in stdout.splitlines():
        m = re.match(r"^  departs: (\S+)\s+(\S+)\s+(.*?)  \(tolerance ", line)
        if m:
            out[(m.group(1), m.group(2))] = m.group(3)
    return out


@pytest.fixture(scope="module")
def paper_top(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    """validate on the paper's top, 4 s, no tuning: the file's own contact never turns it."""
    out = tmp_path_factory.mktemp("units") / "report"
    r = tippetop("validate", str(EXAMPLE), "--no-tune", "--t-end-s", "4", "--out", str(out))
    assert r.returncode == 1, r.stderr
    return r.stdout, out


def test_validate_says_why_an_inversion_time_is_missing(paper_top: tuple[str, Path]) -> None:
    stdout, _ = paper_top
    assert "None" not in stdout, stdout
    shown = _departs(stdout)
    assert shown[("mujoco/file", "t_invert")].startswith(
        "does not turn over within the run's 4 s; the reference turns over at 2.3"), stdout
    head = stdout.splitlines()[0]
    assert "mu = 0.1," in head and "n0 = 100 rad/s" in head and "theta_s = 3.142 rad" in head
    assert "only the reference turns the top over within the run's 4 s" in stdout


def test_validate_report_says_why_too(paper_top: tuple[str, Path]) -> None:
    html = (paper_top[1] / "report.html").read_text()
    verdict_at = html.index("<section id='verdict'>")
    section = html[verdict_at:html.index("</section>", verdict_at)]
    assert "does not turn over within the run&#x27;s 4 s" in section or \
        "does not turn over within the run's 4 s" in section, section
    assert ">None" not in html and "None<" not in html
    runs_at = html.index("<section id='runs'>")
    runs = html[runs_at:html.index("</section>", runs_at)]
    assert "<td>-</td>" not in runs and "does not turn over within" in runs
    # the JSON beside it keeps null where there is no number
    res = json.loads((paper_top[1] / "results.json").read_text())
    assert res["runs"]["mujoco/file"]["t_invert"] is None
    assert any(c["value"] is None for c in res["verdict"] if c["check"] == "t_invert")


def test_validate_on_a_mu_1_file_says_its_mu_and_the_units() -> None:
    r = tippetop("validate", str(MU1), "--no-tune", "--t-end-s", "2")
    assert r.returncode == 1, r.stderr
    out = r.stdout
    assert "None" not in out, out
    assert "mu = 1," in out.splitlines()[0]  # not Python's 1.0
    # the calibrated mu (at the paper's 0.1) scaled to the file's 1, read from the shipped file
    from tippetop.models.calibrated import CALIBRATION_MU, calibrated_native_settings

    scaled = f"{float(calibrated_native_settings()['mu']) / CALIBRATION_MU:.3g}"
    assert f"the file's mu = {scaled}" not in out
    assert f"scaled to the file's mu = 1, which gives MuJoCo's contact mu = {scaled}" in out, out
    for (mode, check), value in _departs(out).items():
        unit = {"t_invert": " s ", "t_stem": " s ", "jellett_before_stem": "(relative)",
                "energy_never_rises": "of E0"}.get(check)
        if unit is not None and re.search(r"\d", value):
            assert unit in f"{value} ", (mode, check, value)
    assert re.search(r"timestep_s 0\.002 s -> 0\.0002 s", out), out


# ---------------------------------------------------------------- compare, matrix, the MuJoCo run
#: A realised law as MuJoCo's native friction gives it on Fig. 3 (the digits beyond the fourth
#: are there to be rounded away).
_FR = {"samples": 4012, "mu_fit": 0.0944612, "Lambda_fit_mps": 0.0101634,
       "residual": 0.0053121, "half_mu_slip_mps": 0.00552341,
       "law_half_mu_slip_mps": 0.01 / 3 ** 0.5, "angle_rms_rad": 0.167991,
       "creep_fraction": 0.842156}
#: What the realised law's and the refit's sentences put after a number, besides simulate's.
_SENTENCE_UNIT = re.compile(_UNIT.pattern + r"|^mm(?![\w/^])|^relative\b")


def _bare_numbers(text: str) -> list[str]:
    """The numbers in a sentence that no unit follows (a ``mu`` is a coefficient)."""
    text = re.sub(r"\bmu \d[\d.e-]*", "mu", text)
    return [m.group() for m in _NUMBER.finditer(text)
            if not _SENTENCE_UNIT.match(text[m.end():].lstrip())]


def _four_digits(text: str) -> list[str]:
    """The numbers in ``text`` with more than four significant digits (none may have)."""
    return [m.group() for m in _NUMBER.finditer(text)
            if len(m.group().split("e")[0].lstrip("+-0.").replace(".", "")) > 4]


def _block(out: str, head: str) -> str:
    """The paragraph under ``head`` as one line (the terminal wraps it at any column)."""
    lines = out.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(head))
    block = []
    for line in lines[i + 1:]:
        if not line.strip():
            break
        block.append(line)
    return " ".join(" ".join(block).split())


def _refit_fr() -> dict[str, Any]:
    from tippetop.compare.studies.refit import refit_result

    ev = {"t_invert": 2.39612, "t_stem": None, "theta_asymp": 3.1041}
    ref = {**ev, "t_invert": 2.32912}
    refit = {**ev, "t_invert": 2.71234}
    ran = {"max_penetration_m": 2.74412e-7, "J_rel_drift": 1.4321e-6, "integrator": "RK4",
           "timestep_s": 2e-4}
    return {**_FR, "refit": refit_result(_FR, ev, ref, refit, ran)}


def test_compare_says_the_realised_law_and_its_refit_in_four_digits_and_units(
        capsys: pytest.CaptureFixture[str]) -> None:
    """``tippetop compare``'s friction block said "5.52 mm/s", "Lambda 10.2 mm/s", a bare
    "residual 0.0053", "turns over at 2.45 s" and "Jellett's drift (1.4e-06:"."""
    from tippetop.compare.presentation.crossval import print_compare
    from tippetop.compare.results.crossval import CompareResult

    print_compare(CompareResult.from_json({
        "scene": "fig3", "group": "II", "theory": {"outcome": "inverted", "theta_s": 3.14159},
        "runs": [{"run": "ode/paper", "engine": "ode", "reference": True,
                  "outcome": "inverted", "t_invert": 2.32912},
                 {"run": "mujoco/native", "engine": "mujoco", "outcome": "inverted",
                  "t_invert": 2.39612, "friction_realised": _refit_fr()}]}))
    block = _block(capsys.readouterr().out, "the friction law as each run realises it")
    assert block.startswith("mujoco/native the contact reaches half of mu N at a slip of "
                            "5.523 mm/s, the paper's law at 5.774 mm/s (fit: mu 0.09446, "
                            "Lambda 10.16 mm/s, residual 0.0053 of |F_t|/N, RMS;"), block
    assert "refit: the reference with the realised law (mu 0.09446, Lambda 10.16 mm/s) turns " \
           "over at 2.712 s, the engine turns over at 2.396 s" in block, block
    assert "Jellett's drift (1.4e-6 relative)" in block and "dt = 2e-4 s" in block, block
    assert _bare_numbers(block) == [] and _four_digits(block) == [], block


def test_matrix_says_the_realised_law_in_four_digits_and_units(
        capsys: pytest.CaptureFixture[str]) -> None:
    from tippetop.compare.presentation.matrix import print_matrix
    from tippetop.compare.results.matrix import MatrixEngine, MatrixResult, MatrixRun

    run = MatrixRun("fig3", "mujoco", "native", "mujoco/native", "ok", agrees=True,
                    friction_realised=_FR)
    print_matrix(MatrixResult((MatrixEngine("mujoco", "mujoco", "4.0.0", "float64", "cpu"),),
                              (run,), (), False, {}, ("native",), ("fig3",), {}))
    block = _block(capsys.readouterr().out, "the friction law as each engine realises it")
    assert block.startswith("fig3 native mujoco: the contact reaches half of mu N at a slip "
                            "of 5.523 mm/s"), block
    assert "creeping 84.22 % of the time" in block, block
    assert _bare_numbers(block) == [] and _four_digits(block) == [], block


def test_the_mujoco_runs_message_has_four_digits_and_units() -> None:
    """It said "50000 steps of RK4 at dt = 2e-05 s to t = 1 s in 1.08 s"."""
    r = tippetop("simulate", "fig3", "--engine", "mujoco", "--set", "run.t_end_s=0.05",
                 "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    m = re.fullmatch(r"paper mode: 2,500 steps of RK4 at dt = 2e-5 s to t = 0\.05 s in (\S+) s",
                     d["message"])
    assert m, d["message"]
    # the wall time the summary keeps, to four significant digits
    assert float(m.group(1)) == float(f"{d['wall_s']:.4g}"), (d["message"], d["wall_s"])
    assert _four_digits(d["message"]) == [], d["message"]


def test_what_ran_says_its_units() -> None:
    from tippetop.compare.measures.summary import describe_ran

    native = {"engine": "mujoco", "mode": "native", "integrator": "RK4", "timestep_s": 2e-4,
              "cone": "pyramidal", "condim": 3, "mu": 0.104, "torsional": 0.0, "rolling": 0.0,
              "impratio": 1.41, "solref": [0.002, 1.0], "solimp": [0.05, 0.95, 0.001, 0.5, 2]}
    text = describe_ran(native)
    assert text == ("MuJoCo RK4 at dt = 2e-4 s, native friction: pyramidal cone, condim 3, "
                    "mu 0.104, torsional 0, rolling 0, impratio 1.41, solref [0.002 s, 1], "
                    "solimp [0.05, 0.95, 0.001 m, 0.5, 2]")
    # MuJoCo's direct form (negative solref: stiffness and damping) has no time constant
    assert "solref [-1000, -10]" in describe_ran({**native, "solref": [-1000.0, -10.0]})


def test_what_ran_names_the_reference_method_that_ran() -> None:
    # the line reads the method back from the run's summary: a stem top's reference runs the
    # Adams method under ode.method = auto, a ball on the table the Taylor method; the line
    # said "DOP853" for both before (validate's report of 2026-11-29)
    from tippetop.compare.measures.summary import describe_ran
    from tippetop.compare.running.engines import plan_for
    from tippetop.models.scene import load_scene

    for sets, method in (([], "taylor (order 12)"), (["effects.stem=true"], "adams"),
                         (["ode.method=dop853"], "dop853")):
        ran = plan_for(load_scene("fig3", sets), "ode").ode.what_runs()
        summary = {"engine": "ode", **ran}
        text = describe_ran(summary)
        assert text.startswith(f"reference ODE, {method} on the vector formulation at rtol "), \
            text


def test_the_method_row_names_every_method_and_the_default() -> None:
    # the glossary's `method` row is made from the declarations (issue 43: it listed dop853,
    # vern9 and adams, not taylor, which simulate and plan run by default on a ball)
    from tippetop.compare.measures.summary import RAN_FIELDS
    from tippetop.models.options import AUTO_RULE, AUTO_TAYLOR, ODE_METHODS

    meaning = RAN_FIELDS["method"].meaning
    for method in ODE_METHODS[1:]:
        assert f"{method}: " in meaning, method
    assert f"The default, auto, runs {AUTO_TAYLOR[0]} at {AUTO_TAYLOR[1]:g} x the rtol" in meaning
    for _, name, _ in AUTO_RULE:
        assert f"{name} " in meaning.split("elsewhere")[1]
