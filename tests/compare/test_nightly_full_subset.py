"""CI's share of the full nightly profile (issue 31, item 5).

The whole full profile takes most of an hour on 2 cores and the stress profile several minutes:
a scheduled job runs them (docs/guide/nightly.md, "Profiles on a schedule"). CI runs, with the
slow tests, the cases of the full profile that the quick profile does not hold and that fit its
time: the bisection of n_c against the theory (the case whose stale baseline once made the full
profile red), the Fig. 9 (b) sweep, n4 from growth rates and the Fig. 4 scene in MuJoCo's
calibrated native contact, against the stored full baseline. Measured: 218 s on 2 cores that a
full nightly and other jobs shared (load 4-9).
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.nightly import BASELINE_DIR, load_catalogue, select_cases

#: The full profile's cases CI runs (``--cases`` globs): each is in full, not in quick.
CI_CASES = (
    "thresholds/nc-fig9a-bisect[ode/paper]",
    "sweeps/fig9b[ode/paper]",
    "thresholds/n4-fig9a[mujoco/native]",
    "paper/fig4[mujoco/native]",
)


def test_ci_cases_are_full_cases_that_quick_does_not_run() -> None:
    cat = load_catalogue()
    full = {c.id for c in select_cases(cat, "full")}
    quick = {c.id for c in select_cases(cat, "quick")}
    for pattern in CI_CASES:
        assert pattern in full, pattern
        assert pattern not in quick, pattern


@pytest.mark.slow
def test_full_subset_matches_the_stored_full_baseline(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Every check of the subset passes against compare/baselines/full.json."""
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = nightly_command.main(["--profile", "full", "--cases", ",".join(CI_CASES),
                                     "--out", str(tmp_path / "out"), "--workers", "2",
                                     "--no-history"])
    assert code == 0, out.getvalue() + err.getvalue()
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert {r["id"] for r in res["cases"]} == set(CI_CASES)
    assert res["baseline_file"] == str(BASELINE_DIR / "full.json")
    c = res["counts"]
    assert c["checks_pass"] == c["checks"] >= 12, c
