"""How a study's runs are run: where, on how many processes, cached or not, and said how.

:class:`RunOptions` is the one group of these settings that the studies share (the command
line's ``--scheduler``, ``--workers``, ``--no-cache``; progress on a terminal), passed whole
in place of four loose arguments.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RunOptions:
    """How a study runs its simulations; the defaults are the command line's.

    A study reads the fields that apply to how it runs and says which in its docstring: runs
    through :func:`~tippetop.compare.running.runner.run_tasks` honour ``scheduler``,
    ``workers`` and ``use_cache`` (its progress bar shows whenever stderr is a terminal); a
    study that times its runs runs them here, uncached; one that draws its own progress reads
    ``progress``.

    Attributes:
        scheduler: A Dask scheduler address (``tcp://HOST:PORT``), or None for local
            processes.
        workers: Local worker processes (None: all cores).
        use_cache: Read and write the run cache.
        progress: Show the study's own progress (bars, lines) on a terminal.
    """

    scheduler: str | None = None
    workers: int | None = None
    use_cache: bool = True
    progress: bool = True


#: The defaults, shared (a frozen value): local processes on every core, the cache read and
#: written, progress shown on a terminal.
DEFAULT_RUN = RunOptions()

__all__ = ["DEFAULT_RUN", "RunOptions"]
