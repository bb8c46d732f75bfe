"""The command-line contract: JSON keys, exit codes, one-line errors, safe outputs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from tippetop.models.observables import COLUMNS
from tippetop.models.scene import load_scene
from tippetop.reference_ode.solve import simulate_ode

THEORY_KEYS = {"group", "n1", "n2", "n3", "n4", "nc", "rc", "theta_c", "theta_f", "theta_d"}
SIMULATE_KEYS = {"engine", "theta_final", "theta_asymp", "t_invert", "J_rel_drift",
                 "energy_monotone", "contact_lost", "wall_s", "n_rhs"}


def tippetop(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


def test_theory_json() -> None:
    r = tippetop("theory", "--A-over-C", "0.95", "--a-over-R", "0.125", "--n0", "47", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert set(d) == THEORY_KEYS | {"theta_s"}
    assert d["group"] == "II"
    assert d["n1"] == pytest.approx(45.7, abs=0.05) and d["n4"] == pytest.approx(49.4, abs=0.05)
    assert d["theta_c"] is None and d["theta_f"] is None
    assert d["theta_d"] == pytest.approx(1.89, abs=0.005)
    assert d["theta_d"] < d["theta_s"] < 3.1416


def test_theory_without_n0_has_no_theta_s() -> None:
    d = json.loads(tippetop("theory", "--A-over-C", "1.25", "--a-over-R", "0.15",
                            "--C-factor", "0.8", "--json").stdout)
    assert set(d) == THEORY_KEYS
    assert d["group"] == "III" and d["theta_f"] == pytest.approx(2.21, abs=0.005)
    assert d["n3"] is None and d["n4"] is None and d["nc"] is None


def test_simulate_default_json(tmp_path: Path) -> None:
    """The default scene (the paper's eq. 3.10 top, the Fig. 3 start) through the command line.

    Its inversion time is checked against the paper's own equations (Appendix A, the paper
    formulation) run in-process: the two formulations integrate the same mechanics and agree
    to 1e-9 s at the default rtol 1e-9 (measured 9.9e-10 s), so 1e-8 s. The command must also
    print exactly what an in-process run of the same scene gives (the JSON float round-trips).
    """
    out = tmp_path / "run.csv"
    r = tippetop("simulate", "--engine", "ode", "--set", "run.t_end_s=4", "--out", str(out),
                 "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert SIMULATE_KEYS <= set(d)
    assert d["contact_lost"] is False and d["energy_monotone"] is True
    scene = load_scene(None, ["run.t_end_s=4"])
    same = simulate_ode(scene.top, scene.friction, scene.init, t_end_s=4.0, options=scene.ode)
    assert d["t_invert"] == same.t_invert
    assert d["theta_final"] == float(same.table["theta"].iloc[-1])
    paper = load_scene(None, ["run.t_end_s=4", "ode.formulation=paper"])
    other = simulate_ode(paper.top, paper.friction, paper.init, t_end_s=4.0, options=paper.ode)
    assert other.status == "ok"
    assert abs(d["t_invert"] - other.t_invert) < 1e-8
    table = pd.read_csv(out)
    assert list(table.columns[: len(COLUMNS)]) == list(COLUMNS)
    assert table["t"].iloc[-1] == pytest.approx(4.0)


def test_simulate_parquet_and_no_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "run.parquet"
    assert tippetop("simulate", "fig7b", "--set", "run.t_end_s=0.5", "--out", str(out),
                    "--json").returncode == 0
    before = out.read_bytes()
    r = tippetop("simulate", "fig7b", "--set", "run.t_end_s=0.2", "--out", str(out), "--json")
    assert r.returncode == 2 and "--force" in r.stderr
    assert out.read_bytes() == before
    r = tippetop("simulate", "fig7b", "--set", "run.t_end_s=0.2", "--out", str(out), "--force",
                 "--json")
    assert r.returncode == 0
    assert pd.read_parquet(out)["t"].iloc[-1] == pytest.approx(0.2)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["simulate", "--set", "top.M_kg=-1"], "top.M_kg"),
        (["simulate", "--set", "top.a_over_R=1.2"], "a/R"),
        (["simulate", "--set", "top.A_over_C=0.3"], "top.A_over_C"),
        (["simulate", "--set", "friction.law=sticky"], "friction.law"),
        (["simulate", "--set", "friction.Lambda_mps=0"], "friction.Lambda_mps"),
        (["simulate", "--set", "init.n0=nan"], "init.n0"),
        (["simulate", "--set", "top.colour=3"], "top.colour"),
        (["simulate", "--engine", "bullet"], "--engine"),
        (["simulate", "--engine", "native"], "which is a mode: give --mode native"),
        (["simulate", "--mode", "mujoco"], "which is an engine: give --engine mujoco"),
        (["simulate", "--engine", "mjy"], "--engine: expected ode, mujoco, mujoco==X.Y.Z"),
        (["simulate", "--engine", "mujoco==3.x"], "expected mujoco==X.Y.Z with a release"),
        (["simulate", "--engine", "ode", "--mode", "native", "--out", "t.csv"],
         "expected a mode the reference ODE runs"),
        (["simulate", "--engine", "mjx", "--mode", "coulomb", "--out", "t.csv"],
         "expected a mode a MuJoCo engine runs"),
        (["simulate", "--engine", "mujoco@/no/such/python"], "expected the path of a Python"),
        (["threshold", "--which", "n1", "--engine", "mujoco", "--mode", "viscous"],
         "'viscous' is a law of the reference's, run on the reference ODE only"),
        (["threshold", "--which", "n1", "--engine", "mujoco=3"],
         "argument --engine: expected ode, mujoco"),
        (["simulate", "no_such_scene"], "no_such_scene"),
        (["simulate", "--set", "ode.formulation=paper", "--set", "init.theta0=0"], "singular"),
        (["simulate", "--out", "x.txt"], ".csv or .parquet"),
        (["theory", "--A-over-C", "abc", "--a-over-R", "0.1"], "--A-over-C"),
        (["theory", "--A-over-C", "1.0", "--a-over-R", "1.5"], "a/R"),
        (["frobnicate"], "frobnicate"),
    ],
)
def test_bad_input_is_one_line_exit_2(args: list[str], fragment: str, tmp_path: Path) -> None:
    r = tippetop(*args, cwd=tmp_path)
    assert r.returncode == 2
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert fragment in lines[0] and "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []  # no partial output


def test_failed_run_leaves_no_output(tmp_path: Path) -> None:
    """A run that fails on bad input after --out was accepted writes nothing."""
    out = tmp_path / "t.csv"
    r = tippetop("simulate", "--set", "ode.formulation=paper", "--set", "init.theta0=0",
                 "--out", str(out))
    assert r.returncode == 2 and not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_theory_and_simulate_for_an_mjcf_top(tmp_path: Path) -> None:
    """A loaded MJCF top: the theory keys plus its derived parameters, and a run in each engine
    (the ODE on the parameters derived from the file).

    The file is written with MuJoCo friction mu = 0.1 (the paper's, which the reference's law
    then takes from the file) and paper mode's stiff contact (solref 0.5 ms,
    models.resolve.PAPER_SOLREF; a loaded top keeps its file's contact). Checks, 0.3 s from the
    Fig. 3 start:

    * ODE: the parameters read back from the file are the top's, so theta_final equals the run
      of ``TopParams.from_ratios`` to 1e-8 rad (measured: identical).
    * MuJoCo, ``--set mujoco.friction=paper`` (a loaded file runs its own friction unless told),
      ``--set mujoco.timestep_s=1e-4``: 3000 steps (the set timestep ran,
      not the file's 2e-5 s), and theta_final within 2e-4 rad of the ODE's. Measured 3.9e-5 rad
      (1.9e-5 at 2e-5 s): the callback's one-evaluation lag of N, first order in dt. With the
      file's contact as soft as MuJoCo's default (solref 20 ms) the gap is 2.5e-3 rad.
    """
    from tippetop.models.mjcf import MjcfContact, make_mjcf
    from tippetop.models.params import FrictionParams, InitialState, TopParams
    from tippetop.models.resolve import PAPER_SOLREF

    top = TopParams.from_ratios(1.25, 0.15, 0.8)
    f = tmp_path / "top.xml"
    f.write_text(make_mjcf(top, contact=MjcfContact(friction_mode="native", mu=0.1,
                                                    solref=PAPER_SOLREF)))
    d = json.loads(tippetop("theory", "--mjcf", str(f), "--json").stdout)
    assert THEORY_KEYS | {"R_m", "a_m", "A", "C", "M_kg", "A_over_C", "a_over_R"} <= set(d)
    assert d["group"] == "III" and d["A_over_C"] == pytest.approx(1.25, rel=1e-9)
    assert d["a_m"] == pytest.approx(top.a_m, rel=1e-9)
    runs = {}
    for engine in ("ode", "mujoco"):
        r = tippetop("simulate", "--mjcf", str(f), "--engine", engine, "--set",
                     "run.t_end_s=0.3", "--set", "mujoco.timestep_s=1e-4", "--set",
                     "mujoco.friction=paper", "--json")
        assert r.returncode == 0, r.stderr
        runs[engine] = json.loads(r.stdout)
    ref = simulate_ode(top, FrictionParams(), InitialState(), t_end_s=0.3)
    theta_ref = float(ref.table["theta"].iloc[-1])
    assert abs(runs["ode"]["theta_final"] - theta_ref) < 1e-8
    assert runs["mujoco"]["n_steps"] == round(0.3 / 1e-4)
    assert abs(runs["mujoco"]["theta_final"] - theta_ref) < 2e-4


def test_diverged_mujoco_run_fails_loudly(tmp_path: Path) -> None:
    """A timestep far too large: one line on stderr, exit 1, no numbers, no table written."""
    out = tmp_path / "t.csv"
    # without sliding friction: with it, paper mode refuses the step before running (exit 2)
    r = tippetop("simulate", "fig3", "--engine", "mujoco", "--set", "mujoco.integrator=Euler",
                 "--set", "mujoco.timestep_s=0.02", "--set", "run.t_end_s=1", "--set",
                 "effects.sliding=false", "--out", str(out), "--json", cwd=tmp_path)
    assert r.returncode == 1
    d = json.loads(r.stdout)
    assert d["status"] == "diverged" and d["theta_asymp"] is None and d["theta_final"] is None
    assert len(r.stderr.strip().splitlines()) == 1 and "diverged" in r.stderr
    assert not out.exists()


def test_paper_law_step_too_long_is_refused(tmp_path: Path) -> None:
    """A step longer than the law's slip relaxation time: one line naming the limit, exit 2."""
    out = tmp_path / "t.csv"
    r = tippetop("simulate", "fig3", "--engine", "mujoco", "--set", "mujoco.timestep_s=0.02",
                 "--out", str(out), cwd=tmp_path)
    assert r.returncode == 2 and r.stdout == "" and not out.exists()
    assert r.stderr.strip().count("\n") == 0
    assert "mujoco.timestep_s: expected at most 0.00254 s" in r.stderr


def test_every_command_is_one_module_with_the_same_two_entry_points() -> None:
    """A module per command in tippetop.compare.commands, with add_parser(sub) and
    run(args) -> int; cli lists every one of them, in the order of --help."""
    import argparse
    import inspect
    import pkgutil

    from tippetop.compare import cli, commands

    names = sorted(m.name for m in pkgutil.iter_modules(commands.__path__) if m.name != "options")
    assert sorted(c.__name__.rpartition(".")[2] for c in cli.COMMANDS) == names
    for command in cli.COMMANDS:
        assert list(inspect.signature(command.add_parser).parameters) == ["sub"], command
        assert list(inspect.signature(command.run).parameters) == ["args"], command
        parser = argparse.ArgumentParser()
        sub = parser.add_subparsers(dest="command")
        assert command.add_parser(sub) is None
        name = command.__name__.rpartition(".")[2]
        assert sub.choices[name].get_default("func") is command.run


def test_command_line_starts_this_installations_tippetop() -> None:
    # the benchmarks time `tippetop` as a user types it: the script beside this Python, run by
    # this Python; without the script, `python -m tippetop.compare.cli` must do the same
    from tippetop.compare.cli import command_line

    words = command_line()
    assert words[0] == sys.executable
    for argv in (words, [sys.executable, "-m", "tippetop.compare.cli"]):
        r = subprocess.run([*argv, "--version"], capture_output=True, text=True, timeout=120,
                           check=False)
        assert r.returncode == 0 and r.stdout.startswith("tippetop "), (argv, r.stderr)


def test_simulate_on_an_engine_runs_there_and_says_so() -> None:
    # mujoco@THIS_PYTHON is this very MuJoCo build, in a worker process: the same plan, the same
    # build and the same steps, so the physics agrees to round-off (rel 1e-9 leaves room for a
    # different summation order, far below any tolerance of the nightly's); what ran says where
    spec = f"mujoco@{sys.executable}"
    args = ("simulate", "fig3", "--set", "run.t_end_s=0.3", "--set", "mujoco.friction=native",
            "--json")
    here = json.loads(tippetop(*args, "--engine", "mujoco").stdout)
    r = tippetop(*args, "--engine", spec)
    assert r.returncode == 0, r.stderr
    there = json.loads(r.stdout)
    assert there["engine"] == spec and here["engine"] == "mujoco"
    assert there["mode"] == here["mode"] == "native" and "engine_spec" not in there
    assert there["path"].startswith("worker")
    assert there["n_steps"] == here["n_steps"]
    for k in ("theta_final", "theta_asymp", "J_rel_drift"):
        assert there[k] == pytest.approx(here[k], rel=1e-9, abs=1e-15), k
