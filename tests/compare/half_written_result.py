"""A command whose pool worker dies half-way through writing its result (for the signal tests).

Run as a script: ``python half_written_result.py [--no-bound]``. It is a tippetop command in a
process of its own (:func:`run_main`, as the ``tippetop`` entry point runs one) whose one run,
on the project's local pool (:func:`local_pool`), writes the header and the first bytes of a
result onto the pool's result pipe and then waits. The pool's manager thread, in the main
process, reads that header and blocks for the rest, which never comes: the main process holds
the pipe's write end too, so no end-of-file arrives when the worker dies. The test sends
Ctrl-C; the command stops its pool (the workers killed, as the runner does) and returns 130;
the interpreter's exit then joins the manager thread, which waits without end, unless the exit
is bounded (:data:`tippetop.compare.running.interrupt.EXIT_BOUND_S`).

``--no-bound`` turns the bound off (to show that without it the process hangs).
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def half_write() -> None:
    """In the worker: a result's header and a few of its bytes on the result pipe, then wait."""
    import gc
    import struct
    from multiprocessing.queues import SimpleQueue

    results = next(o for o in gc.get_objects() if isinstance(o, SimpleQueue))
    os.write(results._writer.fileno(), struct.pack("!i", 1 << 20) + b"half a result")
    print("half-written", flush=True)
    time.sleep(600)


def command(args: argparse.Namespace) -> int:
    from tippetop.compare.running.pool import local_pool, sigint_blocked, stop_pool

    pool, _ = local_pool(1)
    try:
        with sigint_blocked():
            future = pool.submit(half_write)
        print("submitted", flush=True)
        future.result()
    except KeyboardInterrupt:
        stop_pool(pool)  # what the runner does (runner._abandon)
        raise
    return 0


if __name__ == "__main__":
    from tippetop.compare.commands.options import run_main
    from tippetop.compare.running import interrupt

    interrupt.own_process()
    if "--no-bound" in sys.argv:
        interrupt.exit_within = lambda seconds, status: None  # type: ignore[assignment]
    sys.exit(run_main(argparse.Namespace(func=command)))
