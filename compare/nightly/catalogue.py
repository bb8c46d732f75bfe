"""The nightly catalogue (``models/nightly.toml``): profiles and cases, read and validated."""

from __future__ import annotations

import fnmatch
import re
import sys
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from tippetop.compare.measures.metrics import KINDS, TOLERANCES, kind_metrics
from tippetop.compare.studies.sweep import parse_range
from tippetop.compare.studies.threshold import METHODS, WHICH
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.modes import MODES, OLD_NAMES, note, run_label
from tippetop.models.resources import data_path

#: The catalogue shipped with the package.
CATALOGUE_PATH = data_path("tippetop.models", "nightly.toml")
PROFILES = ("quick", "full", "stress")
#: The engine families a catalogue names: ``ode`` (the reference) and ``mujoco`` (the MuJoCo
#: engines ``--engines`` gives: the installed one by default).
ENGINES = ("ode", "mujoco")

#: Metrics each kind of case can check: every metric :mod:`.metrics` declares for the kind
#: with a tolerance against a baseline.
KIND_METRICS: dict[str, tuple[str, ...]] = {
    kind: tuple(m for m in kind_metrics(kind) if m in TOLERANCES) for kind in KINDS}


@dataclass(frozen=True)
class Case:
    """One case of the catalogue on one engine in one mode.

    Its id is ``CATEGORY/NAME[ENGINE/MODE]`` (``paper/fig3[mujoco/native]``). ``engine`` is
    ``ode`` or ``mujoco`` as the catalogue names it, and the engine it runs on after
    :func:`on_engine` (``mujoco==3.3.7``: its id says so).
    """

    id: str
    name: str
    category: str
    kind: str
    scene: str
    engine: str
    mode: str
    metrics: tuple[str, ...]
    profiles: tuple[str, ...]
    set: tuple[str, ...] = ()
    description: str = ""
    which: str | None = None
    method: str = "growth"
    rel_tol: float | None = None
    max_rounds: int = 10
    points_per_round: int = 2
    n0: tuple[float, ...] = ()
    figure: str = ""
    label: str = ""
    A_over_C: str = ""
    a_over_R: str = ""
    departs: str = ""
    extra: tuple[str, ...] = ()

    @property
    def family(self) -> str:
        """``ode`` (the reference) or ``mujoco`` (every MuJoCo engine)."""
        return "ode" if self.engine == "ode" else "mujoco"

    @property
    def run(self) -> str:
        """``ENGINE/MODE``."""
        return run_label(self.engine, self.mode)

    @property
    def overrides(self) -> tuple[str, ...]:
        """The case's ``set`` (and the scene keys an old compound mode name also set).

        The mode's own keys are set by the plan (:func:`tippetop.models.resolve.resolve_plan`).
        """
        return (*self.set, *self.extra)


@dataclass(frozen=True)
class Catalogue:
    """The profiles and the cases (one per mode) of a catalogue file."""

    path: Path
    profiles: dict[str, str]
    cases: tuple[Case, ...]


_COMMON_KEYS = {"name", "category", "kind", "scene", "set", "engines", "modes", "profiles",
                "metrics", "description"}
_KIND_KEYS = {"run": {"departs"}, "atlas": {"A_over_C", "a_over_R"},
              "threshold": {"which", "method", "rel_tol", "max_rounds", "points_per_round"},
              "sweep": {"n0", "figure", "label"}}


def _req(entry: dict[str, Any], key: str, kind: type, where: str) -> Any:
    if key not in entry:
        raise TippetopError(f"{where}: expected a '{key}' key, got none")
    v = entry[key]
    if kind is float:
        # finite and > 0; an int too large for a float (10**400) fails the bound, not float()
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) \
            and 0 < v <= sys.float_info.max
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
        raise TippetopError(f"{where}.kind: expected one of {'|'.join(KINDS)}, got {kind!r}"
                            f"{did_you_mean(kind, KINDS)}")
    allowed = _COMMON_KEYS | _KIND_KEYS[kind]
    for key in entry:
        if key not in allowed:
            raise TippetopError(f"{where}: unknown key {key!r}{did_you_mean(key, allowed)} "
                                f"for a {kind} case (expected one of: "
                                f"{', '.join(sorted(allowed))})")
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
    runs = _runs(entry, modes, where)
    for p in profs:
        if p not in profiles:
            raise TippetopError(f"{where}.profiles: expected names from "
                                f"{', '.join(profiles)}, got {p!r}{did_you_mean(p, profiles)}")
    for m in metrics:
        if m not in KIND_METRICS[kind]:
            raise TippetopError(f"{where}.metrics: expected names from "
                                f"{', '.join(KIND_METRICS[kind])} for a {kind} case, got {m!r}"
                                f"{did_you_mean(m, KIND_METRICS[kind])}")
    if not (runs and profs and metrics):
        raise TippetopError(f"{where}: expected non-empty modes, profiles and metrics")
    extra: dict[str, Any] = {}
    if kind == "threshold":
        which = _req(entry, "which", str, where)
        if which not in WHICH:
            raise TippetopError(f"{where}.which: expected {'|'.join(WHICH)}, got {which!r}"
                                f"{did_you_mean(which, WHICH)}")
        # a case that sets bisection's own keys is a bisection unless it says otherwise
        method = entry.get("method") or ("bisect" if {"max_rounds", "points_per_round"}
                                         & set(entry) else "growth")
        if method not in METHODS:
            raise TippetopError(f"{where}.method: expected {'|'.join(METHODS)}, got "
                                f"{method!r}{did_you_mean(method, METHODS)}")
        extra = {"which": which, "method": method,
                 "rel_tol": (float(_req(entry, "rel_tol", float, where))
                             if method == "bisect" or "rel_tol" in entry else None),
                 "max_rounds": entry.get("max_rounds", 10),
                 "points_per_round": entry.get("points_per_round", 2)}
        for key in ("max_rounds", "points_per_round"):
            if key in entry:
                if method != "bisect":
                    raise TippetopError(f"{where}.{key}: applies to method = 'bisect' only")
                _req(entry, key, int, where)
    elif kind == "atlas":
        from tippetop.compare.studies.atlas import parse_grid

        extra = {"A_over_C": _req(entry, "A_over_C", str, where),
                 "a_over_R": _req(entry, "a_over_R", str, where)}
        parse_grid(extra["A_over_C"], f"{where}.A_over_C")
        parse_grid(extra["a_over_R"], f"{where}.a_over_R")
    elif kind == "run" and "departs" in entry:
        departs = entry["departs"]
        names = {m for _e, m, _x in runs}
        ok = isinstance(departs, dict) and bool(departs)
        if ok:
            departs = {_mode_name(m): why for m, why in departs.items()}
            ok = all(m in names and isinstance(why, str) and why.strip()
                     for m, why in departs.items())
        if not ok:
            raise TippetopError(f"{where}.departs: expected a table of the case's modes "
                                f"({', '.join(sorted(names))}) = 'why it departs from the "
                                f"theory', got {entry['departs']!r}")
        extra = {"departs_by_mode": departs}
    elif kind == "sweep":
        extra = {"n0": tuple(parse_range(_req(entry, "n0", str, where))),
                 "figure": entry.get("figure", ""), "label": entry.get("label", "")}
    departs_by_mode = extra.pop("departs_by_mode", {})
    return [Case(id=f"{category}/{name}[{run_label(engine, mode)}]", name=name,
                 category=category, kind=kind, scene=scene, engine=engine, mode=mode,
                 metrics=tuple(metrics), profiles=tuple(profs), set=tuple(over),
                 description=entry.get("description", ""),
                 departs=departs_by_mode.get(mode, ""), extra=more,  # run cases only
                 **extra)
            for engine, mode, more in runs]


def _mode_name(name: str) -> str:
    """A mode, or the mode of a compound name of the release before (``mujoco-native``)."""
    old = OLD_NAMES.get(name)
    return old[1] or "paper" if old is not None and name not in MODES else name


def _runs(entry: dict[str, Any], modes: list[str],
          where: str) -> list[tuple[str, str, tuple[str, ...]]]:
    """(engine, mode, extra scene keys) of each case of a catalogue entry.

    ``modes`` on every engine family of ``engines`` (default: every family that can run
    it); a compound name of the release before (``mujoco-native``, ``ode-coulomb``) is its
    engine and mode, with a note.
    """
    families = entry.get("engines")
    if families is not None:
        if not (isinstance(families, list) and families
                and all(f in ENGINES for f in families)):
            raise TippetopError(f"{where}.engines: expected a list of {' and '.join(ENGINES)}, "
                                f"got {families!r}")
    out: list[tuple[str, str, tuple[str, ...]]] = []
    old_given = []
    for m in modes:
        if m in MODES:
            fams = [f for f in (families or ENGINES) if f in MODES[m].families]
            if not fams:
                raise TippetopError(f"{where}.modes: expected modes the engines "
                                    f"{', '.join(families or ENGINES)} can run, got {m!r}")
            out += [(f, m, ()) for f in fams]
        elif m in OLD_NAMES:
            engine, mode, extra = OLD_NAMES[m]
            old_given.append(m)
            out.append((engine, mode or "paper", extra))
        else:
            raise TippetopError(f"{where}.modes: expected names from {', '.join(MODES)}, got "
                                f"{m!r}{did_you_mean(m, MODES)}")
    if old_given:
        note(f"{where}: modes {', '.join(old_given)} name engines and modes together: now "
             "engines = [...] and modes = [...] (the old spelling goes in the next release)")
    return out


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
    except ValueError as exc:  # TOML, UTF-8, or an integer of over 4300 digits
        raise TippetopError(f"catalogue {p.name}: expected valid TOML, got: {exc}") from None
    for key in data:
        if key not in ("profiles", "case"):
            raise TippetopError(f"catalogue {p.name}: unknown top-level key {key!r}"
                                f"{did_you_mean(key, ('profiles', 'case'))} (expected "
                                f"[profiles.NAME] and [[case]])")
    prof_raw = data.get("profiles", {})
    if not isinstance(prof_raw, dict):
        raise TippetopError(f"catalogue {p.name}: profiles: expected a table of "
                            f"[profiles.NAME], got {prof_raw!r}")
    profiles = {name: str(body.get("description", "")) if isinstance(body, dict) else ""
                for name, body in prof_raw.items()}
    if not profiles:
        raise TippetopError(f"catalogue {p.name}: expected at least one [profiles.NAME]")
    case_raw = data.get("case", [])
    if not isinstance(case_raw, list):
        raise TippetopError(f"catalogue {p.name}: case: expected [[case]] tables, got "
                            f"{case_raw!r}")
    cases: list[Case] = []
    for i, entry in enumerate(case_raw):
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


#: A case id of the release before: ``HEAD[COMPOUND]`` or ``HEAD[COMPOUND]@ENGINE``.
_OLD_ID = re.compile(r"^(?P<head>.*)\[(?P<mode>[^\]/]+)\](?:@(?P<engine>.+))?$")


def migrate_case_id(case_id: str) -> str:
    """A case id of the release before in today's spelling (today's ids are returned as given).

    ``paper/fig3[mujoco-native]`` -> ``paper/fig3[mujoco/native]``;
    ``paper/fig3[mujoco-native]@mujoco==3.3.7`` -> ``paper/fig3[mujoco==3.3.7/native]``;
    ``paper/fig3[ode]`` -> ``paper/fig3[ode/paper]``.
    """
    m = _OLD_ID.match(case_id)
    if m is None or m["mode"] not in OLD_NAMES:
        return case_id
    family, mode, _extra = OLD_NAMES[m["mode"]]
    return f"{m['head']}[{run_label(m['engine'] or family, mode or 'paper')}]"


def select_cases(catalogue: Catalogue, profile: str, engines: Sequence[str] = ENGINES,
                 patterns: Sequence[str] = (), modes: Sequence[str] = ()) -> list[Case]:
    """The cases of ``profile`` on ``engines`` (families) whose id matches one of ``patterns``.

    Patterns are globs with ``*`` and ``?``; brackets are literal, so ``paper/fig3[*`` selects
    every run of ``paper/fig3``. ``modes``: only the cases in these modes (default: all).
    """
    if profile not in catalogue.profiles:
        raise TippetopError(f"--profile: expected one of {'|'.join(catalogue.profiles)}, got "
                            f"{profile!r}{did_you_mean(profile, catalogue.profiles)}")
    out = [c for c in catalogue.cases if profile in c.profiles and c.family in engines
           and (not modes or c.mode in modes)]
    if patterns:
        new = [migrate_case_id(p) for p in patterns]
        for old, now in zip(patterns, new, strict=True):
            if old != now:
                note(f"--cases {old} is now {now} (the old spelling goes in the next release)")
        globs = [_literal_brackets(p) for p in new]
        out = [c for c in out if any(fnmatch.fnmatchcase(c.id, g) for g in globs)]
    return out


def on_engine(case: Case, engine: str) -> Case:
    """``case`` (a MuJoCo case) on the MuJoCo engine ``engine``: its id says so."""
    if engine == case.engine:
        return case
    return replace(case, id=f"{case.category}/{case.name}[{run_label(engine, case.mode)}]",
                   engine=engine)


def _literal_brackets(pattern: str) -> str:
    """A glob in which ``[`` and ``]`` match themselves (case ids end in ``[engine/mode]``)."""
    return pattern.replace("[", "\0").replace("]", "[]]").replace("\0", "[[]")
