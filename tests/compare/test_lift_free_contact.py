"""A MuJoCo contact that follows the paper's law at mu = 1 on a Group II top (issue 30).

MuJoCo's contact lifts a ball that slides fast at a large mu (``mujoco_runner/contact_lift.py``),
and on the Group II top with a capsule stem (``tests/data/stranger/group2_mu1_implicitfast.xml``)
validate's fit does not find settings that keep it on. This is not a limit of MuJoCo: a family
of settings outside the fit separates the normal row from the friction rows, and with it the
same top follows the reference. These tests hold that claim against the reference ODE.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tippetop.compare.running.engines import run_engine
from tippetop.compare.tuning.tune import starts_for
from tippetop.models.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
LIFT_FREE = ROOT / "tests" / "data" / "group2_mu1_lift_free.xml"
T_END_S = 3.0


@pytest.mark.slow
def test_the_files_contact_follows_the_reference_from_its_start() -> None:
    """validate --no-tune: the file's own settings pass all of its checks from the file's start
    (measured: 5 of 5 over 3 s; turns over at 1.474 s against the reference's 1.464 s, no
    flight, J drift 4.1e-4 before the stem), and what ran is read back from the model,
    solreffriction included (the pair's, not asked for by the harness)."""
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "validate",
                           str(LIFT_FREE), "--no-tune", "--t-end-s", str(T_END_S), "--json"],
                          capture_output=True, text=True, timeout=900, cwd=ROOT)
    res = json.loads(proc.stdout)
    file_answer = res["answer"]["file"]
    assert file_answer["agrees"], res["answer"]
    assert file_answer["passes"] == file_answer["checks"]
    ran = res["runs"]["mujoco/file"]
    assert ran["cone"] == "elliptic" and ran["impratio"] == 300
    assert ran["solreffriction"] == [-1.0, -2.6] and ran["mu"] == 1.0


@pytest.mark.slow
@pytest.mark.parametrize("start", starts_for(150.0, 0.1)[1:], ids=lambda s: s.label())
def test_the_files_contact_follows_the_reference_from_held_out_starts(start) -> None:
    """From the tuning's three held-out starts (a faster and a slower spin, a larger tilt),
    which the file's settings were not chosen on. Bounds, the verdict's: the inversion and
    the first stem contact within max(0.1 s, 10 %) of the reference's, no flight of 10 ms
    or more, Jellett's relative drift below 1e-3 while the ball alone touches. Measured:
    t_invert 0.991 / 2.505 / 1.177 s against 0.974 / 2.372 / 1.174 s; the stem at 2.15 s
    against 2.005 s on the fast spin; no flight; drift 4.1-4.8e-4."""
    overrides = [f"top.mjcf={LIFT_FREE}", *start.overrides(), f"run.t_end_s={T_END_S}"]
    mj = run_engine(load_scene(None, overrides), "mujoco", "file", progress=False).summary
    ref = run_engine(load_scene(None, overrides), "ode", "paper", progress=False).summary
    assert mj["status"] == "ok" and ref["status"] == "ok"
    for event in ("t_invert", "t_stem"):
        assert (mj[event] is None) == (ref[event] is None), event
        if ref[event] is not None:
            assert abs(mj[event] - ref[event]) <= max(0.1, 0.1 * ref[event]), event
    assert mj["t_left_table"] is None
    assert mj["J_rel_drift"] < 1e-3
