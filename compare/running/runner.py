"""Many runs at once, in parallel (local cores or Dask) and cached on disk.

A :class:`Task` is one run; :func:`run_tasks` runs a batch, longest first, and serves what the
cache holds. How the work is spread and what the cache key holds: docs/design.md.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, ThreadPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import metadata
from multiprocessing import get_context
from pathlib import Path
from queue import Empty, Full
from typing import Any

import pandas as pd

from tippetop.compare.running.compiling import compile_s, say_compile
from tippetop.compare.running.cost import expected_cost_s, record_mujoco_runs, say_long_run
from tippetop.compare.running.engines import (
    check_engine,
    measured_steps,
    plan_for,
    run_plan,
)
from tippetop.compare.running.io import write_atomic
from tippetop.compare.running.leftovers import clean_cache_leftovers
from tippetop.compare.running.progress import WorkProgress
from tippetop.models.errors import TippetopError
from tippetop.models.plan import RunPlan
from tippetop.models.resources import data_path, user_cache_dir
from tippetop.models.scene import Scene, load_scene

_PACKAGES = ("tippetop.models", "tippetop.reference_ode", "tippetop.mujoco_runner")
#: Files outside those packages' Python sources that shape a cached result (its summary and
#: table), among them the calibrated native-friction settings that native runs use by default.
_MODULES = (("tippetop.compare.running", "engines.py"), ("tippetop.compare.running", "runner.py"),
            ("tippetop.compare.analysis", "metrics.py"),
            ("tippetop.models", "calibrated_native.toml"))
#: Rows kept of each run's observables table in the cache (for figures and reports).
CACHED_TABLE_ROWS = 4000


@dataclass(frozen=True)
class Task:
    """One run: a scene, its overrides, an engine (or a mode name), and who runs it.

    ``spec``: the engine spec that runs a MuJoCo plan (``mujoco``: this process's MuJoCo;
    :mod:`tippetop.models.engines`).
    """

    scene: str | None
    overrides: tuple[str, ...] = ()
    engine: str = "ode"
    label: str = field(default="", compare=False)
    spec: str = "mujoco"

    def load(self) -> Scene:
        """The validated scene."""
        return load_scene(self.scene, list(self.overrides))

    def plan(self, scene: Scene | None = None) -> RunPlan:
        """The run plan (:func:`tippetop.compare.running.engines.plan_for`)."""
        return plan_for(scene or self.load(), self.engine)


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of the source that computes a run and its summary (and of MuJoCo's version)."""
    h = hashlib.sha256()
    files = [(pkg, p) for pkg in _PACKAGES for p in sorted(data_path(pkg).rglob("*.py"))]
    files += [(pkg, data_path(pkg, name)) for pkg, name in _MODULES]
    for pkg, path in files:
        if not path.is_file():
            continue
        h.update(f"{pkg}/{path.relative_to(data_path(pkg)).as_posix()}".encode())
        h.update(path.read_bytes())
    try:
        h.update(metadata.version("mujoco").encode())
    except metadata.PackageNotFoundError:  # pragma: no cover - mujoco is a dependency
        pass
    return h.hexdigest()[:16]


def task_key(task: Task, plan: RunPlan | None = None) -> str:
    """The cache key of a task: its plan's physics (its MJCF text included), the code.

    And for a MuJoCo plan the engine spec that runs it.
    """
    plan = plan or task.plan()
    payload: dict[str, Any] = {**plan.physics(), "code": code_fingerprint()}
    if plan.engine != "ode" and task.spec != "mujoco":
        payload["spec"] = task.spec
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:24]


def _cacheable(task: Task) -> bool:
    """A user's own build (``mujoco@PYTHON``) changes behind its name: never cached."""
    return not task.spec.startswith("mujoco@")


def default_cache_dir() -> Path:
    """``$TIPPETOP_CACHE``, else ``~/.cache/tippetop``."""
    return user_cache_dir()


def _downsample(table: pd.DataFrame, rows: int = CACHED_TABLE_ROWS) -> pd.DataFrame:
    if table.empty:  # a run that failed before its first sample
        return table.reset_index(drop=True)
    step = max(1, len(table) // rows)
    out = table.iloc[::step]
    if out.index[-1] != table.index[-1]:
        out = pd.concat([out, table.iloc[[-1]]])
    return out.reset_index(drop=True)


#: Where a run going in this process says how far it got, ``(report_key, fraction)``: the
#: progress bar's in the main process, a queue to it in a worker; None: nobody is listening.
_REPORTER: Callable[[str, float], None] | None = None


def execute(task: Task, report_key: str | None = None) -> dict[str, Any]:
    """Plan and run one task in this process; returns its summary and a downsampled table.

    Bad input is returned as ``{"error": message}`` rather than raised, so that one bad task
    in a sweep is reported with the others.

    Args:
        task: The run.
        report_key: See :func:`execute_plan`.
    """
    try:
        plan = task.plan()
    except TippetopError as exc:
        return {"error": str(exc)}
    return execute_plan(plan.to_json(), report_key)


def execute_plan(plan_json: str, report_key: str | None = None) -> dict[str, Any]:
    """Run one plan, given as its JSON (:meth:`RunPlan.to_json`), in this process.

    What the process pool's workers and a Dask cluster are sent: the plan as data, which any
    process of this package can run without resolving a scene. Returns its summary and a
    downsampled table, or ``{"error": message}`` for a plan this engine refuses.

    Args:
        plan_json: The plan.
        report_key: With a progress bar listening, a MuJoCo run reports the fraction of its
            simulated time done under this key now and then (the reference ODE is too quick to
            bother; the results are the same either way).
    """
    from tippetop.mujoco_runner.model import TopModelWarning

    with warnings.catch_warnings():
        # The main process resolved the same plan and said each model warning once already.
        warnings.simplefilter("ignore", TopModelWarning)
        try:
            plan = RunPlan.from_json(plan_json)
            progress: bool | Callable[[float], None] = False
            reporter = _REPORTER
            if report_key is not None and reporter is not None and plan.engine != "ode" \
                    and plan.t_end_s > 0:
                t_end = plan.t_end_s

                def progress(t: float) -> None:
                    reporter(report_key, t / t_end)

            run = run_plan(plan, progress=progress)
        except TippetopError as exc:
            return {"error": str(exc)}
    return {"summary": run.summary, "table": _downsample(run.table)}


@dataclass
class TaskResult:
    """A finished task: its summary (or error), its table, and whether it came from the cache."""

    task: Task
    key: str
    summary: dict[str, Any] | None
    table: pd.DataFrame | None
    error: str | None
    cached: bool


class ResultCache:
    """One JSON entry and one Parquet table per task key, written atomically and checksummed.

    The JSON file is ``{"format", "key", "summary", "summary_sha256", "table_sha256"}``: the
    task's summary, the key it was computed for, and the sha256 of the summary (as canonical
    JSON) and of the Parquet file's bytes. An entry that does not verify (a number edited, a
    file cut short or swapped, JSON of another shape such as ``{}`` or ``[]``, another key, or
    an entry written before checksums) is a miss: the task runs again and the entry is
    rewritten. The checksums catch accidents and edits, not an attacker (who can rehash).
    """

    #: The entry format; an entry of any other (or none) is recomputed.
    FORMAT = "tippetop-cache/2"

    def __init__(self, root: Path) -> None:
        self.root = root

    def _paths(self, key: str) -> tuple[Path, Path]:
        d = self.root / key[:2]
        return d / f"{key}.json", d / f"{key}.parquet"

    @staticmethod
    def _digest(summary: dict[str, Any]) -> str:
        """sha256 of the summary as canonical JSON (sorted keys)."""
        return hashlib.sha256(json.dumps(summary, sort_keys=True).encode("utf-8")).hexdigest()

    def get(self, key: str) -> tuple[dict[str, Any], pd.DataFrame] | None:
        """The cached summary and table if the entry verifies, else None (recompute)."""
        import io

        js, pq = self._paths(key)
        try:
            entry = json.loads(js.read_text(encoding="utf-8"))
            data = pq.read_bytes()
        except (ValueError, OSError):  # missing, unreadable, not JSON (or not UTF-8)
            return None
        if not (isinstance(entry, dict) and entry.get("format") == self.FORMAT
                and entry.get("key") == key and isinstance(entry.get("summary"), dict)):
            return None
        summary = entry["summary"]
        if (entry.get("summary_sha256") != self._digest(summary)
                or entry.get("table_sha256") != hashlib.sha256(data).hexdigest()):
            return None
        try:
            return summary, pd.read_parquet(io.BytesIO(data))
        except (ValueError, OSError):  # (cannot happen to bytes that verify, but never fail)
            return None

    def put(self, key: str, summary: dict[str, Any], table: pd.DataFrame) -> None:
        """Store a task's results: the table, then the entry that vouches for it."""
        import io

        js, pq = self._paths(key)
        js.parent.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        table.to_parquet(buf, index=False)
        data = buf.getvalue()
        entry = {"format": self.FORMAT, "key": key, "summary": summary,
                 "summary_sha256": self._digest(summary),
                 "table_sha256": hashlib.sha256(data).hexdigest()}
        text = json.dumps(entry)
        write_atomic(pq, lambda tmp: tmp.write_bytes(data))
        write_atomic(js, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def _progress(plans: list[RunPlan], label: str, slots: int, cached: int,
              shared: int = 0, here: list[RunPlan] | None = None,
              specs: list[str] | None = None) -> WorkProgress | None:
    """The batch's bar on stderr, each run weighted by its expected cost; None off a terminal.

    Its count is of the runs to compute; the note says what the others are (``cached`` taken
    from the cache, ``shared`` the same run as another task's, run once), so that the count
    and the note add up to the tasks asked for. Until a run moves it says how long the
    compiling of ``here`` (the plans of this installation's engines) takes. ``specs``: the
    engine each plan runs on (default ``mujoco``), whose step cost weighs it.
    """
    if not sys.stderr.isatty() or not plans:
        return None
    note = [f"{cached} from the cache"] if cached else []
    if shared:
        note.append(f"{shared} the same as another, run once")
    specs = specs or ["mujoco"] * len(plans)
    return WorkProgress(label, [expected_cost_s(p, s) for p, s in zip(plans, specs, strict=True)],
                        slots=slots,
                        note=", ".join(note), compile_s=compile_s(here or []))


def _slots(scheduler: str | None, workers: int | None, n_tasks: int) -> int:
    """Runs going at once: the local workers, or (a Dask cluster) every task."""
    if scheduler:
        return max(1, n_tasks)
    n = workers or os.cpu_count() or 1
    return 1 if n_tasks <= 1 else min(n, n_tasks)


def run_tasks(
    tasks: Sequence[Task],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    cache_dir: Path | None = None,
    use_cache: bool = True,
    label: str = "runs",
) -> list[TaskResult]:
    """Run tasks in parallel (locally, or on the Dask cluster at ``scheduler``), with caching.

    Args:
        tasks: The runs.
        scheduler: ``tcp://HOST:PORT`` of a Dask scheduler; None runs on local processes.
        workers: Local worker processes (default: all cores).
        cache_dir: Cache folder (default :func:`default_cache_dir`).
        use_cache: Read and write the cache.
        label: Progress-bar label.

    Returns:
        One result per task, in order.
    """
    cache = ResultCache(cache_dir or default_cache_dir()) if use_cache else None
    if cache is not None:
        _clean_cache_once(str(cache.root))  # what a killed run left (SIGKILL)
    for t in tasks:  # validate everything before any work
        check_engine(t.engine)
    pythons = _engine_pythons(tasks, scheduler)  # managed environments made now, not midway
    # a scene that does not load stops everything; a plan refused for its settings (a step the
    # paper's law cannot follow, effects an engine cannot run) is that task's own row
    scenes = [t.load() for t in tasks]
    plans: list[RunPlan | None] = []
    results: list[TaskResult | None] = [None] * len(tasks)
    for i, (task, scene) in enumerate(zip(tasks, scenes, strict=True)):
        try:
            plans.append(task.plan(scene))
        except TippetopError as exc:
            plans.append(None)
            results[i] = TaskResult(task, "", None, None, str(exc), False)
    keys = [task_key(t, p) if p is not None else "" for t, p in zip(tasks, plans, strict=True)]

    def own(i: int, res_summary: dict[str, Any] | None) -> dict[str, Any] | None:
        """A task's own copy of a (shared or cached) summary, with its own unused keys."""
        plan = plans[i]
        if res_summary is None or plan is None:
            return None
        return {**res_summary, "unused": list(plan.unused)}

    todo: dict[str, list[int]] = {}
    for i, (task, key) in enumerate(zip(tasks, keys, strict=True)):
        if plans[i] is None:
            continue
        hit = cache.get(key) if cache and _cacheable(task) else None
        if hit is not None:
            results[i] = TaskResult(task, key, own(i, hit[0]), hit[1], None, True)
        else:
            todo.setdefault(key, []).append(i)
    # longest first: the last runs to start are short, so the cores finish together
    unique = sorted(((key, tasks[idx[0]]) for key, idx in todo.items()),
                    key=lambda kt: -expected_cost_s(plans[todo[kt[0]][0]], kt[1].spec))
    unique_plans: dict[str, RunPlan] = {key: plans[todo[key][0]] for key, _ in unique}
    specs = [t.spec for _, t in unique]  # in the order of unique_plans
    slots = _slots(scheduler, workers, len(unique))
    here = [unique_plans[key] for key, t in unique if t.spec not in pythons]
    say_compile(here)
    say_long_run(list(unique_plans.values()), slots, specs=specs)  # stderr, above a minute
    hits = sum(r is not None and r.cached for r in results)
    shared = sum(len(idx) - 1 for idx in todo.values())
    bar = _progress(list(unique_plans.values()), label, slots, hits, shared, here, specs)
    writer = _CacheWriter(cache) if cache else None
    finished = False
    try:
        for key, out in _dispatch(unique, scheduler, workers, bar, unique_plans, pythons):
            if "error" in out:
                res_summary, table, err = None, None, out["error"]
            else:
                res_summary, table, err = out["summary"], out["table"], None
                if writer is not None and _cacheable(tasks[todo[key][0]]):
                    writer.put(key, res_summary, table)
            for i in todo[key]:
                results[i] = TaskResult(tasks[i], key, own(i, res_summary), table, err, False)
        finished = True
        if scheduler is None:  # what a step of each engine cost, for the next estimate
            computed = {r.key: r.summary for r in results if r is not None and not r.cached}
            for spec in dict.fromkeys(specs):
                record_mujoco_runs(measured_steps(computed.values(), spec), spec)
    finally:  # erased on Ctrl-C too, so that 'tippetop: interrupted' starts its own line
        if bar is not None:
            bar.close()
        if writer is not None:  # every entry written before returning (or raising)
            writer.close(raise_error=finished)
    return [r for r in results if r is not None]


class _CacheWriter:
    """Writes cache entries on a background thread, so the runs never wait for the disk.

    Entries are written in the order given; :meth:`close` waits for all of them. Each entry is
    atomic (:meth:`ResultCache.put`), so a process stopped while one is written leaves no
    partial entry. The first error (a full disk, say) is raised by the next :meth:`put` or by
    :meth:`close`.
    """

    #: Longest wait for the pending entries when the command is being stopped (s).
    STOP_WAIT_S = 2.0

    def __init__(self, cache: ResultCache) -> None:
        import queue

        self.cache = cache
        self.queue: queue.SimpleQueue[tuple[str, dict[str, Any], pd.DataFrame] | None] = \
            queue.SimpleQueue()
        self.error: BaseException | None = None
        self.thread: threading.Thread | None = None
        #: entries written (for tests)
        self.written = 0

    def put(self, key: str, summary: dict[str, Any], table: pd.DataFrame) -> None:
        """Queue one entry (the table is copied: the caller may change its own)."""
        if self.error is not None:
            raise self.error
        if self.thread is None:
            self.thread = threading.Thread(target=self._work, name="tippetop-cache-writer",
                                           daemon=True)
            self.thread.start()
        self.queue.put((key, summary, table.copy()))

    def _work(self) -> None:
        while True:
            item = self.queue.get()
            if item is None:
                return
            if self.error is not None:
                continue
            try:
                self.cache.put(*item)
                self.written += 1
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                self.error = exc

    def close(self, *, raise_error: bool = True) -> None:
        """Wait for the queued entries (briefly when stopping); raise the first error."""
        if self.thread is not None:
            self.queue.put(None)
            self.thread.join(None if raise_error else self.STOP_WAIT_S)
            self.thread = None
        if raise_error and self.error is not None:
            raise self.error


def _engine_pythons(tasks: Sequence[Task], scheduler: str | None) -> dict[str, str]:
    """The interpreter of each engine spec the tasks name other than this process's MuJoCo.

    Managed environments are made here, before any run (each says so on stderr); an engine
    that cannot run is refused in one line. Dask runs this process's MuJoCo only.
    """
    from tippetop.compare.running.engines import engine_python
    from tippetop.models.engines import parse_engine

    specs = {t.spec: parse_engine(t.spec) for t in tasks}
    others = {k: spec for k, spec in specs.items() if not spec.in_process}
    if others and scheduler:
        raise TippetopError(f"--scheduler: expected the MuJoCo installed with tippetop on a "
                            f"Dask cluster, got engines {', '.join(others)}")

    def say(line: str) -> None:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()

    return {k: engine_python(spec, say=say) for k, spec in others.items()}


def _execute_remote(task: Task, plan: RunPlan, python: str,
                    report: Callable[[float], None] | None) -> dict[str, Any]:
    """Run one MuJoCo plan on another engine (its worker); a failure is ``{"error": ...}``."""
    from tippetop.compare.running.engines import run_plan_on
    from tippetop.models.engines import parse_engine

    try:
        run = run_plan_on(parse_engine(task.spec), plan, python=python, progress=report)
    except TippetopError as exc:
        return {"error": str(exc)}
    return {"summary": run.summary, "table": _downsample(run.table)}


def _dispatch(unique: list[tuple[str, Task]], scheduler: str | None, workers: int | None,
              bar: WorkProgress | None, plans: dict[str, RunPlan] | None = None,
              pythons: dict[str, str] | None = None
              ) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the unique tasks; yield ``(key, out)`` as each ends (:func:`execute`'s ``out``).

    On Dask (``scheduler``) every task runs there. Locally the MuJoCo tasks run in this
    process on threads (:func:`_run_mujoco_batched`) while the reference's run on the worker
    processes; ``unique`` is in the order to start them (longest first).
    """
    if not unique:
        return
    index = {key: i for i, (key, _) in enumerate(unique)}

    def report(key: str, fraction: float) -> None:
        if bar is not None and key in index:
            bar.reached(index[key], fraction)

    def done(key: str) -> None:
        if bar is not None:
            bar.finished(index[key])

    plans = plans or {key: task.plan() for key, task in unique}
    if scheduler:
        for key, out in _dispatch_dask(unique, plans, scheduler):
            yield key, out
            done(key)
        return
    n = workers or os.cpu_count() or 1
    pythons = pythons or {}
    remote_tasks = [(k, t) for k, t in unique if plans[k].engine != "ode" and t.spec in pythons]
    mujoco_tasks = [(k, t) for k, t in unique
                    if plans[k].engine != "ode" and t.spec not in pythons]
    ode_tasks = [(k, t) for k, t in unique if plans[k].engine == "ode"]
    pooled = n > 1 and len(ode_tasks) > 1
    pool = queue = threads = None
    futures: dict[Any, str] = {}
    if pooled:
        pool, queue = local_pool(n)
        with _sigint_blocked():  # the workers start with Ctrl-C blocked (see there)
            futures = {pool.submit(execute_plan, plans[key].to_json(),
                                   key if bar is not None else None): key
                       for key, _task in ode_tasks}
    if remote_tasks:  # other engines' workers: a process each, waited for on threads
        threads = ThreadPoolExecutor(max_workers=n, thread_name_prefix="tippetop-engine")
        for key, task in remote_tasks:
            plan = plans[key]

            def tick(t: float, key: str = key, t_end: float = plan.t_end_s) -> None:
                report(key, t / t_end)

            futures[threads.submit(_execute_remote, task, plan, pythons[task.spec],
                                   tick if bar is not None else None)] = key
    waiting = set(futures)
    try:
        if not pooled:
            global _REPORTER
            for key, task in ode_tasks:
                _REPORTER, before = (report if bar is not None else None), _REPORTER
                try:
                    out = execute(task, key)
                finally:
                    _REPORTER = before
                yield key, out
                done(key)
        collected: list[tuple[str, dict[str, Any]]] = []

        def collect() -> None:
            """Between samples of the batch: take the reference's finished runs, redraw."""
            nonlocal waiting
            if waiting:
                finished, waiting = wait(waiting, timeout=0, return_when=FIRST_COMPLETED)
                collected.extend((futures[f], f.result()) for f in finished)
            if queue is not None:
                _drain(queue, report)
            if bar is not None:
                bar.tick()

        for key, out in _run_mujoco_batched(mujoco_tasks, plans, n, report, collect):
            collected.append((key, out))
            while collected:
                k, o = collected.pop(0)
                yield k, o
                done(k)
        while waiting:
            finished, waiting = wait(waiting, timeout=_TICK_S, return_when=FIRST_COMPLETED)
            if queue is not None:
                _drain(queue, report)
            for fut in finished:
                yield futures[fut], fut.result()
                done(futures[fut])
            if bar is not None:
                bar.tick()
        while collected:
            k, o = collected.pop(0)
            yield k, o
            done(k)
    except BaseException:
        if pool is not None:
            _stop_pool(pool)  # Ctrl-C or an error: do not wait for the runs still going
        if threads is not None:
            from tippetop.mujoco_runner.remote import stop_workers

            threads.shutdown(wait=False, cancel_futures=True)
            stop_workers()
        raise
    if threads is not None:
        threads.shutdown(wait=True)


def _run_mujoco_batched(tasks: list[tuple[str, Task]], plans: dict[str, RunPlan], nthread: int,
                        report: Callable[[str, float], None], tick: Callable[[], None]
                        ) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run MuJoCo tasks in this process, stepped together on ``nthread`` threads.

    :func:`tippetop.mujoco_runner.batch.iter_simulate_plans`: paper-mode runs of one model
    layout share a persistent ``mujoco.batch.Batch``, native-mode runs step on worker threads
    in the compiled stepper; each result equals the single run's. Yields what
    :func:`execute` would give for each task, as each run ends.
    """
    if not tasks:
        return
    from tippetop.compare.running.engines import mujoco_engine_run

    keys = [k for k, _ in tasks]
    mj_plans = [plans[k].mujoco for k in keys]
    # Ctrl-C while MuJoCo or numba is first imported would surface as an ImportError (a C
    # extension's "initialization failed"), which an optional import (numba's of scipy) can
    # swallow, losing the Ctrl-C: it is held back until they are imported (about a second)
    with _sigint_deferred():
        from numba.core import registry

        from tippetop.mujoco_runner.batch import iter_simulate_plans
        from tippetop.mujoco_runner.model import TopModelWarning

        registry.cpu_target.target_context.refresh()  # numba's own imports, done once


    def progress(i: int, fraction: float) -> None:
        report(keys[i], fraction)

    with warnings.catch_warnings():
        # the main process resolved the same plans and said each model warning once already
        warnings.simplefilter("ignore", TopModelWarning)
        for i, res in iter_simulate_plans(mj_plans, nthread=nthread, progress=progress,
                                          tick=tick):
            if isinstance(res, TippetopError):
                yield keys[i], {"error": str(res)}
                continue
            run = mujoco_engine_run(plans[keys[i]], res)
            yield keys[i], {"summary": run.summary, "table": _downsample(run.table)}


#: How often the main process reads the workers' reports and redraws the bar (s).
_TICK_S = 0.25


def _drain(queue: Any, report: Callable[[str, float], None]) -> None:
    """Pass on every report the workers have queued (``(key, fraction)``)."""
    while True:
        try:
            key, fraction = queue.get_nowait()
        except (Empty, OSError, ValueError, EOFError):
            return
        report(key, fraction)


def _queue_reporter(queue: Any) -> Callable[[str, float], None]:
    def put(key: str, fraction: float) -> None:
        try:
            queue.put_nowait((key, fraction))
        except (Full, OSError, ValueError):  # a report lost is only a bar that lags
            pass

    return put


def _init_worker(queue: Any, parent: int | None = None, pdeathsig: bool = False) -> None:
    """Worker initializer: runs report to ``queue``; Ctrl-C is the main process's to handle.

    Args:
        queue: Where runs report their progress.
        parent: The main process's pid: the worker dies with it (:func:`_die_with_parent`).
        pdeathsig: Ask the kernel too (the pool was made in the main thread; see there).
    """
    global _REPORTER
    _ignore_sigint()
    if parent is not None:
        _die_with_parent(parent, pdeathsig=pdeathsig)
    queue.cancel_join_thread()  # never wait at exit for reports nobody reads
    _REPORTER = _queue_reporter(queue)


#: Linux's prctl option that signals a process when its parent dies.
_PR_SET_PDEATHSIG = 1
#: How often a worker's watchdog looks whether its parent is still there (s).
_WATCHDOG_S = 0.5


def _die_with_parent(parent: int, *, pdeathsig: bool = True) -> None:
    """End this worker when the main process ``parent`` dies, however it dies (SIGKILL too).

    On Linux the kernel sends SIGKILL on the parent's death (``prctl(PR_SET_PDEATHSIG)``);
    everywhere a daemon thread checks every :data:`_WATCHDOG_S` that the parent is still this
    process's parent and exits the process at once when it is not (re-parented to init).
    The kernel's signal comes when the *thread* that started the worker ends, so it is asked
    for only when the pool lives in the main thread (``pdeathsig``).
    """
    if pdeathsig and sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL),
                                                    0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - no prctl: the watchdog does
            pass
    if os.getppid() != parent:  # the parent died before the kernel could be told
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(_WATCHDOG_S)
        os._exit(1)  # no cleanup: the main process that would read the results is gone

    threading.Thread(target=watch, name="tippetop-parent-watchdog", daemon=True).start()


@contextmanager
def _sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread while worker processes are started.

    A worker inherits the blocked signal, so a Ctrl-C to the process group while it is still
    importing (before :func:`_ignore_sigint` runs) cannot end it with a traceback; the main
    process gets its own Ctrl-C when the block is lifted, not lost. (Workers start in the
    thread that submits to the pool; off the main thread, or without pthread_sigmask,
    nothing is blocked.)
    """
    if threading.current_thread() is not threading.main_thread() \
            or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold Ctrl-C (and SIGTERM) back while the block runs, then act on it (main thread only).

    For code that must not be interrupted half-way (imports of C extensions): a signal that
    comes during the block is recorded, and its handler (Ctrl-C's KeyboardInterrupt, or the
    command's SIGTERM handler, :mod:`tippetop.compare.running.interrupt`) runs when the block ends.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        caught.append(signum)

    held = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, hold) for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if caught:
        handler = previous[signal.Signals(caught[0])]
        if callable(handler):
            handler(caught[0], None)
        raise KeyboardInterrupt


def _ignore_sigint() -> None:
    """Worker initializer: Ctrl-C is the main process's to handle (one line, no tracebacks)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started, end the workers now, and forget the pool."""
    procs = list((getattr(pool, "_processes", None) or {}).values())  # no public way to
    pool.shutdown(wait=False, cancel_futures=True)  # stop them; shutdown forgets them
    for proc in procs:
        proc.terminate()
    local_pool.cache_clear()


#: Age past which a temporary file in the cache is a killed run's leftover (s): a cache
#: write (a summary, a table of at most CACHED_TABLE_ROWS rows) takes well under a second.
_CACHE_LEFTOVER_AGE_S = 600.0


@lru_cache(maxsize=8)
def _clean_cache_once(root: str) -> None:
    """Remove a killed run's temporary files from the cache at ``root``, once per process."""
    clean_cache_leftovers(root, min_age_s=_CACHE_LEFTOVER_AGE_S)


@lru_cache(maxsize=1)
def local_pool(n: int) -> tuple[ProcessPoolExecutor, Any]:
    """One pool of ``n`` worker processes per process, kept for later calls; and its queue.

    The queue carries the workers' progress reports (for the bar).

    A bisection makes several rounds; fresh workers each round would cost seconds of imports.
    """
    ctx = get_context("spawn")
    queue = ctx.Queue()
    pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_init_worker,
                               initargs=(queue, os.getpid(),
                                         threading.current_thread() is threading.main_thread()))
    # idle workers exit at once on shutdown: wait for them, so none outlives the command
    atexit.register(pool.shutdown, wait=True, cancel_futures=True)
    return pool, queue


def _dispatch_dask(unique: list[tuple[str, Task]], plans: dict[str, RunPlan],
                   scheduler: str) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the tasks' plans on the Dask cluster at ``scheduler``, sent as their JSON."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_as_completed
    except ImportError:  # pragma: no cover - distributed is a dependency
        raise TippetopError("--scheduler: expected the 'distributed' package installed, got an "
                            "ImportError") from None
    if not scheduler.startswith("tcp://"):
        raise TippetopError(f"--scheduler: expected tcp://HOST:PORT, got {scheduler!r}")
    try:
        client = Client(scheduler, timeout="10s")
    except OSError as exc:
        raise TippetopError(f"--scheduler: expected a reachable Dask scheduler, got "
                            f"{scheduler!r} ({exc})") from None
    with client:
        futures = client.map(execute_plan, [plans[key].to_json() for key, _ in unique],
                             pure=False)
        keys = {f.key: k for f, (k, _) in zip(futures, unique, strict=True)}
        for fut in dask_as_completed(futures):
            yield keys[fut.key], fut.result()


def strip_timing(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without its wall time (for comparing runs made on different machines)."""
    return {k: v for k, v in summary.items() if k != "wall_s"}


__all__ = ["ResultCache", "Task", "TaskResult", "code_fingerprint", "execute", "execute_plan",
           "local_pool", "run_tasks", "strip_timing", "task_key"]
