"""Managed environments: an engine in a virtual environment of its own, made on first use.

:func:`env_python` returns the interpreter of ``mujoco==X.Y.Z``'s environment under
``$TIPPETOP_CACHE/envs/``, making it with ``uv`` from the package registry the first time
(``mujoco`` and ``numpy`` only: the worker, :mod:`.worker`, needs nothing else) and finding it
afterwards without running anything; :func:`accelerated_env_python` does the same for MuJoCo
MJX (``mjx-X.Y.Z``: ``mujoco-mjx``, the MuJoCo C release of its number, JAX on the CPU) and
MuJoCo Warp (``warp-X.Y.Z``: ``mujoco-warp`` and ``warp-lang``), and
:func:`package_env_python` for any named set of packages. A failure (no network, no such
release, no wheel for this Python) is one line; a half-made environment is made again.
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
#: The MuJoCo MJX release the ``mjx`` engines install: the newest on the package registry when
#: this was written. MJX follows the MuJoCo C release of the same number (``mujoco-mjx``
#: 3.17.0 asks only ``mujoco>=3.17.0.dev0``, so the environment pins ``mujoco==3.17.0``: the
#: release MJX is compared against).
MJX_VERSION = "3.17.0"
#: The MuJoCo Warp release the ``warp`` engine installs: the newest on the package registry
#: when this was written; it follows MuJoCo 4.0 (and brings its ``mujoco``), with the newest
#: ``warp-lang`` (1.19.0 then) uv resolves.
WARP_VERSION = "4.0.0"


def envs_root() -> Path:
    """Where managed environments live: ``$TIPPETOP_CACHE/envs``."""
    return user_cache_dir() / "envs"


def env_folder(version: str, root: Path | None = None) -> Path:
    """The folder of ``mujoco==version``'s environment for this Python."""
    return named_folder(f"mujoco-{version}", root)


def named_folder(name: str, root: Path | None = None) -> Path:
    """The folder of the environment ``name`` (``mjx-3.17.0``) for this Python."""
    py = f"py{sys.version_info[0]}{sys.version_info[1]}"
    return (root or envs_root()) / f"{name}-{py}"


def accelerated_packages(implementation: str) -> tuple[str, tuple[str, ...]]:
    """The environment name and the packages of an accelerated engine (``mjx`` or ``warp``).

    Raises:
        TippetopError: Another implementation (one line).
    """
    if implementation == "mjx":
        return (f"mjx-{MJX_VERSION}",
                (f"mujoco-mjx=={MJX_VERSION}", f"mujoco=={MJX_VERSION}", "jax", "numpy"))
    if implementation == "warp":
        return (f"warp-{WARP_VERSION}",
                (f"mujoco-warp=={WARP_VERSION}", "warp-lang", "numpy"))
    raise TippetopError(f"engine: expected mjx or warp for an accelerated environment, got "
                        f"{implementation!r}")


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
    return _ready(env_folder(version, root))


def _ready(folder: Path) -> Path | None:
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
    return package_env_python(f"mujoco-{version}", (f"mujoco=={version}", "numpy"),
                              label=f"mujoco=={version}", root=root, say=say,
                              marker={"mujoco": version})


def accelerated_env_python(implementation: str, *, root: Path | None = None,
                           say: Callable[[str], None] | None = None) -> Path:
    """The interpreter of MJX's (``mjx``) or MuJoCo Warp's (``warp``) managed environment.

    Made with uv on first use (:func:`accelerated_packages`), found afterwards.

    Raises:
        TippetopError: Another implementation, or uv could not make it (one line).
    """
    name, packages = accelerated_packages(implementation)
    return package_env_python(name, packages, label=packages[0], root=root, say=say)


def package_env_python(name: str, packages: tuple[str, ...], *, label: str | None = None,
                       root: Path | None = None, say: Callable[[str], None] | None = None,
                       marker: dict[str, str] | None = None) -> Path:
    """The interpreter of the managed environment ``name`` holding ``packages``.

    Made with uv from the package registry (binary wheels only) the first time, one process
    at a time (the others wait for it, then find it); found afterwards without running
    anything.

    Args:
        name: The environment's folder name without the Python tag (``mjx-3.17.0``).
        packages: Requirements for ``uv pip install`` (``mujoco-mjx==3.17.0``, ``numpy``).
        label: How messages name the engine (default ``name``).
        root: Where environments live (default :func:`envs_root`).
        say: Told, one line each, what is being made and how big it came out.
        marker: Extra keys for the environment's :data:`READY` file.

    Raises:
        TippetopError: uv could not make it (one line: uv's reason).
    """
    folder = named_folder(name, root)
    python = _ready(folder)
    if python is not None:
        return python
    label = label or name
    with _locked(folder.with_name(folder.name + ".lock")):
        python = _ready(folder)
        if python is not None:  # another process made it while this one waited
            return python
        shutil.rmtree(folder, ignore_errors=True)
        tell = say or (lambda _line: None)
        tell(f"tippetop: making an environment for {label} with uv (once; kept in "
             f"{folder})")
        t0 = time.monotonic()
        uv = _uv()
        steps = ([uv, "venv", "--quiet", "--python", sys.executable, str(folder)],
                 [uv, "pip", "install", "--quiet", "--no-build", "--python",
                  str(folder / "bin" / "python"), *packages])
        for cmd in steps:
            try:
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
            except (OSError, subprocess.TimeoutExpired) as exc:
                shutil.rmtree(folder, ignore_errors=True)
                raise TippetopError(f"engine {label}: expected uv to make its "
                                    f"environment, got {type(exc).__name__}: {exc}") from None
            if done.returncode != 0:
                shutil.rmtree(folder, ignore_errors=True)
                raise TippetopError(f"engine {label}: expected a release uv can "
                                    f"install from the package registry for Python "
                                    f"{sys.version_info[0]}.{sys.version_info[1]}, got: "
                                    f"{_uv_error(done.stderr)}")
        size = _size_mb(folder)
        made_s = time.monotonic() - t0
        (folder / READY).write_text(json.dumps({**(marker or {}), "packages": list(packages),
                                                "python": sys.executable,
                                                "size_mb": round(size, 1),
                                                "made_s": round(made_s, 1)}) + "\n")
        tell(f"tippetop: {label} ready: {size:.0f} MB in {made_s:.0f} s")
        return folder / "bin" / "python"


__all__ = ["MJX_VERSION", "READY", "WARP_VERSION", "accelerated_env_python",
           "accelerated_packages", "env_folder", "env_python", "envs_root", "named_folder",
           "package_env_python", "ready_python"]
