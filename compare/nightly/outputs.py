"""What a nightly writes and prints: the output folder, JSON values, junit.xml, the summary.

Also the environment recorded with the results (versions, machine, git commit).
"""

from __future__ import annotations

import math
import os
import platform
import socket
import subprocess
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.running.io import check_output_dir
from tippetop.models.resources import data_path

RESULTS_FORMAT = "tippetop-nightly-results/1"
#: Rows of each run's observables kept in the output folder's ``tables/`` (for the report).
TABLE_ROWS = 2000
#: Lines of each list (failures, new, errors) in the printed summary.
SUMMARY_LINES = 12


def timestamp() -> str:
    """Now, local time with its UTC offset, to the second (ISO 8601)."""
    return datetime.now().astimezone().isoformat(timespec="seconds")


def _git(*args: str) -> str | None:
    root = data_path("tippetop.compare")  # git finds the repository from inside it
    try:
        out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True,
                             timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def environment() -> dict[str, Any]:
    """Versions, machine and git commit (when the code runs from a git checkout)."""
    from importlib import metadata

    from tippetop.compare.running.runner import code_fingerprint
    from tippetop.models.calibrated import calibration_label

    versions = {}
    for pkg in ("tippetop", "numpy", "scipy", "numba", "pandas", "pyarrow", "matplotlib",
                "mujoco", "distributed"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    commit = _git("rev-parse", "HEAD")
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "hostname": socket.gethostname(),
        "packages": versions,
        "git_commit": commit or None,
        "git_dirty": None if dirty is None or not commit else bool(dirty),
        "code_fingerprint": code_fingerprint(),
        # what the native mode's cases run with (models/calibrated_native.toml)
        "calibration": calibration_label(),
    }


def junit_xml(results: Mapping[str, Any]) -> bytes:
    """JUnit XML: a suite per category, a testcase per case and metric."""
    from tippetop.compare.presentation.verdict import run_of

    cases = results["cases"]
    profile = results["profile"]
    counts = results["counts"]
    root = ET.Element("testsuites", {
        "name": f"tippetop nightly ({profile})", "tests": str(counts["checks"]),
        "failures": str(counts["checks_fail"]), "errors": str(counts["checks_error"]),
        "skipped": str(counts["checks_new"]), "time": f"{results['wall_s']:.3f}"})
    categories: dict[str, list[dict[str, Any]]] = {}
    for rec in cases:
        categories.setdefault(rec["category"], []).append(rec)
    for cat, recs in categories.items():
        checks = [ch for r in recs for ch in r["checks"]]
        suite = ET.SubElement(root, "testsuite", {
            "name": f"nightly.{profile}.{cat}", "tests": str(len(checks)),
            "failures": str(sum(ch["status"] == "fail" for ch in checks)),
            "errors": str(sum(ch["status"] == "error" for ch in checks)),
            "skipped": str(sum(ch["status"] == "new" for ch in checks)),
            "time": f"{sum(r['wall_s'] for r in recs):.3f}",
            "timestamp": results["started"], "hostname": results["environment"]["hostname"]})
        props = ET.SubElement(suite, "properties")
        env = results["environment"]
        for k, v in (("profile", profile), ("git_commit", env.get("git_commit")),
                     ("mujoco", env["packages"].get("mujoco")),
                     ("baseline", results["baseline_file"])):
            ET.SubElement(props, "property", {"name": k, "value": str(v)})
        for r in recs:
            n = max(1, len(r["checks"]))
            for ch in r["checks"]:
                tc = ET.SubElement(suite, "testcase", {
                    "classname": f"nightly.{profile}.{cat}.{r['name']}[{run_of(r)}]",
                    "name": ch["metric"], "time": f"{r['wall_s'] / n:.3f}"})
                detail = (f"case {r['id']}\nmetric {ch['metric']}\nvalue {ch['value']!r}\n"
                          f"baseline {ch['baseline']!r}\ntolerance {ch['tolerance']['text']}"
                          f"\nwhy {ch['tolerance']['why']}")
                if ch["status"] == "fail":
                    el = ET.SubElement(tc, "failure", {
                        "message": f"{r['id']}: {ch['message']}", "type": "regression"})
                    el.text = detail
                elif ch["status"] == "error":
                    el = ET.SubElement(tc, "error", {"message": ch["message"][:2000],
                                                     "type": "case_error"})
                    el.text = r["error"]
                elif ch["status"] == "new":
                    ET.SubElement(tc, "skipped", {"message": f"new: {ch['message']}"})
                ET.SubElement(tc, "system-out").text = detail
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def count(records: Sequence[dict[str, Any]]) -> dict[str, int]:
    """Case and check counts by status."""
    checks = [ch for r in records for ch in r["checks"]]
    out = {"cases": len(records), "checks": len(checks)}
    for s in ("pass", "fail", "new", "error"):
        out[f"cases_{s}"] = sum(r["status"] == s for r in records)
        out[f"checks_{s}"] = sum(ch["status"] == s for ch in checks)
    return out


def summary_text(results: Mapping[str, Any], out_dir: Path) -> str:
    """The one-screen summary printed at the end.

    Its last lines give the two answers apart: regression against the baseline (what
    ``result`` and the exit status say) and agreement with the theory, where a departure the
    catalogue expects (its ``departs`` reason) is told apart from one it does not.
    """
    c = results["counts"]
    lines = [f"tippetop nightly: profile {results['profile']}, {c['cases']} cases, "
             f"{c['checks']} checks in {results['wall_s']:.0f} s",
             f"  checks: {c['checks_pass']} pass, {c['checks_fail']} fail, {c['checks_new']} "
             f"new, {c['checks_error']} error"]

    def block(title: str, items: list[str], where: str = "results.json") -> None:
        if not items:
            return
        lines.append(title)
        lines.extend(f"  {s}" for s in items[:SUMMARY_LINES])
        if len(items) > SUMMARY_LINES:
            lines.append(f"  ... {len(items)} in all: every one in {out_dir / where}")

    recs = results["cases"]
    update = results.get("baseline_update")
    title = "CHANGED (accepted into the baseline):" if update else "REGRESSIONS:"
    regressions = [f"{r['id']} {ch['message']}" for r in recs for ch in r["checks"]
                   if ch["status"] == "fail"]
    block(title, regressions, "results.json (cases, checks with status 'fail')")
    errors = [f"{r['id']}: {r['error']}" for r in recs if r["status"] == "error"]
    block("ERRORS (case did not run):", errors)
    changed = results.get("model_changed") or {}
    new = {r["id"]: [ch["metric"] for ch in r["checks"] if ch["status"] == "new"]
           for r in recs if r["id"] not in changed}
    block("NEW (no baseline yet; --update-baseline adds them):",
          [f"{r['id']}: " + (f"all {len(new[r['id']])} metrics"
                             if len(new[r["id"]]) == len(r["checks"])
                             else ", ".join(new[r["id"]])) for r in recs if new.get(r["id"])])
    block("MODEL FILE CHANGED (not compared; --update-baseline stores this run's values):",
          [f"{k}: {why}" for k, why in changed.items()])
    if update:
        lines.append(f"baseline updated: {results['baseline_file']} ({update['written']} cases "
                     f"written, {update['added']} added, {update['kept']} kept, "
                     f"{update['dropped']} dropped)")
    rows = results.get("crossval", [])
    theory = theory_answer(rows)
    if rows:
        lines.append("AGAINST THE THEORY (outcome and theta_asymp; the report's verdict table):")
        lines.extend(f"  {s}" for s in crossval_lines(rows))
        expected, unexpected = theory["expected"], theory["unexpected"]
        if expected:
            lines.append("  departures the catalogue expects (with its reason):")
            lines.extend(f"    {s}" for s in expected)
        if unexpected:
            lines.append("  NOT AGREEING, NOT EXPECTED:")
            lines.extend(f"    {s}" for s in unexpected[:UNEXPECTED_LINES])
            if len(unexpected) > UNEXPECTED_LINES:
                lines.append(f"    ... {len(unexpected)} in all: every one in "
                             f"{out_dir / 'report.html'} (#verdict) and results.json "
                             f"(crossval)")
    if results.get("videos", {}).get("requested"):
        lines.append(f"videos: {results['videos']['status']}")
        block("VIDEOS FAILED:", [f"{k}: {v}" for k, v in
                                 sorted((results["videos"].get("failed") or {}).items())])
    if results.get("report_error"):
        lines.append(f"REPORT FAILED: {results['report_error']}")
    hist = results.get("history")
    if hist and hist.get("error"):
        lines.append(f"history: NOT appended to {hist['file']}: {hist['error']}")
    elif hist:
        moved = hist.get("trends") or []
        lines.append(f"history: appended to {hist['file']} (run {hist['run']}); "
                     + (f"{len(moved)} series moved or regressed (the report's trends):"
                        if moved else "nothing moved over its last runs"))
        lines.extend(f"  {t['case']}: " + (t["changes"][-1]["text"] if t["changes"] else
                                          f"{t['metric']} regressed tonight")
                     for t in moved[:SUMMARY_LINES])
    lines.append(f"output: {out_dir}")
    n_fail, n_checks = c["checks_fail"], c["checks"]
    if update:
        regression = f"baseline updated ({len(regressions)} changed checks accepted)"
    elif results.get("no_baseline"):
        regression = "not checked (--no-baseline: every check is new)"
    elif n_fail:
        regression = f"REGRESSION, {n_fail} of {n_checks} checks (listed above)"
    else:
        regression = (f"none, {c['checks_pass']} of {n_checks} checks pass"
                      + (f", {c['checks_new']} new" if c["checks_new"] else ""))
    if errors:
        regression += f"; {len(errors)} cases did not run"
    lines.append(f"regression against the baseline ({results['baseline_file']}): {regression}")
    lines.append(f"agreement with the theory: {theory['text']}")
    lines.append(f"result: {results['verdict']} (regression against the baseline"
                 + ("; the theory's answer is the line above)" if rows else ")"))
    return "\n".join(lines)


#: Unexpected disagreements with the theory listed in the summary before pointing at the report.
UNEXPECTED_LINES = 30


def theory_answer(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Agreement with the theory in one line, and the runs that do not agree, told apart.

    Returns:
        ``text`` (``38 of 43 runs agree; 4 depart as the catalogue expects; 1 not expected
        (1 inconclusive, listed above)``), ``expected`` and ``unexpected``: a line per run
        that does not agree, an expected one with the catalogue's reason.
    """
    from tippetop.compare.presentation.verdict import cell_class, expected_reason

    expected, unexpected = [], []
    kinds: dict[str, int] = {}
    for r in rows:
        cls = cell_class(r)
        if cls == "agree":
            continue
        reasons = r.get("reasons") or []
        if (why := expected_reason(r)) is not None:  # its numbers: the report's
            expected.append(f"{r['scene']} [{r['run']}]: {reasons[0] if reasons else cls}; "
                            f"expected: {why}")
        else:
            unexpected.append(f"{cls}: {r['scene']} [{r['run']}]: {'; '.join(reasons)}")
            kinds[cls] = kinds.get(cls, 0) + 1
    agree = len(rows) - len(expected) - len(unexpected)
    if not rows:
        text = "not checked (no run cases)"
    else:
        text = f"{agree} of {len(rows)} runs agree"
        if expected:
            text += (f"; {len(expected)} {'departs' if len(expected) == 1 else 'depart'} as "
                     f"the catalogue expects")
        if unexpected:
            noun = {"depart": "departing", "inconclusive": "inconclusive", "failed": "failed"}
            text += (f"; {len(unexpected)} not expected ("
                     + ", ".join(f"{n} {noun.get(k, k)}" for k, n in kinds.items())
                     + ", listed above)")
        elif agree + len(expected) == len(rows):
            text += "; none unexpected"
    return {"text": text, "expected": expected, "unexpected": unexpected}


def crossval_lines(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Per run (``ENGINE/MODE``), how many agree with the theory (see :func:`theory_answer`)."""
    from tippetop.compare.presentation.verdict import agreement_counts, run_order

    counts = agreement_counts(rows)
    out = []
    for m in run_order(rows):
        k = counts[m]
        rest = ", ".join(f"{k[c]} {c}" for c in ("depart", "inconclusive", "failed") if k[c])
        out.append(f"{m}: {k['agree']} of {k['runs']} agree" + (f" ({rest})" if rest else ""))
    return out


def prepare_out_dir(out: str | None, force: bool) -> Path:
    """The output folder, checked before any work.

    A new ``nightly-YYYYMMDD-HHMMSS`` in the current folder by default; an existing non-empty
    folder only with ``force``.
    """
    if out is None:
        return check_output_dir(Path.cwd() / f"nightly-{datetime.now():%Y%m%d-%H%M%S}",
                                force=force)
    return check_output_dir(out, force=force)


def downsample(table: pd.DataFrame, rows: int = TABLE_ROWS) -> pd.DataFrame:
    """Every k-th row and the last, at most about ``rows`` rows (the tables/ files)."""
    step = max(1, math.ceil(len(table) / rows))
    out = table.iloc[::step]
    if out.index[-1] != table.index[-1]:
        out = pd.concat([out, table.iloc[[-1]]])
    return out.reset_index(drop=True)


def slug(case_id: str) -> str:
    """A case id or scene name as a file name."""
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in case_id).strip("_")
