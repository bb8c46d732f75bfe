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
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
import traceback
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.io import write_atomic
from tippetop.compare.metrics import classify_outcome
from tippetop.compare.modes import MODES
from tippetop.compare.runner import Task, TaskResult, default_cache_dir, run_tasks
from tippetop.compare.sweep import parse_range
from tippetop.compare.threshold import WHICH, measure_threshold
from tippetop.models.errors import TippetopError
from tippetop.models.resources import data_path
from tippetop.models.scene import Scene, load_scene

#: The catalogue shipped with the package.
CATALOGUE_PATH = data_path("tippetop.models", "nightly.toml")
#: Where the baselines live in the repository (one JSON file per profile).
BASELINE_DIR = data_path("tippetop.compare", "baselines")
PROFILES = ("quick", "full", "stress")
KINDS = ("run", "threshold", "sweep")
ENGINES = ("ode", "mujoco")
EXIT_OK, EXIT_REGRESSION = 0, 1
BASELINE_FORMAT = "tippetop-nightly-baseline/1"
RESULTS_FORMAT = "tippetop-nightly-results/1"
#: Rows of each run's observables kept in the output folder's ``tables/`` (for the report).
TABLE_ROWS = 2000
#: Lines of each list (failures, new, errors) in the printed summary.
SUMMARY_LINES = 12


# ------------------------------------------------------------------------------------ tolerances
@dataclass(frozen=True)
class Tolerance:
    """How far a metric may move from its baseline.

    Attributes:
        kind: ``exact`` (equal), ``abs`` (``|v - b| <= value``), ``rel``
            (``|v - b| <= max(value * |b|, floor)``) or ``growth`` (one-sided:
            ``v <= max(value * b, floor)``, a smaller value always passes).
        value: The bound (unit as the metric for ``abs``; a fraction for ``rel``; a factor for
            ``growth``).
        floor: Absolute allowance under ``rel`` and ``growth`` (unit of the metric).
        unit: The metric's unit, for messages.
        why: One line on why this bound.
    """

    kind: str
    value: float = 0.0
    floor: float = 0.0
    unit: str = ""
    why: str = ""

    def describe(self) -> str:
        """The bound in words, e.g. ``+-0.02 rad``."""
        u = f" {self.unit}" if self.unit else ""
        if self.kind == "exact":
            return "exact"
        if self.kind == "abs":
            return f"+-{self.value:g}{u}"
        if self.kind == "rel":
            extra = f" (at least {self.floor:g}{u})" if self.floor else ""
            return f"+-{100 * self.value:g} %{extra}"
        return f"<= max({self.value:g} x baseline, {self.floor:g}{u})"


#: Per-metric tolerances: the one place they are set. ``measured`` is widened to the case's own
#: bisection ``rel_tol`` when that is coarser (see :func:`tolerance_for`).
TOLERANCES: dict[str, Tolerance] = {
    "outcome": Tolerance(
        "exact", why="upright / intermediate / inverted / inconclusive is the paper's claim"),
    "matches_expect": Tolerance(
        "exact", why="agreement with the scene's [expect] outcome must not be lost"),
    "theta_asymp": Tolerance(
        "abs", 0.02, unit="rad", why="the ODE repeats it to 1e-6 rad; 0.02 rad is below the "
        "0.05-rad agreement with theta_s the tests ask for, so real shifts show"),
    "t_invert": Tolerance(
        "abs", 0.1, unit="s", why="~3 % of the Fig. 3 inversion time; the ODE locates it to "
        "1e-6 s and a MuJoCo timestep change moves it by milliseconds"),
    "J_rel_drift": Tolerance(
        "growth", 10.0, floor=1e-8, why="Jellett's constant is conserved: drift may shrink "
        "freely, grow 10x at most, and below 1e-8 (10x the ODE's rtol) it is noise"),
    "energy_monotone": Tolerance(
        "exact", why="dE/dt = F . v_P <= 0 under every law: a rise is a bug"),
    "energy_lost": Tolerance(
        "rel", 0.02, floor=1e-6, unit="J", why="E0 - E_end sums the friction work; 2 % "
        "catches a changed law, 1 uJ (~1e-4 of E0) ignores the upright tops' tiny losses"),
    "contact_lost": Tolerance(
        "exact", why="leaving the table is a different regime, never a tolerance"),
    "status": Tolerance(
        "exact", why="ok / contact_lost / max_steps / singular must stay what it was"),
    "measured": Tolerance(
        "rel", 0.02, why="a critical spin from bisection: 2 %, or the case's bracket width "
        "if coarser (one bisection step is its resolution)"),
    "converged": Tolerance(
        "exact", why="the bracket must still close within max_rounds"),
    "theta_asymp_vs_n0": Tolerance(
        "abs", 0.05, unit="rad", why="per sweep point; near n1 and n4 the approach outlasts "
        "the horizon, so theta_asymp there is more sensitive than a single run's"),
    "outcomes_vs_n0": Tolerance(
        "exact", why="per sweep point: the classification of each n0"),
}

#: Metrics each kind of case can check.
KIND_METRICS: dict[str, tuple[str, ...]] = {
    "run": ("outcome", "matches_expect", "theta_asymp", "t_invert", "J_rel_drift",
            "energy_monotone", "energy_lost", "contact_lost", "status"),
    "threshold": ("measured", "converged"),
    "sweep": ("theta_asymp_vs_n0", "outcomes_vs_n0"),
}


def tolerance_for(metric: str, case: Case) -> Tolerance:
    """The tolerance of ``metric`` for ``case`` (a threshold's is at least its ``rel_tol``)."""
    tol = TOLERANCES[metric]
    if metric == "measured" and case.rel_tol is not None and case.rel_tol > tol.value:
        return Tolerance(tol.kind, case.rel_tol, tol.floor, tol.unit, tol.why)
    return tol


def _is_missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and not math.isfinite(v))


def _fmt(v: Any, unit: str = "") -> str:
    if _is_missing(v):
        return "none"
    if isinstance(v, float):
        return f"{v:.6g}{' ' + unit if unit else ''}"
    return str(v)


def compare_value(value: Any, baseline: Any, tol: Tolerance) -> tuple[bool, str]:
    """Whether ``value`` is within ``tol`` of ``baseline``, and a message that shows both.

    Dictionaries (sweeps: n0 -> value) are compared point by point on the n0 values both
    have; the message names the worst point.
    """
    if isinstance(baseline, dict) or isinstance(value, dict):
        if not (isinstance(baseline, dict) and isinstance(value, dict)):
            return False, f"{_fmt(value)} vs baseline {_fmt(baseline)}"
        common = [k for k in value if k in baseline]
        bad = []
        for k in common:
            ok, msg = compare_value(value[k], baseline[k], tol)
            if not ok:
                bad.append(f"n0 = {k}: {msg}")
        extra = len(value) - len(common)
        note = f"; {extra} point(s) without baseline" if extra else ""
        if bad:
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            return False, f"{bad[0]}{more}{note}"
        return True, f"{len(common)} points within {tol.describe()}{note}"
    u = tol.unit
    shown = f"{_fmt(value, u)} vs baseline {_fmt(baseline, u)} (tolerance {tol.describe()})"
    if _is_missing(value) or _is_missing(baseline):
        return _is_missing(value) and _is_missing(baseline), shown
    if tol.kind == "exact":
        return value == baseline, shown
    v, b = float(value), float(baseline)
    if tol.kind == "abs":
        return abs(v - b) <= tol.value, shown
    if tol.kind == "rel":
        return abs(v - b) <= max(tol.value * abs(b), tol.floor), shown
    return v <= max(tol.value * b, tol.floor), shown


# ------------------------------------------------------------------------------------- catalogue
@dataclass(frozen=True)
class Case:
    """One case of the catalogue in one mode."""

    id: str
    name: str
    category: str
    kind: str
    scene: str
    mode: str
    metrics: tuple[str, ...]
    profiles: tuple[str, ...]
    set: tuple[str, ...] = ()
    description: str = ""
    which: str | None = None
    rel_tol: float | None = None
    max_rounds: int = 10
    points_per_round: int = 2
    n0: tuple[float, ...] = ()
    figure: str = ""
    label: str = ""

    @property
    def engine(self) -> str:
        """``ode`` or ``mujoco``."""
        return MODES[self.mode][0]

    @property
    def overrides(self) -> tuple[str, ...]:
        """The case's ``set`` then its mode's overrides."""
        return (*self.set, *MODES[self.mode][1])


@dataclass(frozen=True)
class Catalogue:
    """The profiles and the cases (one per mode) of a catalogue file."""

    path: Path
    profiles: dict[str, str]
    cases: tuple[Case, ...]


_COMMON_KEYS = {"name", "category", "kind", "scene", "set", "modes", "profiles", "metrics",
                "description"}
_KIND_KEYS = {"run": set(), "threshold": {"which", "rel_tol", "max_rounds", "points_per_round"},
              "sweep": {"n0", "figure", "label"}}


def _req(entry: dict[str, Any], key: str, kind: type, where: str) -> Any:
    if key not in entry:
        raise TippetopError(f"{where}: expected a '{key}' key, got none")
    v = entry[key]
    if kind is float:
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) \
            and v > 0
    elif kind is int:
        ok = isinstance(v, int) and not isinstance(v, bool) and v > 0
    elif kind is list:
        ok = isinstance(v, list) and all(isinstance(x, str) for x in v)
    else:
        ok = isinstance(v, str) and bool(v)
    if not ok:
        what = {float: "a number > 0", int: "an integer > 0", list: "a list of strings",
                str: "a non-empty string"}[kind]
        raise TippetopError(f"{where}.{key}: expected {what}, got {v!r}")
    return v


def _entry_cases(entry: dict[str, Any], where: str, profiles: dict[str, str]) -> list[Case]:
    if not isinstance(entry, dict):
        raise TippetopError(f"{where}: expected a table, got {entry!r}")
    kind = _req(entry, "kind", str, where)
    if kind not in KINDS:
        raise TippetopError(f"{where}.kind: expected one of {'|'.join(KINDS)}, got {kind!r}")
    allowed = _COMMON_KEYS | _KIND_KEYS[kind]
    for key in entry:
        if key not in allowed:
            raise TippetopError(f"{where}: unknown key {key!r} for a {kind} case (expected "
                                f"one of: {', '.join(sorted(allowed))})")
    name = _req(entry, "name", str, where)
    category = _req(entry, "category", str, where)
    scene = _req(entry, "scene", str, where)
    modes = _req(entry, "modes", list, where)
    profs = _req(entry, "profiles", list, where)
    metrics = _req(entry, "metrics", list, where)
    over = entry.get("set", [])
    if not (isinstance(over, list) and all(isinstance(x, str) for x in over)):
        raise TippetopError(f"{where}.set: expected a list of 'section.key=value' strings, "
                            f"got {over!r}")
    for m in modes:
        if m not in MODES:
            raise TippetopError(f"{where}.modes: expected names from {', '.join(MODES)}, "
                                f"got {m!r}")
    for p in profs:
        if p not in profiles:
            raise TippetopError(f"{where}.profiles: expected names from "
                                f"{', '.join(profiles)}, got {p!r}")
    for m in metrics:
        if m not in KIND_METRICS[kind]:
            raise TippetopError(f"{where}.metrics: expected names from "
                                f"{', '.join(KIND_METRICS[kind])} for a {kind} case, got {m!r}")
    if not (modes and profs and metrics):
        raise TippetopError(f"{where}: expected non-empty modes, profiles and metrics")
    extra: dict[str, Any] = {}
    if kind == "threshold":
        which = _req(entry, "which", str, where)
        if which not in WHICH:
            raise TippetopError(f"{where}.which: expected {'|'.join(WHICH)}, got {which!r}")
        extra = {"which": which, "rel_tol": float(_req(entry, "rel_tol", float, where)),
                 "max_rounds": entry.get("max_rounds", 10),
                 "points_per_round": entry.get("points_per_round", 2)}
        for key in ("max_rounds", "points_per_round"):
            if key in entry:
                _req(entry, key, int, where)
    elif kind == "sweep":
        extra = {"n0": tuple(parse_range(_req(entry, "n0", str, where))),
                 "figure": entry.get("figure", ""), "label": entry.get("label", "")}
    return [Case(id=f"{category}/{name}[{mode}]", name=name, category=category, kind=kind,
                 scene=scene, mode=mode, metrics=tuple(metrics), profiles=tuple(profs),
                 set=tuple(over), description=entry.get("description", ""), **extra)
            for mode in modes]


def load_catalogue(path: str | Path | None = None) -> Catalogue:
    """Read and validate a catalogue file (default: ``models/nightly.toml``).

    Raises:
        TippetopError: unreadable file, unknown keys, modes, profiles or metrics, or two cases
            with the same id in one profile.
    """
    p = Path(path) if path is not None else CATALOGUE_PATH
    if not p.is_file():
        raise TippetopError(f"--catalogue: expected an existing .toml file, got {str(p)!r}")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise TippetopError(f"catalogue {p.name}: expected valid TOML, got: {exc}") from None
    for key in data:
        if key not in ("profiles", "case"):
            raise TippetopError(f"catalogue {p.name}: unknown top-level key {key!r} (expected "
                                f"[profiles.NAME] and [[case]])")
    prof_raw = data.get("profiles", {})
    profiles = {name: str(body.get("description", "")) if isinstance(body, dict) else ""
                for name, body in prof_raw.items()}
    if not profiles:
        raise TippetopError(f"catalogue {p.name}: expected at least one [profiles.NAME]")
    cases: list[Case] = []
    for i, entry in enumerate(data.get("case", [])):
        label = entry.get("name", i) if isinstance(entry, dict) else i
        cases.extend(_entry_cases(entry, f"catalogue {p.name}: case {label!r}", profiles))
    for prof in profiles:
        seen: set[str] = set()
        for c in cases:
            if prof in c.profiles:
                if c.id in seen:
                    raise TippetopError(f"catalogue {p.name}: expected unique case ids in "
                                        f"profile {prof!r}, got {c.id!r} twice")
                seen.add(c.id)
    return Catalogue(p, profiles, tuple(cases))


def select_cases(catalogue: Catalogue, profile: str, engines: Sequence[str] = ENGINES,
                 patterns: Sequence[str] = ()) -> list[Case]:
    """The cases of ``profile`` on ``engines`` whose id matches one of ``patterns``.

    Patterns are globs with ``*`` and ``?``; brackets are literal, so ``paper/fig3[*`` selects
    every mode of ``paper/fig3``.
    """
    if profile not in catalogue.profiles:
        raise TippetopError(f"--profile: expected one of {'|'.join(catalogue.profiles)}, got "
                            f"{profile!r}")
    out = [c for c in catalogue.cases if profile in c.profiles and c.engine in engines]
    if patterns:
        globs = [_literal_brackets(p) for p in patterns]
        out = [c for c in out if any(fnmatch.fnmatchcase(c.id, g) for g in globs)]
    return out


def _literal_brackets(pattern: str) -> str:
    """A glob in which ``[`` and ``]`` match themselves (case ids end in ``[mode]``)."""
    return pattern.replace("[", "\0").replace("]", "[]]").replace("\0", "[[]")


# ------------------------------------------------------------------------------------- baselines
def baseline_file(directory: Path, profile: str) -> Path:
    """``DIR/<profile>.json``."""
    return directory / f"{profile}.json"


def load_baseline(path: Path) -> dict[str, dict[str, Any]]:
    """Case id -> metric -> baseline value; empty when the file does not exist."""
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, OSError) as exc:
        raise TippetopError(f"--baseline: expected a readable JSON baseline at {str(path)!r}, "
                            f"got: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("cases"), dict):
        raise TippetopError(f"--baseline: expected a baseline file with a 'cases' object, got "
                            f"{str(path)!r} without one")
    return data["cases"]


def update_baseline(path: Path, profile: str, records: Sequence[dict[str, Any]],
                    profile_ids: set[str], environment: dict[str, Any]) -> dict[str, int]:
    """Write the baselines of the cases that ran, atomically.

    Cases that did not run this time (filtered out by ``--engines``/``--cases``, or failed)
    keep their stored values; ids no longer in the profile are dropped.

    Returns:
        Counts: ``written`` (cases whose values were stored), ``added`` (new ids), ``dropped``
        and ``kept``.
    """
    old = load_baseline(path)
    cases = {k: v for k, v in old.items() if k in profile_ids}
    written = added = 0
    for rec in records:
        if rec["error"] is not None:
            continue
        added += rec["id"] not in cases
        cases[rec["id"]] = {m: rec["values"].get(m) for m in rec["metrics"]}
        written += 1
    doc = {
        "format": BASELINE_FORMAT,
        "profile": profile,
        "updated": _now(),
        "note": "written by 'tippetop nightly --update-baseline'; never edit by hand except to "
                "test the regression check",
        "environment": environment,
        "cases": dict(sorted(cases.items())),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_clean(doc), indent=1, sort_keys=False) + "\n"
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return {"written": written, "added": added, "dropped": len(set(old) - set(cases)),
            "kept": len(cases) - written}


# --------------------------------------------------------------------------------------- running
@dataclass
class CaseRun:
    """What one case produced: metric values, details for the report, tables, or an error."""

    case: Case
    values: dict[str, Any] = field(default_factory=dict)
    detail: dict[str, Any] = field(default_factory=dict)
    table: pd.DataFrame | None = None
    error: str | None = None
    wall_s: float = 0.0


#: ``set`` overrides in these sections leave the physics, and so the scene's [expect], as is.
_NEUTRAL_SECTIONS = ("run", "ode", "mujoco", "outputs")


def expectation(case: Case, scene: Scene) -> dict[str, Any]:
    """The scene's [expect] table, or {} when the case's ``set`` leaves it behind.

    A ``set`` that changes the top, the friction or the start makes the scene file's
    expectation about another run; one that changes only the horizon or the solver does not.
    """
    if all(o.split(".", 1)[0] in _NEUTRAL_SECTIONS for o in case.set):
        return dict(scene.expect)
    return {}


def run_metrics(scene: Scene, summary: dict[str, Any], table: pd.DataFrame,
                expect: Mapping[str, Any]) -> dict[str, Any]:
    """Every run metric from a run's summary and observables.

    Args:
        scene: The scene that ran.
        summary: The engine's run summary.
        table: The run's observables.
        expect: The expectation that applies (:func:`expectation`).
    """
    outcome = classify_outcome(table)
    exp = expect.get("outcome")
    E = table["E"].to_numpy()
    return {
        "outcome": outcome,
        "matches_expect": None if exp is None else outcome == exp,
        "theta_asymp": summary["theta_asymp"],
        "t_invert": summary["t_invert"],
        "J_rel_drift": summary["J_rel_drift"],
        "energy_monotone": summary["energy_monotone"],
        "energy_lost": float(E[0] - E[-1]),
        "contact_lost": summary["contact_lost"],
        "status": summary.get("status", "ok"),
    }


def _error_text(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}".strip()


def _run_engine_group(tasks: list[Task], *, scheduler: str | None, workers: int | None,
                      cache_dir: Path, log: Callable[[str], None]) -> list[TaskResult | str]:
    """Run tasks; if the batch raises (e.g. an engine that cannot start), rerun one by one.

    Finished tasks of a failed batch are in ``cache_dir`` already, so the retry recomputes
    only what had not finished. Returns a TaskResult or an error message per task.
    """
    try:
        return list(run_tasks(tasks, scheduler=scheduler, workers=workers, cache_dir=cache_dir,
                              use_cache=True, label="nightly"))
    except TippetopError:
        raise
    except Exception as exc:  # noqa: BLE001 - one broken engine must not hide the others
        log(f"  batch failed ({_error_text(exc)}); retrying its runs one by one")
    out: list[TaskResult | str] = []
    for task in tasks:
        try:
            out.append(run_tasks([task], workers=1, cache_dir=cache_dir, use_cache=True)[0])
        except TippetopError:
            raise
        except Exception as exc:  # noqa: BLE001
            out.append(_error_text(exc))
    return out


def _slug(case_id: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in case_id).strip("_")


def run_cases(cases: Sequence[Case], *, scheduler: str | None = None,
              workers: int | None = None, cache_dir: Path | None = None,
              shared_cache: bool = False,
              log: Callable[[str], None] = lambda s: None) -> list[CaseRun]:
    """Run every case: runs and sweep points in parallel batches per engine, then thresholds.

    Args:
        cases: The selected cases.
        scheduler: A Dask scheduler address, or None for local processes.
        workers: Local worker processes (default: all cores).
        cache_dir: The run cache used for this nightly (duplicates and retries).
        shared_cache: Thresholds also read and write the shared cache (``--cache``).
        log: Where progress lines go.

    Returns:
        One :class:`CaseRun` per case, in order.
    """
    out = {c.id: CaseRun(c) for c in cases}
    scenes: dict[str, Scene] = {}
    for c in cases:  # validate every scene before any work
        try:
            scenes[c.id] = load_scene(c.scene, list(c.overrides))
        except TippetopError as exc:
            raise TippetopError(f"case {c.id}: {exc}") from None
    with tempfile.TemporaryDirectory(prefix="tippetop-nightly-") as tmp:
        cache = cache_dir or Path(tmp)
        for engine in ENGINES:
            jobs: list[tuple[Case, float | None, Task]] = []
            for c in cases:
                if c.engine != engine:
                    continue
                if c.kind == "run":
                    jobs.append((c, None, Task(c.scene, c.overrides, engine)))
                elif c.kind == "sweep":
                    jobs += [(c, n0, Task(c.scene, (*c.overrides, f"init.n0={n0!r}"), engine))
                             for n0 in c.n0]
            if not jobs:
                continue
            log(f"nightly: {len(jobs)} {engine} runs")
            t0 = time.perf_counter()
            results = _run_engine_group([j[2] for j in jobs], scheduler=scheduler,
                                        workers=workers, cache_dir=cache, log=log)
            log(f"  done in {time.perf_counter() - t0:.1f} s")
            for (c, n0, _task), res in zip(jobs, results, strict=True):
                _collect(out[c.id], scenes[c.id], n0, res)
        for c in cases:
            if c.kind == "threshold":
                _run_threshold(out[c.id], scheduler=scheduler, workers=workers,
                               use_cache=shared_cache, log=log)
    for c in cases:
        if c.kind == "sweep" and out[c.id].error is None:
            pts = sorted(out[c.id].detail.get("points", []), key=lambda p: p["n0"])
            out[c.id].detail["points"] = pts
            out[c.id].values = {
                "theta_asymp_vs_n0": {f"{p['n0']:g}": p["theta_asymp"] for p in pts},
                "outcomes_vs_n0": {f"{p['n0']:g}": p["outcome"] for p in pts},
            }
    return [out[c.id] for c in cases]


def _collect(cr: CaseRun, scene: Scene, n0: float | None, res: TaskResult | str) -> None:
    err = res if isinstance(res, str) else res.error
    if err is not None:
        msg = err if n0 is None else f"n0 = {n0:g}: {err}"
        cr.error = msg if cr.error is None else cr.error
        return
    assert not isinstance(res, str) and res.summary is not None and res.table is not None
    s = res.summary
    cr.wall_s += float(s.get("wall_s", 0.0))
    if n0 is None:
        cr.values = run_metrics(scene, s, res.table, expectation(cr.case, scene))
        slip = (res.table["vPX"] ** 2 + res.table["vPY"] ** 2) ** 0.5
        small = slip[slip.notna()] < 0.1 * scene.friction.Lambda_mps
        cr.detail = {"summary": s, "cached": res.cached,
                     "E0": float(res.table["E"].iloc[0]),
                     "slip_small_frac": float(small.mean()) if len(small) else None}
        cr.table = res.table
        return
    cr.detail.setdefault("points", []).append({
        "n0": n0, "theta_asymp": s["theta_asymp"], "outcome": classify_outcome(res.table),
        "t_invert": s["t_invert"], "J_rel_drift": s["J_rel_drift"],
        "status": s.get("status", "ok"), "wall_s": s.get("wall_s")})


def _run_threshold(cr: CaseRun, *, scheduler: str | None, workers: int | None,
                   use_cache: bool, log: Callable[[str], None]) -> None:
    c = cr.case
    t0 = time.perf_counter()
    log(f"nightly: threshold {c.id} (rel_tol {c.rel_tol:g})")
    try:
        res = measure_threshold(c.scene, c.engine, c.which or "n1", c.overrides,
                                rel_tol=c.rel_tol or 0.005, max_rounds=c.max_rounds,
                                points_per_round=c.points_per_round, scheduler=scheduler,
                                workers=workers, use_cache=use_cache)
    except Exception as exc:  # noqa: BLE001 - a failed bisection is that case's error
        cr.error = _error_text(exc)
        cr.wall_s = time.perf_counter() - t0
        log(f"  failed: {cr.error}")
        return
    cr.wall_s = time.perf_counter() - t0
    cr.values = {"measured": res["measured"], "converged": bool(res["converged"])}
    cr.detail = {"threshold": {**res, "rel_tol": c.rel_tol}}
    log(f"  {res['measured']:.4g} rad/s (theory {res['theory']:.4g}), {res['n_runs']} runs, "
        f"{cr.wall_s:.1f} s")


# ----------------------------------------------------------------------------------- comparison
def check_case(cr: CaseRun, baseline: Mapping[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One check per listed metric: value, baseline, tolerance, status and message."""
    c = cr.case
    base = baseline.get(c.id)
    checks = []
    for m in c.metrics:
        tol = tolerance_for(m, c)
        value = cr.values.get(m)
        b = None if base is None else base.get(m)
        chk: dict[str, Any] = {"metric": m, "value": value, "baseline": b,
                               "tolerance": {"kind": tol.kind, "value": tol.value,
                                             "floor": tol.floor, "unit": tol.unit,
                                             "text": tol.describe(), "why": tol.why}}
        if cr.error is not None:
            chk.update(status="error", message=f"{m}: the case did not run: {cr.error}")
        elif base is None or m not in base:
            chk.update(status="new", message=f"{m}: {_fmt(value, tol.unit)} (no baseline yet; "
                       f"--update-baseline adds it)")
        else:
            ok, msg = compare_value(value, b, tol)
            chk.update(status="pass" if ok else "fail",
                       message=f"{m}: {msg}" if ok else f"{m} regressed: {msg}")
        checks.append(chk)
    return checks


def case_status(checks: Sequence[dict[str, Any]]) -> str:
    """``error``, ``fail``, ``new`` or ``pass`` (the worst of the checks)."""
    for s in ("error", "fail", "new"):
        if any(ch["status"] == s for ch in checks):
            return s
    return "pass"


def _top_record(scene: Scene) -> tuple[dict[str, Any], dict[str, Any]]:
    from tippetop.compare import theory
    from tippetop.compare.metrics import outcome_of_angle

    top, fr, ini = scene.top, scene.friction, scene.init
    params = {
        "A_over_C": top.A_over_C, "a_over_R": top.a_over_R,
        "C_factor": top.C_kgm2 / (0.4 * top.M_kg * top.R_m**2),
        "R_m": top.R_m, "a_m": top.a_m, "M_kg": top.M_kg, "A_kgm2": top.A_kgm2,
        "C_kgm2": top.C_kgm2, "g_mps2": top.g_mps2,
        "law": fr.law, "mu": fr.mu, "Lambda_mps": fr.Lambda_mps,
        "theta0": ini.theta0, "thetadot0": ini.thetadot0, "Omega0": ini.Omega0, "n0": ini.n0,
        "t_end_s": scene.run.t_end_s,
    }
    try:
        th: dict[str, Any] = dict(theory.summary(top, n0=ini.n0))
        th["outcome"] = outcome_of_angle(float(th["theta_s"]))
    except (ValueError, ArithmeticError) as exc:
        th = {"error": _error_text(exc)}
    return params, th


def case_record(cr: CaseRun, checks: list[dict[str, Any]]) -> dict[str, Any]:
    """The results.json entry of a case."""
    c = cr.case
    scene = load_scene(c.scene, list(c.overrides))
    params, th = _top_record(scene)
    rec: dict[str, Any] = {
        "id": c.id, "name": c.name, "category": c.category, "kind": c.kind, "mode": c.mode,
        "engine": c.engine, "scene": c.scene, "scene_name": scene.name, "set": list(c.set),
        "overrides": list(c.overrides), "description": c.description or scene.description,
        "metrics": list(c.metrics), "status": case_status(checks), "error": cr.error,
        "wall_s": cr.wall_s, "params": params, "theory": th, "expect": expectation(c, scene),
        "values": cr.values, "checks": checks, **cr.detail,
    }
    if c.kind == "sweep":
        rec.update(figure=c.figure, label=c.label, n0_grid=list(c.n0))
    return rec


# -------------------------------------------------------------------------------------- outputs
def _now() -> str:
    return datetime.now().astimezone().isoformat(timespec="seconds")


def _clean(obj: Any) -> Any:
    """JSON-ready: NaN/inf -> None, numpy scalars -> Python, tuples -> lists."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


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

    from tippetop.compare.runner import code_fingerprint

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
    }


def junit_xml(results: Mapping[str, Any]) -> bytes:
    """JUnit XML: a suite per category, a testcase per case and metric."""
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
                    "classname": f"nightly.{profile}.{cat}.{r['name']}[{r['mode']}]",
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
    """The one-screen summary printed at the end."""
    c = results["counts"]
    lines = [f"tippetop nightly: profile {results['profile']}, {c['cases']} cases, "
             f"{c['checks']} checks in {results['wall_s']:.0f} s",
             f"  checks: {c['checks_pass']} pass, {c['checks_fail']} fail, {c['checks_new']} "
             f"new, {c['checks_error']} error"]

    def block(title: str, items: list[str]) -> None:
        if not items:
            return
        lines.append(title)
        lines.extend(f"  {s}" for s in items[:SUMMARY_LINES])
        if len(items) > SUMMARY_LINES:
            lines.append(f"  ... and {len(items) - SUMMARY_LINES} more (see results.json)")

    recs = results["cases"]
    title = ("CHANGED (accepted into the baseline):" if results.get("baseline_update")
             else "REGRESSIONS:")
    block(title, [f"{r['id']} {ch['message']}" for r in recs for ch in r["checks"]
                  if ch["status"] == "fail"])
    block("ERRORS (case did not run):", [f"{r['id']}: {r['error']}" for r in recs
                                         if r["status"] == "error"])
    new = {r["id"]: [ch["metric"] for ch in r["checks"] if ch["status"] == "new"]
           for r in recs}
    block("NEW (no baseline yet; --update-baseline adds them):",
          [f"{r['id']}: " + (f"all {len(new[r['id']])} metrics"
                             if len(new[r["id"]]) == len(r["checks"])
                             else ", ".join(new[r["id"]])) for r in recs if new[r["id"]]])
    upd = results.get("baseline_update")
    if upd:
        lines.append(f"baseline updated: {results['baseline_file']} ({upd['written']} cases "
                     f"written, {upd['added']} added, {upd['kept']} kept, {upd['dropped']} "
                     f"dropped)")
    else:
        lines.append(f"baseline: {results['baseline_file']}")
    if results.get("videos", {}).get("requested"):
        lines.append(f"videos: {results['videos']['status']}")
    if results.get("report_error"):
        lines.append(f"REPORT FAILED: {results['report_error']}")
    lines.append(f"output: {out_dir}")
    lines.append(f"result: {results['verdict']}")
    return "\n".join(lines)


def prepare_out_dir(out: str | None, force: bool) -> Path:
    """The output folder, checked before any work.

    A new ``nightly-YYYYMMDD-HHMMSS`` in the current folder by default; an existing non-empty
    folder only with ``force``.
    """
    if out is None:
        p = Path.cwd() / f"nightly-{datetime.now():%Y%m%d-%H%M%S}"
    else:
        p = Path(out)
    if p.exists() and not p.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(p)!r}")
    if p.is_dir() and any(p.iterdir()) and not force:
        raise TippetopError(f"--out: expected a new or empty folder (or --force to write into "
                            f"it), got {str(p)!r} which is not empty")
    if not p.parent.is_dir():
        raise TippetopError(f"--out: expected an existing parent folder, got "
                            f"{str(p.parent)!r}")
    return p


def _downsample(table: pd.DataFrame, rows: int = TABLE_ROWS) -> pd.DataFrame:
    step = max(1, math.ceil(len(table) / rows))
    out = table.iloc[::step]
    if out.index[-1] != table.index[-1]:
        out = pd.concat([out, table.iloc[[-1]]])
    return out.reset_index(drop=True)


# ------------------------------------------------------------------------------------------ main
@dataclass
class NightlyOptions:
    """Everything ``tippetop nightly`` was asked for."""

    profile: str = "quick"
    catalogue: Path | None = None
    baseline_dir: Path = BASELINE_DIR
    update_baseline: bool = False
    out: str | None = None
    force: bool = False
    engines: tuple[str, ...] = ENGINES
    cases: tuple[str, ...] = ()
    scheduler: str | None = None
    workers: int | None = None
    cache: bool = False
    videos: bool = False
    accuracy_dir: Path | None = None
    argv: tuple[str, ...] = ()


#: Nightly videos: small, side by side (MuJoCo | reference), at most this many frames each.
VIDEO_SIZE = (320, 240)
VIDEO_FPS = 15.0
VIDEO_MAX_FRAMES = 240
VIDEO_OVERRIDES = ("mujoco.timestep_s=1e-4",)  # paper mode is within 3e-4 rad of 1.25e-5 s


def render_videos(cases: Sequence[Case], out_dir: Path,
                  log: Callable[[str], None]) -> dict[str, Any]:
    """Render one short side-by-side video per scene of the profile's ``paper`` run cases.

    The playback speed is chosen so that a video has at most ``VIDEO_MAX_FRAMES`` frames (at
    least quarter-speed slow motion). Returns what the report links: scene -> relative path.
    """
    from tippetop.models.scene import load_scene
    from tippetop.mujoco_runner.render import render_scene

    scenes = sorted({c.scene for c in cases if c.kind == "run" and c.category == "paper"})
    (out_dir / "videos").mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    failed: dict[str, str] = {}
    for name in scenes:
        scene = load_scene(name, list(VIDEO_OVERRIDES))
        speed = max(0.25, scene.run.t_end_s * VIDEO_FPS / VIDEO_MAX_FRAMES)
        rel = f"videos/{_slug(name)}.mp4"
        log(f"nightly: rendering {rel} (speed {speed:.3g})")
        try:
            render_scene(scene, out_dir / rel, engine="both", fps=VIDEO_FPS, speed=speed,
                         size=VIDEO_SIZE, max_frames=VIDEO_MAX_FRAMES, force=True,
                         progress=False)
            files[name] = rel
        except TippetopError as exc:
            failed[name] = str(exc)
    status = f"{len(files)} written" + (f", {len(failed)} failed" if failed else "")
    return {"requested": True, "status": status, "files": files, "failed": failed}


def run_nightly(opts: NightlyOptions, *, log: Callable[[str], None] | None = None,
                echo: Callable[[str], None] = print) -> int:
    """Run the nightly regression; returns the exit status (0 clean, 1 regression or error).

    Raises:
        TippetopError: bad input (exit 2), before any simulation.
    """
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    started, t0 = _now(), time.perf_counter()
    for e in opts.engines:
        if e not in ENGINES:
            raise TippetopError(f"--engines: expected a comma-separated list of "
                                f"{','.join(ENGINES)}, got {e!r}")
    catalogue = load_catalogue(opts.catalogue)
    cases = select_cases(catalogue, opts.profile, opts.engines, opts.cases)
    if not cases:
        raise TippetopError(f"nightly: expected at least one case for profile "
                            f"{opts.profile!r}, engines {','.join(opts.engines)} and cases "
                            f"{','.join(opts.cases) or '*'}, got none")
    base_dir = Path(opts.baseline_dir)
    if not base_dir.is_dir() and not opts.update_baseline:
        raise TippetopError(f"--baseline: expected an existing folder of baseline files, got "
                            f"{str(base_dir)!r}")
    bfile = baseline_file(base_dir, opts.profile)
    baseline = load_baseline(bfile)
    out_dir = prepare_out_dir(opts.out, opts.force)
    if opts.scheduler and not opts.scheduler.startswith("tcp://"):
        raise TippetopError(f"--scheduler: expected tcp://HOST:PORT, got {opts.scheduler!r}")
    if opts.workers is not None and opts.workers < 1:
        raise TippetopError(f"--workers: expected an integer >= 1, got {opts.workers}")
    if opts.accuracy_dir is not None and not Path(opts.accuracy_dir).is_dir():
        raise TippetopError(f"--accuracy-dir: expected an existing folder, got "
                            f"{str(opts.accuracy_dir)!r}")
    log(f"nightly: profile {opts.profile}, {len(cases)} cases, baseline {bfile}"
        f"{'' if bfile.is_file() else ' (missing: every case is new)'}")

    runs = run_cases(cases, scheduler=opts.scheduler, workers=opts.workers,
                     cache_dir=default_cache_dir() if opts.cache else None,
                     shared_cache=opts.cache, log=log)
    records = [case_record(cr, check_case(cr, baseline)) for cr in runs]
    env = environment()
    out_dir.mkdir(parents=True, exist_ok=True)
    tables: dict[str, pd.DataFrame] = {}
    (out_dir / "tables").mkdir(exist_ok=True)
    for cr, rec in zip(runs, records, strict=True):
        if cr.table is not None:
            tab = _downsample(cr.table)
            rel = f"tables/{_slug(cr.case.id)}.parquet"
            write_atomic(out_dir / rel, lambda tmp, t=tab: t.to_parquet(tmp, index=False))
            rec["table"] = rel
            tables[cr.case.id] = tab
    results: dict[str, Any] = {
        "format": RESULTS_FORMAT,
        "profile": opts.profile,
        "profile_description": catalogue.profiles[opts.profile],
        "catalogue": str(catalogue.path),
        "engines": list(opts.engines),
        "case_patterns": list(opts.cases),
        "command": ["tippetop", "nightly", *opts.argv],
        "started": started,
        "baseline_file": str(bfile),
        "baseline_update": None,
        "videos": (render_videos(cases, out_dir, log) if opts.videos
                   else {"requested": False, "status": "not requested", "files": {}}),
        "environment": env,
        "tolerances": {k: {"kind": t.kind, "value": t.value, "floor": t.floor, "unit": t.unit,
                           "text": t.describe(), "why": t.why} for k, t in TOLERANCES.items()},
        "cases": records,
    }
    results["counts"] = count(records)
    if opts.update_baseline:
        profile_ids = {c.id for c in catalogue.cases if opts.profile in c.profiles}
        results["baseline_update"] = update_baseline(bfile, opts.profile, records,
                                                     profile_ids, env)
    c = results["counts"]
    failed = c["cases_error"] > 0 or (c["cases_fail"] > 0 and not opts.update_baseline)
    results["verdict"] = ("REGRESSION" if c["cases_fail"] and not opts.update_baseline
                          else "ERROR" if c["cases_error"] else "OK")
    results["finished"] = _now()
    results["wall_s"] = time.perf_counter() - t0

    def write_results() -> None:
        text = json.dumps(_clean(results), indent=1) + "\n"
        write_atomic(out_dir / "results.json", lambda tmp: tmp.write_text(text, "utf-8"))
        xml = junit_xml(_clean(results))
        write_atomic(out_dir / "junit.xml", lambda tmp: tmp.write_bytes(xml))

    write_results()
    try:
        from tippetop.compare.report import build_report

        build_report(_clean(results), out_dir / "report.html", tables=tables,
                     accuracy_dir=opts.accuracy_dir)
    except Exception as exc:  # noqa: BLE001 - the verdict is written; the report is part of it
        traceback.print_exc(file=sys.stderr)
        results["report_error"] = _error_text(exc)
        results["verdict"] = ("ERROR" if results["verdict"] == "OK" else results["verdict"]) \
            + " (report failed)"
        failed = True
        write_results()
    echo(summary_text(results, out_dir))
    return EXIT_REGRESSION if failed else EXIT_OK


def _csv(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _cmd_nightly(args: argparse.Namespace) -> int:
    opts = NightlyOptions(
        profile=args.profile, catalogue=Path(args.catalogue) if args.catalogue else None,
        baseline_dir=Path(args.baseline) if args.baseline else BASELINE_DIR,
        update_baseline=args.update_baseline, out=args.out, force=args.force,
        engines=_csv(args.engines), cases=_csv(args.cases or ""), scheduler=args.scheduler,
        workers=args.workers, cache=args.cache, videos=args.videos,
        accuracy_dir=Path(args.accuracy_dir) if args.accuracy_dir else None,
        argv=tuple(getattr(args, "_argv", ()) or sys.argv[2:]))
    return run_nightly(opts)


def add_nightly_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``nightly`` subcommand to the ``tippetop`` parser (``set_defaults(func=...)``)."""
    p = subparsers.add_parser(
        "nightly", help="the regression suite: catalogue vs stored baselines; exit 1 on "
        "regression",
        description="Run the nightly catalogue (models/nightly.toml), compare every metric with "
        "the stored baselines, write results.json, junit.xml and report.html into --out, and "
        "exit 1 on any regression.")
    p.add_argument("--profile", default="quick", help="quick (default, a few minutes), full "
                   "(up to an hour) or stress")
    p.add_argument("--baseline", metavar="DIR", help="folder of <profile>.json baselines "
                   "(default: compare/baselines in the repository)")
    p.add_argument("--update-baseline", dest="update_baseline", action="store_true",
                   help="store this run's values as the baselines (the only way they change)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: a new "
                   "nightly-YYYYMMDD-HHMMSS in the current folder)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.add_argument("--engines", default=",".join(ENGINES), help="comma-separated engines to "
                   "run (default: ode,mujoco)")
    p.add_argument("--cases", metavar="GLOBS", help="only case ids matching these "
                   "comma-separated globs, e.g. 'paper/*[ode]'")
    p.add_argument("--catalogue", metavar="FILE", help="catalogue file (default: "
                   "models/nightly.toml)")
    p.add_argument("--scheduler", help="tcp://HOST:PORT of a Dask scheduler (default: local "
                   "processes)")
    p.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    p.add_argument("--cache", action="store_true", help="reuse the shared run cache (default: "
                   "recompute every run)")
    p.add_argument("--videos", action="store_true", help="also render a short side-by-side "
                   "video of each paper scene (MuJoCo | reference), linked from the report")
    p.add_argument("--accuracy-dir", dest="accuracy_dir", metavar="DIR", help="folder of "
                   "accuracy-versus-cost PNG figures to embed in the report")
    p.set_defaults(func=_cmd_nightly)
    return p


def main(argv: list[str] | None = None) -> int:
    """``python -m tippetop.compare.nightly [options]``: the same as ``tippetop nightly``."""
    from tippetop.compare.cli import EXIT_BAD_INPUT, _Parser

    parser = _Parser(prog="tippetop")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    add_nightly_parser(sub)
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(["nightly", *argv])
    args._argv = argv
    try:
        return args.func(args)
    except TippetopError as exc:
        sys.stderr.write(f"tippetop: error: {exc}\n")
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    raise SystemExit(main())
