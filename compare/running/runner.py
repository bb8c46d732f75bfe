"""Many runs at once, in parallel (local cores or Dask) and cached on disk.

A :class:`~.tasks.Task` is one run; :func:`run_tasks` runs a batch, longest first, and serves
what the cache holds (:mod:`.cache`): the reference's runs on the local worker processes
(:mod:`.pool`) or a Dask cluster (:mod:`.cluster`), MuJoCo's stepped together on threads in
this process, other engines' through their workers. How the work is spread and what the cache
key holds: docs/design.md.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

from tippetop.compare.measures.summary import RunSummary, measured_steps
from tippetop.compare.running.cache import (
    CacheWriter,
    ResultCache,
    cacheable,
    clean_cache_once,
    code_fingerprint,
    default_cache_dir,
    task_key,
)
from tippetop.compare.running.compiling import compile_s, say_compile
from tippetop.compare.running.cost import expected_cost_s, record_mujoco_runs, say_long_run
from tippetop.compare.running.pool import (
    TICK_S,
    drain,
    local_pool,
    sigint_blocked,
    sigint_deferred,
    stop_pool,
)
from tippetop.compare.running.progress import WorkProgress
from tippetop.compare.running.tasks import (
    SchedulerLost,
    Task,
    TaskResult,
    downsample,
    execute,
    execute_plan,
    set_reporter,
    strip_timing,
)
from tippetop.models.engines import parse_engine
from tippetop.models.errors import TippetopError
from tippetop.models.modes import parse_mode
from tippetop.models.plan import RunPlan
from tippetop.models.spellings import old_spelling


def _progress(plans: list[RunPlan], label: str, slots: int, cached: int,
              shared: int = 0, here: list[RunPlan] | None = None) -> WorkProgress | None:
    """The batch's bar on stderr, each run weighted by its expected cost; None off a terminal.

    Its count is of the runs to compute; the note says what the others are (``cached`` taken
    from the cache, ``shared`` the same run as another task's, run once), so that the count
    and the note add up to the tasks asked for. Until a run moves it says how long the
    compiling of ``here`` (the plans of this installation's engines) takes. Each plan is
    weighed by the step cost of the engine it runs on.
    """
    if not sys.stderr.isatty() or not plans:
        return None
    note = [f"{cached} from the cache"] if cached else []
    if shared:
        note.append(f"{shared} the same as another, run once")
    return WorkProgress(label, [expected_cost_s(p) for p in plans], slots=slots,
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
        clean_cache_once(str(cache.root))  # what a killed run left (SIGKILL)
    for t in tasks:  # validate everything before any work
        _check_task(t)
    plans, results = _plan_tasks(tasks)
    # managed environments made now, before any run, not midway (on Dask: by each worker)
    pythons = _engine_pythons([p for p in plans if p is not None], scheduler)
    keys = [task_key(t, p) if p is not None else "" for t, p in zip(tasks, plans, strict=True)]
    todo = _serve_cached(tasks, plans, keys, cache, results)
    # longest first: the last runs to start are short, so the cores finish together
    unique = sorted(((key, tasks[idx[0]]) for key, idx in todo.items()),
                    key=lambda kt: -expected_cost_s(plans[todo[kt[0]][0]]))
    unique_plans: dict[str, RunPlan] = {key: plans[todo[key][0]] for key, _ in unique}
    engines = [p.engine for p in unique_plans.values()]
    # on Dask: connected, and each worker has found or made its environments, before the bar
    cluster = _connect_cluster(scheduler, unique_plans) if scheduler and unique else None
    lost: Any = SchedulerLost if cluster is not None else ()  # nothing to catch locally
    slots = cluster.slots() if cluster is not None else _slots(scheduler, workers, len(unique))
    here = [p for p in unique_plans.values() if p.engine not in pythons] if not scheduler \
        else []  # nothing runs (nor compiles) in this process on Dask
    say_compile(here)
    say_long_run(list(unique_plans.values()), slots)  # stderr, above a minute
    hits = sum(r is not None and r.cached for r in results)
    shared = sum(len(idx) - 1 for idx in todo.values())
    bar = _progress(list(unique_plans.values()), label, slots, hits, shared, here)
    writer = CacheWriter(cache) if cache else None
    finished = False
    kept = 0
    try:
        runs = (_dispatch_cluster(cluster, unique, unique_plans, bar) if cluster is not None
                else _dispatch(unique, scheduler, workers, bar, unique_plans, pythons))
        for key, out in runs:
            if "error" in out:
                res_summary, table, err = None, None, out["error"]
            else:
                res_summary, table, err = out["summary"], out["table"], None
                if writer is not None and cacheable(tasks[todo[key][0]]):
                    writer.put(key, res_summary, table)
                    kept += 1
            for i in todo[key]:
                results[i] = TaskResult(tasks[i], key, _own(plans[i], res_summary), table, err,
                                        False)
        finished = True
        if scheduler is None:  # what a step of each engine cost, for the next estimate
            _record_step_costs(results, engines)
    except lost as exc:  # the scheduler went: every run finished before it is kept
        if bar is not None:
            bar.close()
        if writer is not None:
            writer.close(raise_error=True)  # all written (a full disk says so instead)
        where = (f"; {kept} finished run{'s' if kept != 1 else ''} kept in the cache "
                 f"({cache.root})" if cache is not None and kept else "")
        raise type(exc)(f"{exc}{where}") from None
    finally:  # erased on Ctrl-C too, so that 'tippetop: interrupted' starts its own line
        if bar is not None:
            bar.close()
        if writer is not None:  # every entry written before returning (or raising)
            writer.close(raise_error=finished)
        if cluster is not None:
            cluster.close()
    return [r for r in results if r is not None]


def _plan_tasks(tasks: Sequence[Task]) -> tuple[list[RunPlan | None], list[TaskResult | None]]:
    """Each task's plan (None where refused), and the refused tasks' results (else None).

    A scene that does not load stops everything; a plan refused for its settings (a step the
    paper's law cannot follow, effects an engine cannot run) is that task's own row.
    """
    scenes = [t.load() for t in tasks]
    plans: list[RunPlan | None] = []
    results: list[TaskResult | None] = [None] * len(tasks)
    for i, (task, scene) in enumerate(zip(tasks, scenes, strict=True)):
        try:
            plans.append(task.plan(scene))
        except TippetopError as exc:
            plans.append(None)
            results[i] = TaskResult(task, "", None, None, str(exc), False)
    return plans, results


def _own(plan: RunPlan | None, res_summary: RunSummary | None) -> RunSummary | None:
    """A task's own copy of a (shared or cached) summary, with its own unused keys."""
    if res_summary is None or plan is None:
        return None
    return res_summary.replace(unused=tuple(plan.unused))


def _serve_cached(tasks: Sequence[Task], plans: list[RunPlan | None], keys: list[str],
                  cache: ResultCache | None,
                  results: list[TaskResult | None]) -> dict[str, list[int]]:
    """The tasks to run, by key (a task's twins share it); the cache's hits go into ``results``."""
    todo: dict[str, list[int]] = {}
    for i, (task, key) in enumerate(zip(tasks, keys, strict=True)):
        if plans[i] is None:
            continue
        hit = cache.get(key) if cache and cacheable(task) else None
        if hit is not None:
            results[i] = TaskResult(task, key, _own(plans[i], hit[0]), hit[1], None, True)
        else:
            todo.setdefault(key, []).append(i)
    return todo


def _record_step_costs(results: list[TaskResult | None], engines: list[str]) -> None:
    """Record what a step of each engine cost in the runs just computed, for the next estimate."""
    computed = {r.key: r.summary for r in results if r is not None and not r.cached}
    for engine in dict.fromkeys(engines):
        record_mujoco_runs(measured_steps(computed.values(), engine), engine)


def _connect_cluster(scheduler: str, plans: dict[str, RunPlan]) -> Any:
    """The Dask cluster at ``scheduler``, its workers ready for the plans' engines.

    Each worker finds or makes the managed environments itself (its own uv and
    ``$TIPPETOP_CACHE``); this process makes none. Returns a
    :class:`~.cluster.DaskCluster` (closed by the caller).
    """
    from tippetop.compare.running.cluster import DaskCluster

    cluster = DaskCluster.connect(scheduler)
    try:
        cluster.prepare(p.engine for p in plans.values())
    except BaseException:
        cluster.close()
        raise
    return cluster


def _dispatch_cluster(cluster: Any, unique: list[tuple[str, Task]], plans: dict[str, RunPlan],
                      bar: WorkProgress | None) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the unique tasks on the Dask cluster; yield ``(key, out)`` as each ends.

    The bar ticks while none ends and moves as each does (a run on Dask does not report how
    far it got).
    """
    index = {key: i for i, (key, _) in enumerate(unique)}
    for key, out in cluster.run(unique, plans, bar.tick if bar is not None else None):
        if bar is not None:
            bar.finished(index[key])
        yield key, out


def _check_task(task: Task) -> None:
    """Refuse a task's engine or mode that does not exist (one line), before any work."""
    if old_spelling(task.engine) is None or task.mode is not None:
        parse_engine(task.engine)
    if task.mode is not None:
        parse_mode(task.mode)


def _engine_pythons(plans: Sequence[RunPlan], scheduler: str | None) -> dict[str, str]:
    """The interpreter of each engine the plans run on other than this process's own.

    Managed environments are made here, before any run (each says so on stderr); an engine
    that cannot run is refused in one line. On Dask (``scheduler``) none is made here: each
    Dask worker finds or makes its own (:meth:`.cluster.DaskCluster.prepare`); empty.
    """
    from tippetop.compare.running.engines import engine_python

    specs = {p.engine: parse_engine(p.engine) for p in plans}
    others = {k: spec for k, spec in specs.items() if not spec.in_process}
    if scheduler:
        return {}

    def say(line: str) -> None:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()

    return {k: engine_python(spec, say=say) for k, spec in others.items()}


def _execute_remote(task: Task, plan: RunPlan, python: str,
                    report: Callable[[float], None] | None) -> dict[str, Any]:
    """Run one MuJoCo plan on another engine (its worker); a failure is ``{"error": ...}``."""
    from tippetop.compare.running.engines import run_plan_on

    try:
        run = run_plan_on(parse_engine(plan.engine), plan, python=python, progress=report)
    except TippetopError as exc:
        return {"error": str(exc)}
    return {"summary": run.summary, "table": downsample(run.table)}


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
        yield from _dispatch_dask(unique, plans, scheduler, bar, done)
        return
    n = workers or os.cpu_count() or 1
    pythons = pythons or {}
    remote_tasks = [(k, t) for k, t in unique if plans[k].engine in pythons]
    mujoco_tasks = [(k, t) for k, t in unique
                    if not plans[k].is_reference and plans[k].engine not in pythons]
    ode_tasks = [(k, t) for k, t in unique if plans[k].is_reference]
    pooled = n > 1 and len(ode_tasks) > 1
    pool = queue = threads = None
    futures: dict[Any, str] = {}
    if pooled:
        pool, queue, futures = _submit_pooled(ode_tasks, plans, n, bar)
    if remote_tasks:  # other engines' workers: a process each, waited for on threads
        threads = _submit_remote(remote_tasks, plans, pythons, n, bar, report, futures)
    waiting = set(futures)
    try:
        if not pooled:
            for key, task in ode_tasks:
                before = set_reporter(report if bar is not None else None)
                try:
                    out = execute(task, key)
                finally:
                    set_reporter(before)
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
                drain(queue, report)
            if bar is not None:
                bar.tick()

        for key, out in _run_mujoco_batched(mujoco_tasks, plans, n, report, collect):
            collected.append((key, out))
            while collected:
                k, o = collected.pop(0)
                yield k, o
                done(k)
        while waiting:
            finished, waiting = wait(waiting, timeout=TICK_S, return_when=FIRST_COMPLETED)
            if queue is not None:
                drain(queue, report)
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
        _abandon(pool, threads)  # Ctrl-C or an error: do not wait for the runs still going
        raise
    if threads is not None:
        threads.shutdown(wait=True)


def _dispatch_dask(unique: list[tuple[str, Task]], plans: dict[str, RunPlan], scheduler: str,
                   bar: WorkProgress | None,
                   done: Callable[[str], None]) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the unique tasks on the Dask scheduler at ``scheduler``; yield ``(key, out)``."""
    from tippetop.compare.running.cluster import dispatch_dask

    for key, out in dispatch_dask(unique, plans, scheduler,
                                  bar.tick if bar is not None else None):
        yield key, out
        done(key)


def _submit_pooled(ode_tasks: list[tuple[str, Task]], plans: dict[str, RunPlan], n: int,
                   bar: WorkProgress | None) -> tuple[Any, Any, dict[Any, str]]:
    """The local worker pool, its progress queue, and the reference's runs' futures (to keys)."""
    pool, queue = local_pool(n)
    with sigint_blocked():  # the workers start with Ctrl-C blocked (see there)
        futures = {pool.submit(execute_plan, plans[key].to_json(),
                               key if bar is not None else None): key
                   for key, _task in ode_tasks}
    return pool, queue, futures


def _submit_remote(remote_tasks: list[tuple[str, Task]], plans: dict[str, RunPlan],
                   pythons: dict[str, str], n: int, bar: WorkProgress | None,
                   report: Callable[[str, float], None],
                   futures: dict[Any, str]) -> ThreadPoolExecutor:
    """The threads that wait for other engines' workers; each run's future goes in ``futures``."""
    threads = ThreadPoolExecutor(max_workers=n, thread_name_prefix="tippetop-engine")
    for key, task in remote_tasks:
        plan = plans[key]

        def tick(t: float, key: str = key, t_end: float = plan.t_end_s) -> None:
            report(key, t / t_end)

        futures[threads.submit(_execute_remote, task, plan, pythons[plan.engine],
                               tick if bar is not None else None)] = key
    return threads


def _abandon(pool: Any, threads: ThreadPoolExecutor | None) -> None:
    """Stop the local pool and the other engines' workers without waiting for their runs."""
    if pool is not None:
        stop_pool(pool)
    if threads is not None:
        from tippetop.mujoco_runner.remote import stop_workers

        threads.shutdown(wait=False, cancel_futures=True)
        stop_workers()


def _run_mujoco_batched(tasks: list[tuple[str, Task]], plans: dict[str, RunPlan], nthread: int,
                        report: Callable[[str, float], None], tick: Callable[[], None]
                        ) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run MuJoCo tasks in this process, stepped together on ``nthread`` threads.

    :func:`tippetop.mujoco_runner.batch.iter_simulate_plans`: each run steps whole on a
    worker thread in the compiled stepper, every step's pass in its window; each result
    equals the single run's. Yields what :func:`execute` would give for each task, as each
    run ends.
    """
    if not tasks:
        return
    from tippetop.compare.running.engines import mujoco_engine_run

    keys = [k for k, _ in tasks]
    mj_plans = [plans[k].mujoco for k in keys]
    # Ctrl-C while MuJoCo or numba is first imported would surface as an ImportError (a C
    # extension's "initialization failed"), which an optional import (numba's of scipy) can
    # swallow, losing the Ctrl-C: it is held back until they are imported (about a second)
    with sigint_deferred():
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
            yield keys[i], {"summary": run.summary, "table": downsample(run.table)}


#: Re-exported for the callers that import them from here (the runner's public names).
__all__ = ["ResultCache", "SchedulerLost", "Task", "TaskResult", "code_fingerprint",
           "default_cache_dir", "execute", "execute_plan", "local_pool", "run_tasks",
           "strip_timing", "task_key"]
