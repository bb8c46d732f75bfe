"""The command line explains itself: every option's help, ``--version``, the top-level help, and
human output with units and no ``None``, ``nan`` or 16-digit floats."""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pandas as pd
import pytest

from tippetop.compare.cli import build_parser
from tippetop.compare.commands.options import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_RUN_FAILED,
    EXIT_STATUSES,
    EXIT_TERMINATED,
)
from tippetop.compare.presentation.crossval import print_compare
from tippetop.compare.presentation.sweep import print_sweep
from tippetop.compare.presentation.threshold import print_threshold
from tippetop.compare.results.crossval import CompareResult
from tippetop.compare.results.sweep import SweepResult
from tippetop.compare.results.threshold import ThresholdResult
from tippetop.models.modes import MODES
from tippetop.models.scene import catalogue_names, load_scene


def tippetop(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    raise AssertionError("no subcommands")


def _options() -> list[tuple[str, argparse.Action]]:
    out = []
    for name, sub in _subparsers(build_parser()).items():
        for action in sub._actions:
            if isinstance(action, (argparse._HelpAction, argparse._VersionAction)):
                continue
            if action.help is argparse.SUPPRESS:  # the release before's spelling, hidden
                continue
            out.append((f"{name} {'/'.join(action.option_strings) or action.dest}", action))
    return out


OPTIONS = _options()
#: Words that give a numeric option's unit (or say that it is a count or a ratio).
UNIT_WORDS = ("(s;", "(s)", "(m;", "(kg;", "(m/s^2;", "rad/s", " px", "frames", "runs",
              "processes", "relative", "a/R", "A/C", "C = ", "seconds")


def _default_texts(default: object) -> set[str]:
    texts = {str(default)}
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        texts.add(f"{default:g}")
        texts.add(re.sub(r"e([+-])0*(\d)", lambda m: f"e{m[1].lstrip('+')}{m[2]}",
                         f"{default:g}"))  # 1e-09 -> 1e-9
    if isinstance(default, str) and "/" in default:
        texts.add("/".join(Path(default).parts[-2:]))
    return texts


def test_the_walk_finds_every_subcommand_and_option() -> None:
    names = {n.split()[0] for n, _ in OPTIONS}
    assert names >= {"theory", "simulate", "compare", "threshold", "sweep", "bench", "nightly",
                     "calibrate", "render", "validate", "mjcf"}
    assert len(OPTIONS) > 80


@pytest.mark.parametrize(("name", "action"), OPTIONS, ids=[n for n, _ in OPTIONS])
def test_every_option_says_what_it_does_and_its_default(name: str,
                                                        action: argparse.Action) -> None:
    """Help text on every option; an option that takes a value says its default (or that it is
    required), and shows the default's value where it has one."""
    text = " ".join((action.help or "").split())
    assert len(text) >= 15, f"{name}: help {text!r}"
    if action.nargs == 0:  # a flag: off unless given
        return
    if action.required:  # a positional one shows as such in the usage line
        assert "required" in text or not action.option_strings, f"{name}: required, unsaid"
        return
    assert "default" in text, f"{name}: no default in {text!r}"
    if action.default is not None and action.default is not argparse.SUPPRESS:
        assert any(t in text for t in _default_texts(action.default)), \
            f"{name}: default {action.default!r} not shown in {text!r}"


@pytest.mark.parametrize(("name", "action"), OPTIONS, ids=[n for n, _ in OPTIONS])
def test_every_numeric_option_gives_its_unit(name: str, action: argparse.Action) -> None:
    numeric = action.type in (float, int) or getattr(action.type, "__name__", "") in (
        "finite_float", "number", "worker_count")
    text = " ".join((action.help or "").split())
    if numeric:
        assert any(w in text for w in UNIT_WORDS), f"{name}: no unit in {text!r}"
    if action.dest.endswith("_s") and action.dest != "n_runs":
        assert "s;" in text or "(s)" in text or "seconds" in text, f"{name}: {text!r}"


def test_version_is_the_installed_one() -> None:
    r = tippetop("--version")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"tippetop {metadata.version('tippetop')} ")
    assert f"MuJoCo {metadata.version('mujoco')}" in r.stdout


def test_top_level_help_lists_scenes_modes_exit_codes_and_the_cache_variable() -> None:
    r = tippetop("--help")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    for name in catalogue_names():
        assert re.search(rf"^  {re.escape(name)}\s+\S", out, re.M), f"scene {name} not listed"
    flat = " ".join(out.split())
    for mode in MODES:
        assert mode in flat
    assert "TIPPETOP_CACHE" in out and "~/.cache/tippetop" in out
    block = out[out.index("exit status:"):]
    for code in EXIT_STATUSES:
        assert re.search(rf"^  {code}\s+\S", block, re.M), f"exit status {code} not listed"
    for word in ("threshold", "calibrate", "validate"):  # each command on one line with help
        assert re.search(rf"^    {word}\s+\S", out, re.M)


def test_the_exit_codes_listed_are_the_ones_used() -> None:
    """0 ok, 1 a failed run or regression, 2 bad input, 130 interrupted: the help reads them
    from the constants the commands return."""
    assert (EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED,
            EXIT_TERMINATED) == (0, 1, 2, 130, 143)
    assert set(EXIT_STATUSES) == {0, 1, 2, 130, 143}
    assert tippetop("simulate", "--set", "init.n0=nan").returncode == EXIT_BAD_INPUT


# ---------------------------------------------------------------- human output
_LONG_FLOAT = re.compile(r"\d\.\d{6,}")


def _assert_readable(text: str) -> None:
    assert "None" not in text and not re.search(r"\bnan\b", text), text
    assert not _LONG_FLOAT.search(text), _LONG_FLOAT.search(text)


def test_simulate_and_theory_print_units_and_no_raw_values() -> None:
    r = tippetop("simulate", "fig3", "--set", "run.t_end_s=3")
    assert r.returncode == 0, r.stderr
    _assert_readable(r.stdout)
    assert re.search(r"^t_invert\s+2\.329 s$", r.stdout, re.M)
    assert re.search(r"^theta_asymp\s+\d\.\d+ rad$", r.stdout, re.M)
    assert re.search(r"^t_stem\s+never", r.stdout, re.M)
    assert "what ran:" in r.stdout
    r = tippetop("theory", "--A-over-C", "1.25", "--a-over-R", "0.15", "--n0", "60")
    assert r.returncode == 0, r.stderr
    _assert_readable(r.stdout)
    assert re.search(r"^n1\s+\d+\.\d+ rad/s", r.stdout, re.M)
    assert re.search(r"^nc\s+-\s", r.stdout, re.M)


def _compare_result() -> dict:
    mode = {"engine": "mujoco", "mode": "native", "run": "mujoco/native",
            "theta_asymp": 2.278123456789, "t_invert": 2.4960000001,
            "J_rel_drift": 6.9e-6, "outcome": "inverted", "matches_theory": True,
            "theta_rms_vs_ref": 0.06458, "energy_dissipated_J": 0.0017, "note": "because",
            "timestep_s": 2e-4, "integrator": "RK4"}
    return {
        "scene": "fig3", "group": "II", "reference": "ode/paper",
        "theory": {"theta_s": math.pi, "outcome": "inverted", "theta_s_tol": 0.05},
        "runs": [{"engine": "ode", "mode": "paper", "run": "ode/paper", "reference": True,
                  "theta_asymp": 3.1041, "t_invert": 2.329259,
                  "J_rel_drift": 1.3e-9, "outcome": "inverted", "matches_theory": True,
                  "theta_rms_vs_ref": 0.0, "energy_dissipated_J": math.nan},
                 mode,
                 {"run": "mujoco/native-x", "outcome": "failed", "matches_theory": False}],
        "crossval": [{"run": "mujoco/native-x", "agrees": False,
                      "reasons": ["the run failed: boom"]}],
        "differences": [
            {"run": "mujoco/native", "metric": "t_invert", "value": 2.4960000001,
             "reference": 2.329259, "tolerance": 0.1},
            {"run": "mujoco/native", "metric": "J_rel_drift", "value": 6.9e-6,
             "reference": 1.3e-9, "tolerance": 1e-6, "why": "relative; J is exact"},
            {"run": "mujoco/native-x", "metric": "status", "value": "diverged",
             "reference": "ok", "tolerance": None, "note": "energy rose"},
            {"run": "mujoco/native", "metric": "t_invert", "value": None,
             "reference": 2.329259, "tolerance": None},
        ],
        "tolerances": {"t_invert": 0.1},
    }


def test_compare_names_the_tolerance_each_difference_broke(
        capsys: pytest.CaptureFixture) -> None:
    print_compare(CompareResult.from_json(_compare_result()))
    out = capsys.readouterr().out
    _assert_readable(out)
    flat = " ".join(out.split())
    assert ("t_invert 2.496 s against the reference's 2.329 s: 0.1667 s apart, over the "
            "t_invert tolerance of 0.1 s (") in flat
    assert "over the J_rel_drift limit of 1e-6 (J is exact)" in flat
    assert "the run failed (energy rose)" in flat
    assert "never turns over; the reference does at 2.329 s" in flat
    assert "undefined (NaN)" in out  # the NaN energy is said, not hidden
    assert "within 0.05 rad of theta_s" in flat


def test_compare_output_copes_with_missing_keys(capsys: pytest.CaptureFixture) -> None:
    print_compare(CompareResult.from_json({"runs": [{"run": "ode/paper"}],
                                           "differences": [{"metric": "theta_asymp"}]}))
    out = capsys.readouterr().out
    assert "None" not in out and "theta_asymp" in out


def test_threshold_prints_units_a_percentage_and_the_horizon_check(
        capsys: pytest.CaptureFixture) -> None:
    print_threshold(ThresholdResult.from_json({
        "which": "n1", "engine": "ode", "scene": "fig11_n060", "measured": 34.63857,
        "theory": 34.352341016782724, "rel_diff": 0.0083333, "bracket": [34.35234, 34.92488],
        "runs": [{}] * 8, "n_runs": 8, "horizon_s": 60.0, "bracket_converged": True,
        "horizon_check": {"horizon_s": 120.0, "depends_on_horizon": True},
        "depends_on_horizon": True, "warning": "the answer depends on the run length",
        "converged": False}))
    out = capsys.readouterr().out
    _assert_readable(out)
    assert "34.64 rad/s" in out and "34.35 rad/s" in out and "+0.833 %" in out
    assert "over 120 s the bracket's ends change side" in out
    assert "converged: no (the answer depends on the run length)" in out
    assert "warning: the answer depends" in out


def test_threshold_by_growth_rates_says_so(capsys: pytest.CaptureFixture) -> None:
    print_threshold(ThresholdResult.from_json({
        "which": "nc", "engine": "ode", "scene": "fig6", "method": "growth",
        "measured": 54.3431234, "theory": 54.341, "rel_diff": 3.81e-5,
        "bracket": [54.3431, 54.87], "runs": [{}] * 16, "n_runs": 16, "horizon_s": 2.0,
        "settled": False, "converged": False, "n1": 36.3812, "n3": 40.2, "n4": 54.3431}))
    out = capsys.readouterr().out
    _assert_readable(out)
    assert "from growth rates of 16 runs of 2 s" in out and "bisection" not in out
    assert re.search(r"^  n1\s+36\.38 rad/s", out, re.M) and "+0.00381 %" in out
    assert "converged: no (a fit is not clean)" in out


def test_sweep_prints_theta_s_beside_each_point(capsys: pytest.CaptureFixture) -> None:
    table = pd.DataFrame({"run": ["ode/paper", "ode/paper"], "n0": [40.0, 60.0],
                          "theta_asymp": [0.0123456789, 1.45342], "outcome": ["upright", "x"],
                          "t_invert": [None, 3.2], "J_rel_drift": [1e-9, math.nan],
                          "status": ["ok", "ok"], "cached": [True, False]})
    theory = pd.DataFrame({"n0": [40.0, 60.0], "theta_s": [0.0, 1.5]})
    print_sweep(SweepResult(table, theory, load_scene("fig3").top, "s", 1, 1))
    out = capsys.readouterr().out
    assert "None" not in out and not _LONG_FLOAT.search(out)
    assert re.search(r"ode/paper\s+60 rad/s\s+1\.453 rad\s+1\.5 rad", out)
    assert "never" in out and "cache" in out


def test_threshold_and_sweep_say_where_their_files_went(tmp_path: Path) -> None:
    """``--out`` folders: the files are there and the last lines name them."""
    out = tmp_path / "th"
    r = tippetop("threshold", "--which", "n1", "--rel-tol", "0.05", "--workers", "1",
                 "--no-cache", "--out", str(out))
    assert r.returncode == 0, r.stderr
    res = json.loads((out / "threshold.json").read_text())
    assert res["which"] == "n1"
    runs = pd.read_csv(out / "runs.csv")
    assert len(runs) == res["n_runs"] >= 2 and {"n0", "crossed"} <= set(runs.columns)
    assert f"wrote {out / 'threshold.json'}, {out / 'runs.csv'}" in r.stdout
    assert "the cache was not used" in r.stdout
    _assert_readable(r.stdout)
    again = tippetop("threshold", "--which", "n1", "--out", str(out))
    assert again.returncode == 2 and "--force" in again.stderr
    sw = tmp_path / "sw"
    r = tippetop("sweep", "fig11_n060", "--n0", "40:50:10", "--set", "run.t_end_s=5",
                 "--workers", "1", "--no-cache", "--out", str(sw))
    assert r.returncode == 0, r.stderr
    assert f"wrote {sw / 'sweep.csv'}, {sw / 'theory.csv'}, {sw / 'sweep.png'}" in r.stdout
    assert all((sw / f).is_file() for f in ("sweep.csv", "theory.csv", "sweep.png"))
    assert "2 computed, 0 from the cache" in r.stdout
    _assert_readable(r.stdout)
