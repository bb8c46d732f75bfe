"""SIGTERM handled as Ctrl-C in a command's main process (standard library only).

The runs going are stopped (the runner ends its workers on a :class:`KeyboardInterrupt`),
staged outputs removed, one line ``tippetop: interrupted``, exit status 130.
"""

from __future__ import annotations

import signal
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


__all__ = ["Terminated", "install_sigterm_handler"]
