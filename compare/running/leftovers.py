"""Leftovers of a killed run: temporary files and empty staging folders, cleaned later."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

#: ``write_atomic``'s temporary files: ``.<name>.<mkstemp's 8 characters>.tmp``.
_TMP_RE = re.compile(r"^\..+\.[A-Za-z0-9_]{8}\.tmp$")
#: ``staged_output_dir``'s staging folders: ``.<folder>.<mkdtemp's 8 characters>``.
_STAGE_RE = re.compile(r"^\..+\.[A-Za-z0-9_]{8}$")
#: Default age (s) past which a temporary file or empty staging folder is a leftover.
DEFAULT_MIN_AGE_S = 3600.0


def _older(entry: os.DirEntry[str], cutoff: float) -> bool:
    try:
        return entry.stat(follow_symlinks=False).st_mtime < cutoff
    except OSError:
        return False


def clean_leftovers(folder: str | Path, *, min_age_s: float = DEFAULT_MIN_AGE_S) -> list[Path]:
    """Remove a killed run's leftovers directly inside ``folder``.

    Removes hidden temporary files of the atomic writer (``.<name>.XXXXXXXX.tmp``) and empty
    hidden staging folders (``.<name>.XXXXXXXX``) last modified more than ``min_age_s`` ago.
    Errors (a file removed meanwhile by another run, no permission) are ignored.

    Args:
        folder: The folder to clean (a missing one is nothing to clean).
        min_age_s: Leave anything younger: a run going now may still be writing it (s).

    Returns:
        The paths removed.
    """
    cutoff = time.time() - min_age_s
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        try:
            is_file = entry.is_file(follow_symlinks=False)
            is_dir = entry.is_dir(follow_symlinks=False)
        except OSError:
            continue
        try:
            if is_file and _TMP_RE.match(entry.name) and _older(entry, cutoff):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
            elif is_dir and _STAGE_RE.match(entry.name) and _older(entry, cutoff):
                os.rmdir(entry.path)  # only an empty one: rmdir refuses the others
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def clean_cache_leftovers(root: str | Path, *,
                          min_age_s: float = DEFAULT_MIN_AGE_S) -> list[Path]:
    """Remove leftovers from a runs cache: ``root`` and its two-character key folders.

    Args:
        root: The cache folder (``$TIPPETOP_CACHE``).
        min_age_s: As in :func:`clean_leftovers` (s).

    Returns:
        The paths removed.
    """
    removed = clean_leftovers(root, min_age_s=min_age_s)
    try:
        subs = [e.path for e in os.scandir(root)
                if len(e.name) == 2 and e.is_dir(follow_symlinks=False)]
    except OSError:
        return removed
    for sub in subs:
        removed += clean_leftovers(sub, min_age_s=min_age_s)
    return removed


__all__ = ["DEFAULT_MIN_AGE_S", "clean_cache_leftovers", "clean_leftovers"]
