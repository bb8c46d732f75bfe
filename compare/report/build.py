"""Assembling and writing the nightly's report: :func:`render_report`, :func:`build_report`."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.report.atlas import atlas_section
from tippetop.compare.report.figures import sweeps_section, timeseries_section
from tippetop.compare.report.friction import friction_section
from tippetop.compare.report.groupmap import group_map_section
from tippetop.compare.report.markup import page
from tippetop.compare.report.probes import nightly_section as probes_nightly_section
from tippetop.compare.report.sections import (
    accuracy_section,
    checks_section,
    crossval_section,
    environment_section,
    header,
    run_facts,
    scenes_section,
    threshold_section,
    verdict_section,
)
from tippetop.compare.report.trends import trends_section
from tippetop.compare.running.cache import read_parquet_bytes
from tippetop.compare.running.io import write_atomic
from tippetop.models.errors import TippetopError

_NAV = ("<nav><ul><li><a href='#verdict'>Against the theory</a></li>"
        "<li><a href='#checks'>Regression checks</a></li>"
        "<li><a href='#trends'>Trends from the history</a></li>"
        "<li><a href='#scenes'>Scenes and groups</a></li>"
        "<li><a href='#timeseries'>theta(t), xi(t), slip (Figs. 3-8)</a></li>"
        "<li><a href='#sweeps'>theta_asymp against n0 (Figs. 9, 10)</a></li>"
        "<li><a href='#groups'>Group map</a></li>"
        "<li><a href='#atlas'>Group diagram measured</a></li>"
        "<li><a href='#friction'>Friction laws</a></li>"
        "<li><a href='#thresholds'>Thresholds</a></li>"
        "<li><a href='#probes'>Probes</a></li>"
        "<li><a href='#accuracy'>Accuracy against cost</a></li>"
        "<li><a href='#all'>Every check</a></li><li><a href='#env'>Environment</a></li>"
        "</ul></nav>")


def _load_tables(results: Mapping[str, Any], base_dir: Path,
                 tables: Mapping[str, pd.DataFrame] | None) -> dict[str, pd.DataFrame]:
    out: dict[str, pd.DataFrame] = dict(tables or {})
    for rec in results.get("cases", []):
        rel = rec.get("table")
        if rec["id"] in out or not rel:
            continue
        p = base_dir / rel
        if p.is_file():  # read as the run cache reads (read_parquet_bytes says why)
            out[rec["id"]] = read_parquet_bytes(p.read_bytes())
    return out


def render_report(results: Mapping[str, Any], tables: Mapping[str, pd.DataFrame],
                  accuracy_dir: Path | None = None) -> str:
    """The report's HTML text."""
    body = [header(results), crossval_section(results), _NAV, run_facts(results),
            verdict_section(results), trends_section(results), scenes_section(results),
            timeseries_section(results, tables), sweeps_section(results),
            group_map_section(results), atlas_section(results), friction_section(results),
            threshold_section(results), probes_nightly_section(results),
            accuracy_section(accuracy_dir), checks_section(results),
            environment_section(results)]
    title = f"tippetop report ({results.get('profile', '')}, {results.get('verdict', '')})"
    return page(title, body)


def build_report(results: Mapping[str, Any] | str | Path, path: str | Path, *,
                 tables: Mapping[str, pd.DataFrame] | None = None,
                 accuracy_dir: str | Path | None = None,
                 base_dir: str | Path | None = None) -> Path:
    """Write the self-contained HTML report.

    Args:
        results: The nightly's results dictionary, or the path of its ``results.json``.
        path: The HTML file to write (atomically).
        tables: Case id -> observables table; missing ones are read from the ``tables/``
            files named in ``results``, relative to ``base_dir``.
        accuracy_dir: A folder of accuracy-versus-cost PNG figures to embed (optional).
        base_dir: Where the results' relative table paths start (default: the folder of
            ``results.json``, or of ``path``).

    Returns:
        The path written.
    """
    if isinstance(results, (str, Path)):
        rpath = Path(results)
        try:
            data = json.loads(rpath.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise TippetopError(f"report: expected a readable results.json, got "
                                f"{str(rpath)!r} ({exc})") from None
        base = Path(base_dir) if base_dir else rpath.parent
    else:
        data = dict(results)
        base = Path(base_dir) if base_dir else Path(path).parent
    if "cases" not in data:
        raise TippetopError("report: expected nightly results with a 'cases' list, got none")
    acc = Path(accuracy_dir) if accuracy_dir else None
    text = render_report(data, _load_tables(data, base, tables), acc)
    out = Path(path)
    write_atomic(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return out
