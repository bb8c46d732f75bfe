"""tippetop calibrate: the shipped native settings, their provenance and the command itself.

The shipped file ``models/calibrated_native.toml`` is the default of ``mujoco.friction=native``.
Every MuJoCo run here is at the calibration's own timestep (2e-4 s, RK4: about 0.3-0.5 s of
wall per simulated second on one core), so the file-level tests take a few seconds each.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tippetop.compare.calibrate import (
    MUJOCO_DEFAULTS,
    W_T,
    Candidate,
    Evaluator,
    SceneSpec,
    add_calibrate_parser,
    grid_candidates,
    neighbours,
    objective,
    parse_scene_list,
    residual,
)
from tippetop.compare.engines import run_engine
from tippetop.compare.runner import TaskResult
from tippetop.models.calibrated import CALIBRATION_FILE, calibrated_native_settings
from tippetop.models.errors import TippetopError
from tippetop.models.scene import load_scene

SETTINGS_KEYS = {"mu", "cone", "impratio", "solref", "solimp", "timestep_s", "integrator"}


@pytest.fixture(scope="module")
def shipped() -> dict:
    with CALIBRATION_FILE.open("rb") as fh:
        return tomllib.load(fh)


def _sets(data: dict) -> tuple[set[str], set[str]]:
    prov = data["provenance"]
    calib = {s.split(":")[0] for s in prov["calibration_set"]}
    hold = {s.split(":")[0] for s in prov["holdout_set"]}
    return calib, hold


# ---------------------------------------------------------------- the shipped file
def test_shipped_file_has_settings_provenance_and_disjoint_residuals(shipped: dict) -> None:
    s = shipped["settings"]
    assert set(s) == SETTINGS_KEYS
    assert s["cone"] in ("pyramidal", "elliptic") and s["integrator"] == "RK4"
    assert len(s["solref"]) == 2 and len(s["solimp"]) == 5
    assert 0 < s["mu"] < 1 and s["impratio"] > 0 and s["timestep_s"] > 0
    # MuJoCo clamps the solref time constant to >= 2 timesteps: the fit must not sit below
    assert s["solref"][0] >= 2 * s["timestep_s"]
    # the runner reads exactly these settings
    assert calibrated_native_settings()["cone"] == s["cone"]
    assert calibrated_native_settings()["solref"] == tuple(s["solref"])

    prov = shipped["provenance"]
    for key in ("date", "command", "calibration_set", "holdout_set", "objective", "search",
                "grid", "bounds", "wall_s", "findings", "timestep_check"):
        assert key in prov, key
    assert prov["command"].startswith("tippetop calibrate ")
    assert prov["objective"] < prov["objective_mujoco_defaults"]
    calib, hold = _sets(shipped)
    assert calib and hold and not calib & hold

    held = [r for r in shipped["residual"] if r["role"] == "holdout"]
    assert {r["scene"] for r in held} == hold
    for r in held:
        for key in ("rms_rad", "theta_asymp_err", "outcome_match", "J_rel_drift"):
            assert key in r, (r["scene"], key)
        assert math.isfinite(r["rms_rad"])
    # the fit's headline: every held-out scene ends in the reference's outcome class
    assert all(r["outcome_match"] for r in held)


def test_timestep_check_is_small(shipped: dict) -> None:
    # the chosen settings at half the timestep change theta(t) by well under the residuals
    check = shipped["provenance"]["timestep_check"]
    assert check["max_rms_change_rad"] < 0.01
    assert abs(check["objective_change"]) < 0.01


# ---------------------------------------------------------------- the shipped settings in MuJoCo
@pytest.fixture(scope="module")
def fig3_native():
    # no mujoco.* settings but the mode: everything else comes from the shipped file
    return run_engine(load_scene("fig3", ["mujoco.friction=native", "run.t_end_s=4"]),
                      "mujoco", progress=False)


def test_calibrated_native_inverts_fig3(fig3_native, shipped: dict) -> None:
    # the reference inverts at 2.33 s; the calibrated native friction within 3 s
    # (the shipped fit: 2.40 s), at the calibration's timestep
    s = fig3_native.summary
    assert s["timestep_s"] == pytest.approx(shipped["settings"]["timestep_s"])
    assert s["condim"] == 3
    assert s["t_invert"] is not None and s["t_invert"] < 3.0
    assert fig3_native.table["theta"].iloc[-1] > math.pi / 2


def test_calibrated_native_conserves_jellett(fig3_native) -> None:
    # condim 3: the friction force acts at the contact point, so J = -L . X_P is conserved up
    # to where MuJoCo applies it: at the middle of the penetration, delta/2 off the geometric
    # P. With solref 2 ms the static sink is delta ~ (1 - d) g tc^2 ~ 4e-5 m (0.25 % of R), and
    # J drifts by ~ (delta / 2R) times the relative change of L_z, which the flip makes O(1):
    # ~1e-3 at worst; measured 1.5e-5 over 4 s with the flip (3e-4 over 30 s of Fig. 11).
    assert fig3_native.summary["J_rel_drift"] < 1e-4
    z_centre = (fig3_native.table["z"] + 0.0015 * np.cos(fig3_native.table["theta"]))
    assert float((0.015 - z_centre).max()) < 1e-4  # measured 4.5e-5 m: the ball sinks < 0.1 mm


def test_mujoco_default_settings_do_not_invert_fig3(shipped: dict) -> None:
    # facts.md: with MuJoCo's defaults (set explicitly here, so the shipped file does not
    # apply) the Fig. 3 top settles into rolling instead of turning over
    d = MUJOCO_DEFAULTS
    over = ["mujoco.friction=native", "run.t_end_s=6", *d.overrides(
        shipped["settings"]["timestep_s"], "RK4")[1:]]
    assert "mujoco.solref=[0.02, 1.0]" in over and "mujoco.impratio=1.0" in over
    run = run_engine(load_scene("fig3", over), "mujoco", progress=False)
    assert run.summary["t_invert"] is None
    assert float(run.table["theta"].max()) < 0.5


def test_holdout_residual_reproduces(shipped: dict, tmp_path: Path) -> None:
    # runs are deterministic: recompute one held-out scene's residual from scratch (no cache)
    entry = next(r for r in shipped["residual"] if r["role"] == "holdout"
                 and r["scene"] == "fig4")
    s = shipped["settings"]
    cand = Candidate(cone=s["cone"], impratio=s["impratio"], timeconst_s=s["solref"][0],
                     d0=s["solimp"][0], mu=s["mu"], dampratio=s["solref"][1],
                     solimp_tail=tuple(s["solimp"][1:]))
    ev = Evaluator([SceneSpec("fig4", entry["t_end_s"])], s["timestep_s"], s["integrator"],
                   run_options={"use_cache": False, "workers": 1})
    r = ev.evaluate([cand])[0].residuals[0]
    assert r.rms_rad == pytest.approx(entry["rms_rad"], abs=1e-5)
    assert r.t_invert_mujoco == pytest.approx(entry["t_invert_mujoco"], abs=1e-9)
    assert r.theta_asymp_err == pytest.approx(entry["theta_asymp_err"], abs=1e-5)
    assert r.outcome_mujoco == entry["outcome_mujoco"]


# ---------------------------------------------------------------- the command end to end
def _calibrate(*argv: str) -> int:
    p = argparse.ArgumentParser()
    add_calibrate_parser(p.add_subparsers())
    args = p.parse_args(["calibrate", *argv])
    return args.func(args)


def test_tiny_calibration_writes_a_valid_file_and_refuses_to_overwrite(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "cal.toml"
    argv = ("--calibration", "fig3:1", "--holdout", "fig7a:0.5", "--budget-runs", "2",
            "--out", str(out), "--json")
    assert _calibrate(*argv) == 0
    capsys.readouterr()
    data = tomllib.loads(out.read_text())
    assert set(data["settings"]) == SETTINGS_KEYS
    assert data["provenance"]["calibration_set"] == ["fig3:1"]
    assert data["provenance"]["runs_used"] == 2 and data["provenance"]["stop_reason"] == "budget"
    assert [r["scene"] for r in data["residual"] if r["role"] == "holdout"] == ["fig7a"]
    before = out.read_text()
    with pytest.raises(TippetopError, match="--force"):
        _calibrate(*argv)
    assert out.read_text() == before
    assert _calibrate(*argv, "--force") == 0  # from the cache now
    capsys.readouterr()
    assert tomllib.loads(out.read_text())["settings"] == data["settings"]


@pytest.mark.parametrize(("calibration", "holdout", "match"), [
    ("fig3", "fig3,fig4", "not in --calibration"),
    ("fig3:0", "fig4", "T_END_S > 0"),
    ("fig3,fig3", "fig4", "each scene once"),
    ("nosuchscene", "fig4", "catalogue"),
])
def test_bad_scene_lists(tmp_path: Path, calibration: str, holdout: str, match: str) -> None:
    with pytest.raises(TippetopError, match=match):
        _calibrate("--calibration", calibration, "--holdout", holdout,
                   "--out", str(tmp_path / "x.toml"))
    assert not (tmp_path / "x.toml").exists()


def test_parse_scene_list_horizons() -> None:
    specs = parse_scene_list("fig3:6, fig11_n070", "--calibration")
    assert specs == [SceneSpec("fig3", 6.0), SceneSpec("fig11_n070", 60.0)]


# ---------------------------------------------------------------- objective and search pieces
def _result(t: np.ndarray, theta: np.ndarray, t_invert: float | None,
            drift: float = 0.0) -> TaskResult:
    table = pd.DataFrame({"t": t, "theta": theta})
    return TaskResult(task=None, key="", summary={"t_invert": t_invert, "J_rel_drift": drift},
                      table=table, error=None, cached=False)  # type: ignore[arg-type]


def test_residual_and_objective_units() -> None:
    spec = SceneSpec("fig3", 4.0)
    t = np.linspace(0.0, 4.0, 401)
    flip = np.where(t < 2.0, 0.1, 3.0)
    ode = _result(t, flip, 2.0)
    same = residual(spec, ode, _result(t, flip, 2.0))
    assert same.rms_rad == 0.0 and same.t_invert_err_s == 0.0 and same.cost == 0.0
    assert same.outcome_match
    shifted = residual(spec, ode, _result(t, flip + 0.1, 2.0))
    assert shifted.rms_rad == pytest.approx(0.1)
    never = residual(spec, ode, _result(t, np.full_like(t, 0.1), None))
    # only the reference inverts: the error counts as the time left, 4 - 2 = 2 s
    assert never.t_invert_err_s is None and never.t_invert_penalty_s == pytest.approx(2.0)
    assert never.cost == pytest.approx(never.rms_rad + W_T * 2.0)
    assert not never.outcome_match
    # Jellett drift above 1e-4 costs 0.5 rad per decade
    drifty = residual(spec, ode, _result(t, flip, 2.0, drift=1e-2))
    assert objective([drifty]) == pytest.approx(1.0)
    assert objective([same, shifted]) == pytest.approx(0.05)


def test_grid_and_neighbours() -> None:
    grid = grid_candidates()
    assert len(grid) == 24 and len(set(grid)) == 24
    assert {c.cone for c in grid} == {"pyramidal", "elliptic"}
    c = Candidate("pyramidal", 1.0, 0.002, 0.05, 0.1)
    nb = neighbours(c, {"impratio": 0.3, "timeconst_s": 0.3, "d0": 0.3, "mu": 0.15}, 2e-4)
    assert len(nb) == 8 and c not in nb
    assert Candidate("pyramidal", 2.0, 0.002, 0.05, 0.1) in nb
    # the time constant stops at 2 timesteps
    low = neighbours(Candidate("pyramidal", 1.0, 4e-4, 0.05, 0.1),
                     {"impratio": 0.3, "timeconst_s": 0.3, "d0": 0.3, "mu": 0.15}, 2e-4)
    assert min(n.timeconst_s for n in low) == pytest.approx(4e-4)
