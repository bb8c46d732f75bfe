"""The local worker processes: a pool kept for the process, progress from the workers, signals.

:func:`local_pool` starts the workers once per process (a bisection makes several rounds);
each worker reports its runs' progress on a queue (:func:`drain` passes it on), ignores
Ctrl-C (the main process stops everything, :func:`stop_pool`) and dies with the main process
however it dies. :func:`sigint_blocked` and :func:`sigint_deferred` keep a Ctrl-C from
landing half-way through a worker's start or a C extension's import.
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from functools import lru_cache
from multiprocessing import get_context
from queue import Empty, Full
from typing import Any

from tippetop.compare.running.tasks import set_reporter

#: How often the main process reads the workers' reports and redraws the bar (s).
TICK_S = 0.25


def drain(queue: Any, report: Callable[[str, float], None]) -> None:
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
    _ignore_sigint()
    if parent is not None:
        _die_with_parent(parent, pdeathsig=pdeathsig)
    queue.cancel_join_thread()  # never wait at exit for reports nobody reads
    set_reporter(_queue_reporter(queue))


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
def sigint_blocked() -> Iterator[None]:
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
def sigint_deferred() -> Iterator[None]:
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


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started, end the workers now, and forget the pool."""
    procs = list((getattr(pool, "_processes", None) or {}).values())  # no public way to
    pool.shutdown(wait=False, cancel_futures=True)  # stop them; shutdown forgets them
    for proc in procs:
        proc.terminate()
    local_pool.cache_clear()


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


__all__ = ["TICK_S", "drain", "local_pool", "sigint_blocked", "sigint_deferred", "stop_pool"]
