"""Nightly regression: the catalogue against the baselines in the repository, per metric.

:mod:`.catalogue` (the cases), :mod:`.baselines`, :mod:`.running` (the
runs and bisections), :mod:`.checks` (a case against its baseline), :mod:`.outputs`
(results.json values, junit.xml, the summary, the environment), :mod:`.videos` and
:mod:`.suite` (:func:`run_nightly`). The command, which adds the report, is
:mod:`tippetop.compare.commands.nightly`; what the output folder holds is in docs/design.md.
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "BASELINE_DIR": "baselines",
    "baseline_file": "baselines",
    "load_baseline": "baselines",
    "update_baseline": "baselines",
    "CATALOGUE_PATH": "catalogue",
    "KIND_METRICS": "catalogue",
    "KINDS": "catalogue",
    "PROFILES": "catalogue",
    "Case": "catalogue",
    "Catalogue": "catalogue",
    "load_catalogue": "catalogue",
    "select_cases": "catalogue",
    "case_record": "checks",
    "case_status": "checks",
    "check_case": "checks",
    "environment": "outputs",
    "junit_xml": "outputs",
    "summary_text": "outputs",
    "CaseRun": "running",
    "run_cases": "running",
    "EXIT_OK": "suite",
    "EXIT_REGRESSION": "suite",
    "NightlyOptions": "suite",
    "run_nightly": "suite",
    "tolerance_for": "checks",
    "render_videos": "videos",
})

__all__ = [
    "BASELINE_DIR", "CATALOGUE_PATH", "EXIT_OK", "EXIT_REGRESSION", "KINDS",
    "KIND_METRICS", "PROFILES", "Case", "CaseRun", "Catalogue", "NightlyOptions",
    "baseline_file", "case_record", "case_status", "check_case",
    "environment", "junit_xml", "load_baseline", "load_catalogue", "render_videos", "run_cases",
    "run_nightly", "select_cases", "summary_text", "tolerance_for", "update_baseline",
]
