"""Nightly regression: the catalogue, baselines in the repository, per-metric tolerances.

``tippetop nightly --profile quick`` runs every case of ``models/nightly.toml`` that belongs to
the profile (runs, n0 sweeps and threshold bisections, in the reference ODE and in MuJoCo),
compares each listed metric with ``compare/baselines/<profile>.json`` under the tolerance of
:data:`TOLERANCES`, and writes into a fresh output folder:

* ``results.json`` - every case and metric with its value, baseline, tolerance and verdict, the
  run summaries, and the environment (versions, git commit);
* ``junit.xml`` - one testcase per case and metric, a ``<failure>`` naming the metric and both
  values on a regression, ``<skipped>`` for a metric without baseline ("new"), ``<error>``
  when a case could not run;
* ``report.html`` - the model-validation report (:mod:`compare.report`);
* ``tables/`` - the downsampled observables of each run, from which the report can be rebuilt.

It prints a one-screen summary and exits 1 on any regression or failed case, 0 otherwise, 2 on
bad input. Baselines change only with ``--update-baseline``, which also adds the baselines of
new cases. Every run is recomputed (a private cache only removes duplicates inside one nightly);
``--cache`` reuses the shared run cache instead.

Modules: :mod:`.catalogue` (the cases), :mod:`.tolerances`, :mod:`.baselines`, :mod:`.running`
(the runs and bisections), :mod:`.checks` (case against baseline), :mod:`.outputs` (results.json
values, junit.xml, the summary, the environment), :mod:`.videos`, :mod:`.suite`
(:func:`run_nightly` for a :class:`NightlyOptions`) and :mod:`.command` (the parser and
``python -m tippetop.compare.nightly``).
"""

from __future__ import annotations

from tippetop.compare._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "BASELINE_DIR": "baselines",
    "baseline_file": "baselines",
    "load_baseline": "baselines",
    "update_baseline": "baselines",
    "CATALOGUE_PATH": "catalogue",
    "ENGINES": "catalogue",
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
    "add_nightly_parser": "command",
    "cmd_nightly": "command",
    "main": "command",
    "environment": "outputs",
    "junit_xml": "outputs",
    "summary_text": "outputs",
    "CaseRun": "running",
    "run_cases": "running",
    "EXIT_OK": "suite",
    "EXIT_REGRESSION": "suite",
    "NightlyOptions": "suite",
    "run_nightly": "suite",
    "TOLERANCES": "tolerances",
    "Tolerance": "tolerances",
    "compare_value": "tolerances",
    "tolerance_for": "tolerances",
    "render_videos": "videos",
})

__all__ = [
    "BASELINE_DIR", "CATALOGUE_PATH", "ENGINES", "EXIT_OK", "EXIT_REGRESSION", "KINDS",
    "KIND_METRICS", "PROFILES", "TOLERANCES", "Case", "CaseRun", "Catalogue", "NightlyOptions",
    "Tolerance", "add_nightly_parser", "baseline_file", "case_record", "case_status",
    "check_case", "cmd_nightly", "compare_value", "environment", "junit_xml", "load_baseline",
    "load_catalogue", "main", "render_videos", "run_cases", "run_nightly", "select_cases",
    "summary_text", "tolerance_for", "update_baseline",
]
