"""``tippetop compare``: per-mode summaries, outcomes against theory, and the differences."""

from __future__ import annotations

from pathlib import Path

import pytest

from tippetop.compare.crossval import compare_scene, friction_law_table
from tippetop.models.errors import TippetopError

SUMMARY_KEYS = {"engine", "theta_final", "theta_asymp", "t_invert", "J_rel_drift",
                "energy_monotone", "contact_lost", "wall_s"}


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))


def test_fig3_modes_and_differences() -> None:
    """Fig. 3 over its 8 s: the paper's law in MuJoCo agrees with the reference (inverts, J kept);
    exact Coulomb does not invert (it rolls) and is listed as a difference on its outcome."""
    res = compare_scene("fig3", ["ode", "ode-coulomb", "mujoco-paper"],
                        ("mujoco.timestep_s=1e-4",), workers=1)
    assert res["group"] == "II" and res["theory"]["outcome"] == "inverted"
    modes = res["modes"]
    for s in modes.values():
        assert SUMMARY_KEYS | {"outcome", "matches_theory"} <= set(s)
    assert modes["ode"]["outcome"] == "inverted" and modes["ode"]["matches_theory"]
    assert modes["mujoco-paper"]["outcome"] == "inverted"
    assert modes["mujoco-paper"]["matches_theory"]
    assert modes["ode-coulomb"]["outcome"] == "upright"
    assert not modes["ode-coulomb"]["matches_theory"]
    flagged = {(d["mode"], d["metric"]) for d in res["differences"]}
    assert ("ode-coulomb", "outcome") in flagged
    assert not any(m == "mujoco-paper" for m, _ in flagged)
    table = friction_law_table(res)
    assert list(table["mode"]) == ["ode", "ode-coulomb", "mujoco-paper"]
    row = table.set_index("mode").loc["ode-coulomb"]
    assert not row["inverts"] and "upright" in row["departs"]


def test_unknown_mode() -> None:
    with pytest.raises(TippetopError, match="--modes"):
        compare_scene("fig3", ["bullet"])
