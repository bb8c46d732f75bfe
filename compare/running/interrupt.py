"""SIGTERM handled as Ctrl-C in a command's main process (standard library only).

The runs going are stopped (the runner ends its workers on a :class:`KeyboardInterrupt`),
staged outputs removed, one line ``tippetop: interrupted``, exit status 130 (143 for SIGTERM).
From then on the process ends within :data:`EXIT_BOUND_S`, whatever its exit waits on.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from typing import Any

#: After an interrupt has stopped the runs, the process ends within this many seconds (s). What
#: is left then is a line and the interpreter's exit, which joins the process pools' manager
#: threads: measured, one of them can wait without end on a result a worker, killed by the
#: same signal, had half written (2 of 42 Ctrl-Cs to a quick nightly on a loaded machine hung
#: 65 and 145 s). Everything the command owns is complete or removed before the bound starts.
EXIT_BOUND_S = 3.0


class Terminated(KeyboardInterrupt):
    """SIGTERM in the main process, raised where it runs: handled as Ctrl-C is."""


def install_sigterm_handler() -> None:
    """Make SIGTERM raise :class:`Terminated` in the main thread; no interrupt is lost.

    Call it from a command's entry point; outside the main thread it does nothing (Python
    runs signal handlers there only). Worker processes started with ``spawn`` do not inherit
    it: they keep SIGTERM's default, which ends them. In a process of tippetop's own
    (:func:`own_process`) it also installs :func:`_redeliver_lost_interrupts` as
    ``sys.unraisablehook``.
    """
    if threading.current_thread() is not threading.main_thread():
        return

    def on_sigterm(signum: int, frame: Any) -> None:
        raise Terminated(f"signal {signum}")

    signal.signal(signal.SIGTERM, on_sigterm)
    if _owns_process and sys.unraisablehook is not _redeliver_lost_interrupts:
        global _previous_unraisablehook
        _previous_unraisablehook = sys.unraisablehook
        sys.unraisablehook = _redeliver_lost_interrupts


_previous_unraisablehook = sys.unraisablehook


def _redeliver_lost_interrupts(unraisable: Any) -> None:
    """``sys.unraisablehook``: a Ctrl-C (or SIGTERM) that Python could not raise is sent again.

    A signal's handler runs at the main thread's next instruction; when that is inside a
    weakref callback or a ``__del__`` (the garbage collector's), the KeyboardInterrupt it
    raises cannot leave there: Python prints "Exception ignored in ... KeyboardInterrupt" and
    goes on, the user's Ctrl-C lost. Measured: 1 of 20 Ctrl-Cs to a quick nightly
    (tests/compare/test_interrupt_stress.py). Here the signal is raised again from a thread, so
    that its handler runs once more after the callback, where the exception can propagate;
    nothing is printed (a lost SIGTERM is sent again as SIGTERM). Every other unraisable
    exception goes to the hook that was there before.
    """
    exc = unraisable.exc_value
    if isinstance(exc, KeyboardInterrupt):
        sig = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT

        def again() -> None:  # from a thread of its own: the handler runs once this hook is left
            time.sleep(REDELIVER_S)
            signal.raise_signal(sig)

        threading.Thread(target=again, name="tippetop-interrupt-again", daemon=True).start()
        return
    _previous_unraisablehook(unraisable)


#: How long after a lost interrupt it is sent again (s): the hook, and the callback it came
#: from, have returned by then.
REDELIVER_S = 0.01


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

    The process then ends within :data:`EXIT_BOUND_S` with ``status`` whatever its exit waits
    on (:func:`exit_within`).
    """
    def leave(signum: int, frame: Any) -> None:
        _leave(status)

    if _on_interrupts(leave):
        exit_within(EXIT_BOUND_S, status)


def _leave(status: int) -> None:
    """End the process now with ``status``: its streams flushed, its semaphores released."""
    try:
        _release_semaphores()
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed or broken stream: nothing more to say
        pass
    finally:
        os._exit(status)


def _release_semaphores() -> None:
    """Unlink this process's multiprocessing semaphores and tell the resource tracker so.

    An exit that skips the interpreter's cleanup leaves them to the resource tracker, which
    unlinks them too but prints "There appear to be N leaked semaphore objects" under the
    command's last line.
    """
    if "multiprocessing.synchronize" not in sys.modules:
        return
    import gc

    try:
        import _multiprocessing
        from multiprocessing import resource_tracker, synchronize
    except ImportError:  # pragma: no cover - a platform without them: the tracker says it
        return
    for obj in gc.get_objects():
        name = getattr(getattr(obj, "_semlock", None), "name", None) \
            if isinstance(obj, synchronize.SemLock) else None
        if name:
            try:
                _multiprocessing.sem_unlink(name)
                resource_tracker.unregister(name, "semaphore")
            except (OSError, ValueError):  # already gone
                pass


def exit_within(seconds: float, status: int) -> threading.Timer:
    """End the process with ``status`` in ``seconds`` unless it has ended by then.

    A daemon timer thread: it runs while the main thread waits in the interpreter's exit (on a
    pool's manager thread, a result pipe, a lock), which a signal handler cannot interrupt when
    the wait is in C.
    """
    timer = threading.Timer(seconds, _leave, args=(status,))
    timer.daemon = True
    timer.name = "tippetop-exit-bound"
    timer.start()
    return timer


def _on_interrupts(handler: Any) -> bool:
    """Ctrl-C and SIGTERM handled by ``handler`` from now on; whether they are.

    Only in a process of tippetop's own (:func:`own_process`), on its main thread; elsewhere
    nothing changes.
    """
    if not _owns_process or threading.current_thread() is not threading.main_thread():
        return False
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return True


__all__ = ["EXIT_BOUND_S", "Terminated", "exit_at_next_signal", "exit_within",
           "install_sigterm_handler", "outputs_complete", "own_process"]
