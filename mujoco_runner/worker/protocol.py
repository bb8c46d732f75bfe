"""The worker's requests and replies: their format, their channel, a refused request.

A request is one JSON line on stdin whose ``protocol`` is :data:`PROTOCOL`; the worker answers
it with progress lines (``{"t": ...}``, at most one every :data:`PROGRESS_S`) and then one JSON
line, its reply, on stdout, which it keeps for them alone (:func:`keep_stdout_for_replies`). A
request it cannot run is refused in one line (:class:`Refused`); :func:`engine_of` reads what
the request asks to step it with.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys

#: The version of the request and reply formats (3: the request's ``engine``; 4: one request
#: per line, answered in turn until the input ends; 5: the request's ``top``, every step's
#: forward pass added to its sample's window, ``windows_int`` and ``windows_float`` in
#: place of the contacts at the samples and paper mode's forces there).
PROTOCOL = 5
#: What the worker can step a plan with: implementation -> the precisions it runs in.
PRECISIONS = {"mujoco": ("float64",), "mjx": ("float64", "float32"), "warp": ("float32",)}
#: Where the accelerated engines' PyPI packages are (their version is the reply's).
PACKAGES = {"mjx": "mujoco-mjx", "warp": "mujoco-warp"}
#: Wall time between progress lines (s).
PROGRESS_S = 0.2


#: Where progress lines and the reply go: the process's stdout as it was at the start (see
#: :func:`keep_stdout_for_replies`).
_OUT = sys.stdout


class Refused(ValueError):
    """A request this worker cannot run, its message the whole reply's reason (one line)."""


def say(obj: dict) -> None:
    """Write ``obj`` as one JSON line where progress lines and replies go, at once."""
    _OUT.write(json.dumps(obj) + "\n")
    _OUT.flush()


def keep_stdout_for_replies() -> None:
    """Keep fd 1 for the replies alone.

    Anything else printed (JAX's or Warp's banners, their kernels' compile lines, C
    libraries') goes to stderr.
    """
    global _OUT
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stdout.flush()
        _OUT = os.fdopen(os.dup(1), "w")
        os.dup2(2, 1)
        sys.stdout = sys.stderr


@contextlib.contextmanager
def stdout_to_stderr():
    """Python-level prints (MJX's ``Failed to import warp``) go to stderr meanwhile."""
    with contextlib.redirect_stdout(sys.stderr):
        yield


def package_version(name: str) -> str:
    """The installed version of the distribution ``name`` (``"?"``: not installed)."""
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


def engine_of(request: dict) -> tuple[str, str]:
    """The request's ``(implementation, precision)``; MuJoCo C in float64 when it names none.

    Raises:
        Refused: Anything but one of :data:`PRECISIONS` (one line, with what was given).
    """
    engine = request.get("engine") or {}
    if not isinstance(engine, dict):
        raise Refused(f"engine: expected an object with implementation and precision, "
                         f"got {engine!r}")
    impl = engine.get("implementation", "mujoco")
    precision = engine.get("precision", "float64")
    if impl not in PRECISIONS:
        raise Refused(f"engine: expected an implementation of {', '.join(PRECISIONS)}, "
                         f"got {impl!r}")
    if precision not in PRECISIONS[impl]:
        raise Refused(f"engine: expected {impl} in {' or '.join(PRECISIONS[impl])}, "
                         f"got {precision!r}")
    return impl, precision


__all__ = ["PRECISIONS", "PACKAGES", "PROGRESS_S", "PROTOCOL", "Refused", "engine_of",
           "keep_stdout_for_replies", "package_version", "say", "stdout_to_stderr"]
