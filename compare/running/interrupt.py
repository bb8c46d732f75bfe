"""SIGTERM handled as Ctrl-C in a command's main process (standard library only).

The runs going are stopped (the runner ends its workers on a :class:`KeyboardInterrupt`),
staged outputs removed, one line ``tippetop: interrupted``, exit status 130.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Any


class Terminated(KeyboardInterrupt):
    """SIGTERM in the main process, raised where it runs: handled as Ctrl-C is."""


def install_sigterm_handler() -> None:
    """Make SIGTERM raise :class:`Terminated` in the main thread.

    Call it from a command's entry point; outside the main thread it does nothing (Python
    runs signal handlers there only). Worker processes started with ``spawn`` do not inherit
    it: they keep SIGTERM's default, which ends them.
    """
    if threading.current_thread() is not threading.main_thread():
        return

    def on_sigterm(signum: int, frame: Any) -> None:
        raise Terminated(f"signal {signum}")

    signal.signal(signal.SIGTERM, on_sigterm)


#: Set by a command's process entry point (:func:`own_process`): only then may
#: :func:`outputs_complete` change the process's signal handling (not in a caller's process,
#: such as a test calling a command's ``main``).
_owns_process = False


def own_process() -> None:
    """Called by a process entry point (the ``tippetop`` script, ``python -m ...``)."""
    global _owns_process
    _owns_process = True


def outputs_complete() -> None:
    """From now on Ctrl-C and SIGTERM are ignored: the command's outputs are all in place.

    Called when a command's output folder has been moved into place, and when a command has
    returned: what is left is printing and the interpreter's exit (the process pools' threads
    joined), where an interrupt would print a traceback from the standard library and turn a
    complete result into exit 130, or into a 0 that says nothing. Outside the main thread it
    does nothing, and so it does unless :func:`own_process` was called.
    """
    _on_interrupts(signal.SIG_IGN)


def exit_at_next_signal(status: int) -> None:
    """From now on Ctrl-C and SIGTERM end the process at once, with ``status``.

    Called when a command has been interrupted and its runs stopped: what is left is one line
    and the interpreter's exit (the process pools' threads joined). A second signal there
    (a pending Ctrl-C delivered late, or the user's again) ends the process with the same
    status, where it would otherwise raise out of the exit (a traceback, and death by SIGINT in
    place of 130) or interrupt nothing. Outside the main thread it does nothing, and so it
    does unless :func:`own_process` was called.
    """
    def leave(signum: int, frame: Any) -> None:
        try:
            sys.stderr.flush()
        finally:
            os._exit(status)

    _on_interrupts(leave)


def _on_interrupts(handler: Any) -> None:
    """Ctrl-C and SIGTERM handled by ``handler`` from now on.

    Only in a process of tippetop's own (:func:`own_process`), on its main thread; elsewhere
    nothing changes.
    """
    if not _owns_process or threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


__all__ = ["Terminated", "exit_at_next_signal", "install_sigterm_handler", "outputs_complete",
           "own_process"]
