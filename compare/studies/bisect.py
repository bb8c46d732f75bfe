"""Which release moved it: a binary search over releases (or interpreters) for a metric's move.

:func:`bisect` runs a scene on MuJoCo releases in release order (the package registry's list,
:func:`registry_releases`) or on an ordered list of interpreters (:func:`read_pythons`: own
builds in commit order), and finds, for each metric, the first release at which it moves
beyond the nightly's tolerance (the matrix's rule, :func:`~.matrix.differs`) from the first
release's value: about log2(n) releases run, not n. It names the pair (the last release like
the first, the first like the last), the metric's values there and the matrix's attribution at
that pair; it says when the metric moves more than once in the range, and bisects the other
moves within a bound of runs. A release that cannot be installed is skipped and named.

The runs go through a :class:`Runner` (:class:`MatrixRunner`: the matrix's own runs); tests
inject a fake one, and a fake release list (:func:`registry_releases`' ``fetch``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from tippetop.compare.results.bisect import (
    FORMAT,
    BisectResult,
    MetricFinding,
    Move,
    MovePair,
    SkippedRelease,
    TestedRelease,
)
from tippetop.compare.results.matrix import MatrixResult
from tippetop.compare.studies.matrix import COMPARED, differs, metric_tolerance
from tippetop.models.errors import RunFailedError, TippetopError, did_you_mean
from tippetop.models.scene import Override

#: Where the registry's list of a package's releases is read.
REGISTRY_URL = "https://pypi.org/pypi/{package}/json"
#: How long a fetched list of releases is kept in the cache (s).
RELEASES_MAX_AGE_S = 3600.0


# ---------------------------------------------------------------- the list of releases
@dataclass(frozen=True)
class ReleaseList:
    """A package's releases on the registry.

    Attributes:
        releases: The releases that can run here, oldest first (no pre-release, not yanked,
            with a wheel for this platform and Python when the registry says which).
        excluded: Every other version on the registry, with why it cannot run here.
        source: Where the list came from (``https://pypi.org/...``, ``pip index``, ``cache``).
    """

    releases: tuple[str, ...]
    excluded: dict[str, str] = field(default_factory=dict)
    source: str = ""


def _wheel_fits(filename: str, tags: set[Any]) -> bool:
    from packaging.utils import InvalidWheelFilename, parse_wheel_filename

    try:
        return bool(set(parse_wheel_filename(filename)[3]) & tags)
    except InvalidWheelFilename:
        return False


def parse_registry(data: dict[str, Any], *, source: str = "") -> ReleaseList:
    """The releases in a registry's JSON (PyPI's ``/pypi/NAME/json``: ``releases``).

    Each version maps to its files (``filename``, ``yanked``); one without files (a list
    from ``pip index versions``) is kept as it is.
    """
    from packaging.tags import sys_tags
    from packaging.version import InvalidVersion, Version

    tags = set(sys_tags())
    py = f"{sys.version_info[0]}.{sys.version_info[1]}"
    good: list[Any] = []
    excluded: dict[str, str] = {}
    for text, files in (data.get("releases") or {}).items():
        try:
            v = Version(text)
        except InvalidVersion:
            excluded[text] = "not a release number"
            continue
        if v.is_prerelease or v.is_devrelease:
            excluded[text] = "a pre-release"
            continue
        if files:
            live = [f for f in files if not f.get("yanked")]
            if not live:
                excluded[text] = "yanked"
                continue
            if not any(_wheel_fits(str(f.get("filename", "")), tags) for f in live
                       if str(f.get("filename", "")).endswith(".whl")):
                excluded[text] = f"no wheel for this platform and Python {py}"
                continue
        good.append(v)
    return ReleaseList(tuple(str(v) for v in sorted(good)), excluded, source)


def _fetch_pypi(package: str) -> tuple[dict[str, Any], str]:
    url = REGISTRY_URL.format(package=package)
    with urllib.request.urlopen(url, timeout=30) as resp:  # noqa: S310 (a fixed https URL)
        data = json.load(resp)
    return {"releases": {v: [{"filename": f.get("filename"), "yanked": f.get("yanked")}
                             for f in files] for v, files in data["releases"].items()}}, url


def _fetch_pip(package: str) -> tuple[dict[str, Any], str]:
    done = subprocess.run([sys.executable, "-m", "pip", "index", "versions", package],
                          capture_output=True, text=True, timeout=120)
    for line in done.stdout.splitlines():
        if line.strip().startswith("Available versions:"):
            versions = line.split(":", 1)[1].split(",")
            return {"releases": {v.strip(): [] for v in versions if v.strip()}}, "pip index"
    raise OSError((done.stderr.strip().splitlines() or ["no versions listed"])[-1])


def registry_releases(package: str = "mujoco", *,
                      fetch: Callable[[str], dict[str, Any]] | None = None,
                      cache_dir: Path | None = None,
                      max_age_s: float = RELEASES_MAX_AGE_S) -> ReleaseList:
    """A package's releases on the registry, oldest first, kept in the cache a while.

    Args:
        package: The package (``mujoco``).
        fetch: Returns the registry's JSON (``{"releases": {version: [files]}}``) for a
            package (tests inject one; nothing is cached then). Default: PyPI's JSON, else
            ``pip index versions``.
        cache_dir: Where the list is kept (default ``$TIPPETOP_CACHE/registry``).
        max_age_s: How long a kept list is used.

    Raises:
        TippetopError: The registry cannot be read (one line).
    """
    if fetch is not None:
        return parse_registry(fetch(package), source="given")
    from tippetop.models.resources import user_cache_dir

    py = f"py{sys.version_info[0]}{sys.version_info[1]}"
    path = (cache_dir or user_cache_dir() / "registry") / f"{package}-{py}-{sys.platform}.json"
    try:
        kept = json.loads(path.read_text("utf-8"))
        if time.time() - float(kept["fetched"]) < max_age_s:
            return parse_registry(kept["data"], source=f"{kept['source']} (kept "
                                  f"{time.time() - float(kept['fetched']):.0f} s ago)")
    except (OSError, ValueError, KeyError, TypeError):
        pass
    errors = []
    for how in (_fetch_pypi, _fetch_pip):
        try:
            data, source = how(package)
            break
        except (OSError, ValueError, KeyError, subprocess.SubprocessError) as exc:
            errors.append(f"{type(exc).__name__}: {exc}")
    else:
        raise TippetopError(f"--between: expected the package registry's list of {package} "
                            f"releases, got {'; '.join(errors)[:300]}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps({"fetched": time.time(), "source": source, "data": data}),
                       "utf-8")
        os.replace(tmp, path)
    except OSError:
        pass  # a list not kept is fetched again next time
    return parse_registry(data, source=source)


# ---------------------------------------------------------------- what is bisected
@dataclass(frozen=True)
class Candidate:
    """One release or interpreter of the range: its name and the engine that runs it."""

    name: str
    engine: str


def installed_mujoco() -> str | None:
    """The release of the MuJoCo installed with tippetop, or None."""
    from importlib import metadata

    try:
        return metadata.version("mujoco")
    except metadata.PackageNotFoundError:
        return None


def release_range(releases: ReleaseList, a: str, b: str, *,
                  installed: str | None = None) -> list[Candidate]:
    """The releases from ``a`` to ``b`` (both included), each with its engine.

    A release equal to the MuJoCo installed with tippetop (``installed``) runs in this
    process (engine ``mujoco``); the others as ``mujoco==X.Y.Z``.

    Raises:
        TippetopError: An unknown release, A after B, or a range of one release (one line).
    """
    from packaging.version import InvalidVersion, Version

    names = list(releases.releases)
    idx = []
    for text in (a, b):
        t = text.strip().removeprefix("mujoco==")
        try:
            v = str(Version(t))
        except InvalidVersion:
            v = t
        if v in releases.excluded:
            raise TippetopError(f"--between: expected a release that runs here, got {text!r} "
                                f"({releases.excluded[v]})")
        if v not in names:
            raise TippetopError(f"--between: expected a release on the package registry "
                                f"({names[0]} ... {names[-1]}), got {text!r}"
                                f"{did_you_mean(t, names)}" if names else
                                f"--between: expected a release on the package registry, "
                                f"got {text!r} (the registry lists none)")
        idx.append(names.index(v))
    ia, ib = idx
    if ia > ib:
        raise TippetopError(f"--between: expected A before B in release order, got "
                            f"{names[ia]} after {names[ib]}")
    if ia == ib:
        raise TippetopError(f"--between: expected two different releases, got {names[ia]} "
                            "twice (a range with no release to search)")
    return [Candidate(n, "mujoco" if installed and n == installed else f"mujoco=={n}")
            for n in names[ia:ib + 1]]


def read_pythons(path: str | Path) -> list[str]:
    """The interpreters of a ``--pythons`` file, in order: one a line, ``#`` comments.

    A relative path is read from the file's folder; a bare name is a command on PATH.

    Raises:
        TippetopError: No such file, fewer than two interpreters, one that is not there or
            one given twice (one line).
    """
    p = Path(path)
    try:
        text = p.read_text("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TippetopError(f"--pythons: expected a text file of interpreters, one a line, "
                            f"got {str(p)!r} ({getattr(exc, 'strerror', None) or exc})"
                            ) from None
    out: list[str] = []
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if os.sep in line:
            found = line if os.path.isabs(line) else os.path.normpath(p.parent / line)
        else:
            found = shutil.which(line) or ""
        if not (found and os.path.isfile(found) and os.access(found, os.X_OK)):
            raise TippetopError(f"--pythons: expected an interpreter on line {n} of {str(p)!r}"
                                f", got {line!r}, which is not an executable file")
        if found in out:
            raise TippetopError(f"--pythons: expected each interpreter once, got {line!r} "
                                f"again on line {n} of {str(p)!r}")
        out.append(found)
    if len(out) < 2:
        raise TippetopError(f"--pythons: expected at least two interpreters in {str(p)!r}, "
                            f"got {len(out)}")
    return out


def python_range(pythons: Sequence[str], between: Sequence[str] | None) -> list[Candidate]:
    """The interpreters from A to B (default: the first and the last), as ``mujoco@PYTHON``.

    Raises:
        TippetopError: A or B not in the file, or A after B (one line).
    """
    names = list(pythons)
    if between:
        idx = []
        for text in between:
            hit = [i for i, n in enumerate(names) if text in (n, os.path.abspath(text))]
            if not hit:
                raise TippetopError(f"--between: expected two interpreters of --pythons, got "
                                    f"{text!r}{did_you_mean(text, names)}")
            idx.append(hit[0])
        ia, ib = idx
        if ia >= ib:
            raise TippetopError(f"--between: expected A before B in the --pythons file, got "
                                f"{names[ia]!r} {'after' if ia > ib else 'twice, as'} "
                                f"{names[ib]!r}")
        names = names[ia:ib + 1]
    return [Candidate(n, f"mujoco@{n}") for n in names]


def check_metrics(text: str | None) -> list[str]:
    """``--metric``: comma-separated metrics the matrix compares (default: all of them).

    Raises:
        TippetopError: An unknown metric (one line).
    """
    if not text:
        return list(COMPARED)
    out = []
    for m in (s.strip() for s in text.split(",")):
        if not m:
            continue
        if m not in COMPARED:
            raise TippetopError(f"--metric: expected one of {', '.join(COMPARED)}, got {m!r}"
                                f"{did_you_mean(m, COMPARED)}")
        if m not in out:
            out.append(m)
    if not out:
        raise TippetopError(f"--metric: expected one of {', '.join(COMPARED)}, got {text!r}")
    return out


# ---------------------------------------------------------------- the runs
class Runner(Protocol):
    """What runs the releases (:class:`MatrixRunner`; tests inject a fake one)."""

    def prepare(self, engine: str) -> str:
        """Make the engine ready; say how: ``made``, ``found``, ``workers`` or ``none``.

        ``made``: an environment made now; ``workers``: made or found by the Dask workers;
        ``none``: no managed environment. Raises TippetopError when it cannot be installed.
        """

    def measure(self, engines: Sequence[str]) -> dict[str, dict[str, Any]]:
        """Each engine's run: ``{version, status, message, values: {metric: value}}``."""

    def attribute(self, a: str, b: str) -> MatrixResult:
        """The matrix of the two engines, attributed (``run_matrix``'s result)."""


@dataclass
class MatrixRunner:
    """The runs of :func:`~.matrix.run_matrix`: one scene in one mode on the engines asked."""

    scene: str
    mode: str
    overrides: tuple[Override, ...] = ()
    workers: int | None = None
    use_cache: bool = True
    scheduler: str | None = None
    say: Callable[[str], None] | None = None

    def _matrix(self, engines: Sequence[str], attribution: bool) -> MatrixResult:
        from tippetop.compare.studies.matrix import run_matrix
        from tippetop.models.engines import parse_engine

        return run_matrix([self.scene], [parse_engine(e) for e in engines], [self.mode],
                          self.overrides, workers=self.workers, use_cache=self.use_cache,
                          attribution=attribution, scheduler=self.scheduler)

    def prepare(self, engine: str) -> str:
        """Make or find the engine's managed environment (locally; on Dask, its workers do)."""
        from tippetop.compare.running.engines import engine_python
        from tippetop.models.engines import parse_engine
        from tippetop.mujoco_runner.envs import ready_python

        spec = parse_engine(engine)
        if spec.in_process:
            return "none"
        if self.scheduler:
            return "workers" if spec.version is not None else "none"
        if spec.version is None:
            engine_python(spec)  # an interpreter of the user's: there, or one line
            return "none"
        before = ready_python(spec.version)
        engine_python(spec, say=self.say)
        return "found" if before is not None else "made"

    def measure(self, engines: Sequence[str]) -> dict[str, dict[str, Any]]:
        """Run the engines (one batch: the matrix without attribution)."""
        res = self._matrix(engines, attribution=False)
        versions = {e.engine: e.version for e in res.engines}
        out = {}
        for row in res.runs:
            out[row.engine] = {
                "version": row.version or (None if row.status == "failed"
                                           else versions.get(row.engine)),
                "status": row.status, "message": row.message,
                "values": {m: row.value(m) for m in COMPARED}}
        return out

    def attribute(self, a: str, b: str) -> MatrixResult:
        """The matrix of the pair, with its attribution."""
        return self._matrix([a, b], attribution=True)


# ---------------------------------------------------------------- the search
def default_budget(n: int) -> int:
    """The most runs by default: twice a binary search's (its ends and log2 of the range)."""
    return 2 * (2 + math.ceil(math.log2(max(2, n - 1))))


def _not_the_release(exc: TippetopError) -> bool:
    """The cluster's complaint (no scheduler, no worker, gone), not a release's: it stops."""
    from tippetop.compare.running.tasks import SchedulerError

    return isinstance(exc, SchedulerError)


@dataclass
class _Search:
    cands: list[Candidate]
    runner: Runner
    say: Callable[[str], None]
    tty: bool
    rows: dict[int, dict[str, Any]] = field(default_factory=dict)
    skipped: dict[int, str] = field(default_factory=dict)
    steps: int = 0

    @property
    def estimate(self) -> int:
        return 1 + math.ceil(math.log2(max(2, len(self.cands) - 1)))

    def step_line(self, names: list[str], why: str) -> None:
        self.steps += 1
        if self.tty:
            self.say(f"bisect: step {self.steps} of ~{self.estimate}: {' and '.join(names)}"
                     f"{f' ({why})' if why else ''}")

    def run(self, idx: list[int], why: str = "") -> None:
        idx = [i for i in idx if i not in self.rows and i not in self.skipped]
        if not idx:
            return
        self.step_line([self.cands[i].engine for i in idx], why)
        ready: dict[int, str] = {}
        for i in idx:
            try:
                ready[i] = self.runner.prepare(self.cands[i].engine)
            except TippetopError as exc:
                self.skip(i, str(exc))
        if not ready:
            return
        try:
            got = self.runner.measure([self.cands[i].engine for i in ready])
        except TippetopError as exc:
            if _not_the_release(exc):
                raise
            if len(ready) == 1:
                self.skip(next(iter(ready)), str(exc))
                return
            for i in ready:  # one at a time: which of them cannot run
                self.steps -= 1
                self.run_one(i, ready[i])
            return
        for i, env in ready.items():
            self.record(i, got.get(self.cands[i].engine), env)

    def run_one(self, i: int, env: str) -> None:
        self.steps += 1
        try:
            got = self.runner.measure([self.cands[i].engine])
        except TippetopError as exc:
            if _not_the_release(exc):
                raise
            self.skip(i, str(exc))
            return
        self.record(i, got.get(self.cands[i].engine), env)

    def record(self, i: int, row: dict[str, Any] | None, env: str) -> None:
        if row is None or (row["status"] == "failed" and not row.get("version")):
            self.skip(i, (row or {}).get("message") or "it did not run")
            return
        self.rows[i] = {**row, "environment": env, "step": self.steps}

    def skip(self, i: int, reason: str) -> None:
        self.skipped[i] = reason
        self.say(f"bisect: skipped {self.cands[i].name}: {reason}")

    def middle(self, lo: int, hi: int) -> int | None:
        inner = [k for k in range(lo + 1, hi) if k not in self.skipped]
        if not inner:
            return None
        centre = (lo + hi) / 2
        return min(inner, key=lambda k: (abs(k - centre), k))

    def value(self, i: int, metric: str) -> Any:
        return self.rows[i]["values"].get(metric)

    def like(self, metric: str, i: int, j: int) -> bool:
        return not differs(metric, self.value(i, metric), self.value(j, metric))

    def first_move(self, metric: str, a: int, b: int) -> tuple[int, int] | None:
        """The last release like ``a`` and the first unlike it, or None if every run is like it.

        A binary search between the first run unlike ``a`` and the run before it (every run
        before it is like ``a``): with the ends only, the plain bisection; after a search for
        further moves, the first departure those runs saw.
        """
        while True:
            done = sorted(i for i in self.rows if a <= i <= b)
            q = next((i for i in done if not self.like(metric, a, i)), None)
            if q is None:
                return None
            p = max(i for i in done if i < q)
            mid = self.middle(p, q)
            if mid is None:
                return p, q
            self.run([mid], f"{metric}: between {self.cands[p].name} and "
                     f"{self.cands[q].name}")

    def segments(self, metric: str) -> list[tuple[int, int]]:
        """Consecutive runs (in range order) whose values of the metric differ."""
        done = sorted(self.rows)
        return [(p, q) for p, q in zip(done, done[1:], strict=False)
                if not self.like(metric, p, q)]


def _move(s: _Search, metric: str, p: int, q: int) -> Move:
    c = s.cands
    return Move(c[p].name, c[q].name, (s.value(p, metric), s.value(q, metric)),
                not [k for k in range(p + 1, q) if k not in s.skipped],
                tuple(c[k].name for k in range(p + 1, q)))


def bisect(cands: Sequence[Candidate], metrics: Sequence[str], runner: Runner, *,
           budget: int | None = None, attribution: bool = True,
           say: Callable[[str], None] | None = None, tty: bool = False) -> BisectResult:
    """Find each metric's move over the range, and every further move within ``budget`` runs.

    Args:
        cands: The range, in order (:func:`release_range` or :func:`python_range`).
        metrics: The metrics (of :data:`~.matrix.COMPARED`).
        runner: What runs them (:class:`MatrixRunner`).
        budget: The most releases run in all (default :func:`default_budget`); the first move
            of every metric is found whatever it says.
        attribution: Attribute each metric's move at its pair (the matrix's reruns).
        say: Told one line at a time what happens (a note, a skipped release, a step).
        tty: Say each step too (a terminal).

    Returns:
        The search, without its context (the command adds the scene, the mode ...): the
        range, every release that ran or was skipped, and each metric's finding.

    Raises:
        RunFailedError: No release at one end of the range, nor any inside, could run.
    """
    tell = say or (lambda _line: None)
    c = list(cands)
    s = _Search(c, runner, tell, tty)
    n = len(c)
    limit = budget or default_budget(n)
    noun = "interpreters" if c[0].engine.startswith("mujoco@") else "releases"
    tell(f"bisect: {n} {noun} from {c[0].name} to {c[-1].name}: about "
         f"{min(n, s.estimate + 1)} to run, at most {min(n, limit)} for a second move")
    a, b = 0, n - 1
    s.run([a, b], "the ends")
    while a not in s.rows and a < b:  # an end that cannot run: its neighbour stands in
        a += 1
        s.run([a], "an end that could not run: its neighbour")
    while b not in s.rows and b > a:
        b -= 1
        s.run([b], "an end that could not run: its neighbour")
    if a >= b or a not in s.rows or b not in s.rows:
        why = "; ".join(f"{c[k].name}: {r}" for k, r in s.skipped.items())[:400]
        raise RunFailedError(f"bisect: expected two releases of the range to run, got "
                             f"{len(s.rows)}: {why}")
    notes = []
    if (a, b) != (0, n - 1):
        notes.append(f"the range's ends could not run: bisected from {c[a].name} to "
                     f"{c[b].name}")
    firsts = {m: s.first_move(m, a, b) for m in metrics}
    # further moves: consecutive runs that differ, bisected while the budget lasts
    for m in metrics:
        while len(s.rows) + len(s.skipped) < limit:
            open_seg = [(p, q) for p, q in s.segments(m) if s.middle(p, q) is not None]
            if not open_seg:
                break
            p, q = open_seg[0]
            s.run([s.middle(p, q)], f"{m}: a further move, between {c[p].name} and "
                  f"{c[q].name}")
    # the first departure from A's value the further runs saw (a move there and back)
    firsts = {m: s.first_move(m, a, b) for m in metrics}
    by_metric = _by_metric(s, metrics, firsts, a, b)
    if attribution:
        by_metric = _attribute(s, metrics, firsts, by_metric)
    tested = []
    for i in sorted(s.rows):
        r = s.rows[i]
        tested.append(TestedRelease(c[i].name, c[i].engine, r["version"], r["status"],
                                    r.get("message"), r["environment"], r["step"],
                                    r["values"]))
        if r["version"] and not c[i].engine.startswith("mujoco@") and \
                r["version"] != c[i].name:
            notes.append(f"{c[i].engine} read back version {r['version']}, not {c[i].name}")
    return BisectResult(
        tuple(x.name for x in c), (c[0].name, c[-1].name), noun, (c[a].name, c[b].name),
        tuple(tested), len(s.rows),
        sum(1 for i in s.rows if s.rows[i]["environment"] in ("made", "found", "workers")),
        sum(1 for i in s.rows if s.rows[i]["environment"] == "made"), s.steps, limit,
        tuple(SkippedRelease(c[k].name, c[k].engine, r) for k, r in sorted(s.skipped.items())),
        tuple(metrics), by_metric, tuple(notes))


def _by_metric(s: _Search, metrics: Sequence[str], firsts: dict[str, tuple[int, int] | None],
               a: int, b: int) -> dict[str, MetricFinding]:
    """Each metric's finding: its first move from ``a``'s value, every move seen, a sentence."""
    c = s.cands
    by_metric: dict[str, MetricFinding] = {}
    for m in metrics:
        segs = s.segments(m)
        first = firsts[m]
        moves = sorted(set(segs) | ({first} if first else set()))
        more = len(moves) > 1
        by_metric[m] = MetricFinding(
            first is not None,
            MovePair(c[first[0]].name, c[first[1]].name) if first else None,
            (s.value(first[0], m), s.value(first[1], m)) if first else None,
            s.value(a, m), s.value(b, m), metric_tolerance(m).to_json(), more,
            tuple(_move(s, m, p, q) for p, q in moves), None, None,
            _summary(s, m, first, moves, a, b))
    return by_metric


def _attribute(s: _Search, metrics: Sequence[str], firsts: dict[str, tuple[int, int] | None],
               by_metric: dict[str, MetricFinding]) -> dict[str, MetricFinding]:
    """``by_metric`` with the matrix's attribution at each metric's first move."""
    c = s.cands
    out = dict(by_metric)
    pairs: dict[tuple[int, int], list[str]] = {}
    for m in metrics:
        if firsts[m]:
            pairs.setdefault(firsts[m], []).append(m)
    for (p, q), ms in pairs.items():
        s.say(f"bisect: attributing {', '.join(ms)} at {c[p].name} -> {c[q].name}")
        res = s.runner.attribute(c[p].engine, c[q].engine)
        for m in ms:
            d = next((d for d in res.differences if d.metric == m), None)
            if d is None:
                out[m] = dataclasses.replace(out[m], attribution_note=(
                    "the matrix finds no difference of this metric at the pair (each step "
                    "within the tolerance: the move is a drift)"))
                continue
            out[m] = dataclasses.replace(out[m], attribution=d.attribution, closer=d.closer)
    return out


def _summary(s: _Search, m: str, first: tuple[int, int] | None,
             moves: list[tuple[int, int]], a: int, b: int) -> str:
    """The metric's finding in one sentence."""
    c = s.cands
    if first is None and not moves:
        return (f"no move: {c[b].name} is like {c[a].name} (a move and a move back between "
                "two runs would not be seen)")
    if first is None:
        return (f"{c[b].name} is like {c[a].name}, but the metric moves and moves back in "
                f"between ({len(moves)} moves seen)")
    p, q = first
    text = f"moved between {c[p].name} and {c[q].name}"
    if q > p + 1:
        text += f" ({', '.join(c[k].name for k in range(p + 1, q))} could not run)"
    if len(moves) > 1:
        others = [f"{c[x].name} -> {c[y].name}" for x, y in moves if (x, y) != first]
        text += (f"; it moves more than once: both ends of the pair differ from their "
                 f"neighbours ({', '.join(others)})")
    return text


__all__ = ["FORMAT", "REGISTRY_URL", "Candidate", "MatrixRunner", "ReleaseList",
           "Runner", "bisect", "check_metrics", "default_budget", "installed_mujoco",
           "parse_registry", "python_range", "read_pythons",
           "registry_releases", "release_range"]
