"""``tippetop probe``: its JSON contract, its outputs, its bad input, failed runs, the cache.

Issue 44: each probe quantity against its exact value, one row each, format tippetop-probe/1;
``--out`` writes results.json, a figure per probe and report.html; bad input is one line and
exit 2; a run that diverges is its own failed row with the reason.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tippetop.compare.probes import probe_class, probe_metrics, probe_names
from tippetop.compare.probes.study import ROW_KEYS, run_probes
from tippetop.models.engines import parse_engine


def _tippetop(*args: str, cache: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, timeout=600, env=env)


@pytest.fixture(scope="module")
def every_probe(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """``tippetop probe --json --out DIR``: every probe on the installed MuJoCo, once."""
    root = tmp_path_factory.mktemp("probe")
    proc = _tippetop("probe", "--json", "--out", str(root / "out"), cache=root / "cache")
    assert proc.returncode in (0, 1), proc.stderr
    return {"json": json.loads(proc.stdout), "out": root / "out", "proc": proc}


def test_the_json_has_one_row_per_quantity_with_the_contract_keys(every_probe) -> None:
    data = every_probe["json"]
    assert data["format"] == "tippetop-probe/1"
    rows = data["results"]
    for r in rows:
        assert list(r)[:len(ROW_KEYS)] == list(ROW_KEYS)
        assert r["engine"] == "mujoco" and r["version"] and r["timestep_s"] > 0
        if r["value"] is not None and r["exact"] is not None:  # error = value - exact
            assert r["error"] == pytest.approx(r["value"] - r["exact"], abs=1e-12)
            assert r["passed"] == (abs(r["error"]) <= r["tolerance"])
    # every probe, each mode, each of the mode's quantities: nothing left out, nothing twice
    wanted = {(n, m, q.name) for n in probe_names() for m in probe_class(n).modes
              for q in probe_class(n)().quantities_of(m)}
    got = [(r["probe"], r["mode"], r["quantity"]) for r in rows]
    assert len(got) == len(set(got)) and set(got) == wanted
    # what ran is read back: torque-free runs at its own implicitfast, slide-to-roll Euler
    by = {r["probe"]: r["integrator"] for r in rows}
    assert by["torque-free"] == "implicitfast" and by["slide-to-roll"] == "Euler"
    assert {r["metric"] for r in rows} <= set(probe_metrics())


def test_the_exit_status_says_whether_every_quantity_is_within_tolerance(every_probe) -> None:
    rows = every_probe["json"]["results"]
    failed = [r for r in rows if not r["passed"]]
    assert every_probe["proc"].returncode == (1 if failed else 0)
    # MuJoCo's default contact creeps on a slope (issue 44, #3328): a failing row here
    assert any(r["probe"] == "incline" and r["quantity"] == "box_creep_umps"
               and r["mode"] == "elliptic" for r in failed)


def test_out_writes_results_a_figure_per_probe_and_the_report(every_probe) -> None:
    out: Path = every_probe["out"]
    assert json.loads((out / "results.json").read_text()) == every_probe["json"] | {
        "wall_s": json.loads((out / "results.json").read_text())["wall_s"]}
    for name in probe_names():
        png = out / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    html = (out / "report.html").read_text()
    assert "Probes: the engine's parts against exact answers" in html
    assert all(f"{n}.png" in html for n in probe_names())


@pytest.mark.parametrize(("args", "said"), [
    (["slide-to-rol"], "probe: expected one of slide-to-roll"),
    (["--integrator", "rk5"], "did you mean 'RK4'"),
    (["--timestep", "-0.001"], "--timestep: expected a positive step"),
    (["--set", "mu"], "--set: expected KEY=VALUE"),
    (["--set", "nope=1"], "--set: expected a parameter of the probes run"),
    (["--set", "mu=nan"], "--set mu: expected a finite number"),
    (["--modes", "eliptic"], "did you mean 'elliptic'"),
    (["--engines", "ode"], "engine: expected mujoco"),
    (["--engines", "mjx2"], "engine: expected"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: list[str], said: str) -> None:
    proc = _tippetop("probe", *args, cache=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and said in lines[0], proc.stderr
    assert proc.stdout == "" and "Traceback" not in proc.stderr


def test_a_non_empty_out_is_refused_without_force(tmp_path: Path) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    proc = _tippetop("probe", "slide-to-roll", "--out", str(out), cache=tmp_path / "c")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_run_that_diverges_is_its_own_failed_row_with_the_reason() -> None:
    # Euler at 50 ms on the fast free body: the gyroscopic term grows ~(1 + (Omega h)^2)^(1/2)
    # a step (Omega h = 1.25), the state blows up and MuJoCo resets it (mjWARN_BADQACC)
    res = run_probes(["torque-free"], [parse_engine("mujoco")], integrator="Euler",
                     timestep_s=0.05, use_cache=False)
    rows = res.rows
    assert rows and all(not r.passed and math.isnan(r.value) for r in rows)
    assert all(r.reason and "BADQACC" in r.reason and "step" in r.reason for r in rows)
    ok = run_probes(["torque-free"], [parse_engine("mujoco")], integrator="RK4",
                    timestep_s=0.0005, use_cache=False)
    assert all(r.passed and r.reason is None for r in ok.rows)  # the same probe, met


def test_a_second_run_comes_from_the_cache_with_the_same_rows(tmp_path: Path,
                                                              monkeypatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path))
    first = run_probes(["slide-to-roll"], [parse_engine("mujoco")])
    again = run_probes(["slide-to-roll"], [parse_engine("mujoco")])
    assert not any(r.cached for r in first.runs) and all(r.cached for r in again.runs)
    assert [r.to_json() | {"wall_s": 0} for r in first.rows] == \
        [r.to_json() | {"wall_s": 0} for r in again.rows]
    cold = run_probes(["slide-to-roll"], [parse_engine("mujoco")], use_cache=False)
    for a, b in zip(first.rows, cold.rows, strict=True):  # a cached run is the run
        assert a.value == pytest.approx(b.value, rel=1e-12, abs=1e-15)


def test_set_changes_the_exact_value_as_the_closed_form_says() -> None:
    # slide-to-roll's roll time is 2 (v0 - u) / (7 mu g): doubling mu halves it
    base = run_probes(["slide-to-roll"], [parse_engine("mujoco")], modes=["elliptic"],
                      use_cache=False)
    twice = run_probes(["slide-to-roll"], [parse_engine("mujoco")], modes=["elliptic"],
                       sets=["slide-to-roll.mu=0.2"], use_cache=False)
    t1 = next(r for r in base.rows if r.quantity == "roll_time_s")
    t2 = next(r for r in twice.rows if r.quantity == "roll_time_s")
    assert t2.exact == pytest.approx(t1.exact / 2, rel=1e-12)
    assert twice.params["slide-to-roll"]["mu"] == 0.2


@pytest.mark.slow
def test_a_probe_runs_on_two_releases(tmp_path: Path) -> None:
    """slide-to-roll on 3.10.0 and the installed MuJoCo: the same closed form met by both.

    Sliding friction's arithmetic has not changed between them: each value within a tenth of
    its tolerance of the other's (the baseline tolerance, the matrix's rule).
    """
    proc = _tippetop("probe", "slide-to-roll", "--engines", "mujoco,mujoco==3.10.0", "--json",
                     cache=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(proc.stdout)["results"]
    assert {r["version"] for r in rows} >= {"3.10.0"} and len({r["version"] for r in rows}) == 2
    by: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        by.setdefault((r["mode"], r["quantity"]), []).append(r)
    for pair in by.values():
        a, b = pair
        assert a["passed"] and b["passed"]
        assert abs(a["value"] - b["value"]) <= a["tolerance"] / 10
