"""Runs on a Dask cluster: the plans sent as their JSON, the results as each ends.

:class:`DaskCluster` is one connection to a scheduler for one batch of runs. Before the runs,
each Dask worker finds or makes the managed environments of the batch's engines itself
(:func:`prepare_engines`: uv, in the worker's own ``$TIPPETOP_CACHE``); this process makes
none. A run is :func:`~.tasks.execute_plan` on a worker, which keeps its engine workers (the
processes of :mod:`tippetop.mujoco_runner.remote`) from one run to the next and stops them when
it closes (:class:`EngineWorkers`). MJX and MuJoCo Warp runs ask for a ``GPU`` resource when a
worker of the cluster declares one (``dask worker ... --resources "GPU=1"``).

Faults: a worker that dies mid-run has its runs rerun elsewhere by the scheduler (up to its
``distributed.scheduler.allowed-failures``); a run that still fails (``KilledWorker``) is that
run's failed row with a one-line reason. A scheduler that goes away ends the batch with
:class:`SchedulerLost` (one line); the runs finished before it are the caller's to keep.

This module imports ``distributed`` (about a second): the runner imports it only for a
``--scheduler`` run.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import CancelledError
from typing import Any

from distributed import Client, WorkerPlugin, as_completed
from distributed.core import Status

from tippetop.compare.running.tasks import SchedulerError, SchedulerLost, Task, execute_plan
from tippetop.models.engines import parse_engine
from tippetop.models.errors import TippetopError
from tippetop.models.plan import RunPlan

#: The resource an accelerated engine's run asks for, when some worker declares it.
GPU = "GPU"
#: The implementations whose runs ask for :data:`GPU`.
GPU_IMPLEMENTATIONS = ("mjx", "warp")
#: Wall time to connect to the scheduler, and to wait for a first worker (s).
CONNECT_S = 20.0
WAIT_WORKERS_S = 60.0
#: How often the progress bar is redrawn while no run ends (s).
TICK_S = 0.25
#: The name the engine workers' plugin is registered under on every Dask worker.
PLUGIN_NAME = "tippetop-engine-workers"
#: Dask's loggers in this process that would print its own account of a lost scheduler
#: (reconnecting, closing) on stderr: the command says it in one line instead.
QUIET_LOGGERS = ("distributed.client", "distributed.comm", "distributed.core",
                 "distributed.batched", "distributed.utils")


class EngineWorkers(WorkerPlugin):
    """On a Dask worker: its engine workers stop when it closes (not between tasks).

    The engine workers (:mod:`tippetop.mujoco_runner.remote`) live in the Dask worker's process
    and answer one run after another; registering this plugin again (each batch does) must not
    stop them, so only a teardown while the worker closes does.
    """

    name = PLUGIN_NAME

    def teardown(self, worker: Any) -> None:
        """Stop the engine workers if the Dask worker is closing."""
        if worker.status in (Status.closing, Status.closed, Status.closing_gracefully,
                             Status.failed):
            from tippetop.mujoco_runner.remote import close_workers

            close_workers()


def _needs_environment(engine: str) -> bool:
    """Whether ``engine`` runs through a worker in an interpreter of its own."""
    return not parse_engine(engine).in_process


def prepare_engines(engines: Sequence[str]) -> list[str]:
    """On a Dask worker: find or make each engine's environment; returns the interpreters.

    Each managed environment is made with uv in this worker's own ``$TIPPETOP_CACHE`` (what is
    being made is printed on the client's stderr as well as the worker's); a ``mujoco@PYTHON``
    must name an interpreter there.

    Raises:
        TippetopError: An engine that cannot run there (one line, naming the worker).
    """
    from distributed import get_worker
    from distributed import print as dask_print

    from tippetop.compare.running.engines import engine_python

    try:
        where = get_worker().address
    except ValueError:  # not on a worker (a test calling it directly)
        where = "this process"

    def say(line: str) -> None:
        dask_print(f"{line} (on the Dask worker {where})", file=sys.stderr)

    out = []
    for engine in engines:
        try:
            out.append(engine_python(parse_engine(engine), say=say))
        except TippetopError as exc:
            raise TippetopError(f"{exc} (on the Dask worker {where})") from None
    return out


def _cancel_reason(fut: Any) -> str:
    """Why Dask cancelled a future (``scheduler-connection-lost``, ...), or ``""``."""
    try:
        fut.result(timeout=0)
    except CancelledError as exc:
        return str(getattr(exc, "reason", "") or exc)
    except Exception:  # noqa: BLE001 - not cancelled after all: no reason to give
        return ""
    return ""


def run_resources(engine: str, gpu: bool) -> dict[str, float] | None:
    """The resources a run on ``engine`` asks for: a GPU for MJX and Warp if one is declared."""
    if gpu and parse_engine(engine).implementation in GPU_IMPLEMENTATIONS:
        return {GPU: 1}
    return None


def failed_run_reason(exc: BaseException) -> str:
    """A run's one-line reason when its Dask task raised ``exc`` (a worker that died, ...)."""
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        tries = exc.allowed_failures + 1
        last = getattr(exc.last_worker, "address", exc.last_worker)
        return (f"the run was lost: the Dask worker running it died, {tries} time"
                f"{'s' if tries != 1 else ''} on {tries} worker{'s' if tries != 1 else ''} "
                f"(KilledWorker; the last: {last})")
    if isinstance(exc, TippetopError):
        return str(exc)
    text = " ".join(str(exc).split()) or "no message"
    return f"the run failed on the Dask worker: {type(exc).__name__}: {text}"[:400]


class DaskCluster:
    """One connection to a Dask scheduler, for one batch of runs (a context manager).

    Attributes:
        address: The scheduler's address (``tcp://HOST:PORT``).
        client: The Dask client.
    """

    def __init__(self, client: Any, address: str) -> None:
        self.client = client
        self.address = address
        self._quiet: list[tuple[logging.Logger, int]] = []

    @classmethod
    def connect(cls, address: str, *, timeout_s: float = CONNECT_S,
                wait_workers_s: float = WAIT_WORKERS_S) -> DaskCluster:
        """Connect to the scheduler at ``address`` and wait for a first worker.

        Raises:
            SchedulerError: No scheduler there, or no worker joins it in ``wait_workers_s``
                (one line).
        """
        if not address.startswith(("tcp://", "tls://")):
            raise SchedulerError(f"--scheduler: expected tcp://HOST:PORT, got {address!r}")
        try:
            client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            reason = " ".join(str(exc).split())[:200] or type(exc).__name__
            raise SchedulerError(f"--scheduler: expected a reachable Dask scheduler, got "
                                f"{address!r} ({reason})") from None
        self = cls(client, address)
        try:
            try:
                client.wait_for_workers(1, timeout=wait_workers_s)
            except (TimeoutError, OSError):
                raise SchedulerError(f"--scheduler: expected a Dask worker on the scheduler at "
                                    f"{address}, got none within {wait_workers_s:.0f} s "
                                    "(start one: dask worker " + address + ")") from None
            client.register_plugin(EngineWorkers(), name=PLUGIN_NAME)
        except BaseException:
            self.close()
            raise
        self._quiet_logs()
        return self

    def __enter__(self) -> DaskCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _quiet_logs(self) -> None:
        """Dask's own lines of a lost connection are held back while this batch runs."""
        for name in QUIET_LOGGERS:
            log = logging.getLogger(name)
            self._quiet.append((log, log.level))
            log.setLevel(logging.CRITICAL + 1)

    def close(self) -> None:
        """Release the batch's runs on the cluster and disconnect (quickly, if it is gone)."""
        with contextlib.suppress(Exception):
            self.client.close(timeout=2)
        for log, level in self._quiet:
            log.setLevel(level)
        self._quiet.clear()

    # ------------------------------------------------------------ the cluster
    def _workers(self) -> dict[str, dict[str, Any]]:
        try:
            return dict(self.client.scheduler_info(n_workers=-1).get("workers", {}))
        except (OSError, TimeoutError) as exc:
            raise self._lost() from exc

    def slots(self) -> int:
        """Runs going at once: the threads of the cluster's workers (at least 1)."""
        return max(1, sum(int(w.get("nthreads", 1)) for w in self._workers().values()))

    def gpu(self) -> bool:
        """Whether some worker declares a :data:`GPU` resource."""
        return any((w.get("resources") or {}).get(GPU, 0) > 0
                   for w in self._workers().values())

    def _lost(self) -> SchedulerLost:
        return SchedulerLost(f"--scheduler: lost the Dask scheduler at {self.address}")

    def _is_lost(self) -> bool:
        return self.client.status not in ("running", "newly-created")

    # ------------------------------------------------------------ environments
    def prepare(self, engines: Iterable[str]) -> None:
        """Have every worker that may run them find or make the engines' environments.

        This process makes none: each Dask worker runs :func:`prepare_engines` (the GPU
        workers only for MJX and Warp when the cluster declares a GPU). A worker that dies
        meanwhile makes them on its first run instead.

        Raises:
            TippetopError: An engine that cannot run on a worker (one line).
            SchedulerLost: The scheduler went away.
        """
        needed = sorted({e for e in engines if _needs_environment(e)})
        if not needed:
            return
        workers = self._workers()
        gpu_workers = [a for a, w in workers.items()
                       if (w.get("resources") or {}).get(GPU, 0) > 0]
        plan: dict[str, list[str]] = {}
        for engine in needed:
            wanted = run_resources(engine, bool(gpu_workers))
            for addr in (gpu_workers if wanted else list(workers)):
                plan.setdefault(addr, []).append(engine)
        futures = [self.client.submit(prepare_engines, names, workers=[addr],
                                      allow_other_workers=True, pure=False,
                                      key=f"tippetop-prepare-{i}-{time.time_ns()}")
                   for i, (addr, names) in enumerate(sorted(plan.items()))]
        try:
            for fut in as_completed(futures, loop=self.client.loop):
                self._check(fut)
                if fut.status == "error":
                    exc = fut.exception()
                    if isinstance(exc, TippetopError):
                        raise TippetopError(str(exc)) from None
        finally:
            with contextlib.suppress(Exception):
                self.client.cancel(futures)

    def _check(self, fut: Any) -> None:
        """Raise :class:`SchedulerLost` for a future cancelled because the scheduler went."""
        if fut.status != "cancelled":
            return
        if self._is_lost() or "scheduler-connection-lost" in _cancel_reason(fut):
            raise self._lost()

    # ------------------------------------------------------------ runs
    def submit(self, unique: Sequence[tuple[str, Task]], plans: dict[str, RunPlan]
               ) -> dict[Any, str]:
        """Send each run's plan as its JSON, longest first; returns ``{future: key}``."""
        gpu = self.gpu()
        n = len(unique)
        futures: dict[Any, str] = {}
        for i, (key, _task) in enumerate(unique):
            plan = plans[key]
            futures[self.client.submit(execute_plan, plan.to_json(), pure=False,
                                       priority=n - i,
                                       resources=run_resources(plan.engine, gpu))] = key
        return futures

    def results(self, futures: dict[Any, str], tick: Callable[[], None] | None = None
                ) -> Iterator[tuple[str, dict[str, Any]]]:
        """Yield ``(key, out)`` as each run ends (``out`` as :func:`~.tasks.execute_plan`'s).

        A run whose task failed on the cluster (its workers died: ``KilledWorker``) is
        ``{"error": reason}``. ``tick`` is called now and then while none ends.

        Raises:
            SchedulerLost: The scheduler went away; what was yielded before is the caller's.
        """
        pending = as_completed(list(futures), loop=self.client.loop)
        try:
            while not pending.is_empty():
                batch = pending.next_batch(block=False)
                if not batch:
                    if tick is not None:
                        tick()
                    time.sleep(TICK_S if tick is not None else 0.05)
                    continue
                for fut in batch:
                    out = self._outcome(fut)
                    if out is None:  # not done after all: wait for it again
                        pending.add(fut)
                        continue
                    yield futures[fut], out
        finally:
            with contextlib.suppress(Exception):
                self.client.cancel(list(futures))

    def _outcome(self, fut: Any) -> dict[str, Any] | None:
        """The run's ``out``, or None when its future is not done after all.

        A future that ended can be pending again by the time it is read: its run finished,
        then the worker holding its result died (status ``lost``; Dask runs it again), seen
        in CI when a killed worker held the reference's finished run.
        """
        self._check(fut)
        status = fut.status
        if status == "finished":
            try:
                return fut.result()
            except (OSError, TimeoutError) as exc:  # the scheduler went while fetching
                raise self._lost() from exc
        if status == "cancelled":
            return {"error": "the run was cancelled on the Dask cluster"}
        if status != "error":  # lost or pending: not done
            return None
        exc = fut.exception()
        if exc is None:
            if fut.status != "error":  # it was rerun meanwhile (retried): read it again
                return None
            return {"error": "the run failed on the Dask cluster with no reason given"}
        return {"error": failed_run_reason(exc)}

    def run(self, unique: Sequence[tuple[str, Task]], plans: dict[str, RunPlan],
            tick: Callable[[], None] | None = None) -> Iterator[tuple[str, dict[str, Any]]]:
        """:meth:`submit`, then :meth:`results`."""
        if not unique:
            return
        yield from self.results(self.submit(unique, plans), tick)


def dispatch_dask(unique: list[tuple[str, Task]], plans: dict[str, RunPlan],
                  scheduler: str, tick: Callable[[], None] | None = None
                  ) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the tasks' plans on the Dask cluster at ``scheduler``, sent as their JSON.

    Connects, has the workers find or make the environments, runs, disconnects.
    """
    if not unique:
        return
    with DaskCluster.connect(scheduler) as cluster:
        cluster.prepare(plans[key].engine for key, _ in unique)
        yield from cluster.run(unique, plans, tick)


__all__ = ["GPU", "DaskCluster", "EngineWorkers", "SchedulerLost", "dispatch_dask",
           "failed_run_reason", "prepare_engines", "run_resources"]
