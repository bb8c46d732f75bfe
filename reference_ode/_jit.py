"""Where the compiled functions are cached on disk (numba's ``cache=True``).

numba checks a cached function against its own source file only. A function that inlines code
from another file (the integrator specialised on a right-hand side, the MuJoCo callback built
on the friction law, with MuJoCo's struct layout baked in) would be served stale after that
other file, or MuJoCo, changed. So every cache lives in a folder named by a hash of this
package's sources and of the numba and MuJoCo versions: change any of them and everything is
compiled afresh into a new folder. ``NUMBA_CACHE_DIR``, when set, is respected as is.
"""

from __future__ import annotations

import hashlib
import os
from importlib import metadata
from pathlib import Path

from tippetop.models.resources import data_path, user_cache_dir

#: The packages whose versions shape compiled code.
_VERSIONED = ("numba", "mujoco")


def cache_key() -> str:
    """Hash of this package's Python sources and of the numba and MuJoCo versions."""
    h = hashlib.sha256()
    root = data_path("tippetop.reference_ode")
    for path in sorted(root.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    for pkg in _VERSIONED:
        try:
            h.update(f"{pkg}={metadata.version(pkg)}".encode())
        except metadata.PackageNotFoundError:  # pragma: no cover - both are dependencies
            h.update(f"{pkg}=none".encode())
    return h.hexdigest()[:16]


def configure_numba_cache() -> Path | None:
    """Point numba's cache at ``<user cache>/numba/<cache_key()>`` (before any ``@njit``).

    Returns:
        The folder, or None when ``NUMBA_CACHE_DIR`` is set (then numba uses that).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    import numba

    folder = user_cache_dir() / "numba" / cache_key()
    numba.config.CACHE_DIR = str(folder)
    return folder


def is_compiled(source: str | Path) -> bool:
    """Whether numba's cache holds compiled code of a module's functions (any of them).

    Args:
        source: The module's file (its ``__file__``).

    Returns:
        True when the cache folder numba uses for that file has an index (``*.nbi``) of the
        file's functions, so a run loads them instead of compiling.
    """
    import numba
    from numba.core.caching import _CacheLocator

    path = Path(source).resolve()
    folder = Path(numba.config.CACHE_DIR or path.parent / "__pycache__")
    if numba.config.CACHE_DIR:
        folder = folder / _CacheLocator.get_suitable_cache_subpath(str(path))
    return any(folder.glob(f"{path.stem}.*.nbi"))
