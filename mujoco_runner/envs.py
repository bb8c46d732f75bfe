"""Managed environments: a MuJoCo release in a virtual environment of its own, made on first use.

:func:`env_python` returns the interpreter of ``mujoco==X.Y.Z``'s environment under
``$TIPPETOP_CACHE/envs/``, making it with ``uv`` from the package registry the first time
(``mujoco`` and ``numpy`` only: the worker, :mod:`.worker`, needs nothing else) and finding it
afterwards without running anything. A failure (no network, no such release, no wheel for this
Python) is one line; a half-made environment is made again.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from tippetop.models.errors import TippetopError
from tippetop.models.resources import user_cache_dir

#: The marker a finished environment holds (written last).
READY = "ready.json"


def envs_root() -> Path:
    """Where managed environments live: ``$TIPPETOP_CACHE/envs``."""
    return user_cache_dir() / "envs"


def env_folder(version: str, root: Path | None = None) -> Path:
    """The folder of ``mujoco==version``'s environment for this Python."""
    py = f"py{sys.version_info[0]}{sys.version_info[1]}"
    return (root or envs_root()) / f"mujoco-{version}-{py}"


def _uv() -> str:
    try:
        from uv import find_uv_bin
    except ImportError:
        raise TippetopError("engine: expected the uv package to make a managed environment "
                            "(pip install uv), got none") from None
    return find_uv_bin()


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """One process at a time makes a given environment (the others wait, then find it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _size_mb(folder: Path) -> float:
    total = 0
    for dirpath, _dirs, files in os.walk(folder):
        for name in files:
            with contextlib.suppress(OSError):
                total += os.lstat(os.path.join(dirpath, name)).st_size
    return total / 2**20


def _uv_error(stderr: str) -> str:
    """Uv's reason in one line: its ``error:``/``cause:`` lines, or its last line."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    keep = [ln.removeprefix("error: ").removeprefix("cause: ") for ln in lines
            if ln.startswith(("error:", "cause:", "×", "╰─▶"))]
    text = "; ".join(keep or lines[-1:]) or "no output"
    return " ".join(text.split())[:400]


def ready_python(version: str, root: Path | None = None) -> Path | None:
    """The interpreter of a finished environment of ``mujoco==version``, or None."""
    folder = env_folder(version, root)
    python = folder / "bin" / "python"
    return python if (folder / READY).is_file() and python.exists() else None


def env_python(version: str, *, root: Path | None = None,
               say: Callable[[str], None] | None = None) -> Path:
    """The interpreter of ``mujoco==version``'s managed environment, made if it is missing.

    Args:
        version: A MuJoCo release (``3.3.7``).
        root: Where environments live (default :func:`envs_root`).
        say: Told, one line each, what is being made and how big it came out.

    Raises:
        TippetopError: uv could not make it (one line: uv's reason).
    """
    python = ready_python(version, root)
    if python is not None:
        return python
    folder = env_folder(version, root)
    with _locked(folder.with_name(folder.name + ".lock")):
        python = ready_python(version, root)
        if python is not None:  # another process made it while this one waited
            return python
        shutil.rmtree(folder, ignore_errors=True)
        tell = say or (lambda _line: None)
        tell(f"tippetop: making an environment for mujoco=={version} with uv (once; kept in "
             f"{folder})")
        t0 = time.monotonic()
        uv = _uv()
        steps = ([uv, "venv", "--quiet", "--python", sys.executable, str(folder)],
                 [uv, "pip", "install", "--quiet", "--no-build", "--python",
                  str(folder / "bin" / "python"), f"mujoco=={version}", "numpy"])
        for cmd in steps:
            try:
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
            except (OSError, subprocess.TimeoutExpired) as exc:
                shutil.rmtree(folder, ignore_errors=True)
                raise TippetopError(f"engine mujoco=={version}: expected uv to make its "
                                    f"environment, got {type(exc).__name__}: {exc}") from None
            if done.returncode != 0:
                shutil.rmtree(folder, ignore_errors=True)
                raise TippetopError(f"engine mujoco=={version}: expected a release uv can "
                                    f"install from the package registry for Python "
                                    f"{sys.version_info[0]}.{sys.version_info[1]}, got: "
                                    f"{_uv_error(done.stderr)}")
        size = _size_mb(folder)
        (folder / READY).write_text(json.dumps({"mujoco": version, "python": sys.executable,
                                                "size_mb": round(size, 1)}) + "\n")
        tell(f"tippetop: mujoco=={version} ready: {size:.0f} MB in "
             f"{time.monotonic() - t0:.0f} s")
        return folder / "bin" / "python"


__all__ = ["READY", "env_folder", "env_python", "envs_root", "ready_python"]
