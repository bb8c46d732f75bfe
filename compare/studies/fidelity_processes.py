"""The fidelity map's points at once: the cores each gets, and the process each is tuned in.

:func:`point_cores` shares the machine's cores among the points tuned at once; a point's own
process (:func:`init_point_process`) leaves Ctrl-C to the map, draws no bars of its own
(:class:`NotATerminal`) and dies with the map.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from typing import Any

#: Threads (and reference workers) each point tuned at once gets, at least (where there are
#: as many cores): :func:`point_cores`.
POINT_MIN_CORES = 2


def machine_cores() -> int:
    """The cores this process may use."""
    from tippetop.mujoco_runner.batch import default_threads

    return max(1, default_threads())


def point_cores(cores: int, at_once: int) -> int:
    """The threads each of ``at_once`` points gets on ``cores``: its rollouts' and its runs'.

    At least two where there are two cores: a point's own parallel phases (the fit's batched
    rollouts, its four verification runs) then use both while the other points fill what its
    serial ones (the fit's trial steps, one rollout each) leave idle.
    """
    return max(min(POINT_MIN_CORES, cores), cores // max(1, at_once))


class NotATerminal:
    """A stream that is no terminal: the points' own bars would draw over each other's."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def isatty(self) -> bool:
        """False: no terminal."""
        return False

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def init_point_process(parent: int, pdeathsig: bool) -> None:
    """A point's process: Ctrl-C is the map's, no bars of its own, and it dies with the map.

    However the map's process ends (SIGKILL too), as the runner's workers do: the kernel is
    asked to kill it (Linux, ``pdeathsig``: the pool made in the main thread), and a thread
    looks every half second that the map is still its parent.
    """
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.stderr = NotATerminal(sys.stderr)
    if pdeathsig and sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # DEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - no prctl: the thread does
            pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)  # the map that would read the answer is gone

    threading.Thread(target=watch, name="tippetop-map-watchdog", daemon=True).start()


__all__ = ["POINT_MIN_CORES", "NotATerminal", "init_point_process", "machine_cores",
           "point_cores"]
