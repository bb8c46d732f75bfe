"""``run_nightly``: the whole regression for one :class:`NightlyOptions`, start to verdict.

The report is written by the function the caller passes (``write_report``): the nightly
command composes the nightly with :mod:`tippetop.compare.report`, which this package does not
import.
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.measures.tolerances import TOLERANCES
from tippetop.compare.nightly.baselines import (
    BASELINE_DIR,
    baseline_calibrations,
    baseline_file,
    load_baseline,
    model_file_changes,
    update_baseline,
)
from tippetop.compare.nightly.catalogue import (
    FAMILIES,
    Case,
    Catalogue,
    load_catalogue,
    on_engine,
    select_cases,
)
from tippetop.compare.nightly.checks import case_record, check_case
from tippetop.compare.nightly.history import check_history, record_nightly
from tippetop.compare.nightly.outputs import (
    RESULTS_FORMAT,
    count,
    downsample,
    environment,
    junit_xml,
    prepare_out_dir,
    slug,
    summary_text,
    timestamp,
)
from tippetop.compare.nightly.running import CaseRun, error_text, run_cases
from tippetop.compare.nightly.videos import render_videos
from tippetop.compare.presentation.verdict import crossval_rows
from tippetop.compare.results.nightly import NightlyResult
from tippetop.compare.running.io import (
    check_output_dir,
    json_ready,
    locked_output_dir,
    staged_output_dir,
    write_atomic,
)
from tippetop.compare.running.runner import default_cache_dir
from tippetop.models.errors import TippetopError, did_you_mean

EXIT_OK, EXIT_REGRESSION = 0, 1

#: Writes the report of a nightly's results: ``write_report(results, path, tables,
#: accuracy_dir)``, with ``results`` as ``results.json`` holds them, ``path`` the HTML file,
#: ``tables`` the downsampled run tables by case id, ``accuracy_dir`` a folder of figures or
#: None.
ReportWriter = Callable[[Mapping[str, Any], Path, Mapping[str, pd.DataFrame], Path | None],
                        None]


@dataclass
class NightlyOptions:
    """Everything ``tippetop nightly`` was asked for."""

    profile: str = "quick"
    catalogue: Path | None = None
    baseline_dir: Path = BASELINE_DIR
    update_baseline: bool = False
    no_baseline: bool = False
    out: str | None = None
    force: bool = False
    engines: tuple[str, ...] = FAMILIES
    modes: tuple[str, ...] = ()
    cases: tuple[str, ...] = ()
    scheduler: str | None = None
    workers: int | None = None
    cache: bool = False
    videos: bool = False
    accuracy_dir: Path | None = None
    #: The history file appended to (``--history``; None: the cache's), or none at all.
    history: Path | None = None
    no_history: bool = False
    #: MJCF tops added to the profile's cases (``--models``; catalogue.model_cases).
    models: tuple[str, ...] = ()
    argv: tuple[str, ...] = ()


@dataclass(frozen=True)
class _Checked:
    """What :func:`run_nightly` read and checked before it locked the output folder.

    Attributes:
        started: When the nightly started (:func:`~.outputs.timestamp`).
        t0: ``time.perf_counter()`` then.
        catalogue: The catalogue the cases come from.
        cases: The cases to run, each on its engine.
        skipped: The cases that cannot run on an engine asked for, said.
        files: Each engine's baseline file.
        baseline: The baseline's records by case id (empty with ``no_baseline``).
        out_dir: The output folder (locked).
    """

    started: str
    t0: float
    catalogue: Catalogue
    cases: list[Case]
    skipped: list[str]
    files: dict[str, Path]
    baseline: dict[str, dict[str, Any]]
    out_dir: Path


def run_nightly(opts: NightlyOptions, *, write_report: ReportWriter,
                log: Callable[[str], None] | None = None,
                echo: Callable[[str], None] = print) -> int:
    """Run the nightly regression; returns the exit status (0 clean, 1 regression or error).

    ``write_report`` writes ``report.html`` (:data:`ReportWriter`); if it fails, the verdict
    says so and the exit status is 1. The output folder is locked
    (:func:`~tippetop.compare.running.io.locked_output_dir`) before any work and until the run
    ends: a second run into the same folder is refused.

    Raises:
        TippetopError: bad input (exit 2), before any simulation: among it a baseline file
            that is missing without ``update_baseline`` or ``no_baseline``, and an output
            folder another run holds.
    """
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    started, t0 = timestamp(), time.perf_counter()
    kinds, specs = engine_specs(opts.engines)
    catalogue = load_catalogue(opts.catalogue)
    cases, skipped = cases_on_specs(select_cases(catalogue, opts.profile, kinds, opts.cases,
                                                 opts.modes, opts.models), specs)
    if not cases:
        modes = f", modes {','.join(opts.modes)}" if opts.modes else ""
        ids = [c.id for c in catalogue.cases if opts.profile in c.profiles]
        hint = next((h for h in (did_you_mean(p, ids) for p in opts.cases) if h), "")
        raise TippetopError(f"nightly: expected at least one case for profile "
                            f"{opts.profile!r}, engines {','.join(opts.engines)}{modes} and "
                            f"cases {','.join(opts.cases) or '*'}{hint}, got none")
    if opts.no_baseline and opts.update_baseline:
        raise TippetopError("--no-baseline: expected without --update-baseline (which "
                            "compares with and writes the baseline file), got both")
    base_dir = Path(opts.baseline_dir)
    if not base_dir.is_dir() and not (opts.update_baseline or opts.no_baseline):
        raise TippetopError(f"--baseline: expected an existing folder of baseline files, got "
                            f"{str(base_dir)!r}")
    files = baseline_files(base_dir, opts.profile, cases)
    baseline: dict[str, dict[str, Any]] = {}
    if not opts.no_baseline:
        for f in files.values():
            baseline.update(load_baseline(f, missing_ok=opts.update_baseline))
    out_dir = prepare_out_dir(opts.out, opts.force)
    if opts.scheduler and not opts.scheduler.startswith("tcp://"):
        raise TippetopError(f"--scheduler: expected tcp://HOST:PORT, got {opts.scheduler!r}")
    if opts.accuracy_dir is not None and not Path(opts.accuracy_dir).is_dir():
        raise TippetopError(f"--accuracy-dir: expected an existing folder, got "
                            f"{str(opts.accuracy_dir)!r}")
    if not opts.no_history:  # before the runs: a file that is not a history is bad input
        check_history(opts.history)
    with locked_output_dir(out_dir):
        check_output_dir(out_dir, force=opts.force)  # again, now that no other run writes
        checked = _Checked(started, t0, catalogue, cases, skipped, files, baseline, out_dir)
        return _run_locked(opts, checked, write_report, log, echo)


def engine_specs(engines: tuple[str, ...]) -> tuple[tuple[str, ...], list[str]]:
    """``--engines`` read: the engine families to select, and the MuJoCo engines.

    The families are ``ode``/``mujoco``; the catalogue's MuJoCo cases run on each MuJoCo
    engine. ``ode`` is the reference; every other entry is a MuJoCo engine
    (:func:`tippetop.models.engines.parse_engine`).

    Raises:
        TippetopError: A bad engine, or none at all (one line).
    """
    from tippetop.models.engines import SPEC_FORMS, parse_engine

    kinds: list[str] = []
    specs: list[str] = []
    for e in engines:
        if e == "ode":
            kinds.append("ode")
            continue
        try:
            spec = parse_engine(e).spec
        except TippetopError:
            names = ("ode", *SPEC_FORMS.replace(" or ", ", ").split(", "))
            raise TippetopError(f"--engines: expected a comma-separated list of ode and "
                                f"engine specs ({SPEC_FORMS}), got {e!r}"
                                f"{did_you_mean(e, names)}") from None
        if spec not in specs:
            specs.append(spec)
    if specs:
        kinds.append("mujoco")
    if not kinds:
        raise TippetopError(f"--engines: expected a comma-separated list of "
                            f"{','.join(FAMILIES)} or engine specs, got none")
    return tuple(kinds), specs


def cases_on_specs(cases: list[Case], specs: list[str]) -> tuple[list[Case], list[str]]:
    """Each MuJoCo case on each MuJoCo engine; the cases that cannot run on one, said.

    Runs, sweeps, thresholds, the atlas and the probes run on any engine (a release, a build,
    MJX, Warp: locally or on a Dask cluster; probes locally).
    """
    out, skipped = [], []
    for c in cases:
        if c.family == "ode":
            out.append(c)
            continue
        for spec in specs:
            if spec != "mujoco" and c.kind not in ("run", "sweep", "threshold", "atlas",
                                                   "probe"):
                skipped.append(f"{c.id} on {spec} (a {c.kind} runs on the installed MuJoCo "
                               "only)")
                continue
            out.append(on_engine(c, spec))
    return out, skipped


def spec_slug(spec: str) -> str:
    """A file-name-safe form of an engine spec (``mujoco==3.3.7`` stays as it is)."""
    import re

    return re.sub(r"[^A-Za-z0-9._=+-]", "_", spec)


def baseline_files(base_dir: Path, profile: str, cases: list[Case]) -> dict[str, Path]:
    """The baseline file of each engine the cases run on.

    The reference's and the installed MuJoCo's (``mujoco``) cases: ``DIR/<profile>.json`` as
    always; another engine's: ``DIR/<profile>@<engine>.json``, so a release, a build or MJX is
    compared with its own past, never with another engine's.
    """
    out: dict[str, Path] = {}
    for c in cases:
        key = "mujoco" if c.engine == "ode" else c.engine
        if key not in out:
            out[key] = (baseline_file(base_dir, profile) if key == "mujoco"
                        else base_dir / f"{profile}@{spec_slug(key)}.json")
    return out


def _update_baselines(files: dict[str, Path], profile: str, catalogue: Catalogue,
                      cases: list[Case], records: list[dict[str, Any]],
                      env: dict[str, Any]) -> dict[str, int]:
    """Write each engine's baseline file from its cases' records; the counts summed."""
    mine_ids = [c for c in catalogue.cases if profile in c.profiles]
    spec_of = {c.id: ("mujoco" if c.engine == "ode" else c.engine) for c in cases}
    total: dict[str, int] = {}
    for key, path in files.items():
        mine = [r for r in records if spec_of.get(r["id"]) == key]
        profile_ids = ({c.id for c in mine_ids} if key == "mujoco" else
                       {on_engine(c, key).id for c in mine_ids if c.family == "mujoco"})
        counts = update_baseline(path, profile, mine, profile_ids, env)
        for k, v in counts.items():
            total[k] = total.get(k, 0) + v
    return total


def _run_locked(opts: NightlyOptions, checked: _Checked, write_report: ReportWriter,
                log: Callable[[str], None], echo: Callable[[str], None]) -> int:
    """The run itself, its inputs checked and its output folder locked; the exit status."""
    cases, skipped, files = checked.cases, checked.skipped, checked.files
    baseline, out_dir = checked.baseline, checked.out_dir
    shown = ", ".join(f"{f}{'' if f.is_file() else ' (missing: every case is new)'}"
                      for f in files.values())
    log(f"nightly: profile {opts.profile}, {len(cases)} cases, baseline "
        + ("none (--no-baseline: every check is new)" if opts.no_baseline else shown))
    for line in skipped:
        log(f"nightly: not run: {line}")

    runs = run_cases(cases, scheduler=opts.scheduler, workers=opts.workers,
                     cache_dir=default_cache_dir() if opts.cache else None,
                     shared_cache=opts.cache, log=log)
    records = [case_record(cr, check_case(cr, baseline)) for cr in runs]
    model_changed = model_file_changes(records, baseline)  # said, not compared
    env = environment()
    # everything goes into a hidden staging folder that becomes --out at the end: a run
    # stopped on the way (Ctrl-C during the videos, say) leaves no half-written folder
    with staged_output_dir(out_dir) as stage:
        tables: dict[str, pd.DataFrame] = {}
        (stage / "tables").mkdir(exist_ok=True)
        for cr, rec in zip(runs, records, strict=True):
            if cr.table is not None:
                tab = downsample(cr.table)
                rel = f"tables/{slug(cr.case.id)}.parquet"
                write_atomic(stage / rel, lambda tmp, t=tab: t.to_parquet(tmp, index=False))
                rec["table"] = rel
                tables[cr.case.id] = tab
        res = _result(opts, checked, runs, records, model_changed, env, stage, log)
        c = res.counts
        failed = (c["cases_error"] > 0 or (c["cases_fail"] > 0 and not opts.update_baseline)
                  or res.videos_failed)
        if not opts.no_history:  # a failed append is said, and the results are kept
            res = replace(res, history=record_nightly(res.to_json(), opts.history, log))
        results = res.to_json()
        _write_results(stage, results)
        try:
            write_report(json_ready(results), stage / "report.html", tables, opts.accuracy_dir)
        except Exception as exc:  # noqa: BLE001 - the verdict is written; the report is part of it
            traceback.print_exc(file=sys.stderr)
            res = replace(res, report_error=error_text(exc),
                          verdict=("ERROR" if res.verdict == "OK" else res.verdict)
                          + " (report failed)")
            failed = True
            _write_results(stage, res.to_json())
    echo(summary_text(res.to_json(), out_dir))
    return EXIT_REGRESSION if failed else EXIT_OK


def _result(opts: NightlyOptions, checked: _Checked, runs: list[CaseRun],
            records: list[dict[str, Any]], model_changed: dict[str, str], env: dict[str, Any],
            stage: Path, log: Callable[[str], None]) -> NightlyResult:
    """The nightly's result, before the history and the report are added to it.

    With ``update_baseline`` it writes the baselines; with ``videos`` it renders the videos
    into ``stage``.
    """
    catalogue, files, baseline = checked.catalogue, checked.files, checked.baseline
    videos = (render_videos(checked.cases, stage, log) if opts.videos
              else {"requested": False, "status": "not requested", "files": {}})
    # the native cases: the calibration this run used, and each baseline's
    calibration = {"this_run": env.get("calibration"),
                   "baselines": baseline_calibrations(
                       {k: v for k, v in baseline.items()
                        if k in {cr.case.id for cr in runs}})}
    tolerances = {k: {"kind": t.kind, "value": t.value, "floor": t.floor, "unit": t.unit,
                      "text": t.describe(), "why": t.why} for k, t in TOLERANCES.items()}
    crossval = crossval_rows(records)
    c = count(records)
    update = (_update_baselines(files, opts.profile, catalogue, checked.cases, records, env)
              if opts.update_baseline else None)
    verdict = ("REGRESSION" if c["cases_fail"] and not opts.update_baseline
               else "ERROR" if c["cases_error"] else
               "ERROR (videos failed)" if videos.get("failed") else "OK")
    return NightlyResult(
        format=RESULTS_FORMAT, profile=opts.profile,
        profile_description=catalogue.profiles[opts.profile],
        catalogue=str(catalogue.path), engines=tuple(opts.engines),
        case_patterns=tuple(opts.cases),
        models=tuple(str(Path(m).absolute()) for m in opts.models),
        model_changed=model_changed, command=("tippetop", "nightly", *opts.argv),
        started=checked.started,
        baseline_file=("none (--no-baseline: every check is new)" if opts.no_baseline
                       else ", ".join(str(f) for f in files.values())),
        baseline_files={k: str(f) for k, f in files.items()}, not_run=tuple(checked.skipped),
        no_baseline=opts.no_baseline, baseline_update=update, videos=videos, environment=env,
        calibration=calibration, tolerances=tolerances, cases=tuple(records),
        crossval=tuple(crossval), counts=c, verdict=verdict, finished=timestamp(),
        wall_s=time.perf_counter() - checked.t0)


def _write_results(stage: Path, results: dict[str, Any]) -> None:
    """``results.json`` and ``junit.xml`` of the results, into the staging folder."""
    text = json.dumps(json_ready(results), indent=1) + "\n"
    write_atomic(stage / "results.json", lambda tmp: tmp.write_text(text, "utf-8"))
    xml = junit_xml(json_ready(results))
    write_atomic(stage / "junit.xml", lambda tmp: tmp.write_bytes(xml))
