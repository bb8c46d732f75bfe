"""The nightly catalogue (``models/nightly.toml``): profiles and cases, read and validated."""

from __future__ import annotations

import fnmatch
import hashlib
import os
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
from tippetop.models.engines import FAMILIES
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.modes import MODES, run_label
from tippetop.models.resources import data_path
from tippetop.models.scene import Override
from tippetop.models.spellings import GOES, OLD_NAMES, note, note_old, old_case_id

#: The catalogue shipped with the package.
CATALOGUE_PATH = data_path("tippetop.models", "nightly.toml")
PROFILES = ("quick", "full", "stress")

#: Metrics each kind of case can check: every metric :mod:`.metrics` declares for the kind
#: with a tolerance against a baseline.
KIND_METRICS: dict[str, tuple[str, ...]] = {
    kind: tuple(m for m in kind_metrics(kind) if m in TOLERANCES) for kind in KINDS}

#: A model case (``model = "top.xml"`` or ``nightly --models``): the modes it runs in when it
#: names none, as ``tippetop matrix`` runs an MJCF top (the file's own contact, then the
#: paper's law, at the largest timestep it fits).
MODEL_MODES = ("file", "paper")
#: A model case's metrics when it names none: the run metrics the catalogue's scenes check,
#: but ``matches_expect`` (a model file has no ``[expect]`` to match). A catalogue case may
#: name others of :data:`KIND_METRICS` (``t_stem``, ``t_left_table``).
MODEL_METRICS = ("outcome", "theta_asymp", "t_invert", "J_rel_drift", "energy_monotone",
                 "energy_lost", "contact_lost", "status")
#: The report's section of the cases ``nightly --models`` adds.
MODELS_CATEGORY = "models"


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
    #: A model case: the MJCF top's absolute path (``scene`` is then the path as given), its
    #: content hash (:func:`model_hash`) and where it came from (``catalogue`` or
    #: ``--models``); empty for a scene.
    model: str = ""
    model_sha256: str = ""
    model_origin: str = ""

    @property
    def scene_arg(self) -> str | None:
        """What :func:`~tippetop.models.scene.load_scene` reads: the scene, or None.

        None for a model case, whose top is ``top.mjcf`` in :attr:`overrides`.
        """
        return None if self.model else self.scene

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
        A model case's top is its file (``top.mjcf``), and in paper mode MuJoCo runs at the
        largest timestep the paper's law fits (``mujoco.fit_paper_timestep``), as ``tippetop
        matrix`` runs an MJCF top.
        """
        if not self.model:
            return (*self.set, *self.extra)
        fit = ((Override.of("mujoco.fit_paper_timestep", True),)
               if self.family == "mujoco" and self.mode == "paper" else ())
        return (Override.of("top.mjcf", self.model), *self.set, *self.extra, *fit)


@dataclass(frozen=True)
class Catalogue:
    """The profiles and the cases (one per mode) of a catalogue file."""

    path: Path
    profiles: dict[str, str]
    cases: tuple[Case, ...]


_COMMON_KEYS = {"name", "category", "kind", "scene", "model", "set", "engines", "modes",
                "profiles", "metrics", "description"}
#: The kinds of case: the run metrics' kinds, and ``probe`` (``tippetop probe``: one probe's
#: quantities against their exact values, in each of its modes).
CASE_KINDS: tuple[str, ...] = (*KINDS, "probe")
_KIND_KEYS = {"run": {"departs"}, "atlas": {"A_over_C", "a_over_R"}, "probe": {"probe"},
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


def model_files(path: Path) -> list[Path]:
    """The files an MJCF top is made of: itself, its ``<include>`` files and its asset files.

    Includes are relative to the including file's folder; mesh, skin and height-field files
    to ``meshdir`` (else ``assetdir``), textures to ``texturedir`` (else ``assetdir``), both
    relative to the top's folder, as MuJoCo reads them. A file that cannot be read is left out
    (the top's parse says what is wrong with it).
    """
    import xml.etree.ElementTree as ET

    from tippetop.models.mjcf_document import parse, read_text

    folder = path.parent
    files: list[Path] = [path]
    roots: list[ET.Element] = []

    def walk(p: Path) -> None:
        try:
            root = parse(read_text(p), str(p))
        except (OSError, TippetopError, ET.ParseError):
            return
        roots.append(root)
        for inc in root.iter("include"):
            name = inc.get("file", "")
            sub = Path(name) if os.path.isabs(name) else p.parent / name
            if name and sub not in files and sub.is_file():
                files.append(sub)
                walk(sub)

    walk(path)
    dirs: dict[str, str] = {}
    for root in roots:
        for comp in root.iter("compiler"):
            for key in ("meshdir", "texturedir", "assetdir"):
                if comp.get(key) is not None:
                    dirs.setdefault(key, comp.get(key, ""))
    for root in roots:
        for tag in ("mesh", "skin", "hfield", "texture"):
            key = "texturedir" if tag == "texture" else "meshdir"
            for el in root.iter(tag):
                name = el.get("file")
                if not name:
                    continue
                asset = Path(name) if os.path.isabs(name) else \
                    folder / dirs.get(key, dirs.get("assetdir", "")) / name
                if asset not in files and asset.is_file():
                    files.append(asset)
    return files


def model_hash(path: Path) -> tuple[str, list[str]]:
    """The SHA-256 of an MJCF top's content (:func:`model_files`), and the files it covers.

    Each file's name relative to the top's folder and its bytes go into the hash, so a moved
    folder keeps its hash and an edit to any of its files changes it.
    """
    h = hashlib.sha256()
    names = []
    for f in model_files(path):
        name = os.path.relpath(f, path.parent)
        names.append(name)
        h.update(name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest(), names


def check_model(given: str, base: Path, where: str) -> tuple[str, str]:
    """A model file checked: it exists and parses as a top. (absolute path, content hash).

    Args:
        given: The path as written (relative to ``base`` unless absolute).
        base: The folder a relative path is relative to (the catalogue's; ``--models``: the
            current folder).
        where: What the error names (``catalogue nightly.toml: case 'x'.model``).

    Raises:
        TippetopError: The file is missing or is not an MJCF top (one line).
    """
    from tippetop.mujoco_runner.state import file_top

    path = Path(given) if os.path.isabs(given) else base / given
    path = Path(os.path.abspath(path))
    if not path.is_file():
        rel = "" if os.path.isabs(given) else f" (relative to {str(base)!r})"
        raise TippetopError(f"{where}: expected an MJCF top file{rel}, got {given!r} (no such "
                            f"file)")
    try:
        file_top(path)
    except TippetopError as exc:
        raise TippetopError(f"{where}: expected an MJCF top file, got {given!r}: {exc}") \
            from None
    return str(path), model_hash(path)[0]


def _entry_cases(entry: dict[str, Any], where: str, profiles: dict[str, str],
                 base: Path | None = None, origin: str = "catalogue") -> list[Case]:
    """The cases of one ``[[case]]`` entry (a model case's file relative to ``base``)."""
    if not isinstance(entry, dict):
        raise TippetopError(f"{where}: expected a table, got {entry!r}")
    kind = _req(entry, "kind", str, where)
    if kind not in CASE_KINDS:
        raise TippetopError(f"{where}.kind: expected one of {'|'.join(CASE_KINDS)}, got "
                            f"{kind!r}{did_you_mean(kind, CASE_KINDS)}")
    if kind == "probe":
        return _probe_cases(entry, where, profiles)
    allowed = _COMMON_KEYS | _KIND_KEYS[kind]
    for key in entry:
        if key not in allowed:
            raise TippetopError(f"{where}: unknown key {key!r}{did_you_mean(key, allowed)} "
                                f"for a {kind} case (expected one of: "
                                f"{', '.join(sorted(allowed))})")
    name = _req(entry, "name", str, where)
    category = _req(entry, "category", str, where)
    scene, model, model_sha256 = _entry_scene(entry, kind, where, base, origin)
    modes = (_req(entry, "modes", list, where) if "modes" in entry or not model
             else list(MODEL_MODES))
    profs = _req(entry, "profiles", list, where)
    metrics = (_req(entry, "metrics", list, where) if "metrics" in entry or not model
               else list(MODEL_METRICS))
    if model and "matches_expect" in metrics:
        raise TippetopError(f"{where}.metrics: expected names from {', '.join(MODEL_METRICS)} "
                            f"for a model case (a model file has no [expect] to match), got "
                            f"'matches_expect'")
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
    extra = _kind_extra(entry, kind, runs, where)
    departs_by_mode = extra.pop("departs_by_mode", {})
    return [Case(id=f"{category}/{name}[{run_label(engine, mode)}]", name=name,
                 category=category, kind=kind, scene=scene, engine=engine, mode=mode,
                 metrics=tuple(metrics), profiles=tuple(profs), set=tuple(over),
                 description=entry.get("description", ""),
                 departs=departs_by_mode.get(mode, ""), extra=more,  # run cases only
                 model=model, model_sha256=model_sha256,
                 model_origin=origin if model else "", **extra)
            for engine, mode, more in runs]


def _probe_cases(entry: dict[str, Any], where: str, profiles: dict[str, str]) -> list[Case]:
    """A probe entry's cases: the probe in each of its modes (all by default) on MuJoCo.

    Its ``scene`` is the probe's name, its ``set`` the probe's parameters (``KEY=VALUE``), its
    metrics the probe's quantities (``probe.<probe>.<quantity>``; a bare quantity name is
    read as the probe's; default: all of them).
    """
    from tippetop.compare.probes import probe_class
    from tippetop.compare.probes.base import metric_name
    from tippetop.compare.probes.study import probes_for

    allowed = {"name", "category", "kind", "probe", "set", "modes", "profiles", "metrics",
               "description"}
    for key in entry:
        if key not in allowed:
            raise TippetopError(f"{where}: unknown key {key!r}{did_you_mean(key, allowed)} "
                                f"for a probe case (expected one of: "
                                f"{', '.join(sorted(allowed))})")
    name = _req(entry, "name", str, where)
    category = _req(entry, "category", str, where)
    probe = _req(entry, "probe", str, where)
    try:
        cls = probe_class(probe)
        over = entry.get("set", [])
        if not (isinstance(over, list) and all(isinstance(x, str) for x in over)):
            raise TippetopError(f"set: expected a list of 'KEY=VALUE' strings, got {over!r}")
        probes_for([probe], over)  # the parameters checked
    except TippetopError as exc:
        raise TippetopError(f"{where}: {exc}") from None
    modes = list(entry.get("modes", cls.modes))
    for m in modes:
        if m not in cls.modes:
            raise TippetopError(f"{where}.modes: expected modes of probe {probe} ("
                                f"{', '.join(cls.modes)}), got {m!r}"
                                f"{did_you_mean(str(m), cls.modes)}")
    known = [metric_name(probe, q.name) for q in cls.quantities]
    metrics = []
    for m in entry.get("metrics", known):
        full = m if str(m).startswith("probe.") else metric_name(probe, str(m))
        if full not in known:
            raise TippetopError(f"{where}.metrics: expected quantities of probe {probe} ("
                                f"{', '.join(q.name for q in cls.quantities)}), got {m!r}")
        metrics.append(full)
    profs = _req(entry, "profiles", list, where)
    for p in profs:
        if p not in profiles:
            raise TippetopError(f"{where}.profiles: expected names from "
                                f"{', '.join(profiles)}, got {p!r}{did_you_mean(p, profiles)}")
    if not (modes and profs and metrics):
        raise TippetopError(f"{where}: expected non-empty modes, profiles and metrics")
    probe_ = cls()

    def measured(mode: str) -> tuple[str, ...]:  # the mode's own quantities, in that order
        own = {metric_name(probe, q.name) for q in probe_.quantities_of(mode)}
        return tuple(m for m in metrics if m in own)

    return [Case(id=f"{category}/{name}[{run_label('mujoco', m)}]", name=name,
                 category=category, kind="probe", scene=probe, engine="mujoco", mode=m,
                 metrics=measured(m), profiles=tuple(profs), set=tuple(over),
                 description=entry.get("description", "") or cls.title)
            for m in modes if measured(m)]


def _entry_scene(entry: dict[str, Any], kind: str, where: str, base: Path | None,
                 origin: str) -> tuple[str, str, str]:
    """The entry's scene as written, and its model file's absolute path and hash (else "")."""
    model = model_sha256 = ""
    if "model" in entry:
        if "scene" in entry:
            raise TippetopError(f"{where}: expected a 'scene' or a 'model' key, got both")
        if kind != "run":
            raise TippetopError(f"{where}.model: expected kind = 'run' (a model file runs as "
                                f"one top), got kind = {kind!r}")
        scene = _req(entry, "model", str, where)
        model, model_sha256 = check_model(scene, base or Path.cwd(),
                                          f"{where}.model" if origin == "catalogue" else where)
    else:
        scene = _req(entry, "scene", str, where)
    return scene, model, model_sha256


def _kind_extra(entry: dict[str, Any], kind: str,
                runs: list[tuple[str, str, tuple[str, ...]]], where: str) -> dict[str, Any]:
    """The keys of the entry's own kind, checked, as :class:`Case` fields (run: its departs)."""
    if kind == "threshold":
        return _threshold_extra(entry, where)
    if kind == "atlas":
        from tippetop.compare.studies.atlas import parse_grid

        extra = {"A_over_C": _req(entry, "A_over_C", str, where),
                 "a_over_R": _req(entry, "a_over_R", str, where)}
        parse_grid(extra["A_over_C"], f"{where}.A_over_C")
        parse_grid(extra["a_over_R"], f"{where}.a_over_R")
        return extra
    if kind == "run" and "departs" in entry:
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
        return {"departs_by_mode": departs}
    if kind == "sweep":
        return {"n0": tuple(parse_range(_req(entry, "n0", str, where))),
                "figure": entry.get("figure", ""), "label": entry.get("label", "")}
    return {}


def _threshold_extra(entry: dict[str, Any], where: str) -> dict[str, Any]:
    """A threshold case's own keys, checked: which, method and bisection's settings."""
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
    return extra


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
                and all(f in FAMILIES for f in families)):
            raise TippetopError(f"{where}.engines: expected a list of {' and '.join(FAMILIES)}, "
                                f"got {families!r}")
    out: list[tuple[str, str, tuple[str, ...]]] = []
    old_given = []
    for m in modes:
        if m in MODES:
            fams = [f for f in (families or FAMILIES) if f in MODES[m].families]
            if not fams:
                raise TippetopError(f"{where}.modes: expected modes the engines "
                                    f"{', '.join(families or FAMILIES)} can run, got {m!r}")
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
             f"engines = [...] and modes = [...] {GOES}")
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
        cases.extend(_entry_cases(entry, f"catalogue {p.name}: case {label!r}", profiles,
                                  base=p.resolve().parent))
    for prof in profiles:
        seen: set[str] = set()
        for c in cases:
            if prof in c.profiles:
                if c.id in seen:
                    raise TippetopError(f"catalogue {p.name}: expected unique case ids in "
                                        f"profile {prof!r}, got {c.id!r} twice")
                seen.add(c.id)
    return Catalogue(p, profiles, tuple(cases))


def migrate_case_id(case_id: str) -> str:
    """A case id of the release before in today's spelling (today's ids are returned as given).

    ``paper/fig3[mujoco-native]`` -> ``paper/fig3[mujoco/native]``;
    ``paper/fig3[mujoco-native]@mujoco==3.3.7`` -> ``paper/fig3[mujoco==3.3.7/native]``;
    ``paper/fig3[ode]`` -> ``paper/fig3[ode/paper]``.
    """
    old = old_case_id(case_id)
    if old is None:
        return case_id
    head, engine, mode, _extra = old
    return f"{head}[{run_label(engine, mode or 'paper')}]"


def model_cases(models: Sequence[str | Path], profile: str, catalogue: Catalogue,
                modes: Sequence[str] = ()) -> list[Case]:
    """The cases ``nightly --models FILE...`` adds to ``profile``: one run case per file.

    Each is in category ``models``, named by its file's stem (made unique against the
    catalogue's names in that category and the other files: the folder's name first, then a
    number), in ``modes`` (default :data:`MODEL_MODES`) on every engine family that can run
    each, with the run metrics of :data:`MODEL_METRICS`. A file given twice runs once.

    Raises:
        TippetopError: A file is missing or is not an MJCF top (one line), before any run.
    """
    taken = {c.name for c in catalogue.cases if c.category == MODELS_CATEGORY}
    out: list[Case] = []
    seen: set[str] = set()
    for given in models:
        given = str(given)
        path = os.path.abspath(given)
        if path in seen:
            continue
        seen.add(path)
        p = Path(path)
        stem = _safe_name(p.stem)
        name = stem
        if name in taken:
            name = f"{_safe_name(p.parent.name)}-{stem}"
        k = 2
        while name in taken:
            name, k = f"{stem}-{k}", k + 1
        taken.add(name)
        entry = {"name": name, "category": MODELS_CATEGORY, "kind": "run", "model": given,
                 "modes": list(modes or MODEL_MODES), "profiles": [profile],
                 "metrics": list(MODEL_METRICS),
                 "description": f"{given} (nightly --models)"}
        out += _entry_cases(entry, "--models", {profile: ""}, base=Path.cwd(),
                            origin="--models")
    return out


def _safe_name(text: str) -> str:
    """``text`` as a case name: letters, digits, ``.``, ``_`` and ``-`` (others ``_``)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", text) or "model"


def select_cases(catalogue: Catalogue, profile: str, engines: Sequence[str] = FAMILIES,
                 patterns: Sequence[str] = (), modes: Sequence[str] = (),
                 models: Sequence[str | Path] = ()) -> list[Case]:
    """The cases of ``profile`` on ``engines`` (families) whose id matches one of ``patterns``.

    Patterns are globs with ``*`` and ``?``; brackets are literal, so ``paper/fig3[*`` selects
    every run of ``paper/fig3``. ``modes``: only the cases in these modes (default: all).

    ``models``: MJCF tops added to the profile (:func:`model_cases`), in ``modes`` when given
    (else :data:`MODEL_MODES`). The patterns select among the catalogue's cases; they narrow
    the files' cases too only when one of them matches one of those (``models/*`` runs the
    files alone; ``paper/*`` runs the paper's cases and the files).

    Raises:
        TippetopError: An unknown profile, or a model file that is missing or not a top.
    """
    if profile not in catalogue.profiles:
        raise TippetopError(f"--profile: expected one of {'|'.join(catalogue.profiles)}, got "
                            f"{profile!r}{did_you_mean(profile, catalogue.profiles)}")
    out = [c for c in catalogue.cases if profile in c.profiles and c.family in engines
           and (not modes or c.mode in modes)]
    added = [c for c in model_cases(models, profile, catalogue, modes) if c.family in engines]
    if patterns:
        new = [migrate_case_id(p) for p in patterns]
        for old, now in zip(patterns, new, strict=True):
            if old != now:
                note_old(f"--cases {old}", now)
        globs = [_literal_brackets(p) for p in new]

        def chosen(cs: list[Case]) -> list[Case]:
            return [c for c in cs if any(fnmatch.fnmatchcase(c.id, g) for g in globs)]

        out = chosen(out)
        added = chosen(added) or added
    return out + added


def on_engine(case: Case, engine: str) -> Case:
    """``case`` (a MuJoCo case) on the MuJoCo engine ``engine``: its id says so."""
    if engine == case.engine:
        return case
    return replace(case, id=f"{case.category}/{case.name}[{run_label(engine, case.mode)}]",
                   engine=engine)


def _literal_brackets(pattern: str) -> str:
    """A glob in which ``[`` and ``]`` match themselves (case ids end in ``[engine/mode]``)."""
    return pattern.replace("[", "\0").replace("]", "[]]").replace("\0", "[[]")
