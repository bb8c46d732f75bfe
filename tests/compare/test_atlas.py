"""``tippetop atlas``: the group diagram measured from growth rates, against the paper's groups.

The groups are closed-form (Sec. 3.2: A/C against 1 -+ a/R), and so are n1 and n4; the reference
ODE must reproduce them at points in every group. Tolerance on n1 and n4: 1e-3 relative, the
growth method's target on tops other than the paper's (measured 3e-5 to 1e-4 here).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import matplotlib.image as mpimg
import pandas as pd
import pytest

from tippetop.compare.results.atlas import AtlasPoint, AtlasResult
from tippetop.compare.studies.atlas import group_of, parse_grid, run_atlas
from tippetop.models.errors import TippetopError


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TIPPETOP_CACHE", str(tmp_path / "cache"))


@pytest.mark.slow  # about 40 s on 2 cores: the default suite stays near 10 min
def test_the_reference_reproduces_groups_one_to_three() -> None:
    # a/R = 0.1: Group I below A/C = 0.9, II between 0.9 and 1.1, III above 1.1
    res = run_atlas([0.8, 1.0, 1.3], [0.1], [("ode", "paper", ())], workers=2)
    by = {p.A_over_C: p for p in res.points}
    assert [by[r].group_theory for r in (0.8, 1.0, 1.3)] == ["I", "II", "III"]
    assert all(p.agrees for p in res.points) and res.agreement == {"ode/paper": 1.0}
    assert by[0.8].n1_measured is None and by[1.3].n4_measured is None
    for p in res.points:
        assert p.n1_theory is None or p.n1_measured == pytest.approx(p.n1_theory, rel=1e-3)
        assert p.n4_theory is None or p.n4_measured == pytest.approx(p.n4_theory, rel=1e-3)
        assert p.settled
    assert any("keeps n1 within" in f for f in res.findings)
    # the result says itself as atlas.json and reads itself back
    assert AtlasResult.from_json(json.loads(json.dumps(res.to_json()))) == res


def test_an_atlas_says_itself_and_reads_itself_back() -> None:
    pts = (AtlasPoint(0.8, 0.1, "ode", "paper", "ode/paper", "I", "I", None, None, 44.4, 45.0,
                      True, 12, True),
           AtlasPoint(1.3, 0.1, "ode", "paper", "ode/paper", "III", "II", 30.1, 30.2, None,
                      90.0, False, 14, False))
    res = AtlasResult(pts, {"ode/paper": 0.5}, ("a finding.",), (0.8, 1.3), (0.1,),
                      ("ode/paper",), (5.0, 15.0))
    data = res.to_json()
    assert list(data) == ["points", "agreement", "findings", "grid", "runs", "scan_spins",
                          "n_runs"]
    assert data["n_runs"] == 26 and data["grid"] == {"A_over_C": [0.8, 1.3], "a_over_R": [0.1]}
    assert list(data["points"][0])[:3] == ["A_over_C", "a_over_R", "engine"]
    assert AtlasResult.from_json(json.loads(json.dumps(data))) == res


def test_group_of_and_grids() -> None:
    assert group_of(None, 30.0) == "I" and group_of(30.0, 60.0) == "II"
    assert group_of(30.0, None) == "III"
    assert parse_grid("0.8:1.4:4", "x") == pytest.approx([0.8, 1.0, 1.2, 1.4])
    assert parse_grid("0.1:0.1:1", "x") == [0.1]
    for bad in ("0.8:1.4", "a:b:c", "1.4:0.8:3", "0.8:1.4:0", "-1:1:3"):
        with pytest.raises(TippetopError, match="--A-over-C"):
            parse_grid(bad, "--A-over-C")


def _tippetop(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.slow  # about 40 s on 2 cores: the default suite stays near 10 min
def test_the_command_writes_csv_png_json_and_refuses_bad_input(tmp_path: Path) -> None:
    args = ("atlas", "--engines", "ode", "--A-over-C", "0.8:1.0:2", "--a-over-R",
            "0.1:0.1:1")
    out = tmp_path / "atlas"
    r = _tippetop(*args, "--out", str(out), "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert set(data) >= {"points", "agreement"} and data["agreement"] == {"ode/paper": 1.0}
    keys = {"A_over_C", "a_over_R", "engine", "mode", "run", "group_theory", "group_measured",
            "n1_theory", "n1_measured", "n4_theory", "n4_measured"}
    assert all(keys <= set(p) for p in data["points"]) and len(data["points"]) == 2
    table = pd.read_csv(out / "atlas.csv")
    assert list(table["group_measured"]) == ["I", "II"]
    assert mpimg.imread(out / "atlas.png").shape[1] > 400
    # an existing --out is refused before any run, and a bad grid is one line, exit 2
    again = _tippetop(*args, "--out", str(out), cwd=tmp_path)
    assert again.returncode == 2 and "--force" in again.stderr
    bad = _tippetop("atlas", "--A-over-C", "1.4:0.8:3", cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--A-over-C" in bad.stderr
    # any engine spec runs the atlas (tests/compare/test_cluster.py); one that is none is not
    bad = _tippetop("atlas", "--engines", "ode,bullet", cwd=tmp_path)
    assert bad.returncode == 2 and "bullet" in bad.stderr and "Traceback" not in bad.stderr
