"""Every metric declared once (:mod:`tippetop.compare.measures.metrics`), and read from there.

A key an output uses must be a declared metric, a setting of what ran
(:data:`~tippetop.compare.measures.summary.RAN_FIELDS`) or a record key (who ran, words,
structure: :data:`~tippetop.compare.measures.metrics.RECORD_KEYS`); a number an output
carries must be a metric or a setting. The outputs checked are the commands' ``--json``
(simulate on the reference and on MuJoCo, compare, matrix) and the nightly's run values.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterable, Mapping
from typing import Any

import pytest

from tippetop.compare.measures.metrics import KINDS, METRICS, RECORD_KEYS, STYLES
from tippetop.compare.measures.summary import RAN_FIELDS, RunSummary
from tippetop.compare.nightly.catalogue import KIND_METRICS
from tippetop.compare.nightly.running import run_metrics
from tippetop.compare.presentation.terminal import fmt_value, unit_of
from tippetop.models.scene import load_scene

UNITS = {"", "rad", "s", "rad/s", "J", "m", "relative", "fraction"}
DECLARED = set(METRICS) | set(RAN_FIELDS) | set(RECORD_KEYS)


def _tippetop(*args: str) -> Any:
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", *args, "--json"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode in (0, 1), proc.stderr
    return json.loads(proc.stdout)


def _undeclared(rows: Iterable[Mapping[str, Any]]) -> set[str]:
    """Keys none declares, and numbers that are neither a metric nor a setting of what ran."""
    bad = set()
    for row in rows:
        for key, value in row.items():
            if key not in DECLARED:
                bad.add(key)
            elif (isinstance(value, (int, float)) and not isinstance(value, bool)
                  and key not in METRICS and key not in RAN_FIELDS):
                bad.add(f"{key} (a number)")
    return bad


def test_every_declaration_is_whole() -> None:
    assert not set(METRICS) & set(RECORD_KEYS) and not set(METRICS) & set(RAN_FIELDS)
    for m in METRICS.values():
        assert m.unit in UNITS and len(m.meaning) > 20, m.name
        assert set(m.kinds) <= set(KINDS) and m.style in STYLES, m.name
        for tol in (m.tolerance, m.agreement):
            if tol is not None:
                assert tol.kind in ("exact", "abs", "rel", "growth", "max") and len(tol.why) > 20
        assert (m.agreement is None) == (m.against == ""), m.name
    assert all(len(v) > 10 for v in RECORD_KEYS.values())


def test_the_nightly_checks_what_is_declared_and_stores_each() -> None:
    # the kinds of case check the declared metrics that have a tolerance, and a run case's
    # values are exactly its kind's metrics
    for kind, names in KIND_METRICS.items():
        assert names and all(kind in METRICS[n].kinds and METRICS[n].tolerance for n in names)
    scene = load_scene("fig3", ["run.t_end_s=0.2"])
    from tippetop.compare.running.engines import run_engine

    run = run_engine(scene, "ode", progress=False)
    assert set(run_metrics(scene, run.summary, run.table, {})) == set(KIND_METRICS["run"])


def test_metrics_command_lists_the_declarations() -> None:
    from tippetop.compare.probes import probe_metrics

    listed = _tippetop("metrics")
    # the run metrics, then every probe quantity (issue 44), each declared once
    assert [m["name"] for m in listed] == [*METRICS, *probe_metrics()]
    for m in listed:
        assert {"name", "unit", "meaning", "kinds", "tolerance"} <= set(m)
    probes = _tippetop("metrics", "probe.*", "--kind", "probe")
    assert probes and all(m["name"].startswith("probe.") and m["kinds"] == ["probe"]
                          and m["unit"] and m["agreement"]["value"] >= 0 for m in probes)
    t_invert = next(m for m in listed if m["name"] == "t_invert")
    assert t_invert["unit"] == "s" and t_invert["tolerance"]["text"] == "+-0.1 s"
    proc = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "metrics", "t_invrt"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and proc.stdout == ""
    assert "did you mean 't_invert'" in proc.stderr
    text = subprocess.run([sys.executable, "-m", "tippetop.compare.cli", "metrics", "--kind",
                           "threshold"], capture_output=True, text=True, timeout=60).stdout
    assert text.startswith("measured (rad/s): threshold") and "t_invert" not in text


@pytest.mark.parametrize("args", [
    ("simulate", "fig3", "--set", "run.t_end_s=0.3"),
    ("simulate", "fig3", "--engine", "mujoco", "--mode", "native", "--set", "run.t_end_s=0.3"),
    ("simulate", "fig3", "--set", "effects.stem=true", "--set", "run.t_end_s=0.3"),
])
def test_a_run_summary_uses_declared_keys_only(args: tuple[str, ...]) -> None:
    out = _tippetop(*args)
    assert _undeclared([out]) == set()
    # and reads back as the same typed summary
    assert RunSummary.from_json(out).to_json().keys() <= out.keys() | {"scene"}


def test_compare_and_matrix_use_declared_keys_only() -> None:
    res = _tippetop("compare", "fig3", "--engines", "ode,mujoco", "--modes", "paper",
                    "--set", "run.t_end_s=0.3")
    assert _undeclared(res["runs"]) == set() and _undeclared(res["crossval"]) == set()
    assert {d["metric"] for d in res["differences"]} <= set(METRICS)
    assert set(res["tolerances"]) <= set(METRICS) | {"theta_s"}
    mx = _tippetop("matrix", "fig3", "--engines", "mujoco", "--modes", "paper", "--set",
                   "run.t_end_s=0.3", "--no-attribution")
    assert _undeclared(mx["runs"]) == set()
    assert set(mx["tolerances"]) <= set(METRICS)


def test_the_terminal_prints_each_number_with_its_declared_unit() -> None:
    for m in METRICS.values():
        if m.style != "number" or not m.unit or m.unit == "fraction":
            continue
        assert unit_of(m.name) == m.unit, m.name
        text = fmt_value(m.name, 0.5)
        assert text.endswith(m.unit) or m.unit in text, (m.name, text)


def test_a_metric_is_added_in_one_place(monkeypatch: pytest.MonkeyPatch) -> None:
    """A metric declared in METRICS alone is read by every place that handles a metric: its
    unit and its None (the terminal), its agreement bound (the verdict), how a difference is
    worded (compare) and its listing (``tippetop metrics``). Nothing else is edited here."""
    from tippetop.compare.commands.metrics import selected
    from tippetop.compare.measures.metrics import EVENT_RTOL, Metric, Tolerance, Wording
    from tippetop.compare.measures.verdict import tolerance_of
    from tippetop.compare.presentation.crossval import difference_text

    new = Metric("t_spin_down", "s", "the first time the spin n falls below 1 rad/s",
                 agreement=Tolerance("rel", EVENT_RTOL, 0.1, "s", "an event time"),
                 against="reference", agreement_rule="event",
                 none_means="never (keeps spinning)",
                 wording=Wording(run_none="keeps spinning; the reference stops at {ref}"))
    monkeypatch.setitem(METRICS, new.name, new)
    assert unit_of("t_spin_down") == "s"
    assert fmt_value("t_spin_down", None) == "never (keeps spinning)"
    assert fmt_value("t_spin_down", 2.5) == "2.5 s"
    # an event's bound grows with the reference's time: 10 % of 5 s, 0.1 s at least
    assert tolerance_of("t_spin_down", "mujoco", 5.0) == pytest.approx(0.5)
    assert tolerance_of("t_spin_down", "mujoco", 0.2) == pytest.approx(0.1)
    assert difference_text({"metric": "t_spin_down", "value": None, "reference": 3.0,
                            "tolerance": 0.3}) == "keeps spinning; the reference stops at 3 s"
    assert difference_text({"metric": "t_spin_down", "value": 3.5, "reference": 3.0,
                            "tolerance": 0.3, "why": "an event time"}) == (
        "t_spin_down 3.5 s against the reference's 3 s: 0.5 s apart, over the t_spin_down "
        "tolerance of 0.3 s (an event time)")
    assert [m.name for m in selected(["t_spin_down"], None)] == ["t_spin_down"]


def test_agreement_rules_are_declared() -> None:
    from tippetop.compare.measures.metrics import AGREEMENT_RULES, J_TOL

    assert {m.agreement_rule for m in METRICS.values()} <= set(AGREEMENT_RULES)
    # the rule says whose bound: the reference's Jellett drift is its integration tolerance
    assert METRICS["J_rel_drift"].agreement_bound("ode") == J_TOL["ode"]
    assert METRICS["J_rel_drift"].agreement_bound("mujoco") == J_TOL["mujoco"]
    with pytest.raises(KeyError):
        METRICS["theta_final"].agreement_bound()
