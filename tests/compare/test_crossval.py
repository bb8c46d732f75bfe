"""``tippetop compare``: per-mode summaries, outcomes against theory, and the differences."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tippetop.compare.measures.metrics import THETA_S_TOL
from tippetop.compare.measures.series import classify_outcome, theta_trend
from tippetop.compare.measures.verdict import crossval_row
from tippetop.compare.results.crossval import CompareResult
from tippetop.compare.studies.crossval import compare_scene, friction_law_table
from tippetop.models.errors import TippetopError
from tippetop.models.numbers import number_text

SUMMARY_KEYS = {"engine", "theta_final", "theta_asymp", "t_invert", "J_rel_drift",
                "energy_monotone", "contact_lost", "wall_s"}


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))


def test_fig3_modes_and_differences() -> None:
    """Fig. 3 over its 8 s: the paper's law in MuJoCo agrees with the reference (inverts, J kept);
    exact Coulomb does not invert (it rolls) and is listed as a difference on its outcome."""
    res = compare_scene("fig3", [("ode", "paper", ()), ("ode", "coulomb", ()),
                                 ("mujoco", "paper", ())],
                        ("mujoco.timestep_s=1e-4",), workers=1)
    assert res.group == "II" and res.theory.outcome == "inverted"
    runs = {s["run"]: s for s in res.runs}
    for s in runs.values():
        assert SUMMARY_KEYS | {"outcome", "matches_theory", "engine", "mode"} <= set(s)
    assert runs["ode/paper"]["outcome"] == "inverted" and runs["ode/paper"]["matches_theory"]
    assert runs["mujoco/paper"]["outcome"] == "inverted"
    assert runs["mujoco/paper"]["matches_theory"]
    assert runs["ode/coulomb"]["outcome"] == "upright"
    assert not runs["ode/coulomb"]["matches_theory"]
    flagged = {(d["run"], d["metric"]) for d in res.differences}
    assert ("ode/coulomb", "outcome") in flagged
    assert not any(m == "mujoco/paper" for m, _ in flagged)
    rows = {r["run"]: r for r in res.crossval}
    assert set(rows) == {"ode/paper", "ode/coulomb", "mujoco/paper"}
    assert (rows["mujoco/paper"]["engine"], rows["mujoco/paper"]["mode"]) == ("mujoco", "paper")
    # the theory says theta_s = pi; both inverting runs end within THETA_S_TOL of it
    assert rows["ode/paper"]["agrees"]
    assert abs(rows["ode/paper"]["d_theta_asymp"]) <= THETA_S_TOL
    assert rows["mujoco/paper"]["agrees"] and rows["mujoco/paper"]["d_t_invert"] is not None
    assert not rows["ode/coulomb"]["agrees"] and rows["ode/coulomb"]["reasons"]
    table = friction_law_table(res)
    assert list(table["run"]) == ["ode/paper", "ode/coulomb", "mujoco/paper"]
    row = table.set_index("run").loc["ode/coulomb"]
    assert not row["inverts"] and "upright" in row["departs"]
    # the result says itself as the command's JSON and reads itself back
    assert CompareResult.from_json(res.to_json()) == res
    assert list(res.to_json()) == ["scene", "group", "theory", "reference", "runs", "crossval",
                                   "differences", "tolerances"]


def test_unknown_mode() -> None:
    with pytest.raises(TippetopError, match="expected a mode"):
        compare_scene("fig3", [("mujoco", "bullet", ())])
    with pytest.raises(TippetopError, match="expected a mode the reference ODE runs"):
        compare_scene("fig3", [("ode", "native", ())])


def _facts(**kw: object) -> dict:
    """A finished run as the verdict reads it (:func:`run_facts`'s keys), inverted at 3 s."""
    base = {"outcome": "inverted", "theta_final": 3.1, "theta_asymp": 3.1, "t_invert": 3.0,
            "t_stem": None, "t_left_table": None, "J_rel_drift": 1e-9,
            "energy_monotone": True, "energy_rise_rel": 0.0, "E0_J": 1.0,
            "contact_energy_bound_J": 0.0, "error": None, "end_state": "inverted"}
    return {**base, **kw}


def test_matching_the_theory_needs_the_angle_too() -> None:
    # the case: a native elliptic-cone run ending 'inverted' at 2.600 rad where the
    # theory's theta_s is 2.752 (also 'inverted' by class) does not match the theory
    row = crossval_row("fig11_n070", "mujoco/native-elliptic",
                       _facts(theta_asymp=2.600, J_rel_drift=1e-6),
                       _facts(theta_asymp=2.75, t_invert=2.9), theta_s=2.752,
                       theory_outcome="inverted")
    assert not row["agrees"] and row["against"] == "theory"
    assert row["d_theta_asymp"] == pytest.approx(-0.152)
    assert row["d_t_invert"] == pytest.approx(0.1)
    assert "beyond 0.05 rad" in row["reasons"][0] and len(row["reasons"]) == 1
    near = crossval_row("x", "ode/paper", _facts(theta_asymp=2.73), None, theta_s=2.752,
                        theory_outcome="inverted")
    assert near["agrees"] and near["d_t_invert"] is None


def test_a_run_still_moving_is_inconclusive_with_its_trend() -> None:
    # theta creeping up from 0.05 rad at 0.01 rad/s over 10 s: its mean over the last 10 % is
    # 0.145 ('upright' by angle), but it is still moving; it is inconclusive, never upright,
    # and the trend is the slope itself
    t = np.linspace(0.0, 10.0, 2001)
    table = pd.DataFrame({"t": t, "theta": 0.05 + 0.01 * t})
    assert classify_outcome(table) == "inconclusive"
    assert theta_trend(table) == pytest.approx(0.01, rel=0.01)  # windows of 100 samples: 1 %
    row = crossval_row("x", "mujoco/paper",
                       _facts(outcome="inconclusive", theta_asymp=0.145, t_invert=None,
                              theta_trend_rad_s=theta_trend(table)),
                       _facts(outcome="upright", theta_asymp=0.02, t_invert=None),
                       theta_s=0.0, theory_outcome="upright")
    trend = number_text(theta_trend(table), "rad/s")  # four digits: +0.01005 rad/s
    assert not row["agrees"] and f"at +{trend}: inconclusive" in row["reasons"][0]
