"""The history: every nightly's, matrix's and bisect's results, in one SQLite file.

The store is a SQLite database (the standard library's :mod:`sqlite3`), one file,
``$TIPPETOP_CACHE/history.sqlite`` by default (:func:`history_path`). Two processes may append
at once: the file is in WAL mode, a writer waits up to :data:`BUSY_TIMEOUT_S` for the other,
and each append (:func:`append_run`) is one transaction, so a run is in the history whole or
not at all.

What each append keeps (table ``runs``): the kind (``nightly``, ``matrix``, ``bisect``), when it
started, the profile, the project's commit (``git rev-parse HEAD`` of the checkout, else none)
and the package version, the machine (host name, CPU count, platform), the command's
arguments; per engine spec the engine version read back from its runs (table ``engines``); and
one row per case, engine, metric and point (a sweep's n0, an atlas point; ``''`` for a single
value) with its value, unit, tolerance and the nightly's status (table ``measures``).

The file says what it is: SQLite's ``application_id`` is :data:`APPLICATION_ID` and its
``user_version`` the format version, :data:`FORMAT_VERSION`. A file that is not a SQLite
database, a database that is not a tippetop history, or a history of a newer format is refused
in one line (:class:`~tippetop.models.errors.TippetopError`) and left untouched.

Reading it back: :func:`load_series` (every series, its values in time order) and
:func:`change_points` (where a series moved beyond its tolerance: a step, a one-night blip, or
a move on the last night that is not yet either), which name the engine version, else the
commit, that changed on that night (:func:`describe_change`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import sqlite3
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from tippetop.compare.nightly.history_series import (  # noqa: F401 - the history's API
    Change,
    Series,
    Value,
    change_points,
    describe_change,
    engine_family,
    fmt_value,
    levels,
    point_key,
    same_level,
    series_json,
    series_text,
    text_value,
    what_changed,
)
from tippetop.models.errors import TippetopError

#: The history file's name in the cache folder.
FILE_NAME = "history.sqlite"
#: SQLite's ``application_id`` of a tippetop history ("tTpH").
APPLICATION_ID = 0x74547048
#: The format of the file (SQLite's ``user_version``); a newer one is refused.
FORMAT_VERSION = 1
#: What ``tippetop history --json`` prints (its ``format`` key).
JSON_FORMAT = "tippetop-history/1"
#: How long a writer waits for another to finish its append, in seconds.
BUSY_TIMEOUT_S = 60.0
#: The first 16 bytes of every SQLite database file.
SQLITE_HEADER = b"SQLite format 3\x00"
#: The values of a series drawn in the nightly report's trend figures, at most.
TREND_RUNS = 30
#: The series the nightly report draws, at most.
TREND_SERIES = 40

EXPECTED = (f"a tippetop history (a SQLite file of format {FORMAT_VERSION} or older) or a "
            "new file")

_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS runs ("
    " id INTEGER PRIMARY KEY AUTOINCREMENT, kind TEXT NOT NULL, started TEXT NOT NULL,"
    " recorded TEXT NOT NULL, profile TEXT, commit_id TEXT, commit_dirty INTEGER,"
    " tippetop_version TEXT, hostname TEXT, cpu_count INTEGER, platform TEXT,"
    " argv TEXT NOT NULL, verdict TEXT, source TEXT, digest TEXT NOT NULL)",
    "CREATE INDEX IF NOT EXISTS runs_digest ON runs(digest)",
    "CREATE TABLE IF NOT EXISTS engines ("
    " run_id INTEGER NOT NULL REFERENCES runs(id), engine TEXT NOT NULL, version TEXT,"
    " PRIMARY KEY (run_id, engine))",
    "CREATE TABLE IF NOT EXISTS measures ("
    " run_id INTEGER NOT NULL REFERENCES runs(id), case_id TEXT NOT NULL,"
    " engine TEXT NOT NULL, engine_version TEXT, mode TEXT, metric TEXT NOT NULL,"
    " point TEXT NOT NULL DEFAULT '', value REAL, text TEXT, unit TEXT, tol_kind TEXT,"
    " tol_value REAL, tol_floor REAL, status TEXT)",
    "CREATE INDEX IF NOT EXISTS measures_series ON measures(case_id, engine, metric, point)",
)


# --------------------------------------------------------------------------- the file
def history_path(path: str | Path | None = None) -> Path:
    """``path``, else ``$TIPPETOP_CACHE/history.sqlite`` (the cache's history)."""
    if path:
        return Path(path).expanduser()
    from tippetop.compare.running.cache import default_cache_dir

    return default_cache_dir() / FILE_NAME


def _refuse(path: Path, what: str) -> TippetopError:
    return TippetopError(f"--history: expected {EXPECTED}, got {str(path)!r} ({what})")


def _inspect(con: sqlite3.Connection, path: Path) -> int:
    """The file's format version (0: an empty database); refuses a file that is not one."""
    try:
        # one statement, one snapshot: three statements in autocommit are three reads, and a
        # writer creating the history between them showed its tables under no application id
        app, version, tables = con.execute(
            "SELECT (SELECT application_id FROM pragma_application_id),"
            " (SELECT user_version FROM pragma_user_version),"
            " (SELECT count(*) FROM sqlite_master)").fetchone()
    except sqlite3.DatabaseError as exc:
        raise _refuse(path, f"not a SQLite database: {exc}") from None
    if app != APPLICATION_ID:
        if app == 0 and tables == 0 and version == 0:
            return 0  # an empty database: a new history
        raise _refuse(path, "a SQLite database that is not a tippetop history")
    if version > FORMAT_VERSION:
        raise _refuse(path, f"a history of format {version}, newer than this tippetop's "
                      f"{FORMAT_VERSION}: read it with a newer tippetop")
    return int(version)


def check_history(path: str | Path | None = None) -> Path:
    """The history file, checked without writing to it (before a long run appends to it).

    A file that does not exist yet is fine (an append makes it), and so is an empty one.

    Raises:
        TippetopError: A folder, a file that is not a SQLite database, a database that is not
            a tippetop history, or a history of a newer format (one line; the file untouched).
    """
    p = history_path(path)
    if p.is_dir():
        raise _refuse(p, "a folder")
    if not p.exists() or p.stat().st_size == 0:
        return p
    try:
        with p.open("rb") as f:
            head = f.read(len(SQLITE_HEADER))
    except OSError as exc:
        raise _refuse(p, f"unreadable: {exc.strerror or exc}") from None
    if head != SQLITE_HEADER:
        raise _refuse(p, "not a SQLite database")
    con = sqlite3.connect(f"{p.resolve().as_uri()}?mode=ro", uri=True, timeout=BUSY_TIMEOUT_S)
    try:
        _inspect(con, p)
    finally:
        con.close()
    return p


@contextmanager
def open_history(path: str | Path | None = None, *,
                 create: bool = True) -> Iterator[sqlite3.Connection]:
    """A connection to the history (in autocommit: each writer opens its own transaction).

    Args:
        path: The file (default: the cache's, :func:`history_path`).
        create: Make the file and its tables if it has none (else: it must exist).

    Raises:
        TippetopError: As :func:`check_history`, and a missing file when not ``create``.
    """
    p = check_history(path)
    if not create and not p.is_file():
        raise TippetopError(f"--history: expected an existing history file, got {str(p)!r} "
                            "(no such file: a nightly or a matrix makes it, and 'tippetop "
                            "history --import' adds old results)")
    if create:
        p.parent.mkdir(parents=True, exist_ok=True)
    try:
        con = sqlite3.connect(p, timeout=BUSY_TIMEOUT_S, isolation_level=None)
    except sqlite3.Error as exc:
        raise _refuse(p, f"cannot open: {exc}") from None
    try:
        con.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
        if create:
            _initialise(con, p)
        else:
            _inspect(con, p)
        yield con
    finally:
        con.close()


def _switch_to_wal(con: sqlite3.Connection) -> None:
    """``PRAGMA journal_mode = WAL``, retried while another process holds the file.

    The switch needs the file to itself, and SQLite answers "database is locked" at once,
    without its busy handler, where two connections that read it would otherwise wait on each
    other (two writers opening a new history at the same moment); so it is retried here, for
    up to :data:`BUSY_TIMEOUT_S`.
    """
    deadline = time.monotonic() + BUSY_TIMEOUT_S
    while True:
        try:
            con.execute("PRAGMA journal_mode = WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.005 + 0.02 * random.random())  # apart from the other writer's retry


def _initialise(con: sqlite3.Connection, path: Path) -> None:
    """WAL mode, and the tables in one transaction if the file has none yet."""
    _inspect(con, path)
    if con.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
        _switch_to_wal(con)
    con.execute("BEGIN IMMEDIATE")
    try:
        if _inspect(con, path) == 0:  # again, now that no other writer can start it
            for stmt in _SCHEMA:
                con.execute(stmt)
            con.executemany("INSERT OR REPLACE INTO meta VALUES (?, ?)",
                            [("format", "tippetop-history"),
                             ("format_version", str(FORMAT_VERSION)),
                             ("created", _now())])
            con.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            con.execute(f"PRAGMA user_version = {FORMAT_VERSION}")
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise


def timestamp_now() -> str:
    """Now, local time with its UTC offset, to the second (ISO 8601): a run's ``started``."""
    return datetime.now().astimezone().isoformat(timespec="seconds")


_now = timestamp_now


# --------------------------------------------------------------------------- appending
@dataclass
class Measure:
    """One value of one case, engine, metric and point, as the history keeps it."""

    case: str
    engine: str
    metric: str
    value: Any
    engine_version: str | None = None
    mode: str | None = None
    point: str = ""
    unit: str = ""
    tolerance: Mapping[str, Any] | None = None
    status: str | None = None


@dataclass
class RunInfo:
    """Where and when a run ran (the history's ``runs`` row)."""

    kind: str
    started: str
    argv: Sequence[str] = ()
    profile: str | None = None
    commit: str | None = None
    commit_dirty: bool | None = None
    tippetop_version: str | None = None
    hostname: str | None = None
    cpu_count: int | None = None
    platform: str | None = None
    verdict: str | None = None
    source: str | None = None
    engines: dict[str, str | None] = field(default_factory=dict)


def _value_columns(v: Any) -> tuple[float | None, str | None]:
    """(value, text): a number in ``value``; a word, a flag or a non-finite number in text."""
    if v is None:
        return None, None
    if isinstance(v, bool):
        return None, "true" if v else "false"
    if isinstance(v, (int, float)):
        return (float(v), None) if math.isfinite(v) else (None, str(v))
    return None, str(v)


def append_run(run: RunInfo, measures: Sequence[Measure],
               path: str | Path | None = None, *, digest: str | None = None) -> int | None:
    """Append one run and its measures in one transaction; its id (None: already there).

    ``digest`` names the results (the same results imported twice are kept once).
    """
    digest = digest or hashlib.sha256(f"{run.kind}{run.started}{time.time_ns()}{os.getpid()}"
                                      .encode()).hexdigest()
    with open_history(path) as con:
        con.execute("BEGIN IMMEDIATE")
        try:
            if con.execute("SELECT 1 FROM runs WHERE digest = ?", (digest,)).fetchone():
                con.execute("ROLLBACK")
                return None
            cur = con.execute(
                "INSERT INTO runs (kind, started, recorded, profile, commit_id, commit_dirty,"
                " tippetop_version, hostname, cpu_count, platform, argv, verdict, source,"
                " digest) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (run.kind, run.started, _now(), run.profile, run.commit,
                 None if run.commit_dirty is None else int(run.commit_dirty),
                 run.tippetop_version, run.hostname, run.cpu_count, run.platform,
                 json.dumps(list(run.argv)), run.verdict, run.source, digest))
            rid = int(cur.lastrowid or 0)
            con.executemany("INSERT INTO engines VALUES (?, ?, ?)",
                            [(rid, e, v) for e, v in run.engines.items()])
            rows = []
            for m in measures:
                value, text = _value_columns(m.value)
                tol = m.tolerance or {}
                rows.append((rid, m.case, m.engine, m.engine_version, m.mode, m.metric,
                             m.point, value, text, m.unit or tol.get("unit") or "",
                             tol.get("kind"), tol.get("value"), tol.get("floor"), m.status))
            con.executemany("INSERT INTO measures VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?,"
                            " ?, ?)", rows)
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
    return rid


def _here() -> dict[str, Any]:
    """The machine and checkout this process runs on (the nightly's ``environment``)."""
    from tippetop.compare.nightly.outputs import environment

    return environment()


def _spec_version(spec: str, packages: Mapping[str, Any]) -> str | None:
    """An engine's version where its runs did not say it: the package's, or the spec's."""
    if spec == "ode":
        return packages.get("tippetop")
    if spec == "mujoco":
        return packages.get("mujoco")
    try:
        from tippetop.models.engines import parse_engine

        v = parse_engine(spec).version
    except TippetopError:
        return None
    return None if v is None else str(v)


def _nightly_measures(results: Mapping[str, Any]) -> tuple[list[Measure], dict[str, Any]]:
    packages = (results.get("environment") or {}).get("packages") or {}
    versions: dict[str, str | None] = {}
    for rec in results.get("cases", []):  # read back from the runs first
        v = (rec.get("summary") or {}).get("version")
        if v and rec["engine"] not in versions:
            versions[rec["engine"]] = str(v)
    for rec in results.get("cases", []):
        versions.setdefault(rec["engine"], _spec_version(rec["engine"], packages))
    out = []
    for rec in results.get("cases", []):
        for ch in rec.get("checks", []):
            tol = ch.get("tolerance") or {}
            base = dict(case=rec["id"], engine=rec["engine"], metric=ch["metric"],
                        engine_version=versions.get(rec["engine"]), mode=rec.get("mode"),
                        unit=tol.get("unit") or "", tolerance=tol, status=ch.get("status"))
            v = ch.get("value")
            if isinstance(v, dict):
                out += [Measure(value=pv, point=str(k), **base) for k, pv in v.items()]
            else:
                out.append(Measure(value=v, **base))
    return out, versions


def _matrix_measures(results: Mapping[str, Any],
                     settings: Sequence[str]) -> tuple[list[Measure], dict[str, Any]]:
    tols = results.get("tolerances") or {}
    versions: dict[str, str | None] = {e["engine"]: e.get("version")
                                       for e in results.get("engines", [])}
    rows = list((results.get("reference") or {}).values()) + list(results.get("runs", []))
    for r in rows:
        if r.get("version"):
            versions.setdefault(r["engine"], r["version"])
            versions[r["engine"]] = versions[r["engine"]] or r["version"]
        else:
            versions.setdefault(r["engine"], None)
    suffix = f" set {','.join(settings)}" if settings else ""
    out = []
    for r in rows:
        case = f"{r['scene']}[{r.get('run') or r['engine'] + '/' + str(r['mode'])}]{suffix}"
        for metric, tol in tols.items():
            out.append(Measure(case=case, engine=r["engine"], metric=metric,
                               value=r.get(metric), engine_version=r.get("version")
                               or versions.get(r["engine"]), mode=r.get("mode"),
                               unit=tol.get("unit") or "", tolerance=tol))
    return out, versions


def _bisect_measures(results: Mapping[str, Any]) -> tuple[list[Measure], dict[str, Any]]:
    """A bisect's (``tippetop-bisect/1``): each release it ran, its values read back."""
    from tippetop.compare.measures.tolerances import TOLERANCES

    over = results.get("overrides") or []
    suffix = f" set {','.join(over)}" if over else ""
    out, versions = [], {}
    for t in results.get("tested", []):
        engine = str(t["engine"])
        versions.setdefault(engine, t.get("version"))
        case = f"{results.get('scene')}[{engine}/{results.get('mode')}]{suffix}"
        for metric, v in (t.get("values") or {}).items():
            tol = TOLERANCES[metric].to_json() if metric in TOLERANCES else None
            base = dict(case=case, engine=engine, metric=metric,
                        engine_version=t.get("version"), mode=results.get("mode"),
                        tolerance=tol, unit=(tol or {}).get("unit") or "",
                        status=t.get("status"))
            if isinstance(v, dict):
                out += [Measure(value=pv, point=str(k), **base) for k, pv in v.items()]
            else:
                out.append(Measure(value=v, **base))
    return out, versions


def _generic_measures(results: Mapping[str, Any]) -> tuple[list[Measure], dict[str, Any]]:
    from tippetop.compare.measures.tolerances import TOLERANCES

    out, versions = [], {}
    for r in results.get("rows", []):
        tol = r.get("tolerance")
        if tol is None and r["metric"] in TOLERANCES:
            tol = TOLERANCES[r["metric"]].to_json()
        out.append(Measure(case=str(r["case"]), engine=str(r["engine"]),
                           metric=str(r["metric"]), value=r.get("value"),
                           engine_version=r.get("engine_version"), mode=r.get("mode"),
                           point=str(r.get("point") or ""), tolerance=tol,
                           unit=(tol or {}).get("unit") or "", status=r.get("status")))
        versions.setdefault(str(r["engine"]), r.get("engine_version"))
    return out, versions


def results_kind(results: Mapping[str, Any]) -> str | None:
    """``nightly``, ``matrix`` or ``bisect`` from a results dictionary's ``format`` (else None)."""
    fmt = str(results.get("format", ""))
    if fmt.startswith("tippetop-nightly-results/"):
        return "nightly"
    if fmt.startswith("tippetop-matrix/"):
        return "matrix"
    if fmt.startswith("tippetop-bisect/") and isinstance(results.get("tested"), list):
        return "bisect"
    if "rows" in results and isinstance(results["rows"], list):
        return "bisect" if "bisect" in fmt else str(results.get("kind") or "bisect")
    return None


def record_results(kind: str, results: Mapping[str, Any], *, path: str | Path | None = None,
                   profile: str | None = None, argv: Sequence[str] = (),
                   started: str | None = None, source: str | None = None,
                   settings: Sequence[str] = ()) -> int | None:
    """Append a nightly's, a matrix's or a bisect's results to the history; the run's id.

    Args:
        kind: ``nightly``, ``matrix`` or ``bisect`` (what the history calls the run).
        results: The nightly's ``results.json`` dictionary (``format``
            ``tippetop-nightly-results/1``), the matrix's (``tippetop-matrix/2``), the
            bisect's (``tippetop-bisect/1``: each release in ``tested`` with the version read
            back and its ``values``, the case ``SCENE[ENGINE/MODE]``), or any other with
            ``rows``: ``[{case, engine, engine_version, metric, value}]`` and,
            optionally, ``mode``, ``point``, ``status`` and ``tolerance`` ({kind, value,
            floor, unit}; default: the nightly's for that metric).
        path: The history file (default: the cache's).
        profile: The profile (default: ``results["profile"]``).
        argv: The command's arguments (default: ``results["command"]``).
        started: When the run started, ISO 8601 (default: ``results["started"]``, else now).
        source: The file the results were imported from (None: a run of this process, whose
            machine and checkout are recorded where the results do not say them).
        settings: Scene overrides every case ran with (a matrix's ``--set``): part of the case.

    Returns:
        The run's id in the history; None when these results were there already.

    Raises:
        TippetopError: A history file that cannot be one (:func:`check_history`), or results
            of no known form.
        sqlite3.Error, OSError: The append failed (nothing of it is kept).
    """
    fmt = results_kind(results)
    if fmt == "nightly":
        measures, versions = _nightly_measures(results)
    elif fmt == "matrix":
        measures, versions = _matrix_measures(results, settings)
    elif fmt == "bisect" and "tested" in results:
        measures, versions = _bisect_measures(results)
    elif fmt is not None:
        measures, versions = _generic_measures(results)
    else:
        raise TippetopError(f"history: expected nightly, matrix or bisect results "
                            f"(format tippetop-nightly-results/1, tippetop-matrix/2, or "
                            f"'rows'), got format {results.get('format')!r}")
    env = results.get("environment")
    if not env and source is None:
        env = _here()
    env = env or {}
    packages = env.get("packages") or {}
    version = packages.get("tippetop")
    for k, v in versions.items():  # what the runs did not say: the package's, or the spec's
        versions[k] = v or _spec_version(k, packages)
    for m in measures:
        m.engine_version = m.engine_version or versions.get(m.engine)
    command = results.get("command")
    run = RunInfo(kind=kind, started=started or str(results.get("started") or _now()),
                  argv=list(argv) or [str(a) for a in (command or [])],
                  profile=profile or results.get("profile"), commit=env.get("git_commit"),
                  commit_dirty=env.get("git_dirty"), tippetop_version=version,
                  hostname=env.get("hostname"), cpu_count=env.get("cpu_count"),
                  platform=env.get("platform"), verdict=results.get("verdict"), source=source,
                  engines={k: (None if v is None else str(v)) for k, v in versions.items()})
    digest = hashlib.sha256(json.dumps(results, sort_keys=True, default=str).encode()
                            ).hexdigest()
    return append_run(run, measures, path, digest=digest)


def import_results(files: Sequence[str | Path], path: str | Path | None = None
                   ) -> list[tuple[Path, str, int | None]]:
    """Append old ``results.json`` files (nightly, matrix, bisect); (file, kind, run id or None).

    Each file's date is its ``started`` (or ``timestamp``) field, else the file's mtime. Every
    file is read and checked before the first is appended.

    Raises:
        TippetopError: A file that cannot be read, is not JSON or not a nightly's or a
            matrix's results (one line, before anything is appended).
    """
    loaded = []
    for f in files:
        p = Path(f)
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except OSError as exc:
            raise TippetopError(f"--import: expected a readable results.json, got {str(p)!r} "
                                f"({exc.strerror or exc})") from None
        except ValueError as exc:
            raise TippetopError(f"--import: expected a results.json (JSON), got {str(p)!r} "
                                f"({exc})") from None
        kind = results_kind(data) if isinstance(data, dict) else None
        if kind is None:
            got = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise TippetopError(f"--import: expected a nightly's, a matrix's or a bisect's "
                                f"results.json (format tippetop-nightly-results/1, "
                                f"tippetop-matrix/2 or tippetop-bisect/1), got {str(p)!r} "
                                f"(format {got!r})")
        when = data.get("started") or data.get("timestamp")
        if not when:
            when = datetime.fromtimestamp(p.stat().st_mtime).astimezone().isoformat(
                timespec="seconds")
        loaded.append((p, kind, data, str(when)))
    check_history(path)
    return [(p, kind, record_results(kind, data, path=path, started=when,
                                     source=str(p.resolve())))
            for p, kind, data, when in loaded]


# --------------------------------------------------------------------------- reading back
def load_series(path: str | Path | None = None, *, kinds: Sequence[str] = (),
                cases: Sequence[str] = (), engines: Sequence[str] = (),
                metrics: Sequence[str] = (), last: int | None = None,
                case_ids: Sequence[str] | None = None) -> tuple[list[Series], list[dict]]:
    """Every series of the history, its values in time order; and the runs.

    Args:
        path: The history file (it must exist).
        kinds: Only the runs of these kinds (``nightly``, ``matrix``, ``bisect``).
        cases: Only the case ids matching these globs.
        engines: Only these engine specs (``mujoco`` also matches ``mujoco==3.3.7``).
        metrics: Only these metrics.
        last: Only the last ``last`` runs of each kind.
        case_ids: Only these exact case ids.

    Returns:
        The series, and the runs ({id, kind, started, profile, commit, tippetop_version,
        hostname, cpu_count, platform, argv, verdict, source, engines}) in time order.

    Raises:
        TippetopError: As :func:`open_history` without ``create``.
    """
    import fnmatch

    with open_history(path, create=False) as con:
        if _inspect(con, history_path(path)) == 0:
            return [], []
        con.row_factory = sqlite3.Row
        runs = [dict(r) for r in con.execute("SELECT * FROM runs ORDER BY started, id")]
        eng: dict[int, dict[str, str | None]] = {}
        for r in con.execute("SELECT run_id, engine, version FROM engines"):
            eng.setdefault(r["run_id"], {})[r["engine"]] = r["version"]
        if kinds:
            runs = [r for r in runs if r["kind"] in kinds]
        if last:
            keep: list[dict] = []
            for k in dict.fromkeys(r["kind"] for r in runs):
                keep += [r for r in runs if r["kind"] == k][-last:]
            runs = sorted(keep, key=lambda r: (r["started"], r["id"]))
        by_id = {r["id"]: r for r in runs}
        where, params = [], []
        if (kinds or last) and len(by_id) < 30000:  # only the runs kept (SQLite's 32766 ?s)
            where.append(f"run_id IN ({','.join('?' * len(by_id)) or 'NULL'})")
            params += list(by_id)
        if metrics:
            where.append(f"metric IN ({','.join('?' * len(metrics))})")
            params += list(metrics)
        rows = con.execute("SELECT * FROM measures" + (" WHERE " + " AND ".join(where)
                                                       if where else "") + " ORDER BY run_id",
                           params).fetchall()
    for r in runs:
        r["engines"] = eng.get(r["id"], {})
        r["argv"] = json.loads(r["argv"] or "[]")
        r["commit"] = r.pop("commit_id")
        r.pop("digest", None)
    order = {r["id"]: i for i, r in enumerate(runs)}
    series: dict[tuple[str, ...], Series] = {}
    for m in rows:
        run = by_id.get(m["run_id"])
        if run is None:
            continue
        if case_ids is not None and m["case_id"] not in case_ids:
            continue
        if cases and not any(fnmatch.fnmatchcase(m["case_id"], g) for g in cases):
            continue
        if engines and m["engine"] not in engines and engine_family(m["engine"]) not in engines:
            continue
        if metrics and m["metric"] not in metrics:
            continue
        key = (run["kind"], m["case_id"], m["engine"], m["metric"], m["point"])
        s = series.get(key)
        tol = {"kind": m["tol_kind"], "value": m["tol_value"], "floor": m["tol_floor"],
               "unit": m["unit"] or ""}
        if s is None:
            s = series[key] = Series(run["kind"], m["case_id"], m["engine"], m["metric"],
                                     m["point"], m["unit"] or "", tol, [])
        else:
            s.tolerance, s.unit = tol, m["unit"] or s.unit  # the latest run's
        value = m["value"] if m["value"] is not None else text_value(m["text"])
        s.values.append(Value(run["id"], run["started"], value, m["engine_version"],
                              run["commit"], run["tippetop_version"], run["hostname"],
                              m["status"]))
    for s in series.values():
        s.values.sort(key=lambda v: order[v.run])
    return sorted(series.values(), key=lambda s: (s.kind, s.case, s.engine, s.metric,
                                                  point_key(s.point))), runs


def trends(path: str | Path | None, case_ids: Sequence[str], regressed: set[tuple[str, str]],
           *, kind: str = "nightly", runs: int = TREND_RUNS) -> list[dict[str, Any]]:
    """The series of ``case_ids`` that moved over the last ``runs`` runs, for the report.

    A series moved when it has a change-point among those runs, or regressed tonight (its
    (case, metric) in ``regressed``). Each is :func:`series_json`'s, with ``regressed``.
    """
    found, _ = load_series(path, kinds=(kind,), case_ids=list(case_ids), last=runs)
    out = []
    for s in found:
        changes = change_points([v.value for v in s.values], s.tolerance)
        bad = (s.case, s.metric) in regressed
        if changes or bad:
            out.append({**series_json(s, changes), "regressed": bad})
    out.sort(key=lambda t: (not t["regressed"], t["metric"], t["case"]))
    return out[:TREND_SERIES]


def record_nightly(results: Mapping[str, Any], path: str | Path | None,
                   log: Callable[[str], None]) -> dict[str, Any]:
    """Append a nightly's results and read back what moved; never raises.

    Returns:
        ``results["history"]``: ``file``, ``run`` (its id, or None), ``error`` (why it was not
        appended, or None) and ``trends`` (:func:`trends`, for the report's figures).
    """
    from tippetop.compare.running.io import json_ready

    p = history_path(path)
    out: dict[str, Any] = {"file": str(p), "run": None, "error": None, "trends": []}
    try:
        data = json_ready(results)
        out["run"] = record_results("nightly", data, path=p)
        ids = [r["id"] for r in data.get("cases", [])]
        bad = {(r["id"], ch["metric"]) for r in data.get("cases", [])
               for ch in r.get("checks", []) if ch.get("status") == "fail"}
        out["trends"] = trends(p, ids, bad)
    except Exception as exc:  # noqa: BLE001 - the run's results are kept whatever happens here
        out["error"] = " ".join(f"{type(exc).__name__}: {exc}".split())
        log(f"nightly: history not appended to {p}: {out['error']} (the results are kept)")
    return out
