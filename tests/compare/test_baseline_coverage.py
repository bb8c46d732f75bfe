"""Every case of every profile has a stored baseline for every metric it checks (issue 31, item 5).

A case without one is only ``new`` at night: it is never compared, so it can drift unseen. The
cases are expanded as ``tippetop nightly --profile P`` expands them with its default
``--engines`` (each catalogue entry on each engine family and mode; the MuJoCo ones on the
installed MuJoCo) and looked up in the baseline file the nightly reads for each. No simulation:
this reads the catalogue and the JSON files only.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tippetop.compare.nightly.baselines import BASELINE_DIR, load_baseline
from tippetop.compare.nightly.catalogue import Catalogue, load_catalogue, select_cases
from tippetop.compare.nightly.suite import (
    NightlyOptions,
    baseline_files,
    cases_on_specs,
    engine_specs,
)

CATALOGUE = load_catalogue()


def missing_baselines(catalogue: Catalogue, profile: str,
                      base_dir: Path = BASELINE_DIR) -> list[str]:
    """``CASE_ID: metric, ...`` for each case of ``profile`` lacking a stored metric.

    The cases and their baseline files are those the nightly's default run uses
    (:func:`~tippetop.compare.nightly.suite.run_nightly`); a missing file lacks every case.
    """
    kinds, specs = engine_specs(NightlyOptions().engines)
    cases, _not_run = cases_on_specs(select_cases(catalogue, profile, kinds), specs)
    files = baseline_files(base_dir, profile, cases)
    stored: dict[str, dict] = {}
    for path in files.values():
        stored.update(load_baseline(path, missing_ok=True))
    out = []
    for c in cases:
        lacking = [m for m in c.metrics if m not in stored.get(c.id, {})]
        if lacking:
            out.append(f"{c.id}: {', '.join(lacking)}")
    return out


@pytest.mark.parametrize("profile", sorted(CATALOGUE.profiles))
def test_every_case_has_every_metric_in_its_baseline(profile: str) -> None:
    missing = missing_baselines(CATALOGUE, profile)
    assert not missing, (
        f"{len(missing)} case(s) of profile {profile!r} have no baseline for a metric they "
        f"check; run 'tippetop nightly --profile {profile} --cases ID,... --update-baseline' "
        f"and commit it with what moved and why:\n  " + "\n  ".join(missing))


@pytest.mark.parametrize("profile", sorted(CATALOGUE.profiles))
def test_no_baseline_entry_outlives_its_case(profile: str) -> None:
    """An id the profile no longer runs is a renamed or removed case's stale entry."""
    kinds, specs = engine_specs(NightlyOptions().engines)
    cases, _ = cases_on_specs(select_cases(CATALOGUE, profile, kinds), specs)
    stored = load_baseline(BASELINE_DIR / f"{profile}.json")
    stale = sorted(set(stored) - {c.id for c in cases})
    assert not stale, stale


def test_the_check_finds_a_missing_case_and_a_missing_metric(tmp_path: Path) -> None:
    """The check can fail: a baseline with a case dropped and a metric deleted is caught."""
    src = BASELINE_DIR / "quick.json"
    doc = json.loads(src.read_text(encoding="utf-8"))
    dropped = "paper/fig3[ode/paper]"
    trimmed = "thresholds/n1-fig9a[ode/paper]"
    assert dropped in doc["cases"] and "converged" in doc["cases"][trimmed]
    del doc["cases"][dropped]
    del doc["cases"][trimmed]["converged"]
    (tmp_path / "quick.json").write_text(json.dumps(doc), encoding="utf-8")
    missing = missing_baselines(CATALOGUE, "quick", tmp_path)
    assert any(m.startswith(dropped + ":") and "t_invert" in m for m in missing), missing
    assert f"{trimmed}: converged" in missing
    assert len(missing) == 2, missing
