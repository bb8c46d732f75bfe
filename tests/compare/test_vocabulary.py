"""Two nouns: ``--engine(s)`` take engines only, ``--mode(s)`` modes only, in every command.

And what the release before wrote or took still works: its compound names run with one note on
stderr, its plans (``tippetop-plan/1``), stored baselines (format 1) and cache entries read as
today's. The files of the release before are in ``tests/data/before`` (written by tippetop at
commit f673299; see its README) and ``tests/data/baselines/quick-format1.json``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tippetop.compare.cli import build_parser
from tippetop.compare.measures.summary import RunSummary
from tippetop.compare.nightly.baselines import load_baseline
from tippetop.compare.nightly.catalogue import load_catalogue, select_cases
from tippetop.compare.running.cache import ResultCache
from tippetop.models.modes import MODES
from tippetop.models.plan import RunPlan

DATA = Path(__file__).resolve().parents[1] / "data"
BEFORE = DATA / "before"


def _tippetop(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, timeout=600, cwd=cwd)


def _options() -> dict[str, dict[str, argparse.Action]]:
    """command -> option -> action, for the engine and mode options of every command."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {o: a for a in sp._actions for o in a.option_strings
                   if o in ("--engine", "--engines", "--mode", "--modes", "--on")}
            for name, sp in sub.choices.items()}


def test_every_engine_option_names_engines_and_every_mode_option_modes() -> None:
    seen = set()
    for command, opts in _options().items():
        for option, action in opts.items():
            seen.add(option)
            if option == "--on":  # the release before's --engine: read with a note, unlisted
                assert action.help == argparse.SUPPRESS, command
                continue
            text = action.help or ""
            if option.startswith("--engine"):
                assert "mujoco" in text and "engine" in text.lower(), (command, option, text)
            else:
                assert "paper" in text and "mode" in text.lower(), (command, option, text)
                assert "mujoco==" not in text, (command, option)
    assert seen == {"--engine", "--engines", "--mode", "--modes", "--on"}


# each command with its engine or mode option, given the other noun: one line, exit 2
CASES = [
    (["simulate", "fig3", "--engine", "native"], "engine"),
    (["simulate", "fig3", "--mode", "mjx"], "mode"),
    (["plan", "fig3", "--engine", "paper"], "engine"),
    (["plan", "fig3", "--mode", "warp"], "mode"),
    (["threshold", "fig11_n060", "--which", "n1", "--engine", "native"], "engine"),
    (["threshold", "fig11_n060", "--which", "n1", "--mode", "mjx"], "mode"),
    (["mjcf", "fig3", "--engine", "native"], "engine"),
    (["mjcf", "fig3", "--mode", "mujoco==3.3.7"], "mode"),
    (["compare", "fig3", "--engines", "native"], "engine"),
    (["compare", "fig3", "--modes", "mjx"], "mode"),
    (["sweep", "fig3", "--n0", "40:60:10", "--engines", "paper"], "engine"),
    (["sweep", "fig3", "--n0", "40:60:10", "--modes", "warp"], "mode"),
    (["matrix", "fig3", "--engines", "native"], "engine"),
    (["matrix", "fig3", "--engines", "mujoco", "--modes", "mjx"], "mode"),
    (["atlas", "--engines", "native-elliptic"], "engine"),
    (["atlas", "--modes", "mjx"], "mode"),
    (["nightly", "--engines", "native"], "engine"),
    (["nightly", "--modes", "mjx"], "mode"),
    (["render", "fig3", "--engine", "native"], "engine"),
    (["render", "fig3", "--mode", "mjx"], "mode"),
    (["validate", "examples/paper_loaded_sphere.xml", "--engines", "native"], "engine"),
]


@pytest.mark.parametrize(("args", "noun"), CASES, ids=[" ".join(c[0][:1] + c[0][-2:])
                                                        for c in CASES])
def test_the_other_noun_is_one_line_and_exit_2(args: list[str], noun: str,
                                                tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[2]
    args = [str(root / a) if a.endswith(".xml") else a for a in args]
    if args[0] in ("nightly", "render", "atlas"):
        args += ["--out", str(tmp_path / ("out.mp4" if args[0] == "render" else "out"))]
    proc = _tippetop(*args, cwd=tmp_path)
    assert proc.returncode == 2, (args, proc.stderr)
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("tippetop: note:")]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith("tippetop: error:") and "expected" in lines[0], lines[0]
    word = "engine" if noun == "engine" else "mode"
    assert word in lines[0].lower(), lines[0]
    assert proc.stdout == "" and not (tmp_path / "out").exists()


# ---------------------------------------------------------------- the release before's words
@pytest.mark.parametrize(("args", "new"), [
    (["simulate", "fig3", "--engine", "mujoco-native", "--set", "run.t_end_s=0.05"],
     "--engine mujoco --mode native"),
    (["simulate", "fig3", "--engine", "mujoco", "--on", "mujoco", "--set", "run.t_end_s=0.05"],
     "--engine mujoco"),
    (["plan", "fig3", "--engine", "ode-coulomb"], "--engine ode --mode coulomb"),
    (["compare", "fig3", "--modes", "ode,mujoco-paper", "--set", "run.t_end_s=0.05"],
     "--engines ode,mujoco --modes paper"),
])
def test_old_spellings_run_with_one_note(args: list[str], new: str, tmp_path: Path) -> None:
    proc = _tippetop(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    notes = [ln for ln in proc.stderr.splitlines() if ln.startswith("tippetop: note:")]
    assert len(notes) == 1 and new in notes[0], proc.stderr
    assert "next release" in notes[0]


def test_an_old_catalogue_reads_with_one_note(tmp_path: Path, capsys: pytest.CaptureFixture
                                              ) -> None:
    cat = tmp_path / "old.toml"
    cat.write_text('[profiles.tiny]\ndescription = "x"\n\n[[case]]\nname = "fig3"\n'
                   'category = "paper"\nkind = "run"\nscene = "fig3"\n'
                   'modes = ["ode", "mujoco-native"]\nprofiles = ["tiny"]\n'
                   'metrics = ["outcome"]\n')
    cases = select_cases(load_catalogue(cat), "tiny")
    assert {c.id for c in cases} == {"paper/fig3[ode/paper]", "paper/fig3[mujoco/native]"}
    err = capsys.readouterr().err
    assert err.count("tippetop: note:") == 1 and "engines = [...]" in err


@pytest.mark.parametrize("name", ["plan1-native.json", "plan1-ode.json"])
def test_a_plan_of_the_release_before_reads_and_runs(name: str, tmp_path: Path) -> None:
    old = json.loads((BEFORE / name).read_text())
    assert old["format"] == "tippetop-plan/1"
    plan = RunPlan.from_json(json.dumps(old))
    want = ("mujoco", "native") if "native" in name else ("ode", "paper")
    assert (plan.engine, plan.mode) == want
    assert json.loads(plan.to_json())["format"] == "tippetop-plan/2"
    # and simulate runs it (shortened: the plan's own 8 s are not needed to show it runs)
    short = dict(old)
    part = "mujoco" if plan.engine == "mujoco" else "ode"
    short[part] = {**old[part], "t_end_s": 0.05}
    path = tmp_path / name
    path.write_text(json.dumps(short))
    proc = _tippetop("simulate", "--plan", str(path), "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert (out["engine"], out["mode"]) == want and out["status"] == "ok"


def test_a_baseline_of_the_release_before_reads_with_todays_ids() -> None:
    old = json.loads((DATA / "baselines" / "quick-format1.json").read_text())
    assert old.get("format", "tippetop-baseline/1").endswith("/1")
    assert any("[mujoco-native]" in k for k in old["cases"])
    cases = load_baseline(DATA / "baselines" / "quick-format1.json")
    quick = {c.id for c in select_cases(load_catalogue(), "quick")}
    assert set(cases) <= quick | {k for k in cases if k not in quick and "[" in k}
    assert "paper/fig3[mujoco/native]" in cases and "paper/fig3[ode/paper]" in cases
    # the values came along, under the new ids
    assert cases["paper/fig3[mujoco/native]"] == old["cases"]["paper/fig3[mujoco-native]"]


def test_a_cache_entry_of_the_release_before_reads_as_todays(tmp_path: Path) -> None:
    root = tmp_path / "cache"
    shutil.copytree(BEFORE / "cache", root)
    cache = ResultCache(root)
    native = cache.get("b006a5c213615da9dcef9dea")
    assert native is not None
    summary, table = native
    assert isinstance(summary, RunSummary) and len(table) > 100
    assert (summary.engine, summary.mode) == ("mujoco", "native")
    assert summary["friction_law"] == "mujoco_contact" and "engine_spec" not in summary
    ode = cache.get("4a41d31dd19788155497153a")
    assert ode is not None and (ode[0].engine, ode[0].mode) == ("ode", "paper")
    assert ode[0].rolling_phases is not None and "rolling" not in ode[0]


def test_every_mode_says_which_engines_run_it() -> None:
    for m in MODES.values():
        assert set(m.families) <= {"ode", "mujoco"} and m.families and len(m.meaning) > 20


@pytest.mark.slow
def test_a_plan_with_a_release_runs_on_that_release(tmp_path: Path) -> None:
    """``tippetop plan fig3 --engine mujoco==3.17.0 --mode native --json``, then ``simulate
    --plan``: the run reports the release it ran on, read back from that MuJoCo."""
    proc = _tippetop("plan", "fig3", "--engine", "mujoco==3.17.0", "--mode", "native",
                     "--set", "run.t_end_s=0.2", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    plan = json.loads(proc.stdout)
    assert plan["format"] == "tippetop-plan/2" and plan["engine"] == "mujoco==3.17.0"
    path = tmp_path / "plan.json"
    path.write_text(proc.stdout)
    run = _tippetop("simulate", "--plan", str(path), "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["engine"] == "mujoco==3.17.0" and out["version"] == "3.17.0"
    assert out["mode"] == "native" and out["status"] == "ok"
