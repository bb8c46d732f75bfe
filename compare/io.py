"""Writing results: atomically, and never over a user's file without ``--force``."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from tippetop.models.errors import TippetopError

TABLE_SUFFIXES = (".csv", ".parquet")


def check_output_path(path: str | Path, *, force: bool, suffixes: tuple[str, ...]) -> Path:
    """Validate an output path before any work is done.

    Raises:
        TippetopError: wrong suffix, missing folder, or an existing file without ``force``.
    """
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise TippetopError(f"--out: expected a file ending in {' or '.join(suffixes)}, "
                            f"got {str(path)!r}")
    if not p.parent.is_dir():
        raise TippetopError(f"--out: expected an existing folder for the file, got "
                            f"{str(p.parent)!r}")
    if p.exists() and not force:
        raise TippetopError(f"--out: expected a path that does not exist yet (or --force to "
                            f"overwrite), got existing {str(path)!r}")
    return p


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it into place.

    An interrupted or failed write leaves no partial file at ``path``.
    """
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Write the observables table as CSV or Parquet (by suffix), atomically."""
    if path.suffix.lower() == ".parquet":
        write_atomic(path, lambda tmp: table.to_parquet(tmp, index=False))
    else:
        write_atomic(path, lambda tmp: table.to_csv(tmp, index=False, float_format="%.17g"))
