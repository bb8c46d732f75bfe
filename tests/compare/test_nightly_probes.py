"""The nightly's probes category (issue 44): probe cases, their baselines, report and history."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from tippetop.compare.nightly.catalogue import load_catalogue, select_cases
from tippetop.compare.probes import probe_class
from tippetop.models.errors import TippetopError

ROOT = Path(__file__).resolve().parents[2]


def _catalogue(tmp_path: Path, entry: str) -> Path:
    path = tmp_path / "cat.toml"
    path.write_text('[profiles.quick]\ndescription = "q"\n\n[[case]]\n' + entry)
    return path


def test_a_probe_entry_expands_into_its_modes_with_its_quantities(tmp_path: Path) -> None:
    cat = load_catalogue(_catalogue(tmp_path, 'name = "s"\ncategory = "probes"\n'
                                    'kind = "probe"\nprobe = "spin-decay"\n'
                                    'profiles = ["quick"]\n'))
    cases = select_cases(cat, "quick")
    assert [c.mode for c in cases] == list(probe_class("spin-decay").modes)
    by = {c.mode: c.metrics for c in cases}
    assert by["condim3"] == ("probe.spin-decay.spin_final_radps",)
    assert by["condim4-elliptic"] == ("probe.spin-decay.spin_decay_radps2",)
    assert all(c.id == f"probes/s[mujoco/{c.mode}]" and c.kind == "probe" for c in cases)


@pytest.mark.parametrize(("entry", "said"), [
    ('probe = "spin-decy"', "did you mean 'spin-decay'"),
    ('probe = "spin-decay"\nmodes = ["condim5"]', "expected modes of probe spin-decay"),
    ('probe = "spin-decay"\nmetrics = ["nope"]', "expected quantities of probe spin-decay"),
    ('probe = "spin-decay"\nset = ["w9=1"]', "expected a parameter of the probes run"),
    ('probe = "spin-decay"\nscene = "fig3"', "unknown key 'scene' for a probe case"),
])
def test_a_bad_probe_entry_is_one_line(tmp_path: Path, entry: str, said: str) -> None:
    path = _catalogue(tmp_path, f'name = "s"\ncategory = "probes"\nkind = "probe"\n{entry}\n'
                                'profiles = ["quick"]\n')
    with pytest.raises(TippetopError, match=said.replace("(", r"\(").replace(")", r"\)")):
        load_catalogue(path)


def test_the_quick_nightly_checks_the_probes_against_their_baselines(tmp_path: Path) -> None:
    """``nightly --cases 'probes/slide-to-roll*'``: both modes pass their stored baselines.

    The history records each quantity as any check, and the report shows the Probes section.
    """
    env = {**os.environ, "TIPPETOP_CACHE": str(tmp_path / "cache")}
    out = tmp_path / "night"
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "nightly", "--profile",
                           "quick", "--cases", "probes/slide-to-roll*", "--out", str(out)],
                          capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    res = json.loads((out / "results.json").read_text())
    cases = [c for c in res["cases"] if c["kind"] == "probe"]
    assert {c["mode"] for c in cases} == {"pyramidal", "elliptic", "paper"}
    for c in cases:
        assert c["status"] == "pass" and c["error"] is None
        assert [ch["metric"] for ch in c["checks"]] == ["probe.slide-to-roll.roll_time_s",
                                                        "probe.slide-to-roll.roll_speed_mps"]
        assert all(ch["status"] == "pass" for ch in c["checks"])
        assert all(r["passed"] for r in c["probe"]["rows"])  # and each against its exact value
    html = (out / "report.html").read_text()
    assert "Probes: the engine's parts against exact answers" in html
    with sqlite3.connect(tmp_path / "cache" / "history.sqlite") as db:
        names = {row[0] for row in db.execute("SELECT DISTINCT metric FROM measures")}
    assert {"probe.slide-to-roll.roll_time_s", "probe.slide-to-roll.roll_speed_mps"} <= names
