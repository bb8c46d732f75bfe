"""Data files shipped inside the package (scenes, the catalogue, calibrations, baselines).

They are found through :mod:`importlib.resources` from the package that ships them, never from
``__file__``: the installed layout (``tippetop.models``, ...) need not mirror the repository's.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

from tippetop.models.errors import TippetopError


def data_path(package: str, *parts: str) -> Path:
    """The file-system path of a data file or folder shipped in ``package``.

    Args:
        package: A package of this distribution, e.g. ``"tippetop.models"``.
        *parts: Path components inside it, e.g. ``"scenes"``.

    Raises:
        RuntimeError: If the package is not installed as plain files (a zip import), where
            data files have no path to write or glob.
    """
    p = files(package).joinpath(*parts)
    if not isinstance(p, Path):  # pragma: no cover - only for zip imports
        raise RuntimeError(f"{package}: expected an installation on the file system, got {p!r}")
    return p


def user_cache_dir() -> Path:
    """``$TIPPETOP_CACHE``, else ``~/.cache/tippetop``: cached runs and compiled code.

    Raises:
        TippetopError: The path, or the nearest of its parents that exists, is not a folder
            (``TIPPETOP_CACHE`` pointing at a file), so no cache folder can be made there.
    """
    env = os.environ.get("TIPPETOP_CACHE")
    folder = Path(env) if env else Path.home() / ".cache" / "tippetop"
    existing = next((p for p in (folder, *folder.parents) if p.exists()), None)
    if existing is not None and not existing.is_dir():
        what = "$TIPPETOP_CACHE" if env else "the cache folder ~/.cache/tippetop"
        raise TippetopError(f"{what}: expected a folder (or a path where one can be made), "
                            f"got {str(folder)!r}, where {str(existing)!r} is a file")
    return folder
