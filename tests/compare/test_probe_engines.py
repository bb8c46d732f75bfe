"""Probes across engines (issue 44): ``bisect --probe`` and ``matrix --probes``.

Fast: ``bisect --probe`` over two interpreters that are the same (``--pythons``: no managed
environment), which must find no move; the matrix's rule for probe moves on results made up
here. Slow: the torque-free probe bisected between MuJoCo 3.10.0 and 3.12.0 (the damped
tumbling of 3.11.0's changelog) and ``matrix --probes`` on two releases.
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

from tippetop.compare.probes.study import ProbeResult, ProbeRow, ProbeRun, probe_moves


def _tippetop(*args: str, cache: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TIPPETOP_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args],
                          capture_output=True, text=True, timeout=1800, env=env)


def _row(engine: str, value: float, quantity: str = "roll_time_s") -> ProbeRow:
    return ProbeRow("slide-to-roll", engine, "x", "pyramidal", "Euler", 0.002, quantity, value,
                    0.288, "s", 0.01, abs(value - 0.288) <= 0.01)


def _result(values: dict[str, float]) -> ProbeResult:
    runs = tuple(ProbeRun("slide-to-roll", "pyramidal", e, (_row(e, v),), None)
                 for e, v in values.items())
    return ProbeResult(runs, ("slide-to-roll",), tuple(values), None, None, {})


def test_a_probe_quantity_moves_beyond_a_tenth_of_its_tolerance() -> None:
    # roll_time_s: tolerance 0.01 s against the exact value, so 0.001 s between engines
    assert probe_moves(_result({"a": 0.2900, "b": 0.2909})) == []
    moved = probe_moves(_result({"a": 0.2900, "b": 0.2920, "c": 0.2900}))
    assert [(m.engines, m.quantity) for m in moved] == [(("a", "b"), "roll_time_s"),
                                                         (("b", "c"), "roll_time_s")]
    js = moved[0].to_json()
    assert js["nearer_exact"] == "a" and js["metric"] == "probe.slide-to-roll.roll_time_s"
    failed = probe_moves(_result({"a": 0.29, "b": math.nan}))  # a failed run moved
    assert len(failed) == 1 and failed[0].to_json()["values"] == [0.29, None]


def test_bisect_a_probe_over_two_same_interpreters_finds_no_move(tmp_path: Path) -> None:
    other = tmp_path / "python-again"  # the same interpreter under another name
    other.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    other.chmod(0o755)
    pythons = tmp_path / "pythons.txt"
    pythons.write_text(f"{sys.executable}\n{other}\n")
    proc = _tippetop("bisect", "--probe", "spin-decay", "--mode", "condim3", "--pythons",
                     str(pythons), "--no-history", "--json", cache=tmp_path / "cache")
    assert proc.returncode == 0, proc.stderr
    res: dict[str, Any] = json.loads(proc.stdout)
    finding = res["by_metric"]["probe.spin-decay.spin_final_radps"]
    assert finding["moved"] is False
    assert [t["values"]["probe.spin-decay.spin_final_radps"] for t in res["tested"]] == [
        pytest.approx(100.0, abs=1e-6)] * 2  # condim 3 keeps the spin: w0


@pytest.mark.parametrize(("args", "said"), [
    (["--probe", "torque-fre"], "did you mean 'torque-free'"),
    (["--probe", "torque-free", "--metric", "energy"], "expected quantities of probe"),
    (["--probe", "torque-free", "--mode", "bound"], "--mode: expected one of probe"),
    (["fig3", "--probe", "torque-free"], "expected no scene with --probe"),
    (["fig3", "--timestep", "0.001"], "--timestep: expected only with --probe"),
])
def test_bisect_probe_bad_input_is_one_line(tmp_path: Path, args: list[str], said: str) -> None:
    proc = _tippetop("bisect", *args, "--between", "3.10.0", "3.12.0", cache=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and said in proc.stderr, proc.stderr


@pytest.mark.slow
def test_bisect_finds_the_release_that_damped_tumbling(tmp_path: Path) -> None:
    """3.11.0's changelog: "tumbling motion is now mildly damped" (implicitfast's free body).

    torque-free's transverse spin is kept to rounding by 3.10.0's implicitfast and shrinks
    x0.29 over 2 s from 3.11.0 on: bisect names the pair 3.10.0 -> 3.11.0.
    """
    proc = _tippetop("bisect", "--probe", "torque-free", "--metric", "transverse_drift",
                     "--between", "3.10.0", "3.12.0", "--no-history", "--json",
                     cache=tmp_path / "cache")
    assert proc.returncode == 0, proc.stderr
    finding = json.loads(proc.stdout)["by_metric"]["probe.torque-free.transverse_drift"]
    assert finding["moved"] and finding["pair"] == {"last_like_a": "3.10.0",
                                                    "first_like_b": "3.11.0"}
    before, after = finding["values"]
    assert abs(before) < 1e-9 and after == pytest.approx(-0.713, abs=0.01)


@pytest.mark.slow
def test_matrix_probes_says_which_quantities_moved(tmp_path: Path) -> None:
    proc = _tippetop("matrix", "fig3", "--engines", "mujoco,mujoco==3.10.0", "--modes",
                     "native", "--set", "run.t_end_s=0.3", "--no-attribution", "--probes",
                     "torque-free,slide-to-roll", "--no-history", "--json",
                     cache=tmp_path / "cache")
    assert proc.returncode in (0, 1), proc.stderr
    probes = json.loads(proc.stdout)["probes"]
    assert probes["format"] == "tippetop-probe/1"
    moved = {(m["probe"], m["quantity"]) for m in probes["moved"]}
    assert ("torque-free", "transverse_drift") in moved  # 3.11.0's damping
    assert not any(p == "slide-to-roll" for p, _ in moved)  # sliding friction did not move
