"""Writing results: atomically, and never over a user's file without ``--force``."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tippetop.models.errors import TippetopError

if TYPE_CHECKING:  # pandas is imported by the table's own methods, not by this module
    import pandas as pd

TABLE_SUFFIXES = (".csv", ".parquet")


def json_ready(obj: Any) -> Any:
    """JSON-ready: NaN/inf -> None, numpy scalars -> Python, tuples -> lists.

    A typed record (a run's summary, a plan) is its ``to_json()``.
    """
    if hasattr(obj, "to_json") and not isinstance(obj, type):
        obj = obj.to_json()
    if isinstance(obj, dict):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


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
    if p.exists() and p.is_dir():
        raise TippetopError(f"--out: expected a file, got the folder {str(path)!r}")
    if p.exists() and not force:
        raise TippetopError(f"--out: expected a path that does not exist yet (or --force to "
                            f"overwrite), got existing {str(path)!r}")
    check_writable(p.parent)
    return p


def check_writable(folder: Path) -> None:
    """A file can be made in ``folder`` (checked by making one): before the work, not after.

    A killed run's temporary files older than any live write are removed on the way
    (:func:`tippetop.compare.running.leftovers.clean_leftovers`).
    """
    from tippetop.compare.running.leftovers import clean_leftovers

    try:
        fd, probe = tempfile.mkstemp(prefix=".tippetop-probe.", dir=folder)
    except OSError as exc:
        raise TippetopError(f"--out: expected a folder tippetop can write into, got "
                            f"{str(folder)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    clean_leftovers(folder)


def check_output_dir(path: str | Path, *, force: bool) -> Path:
    """Validate an output folder before any work: new or empty, or ``force``.

    Raises:
        TippetopError: a file where a folder is needed, a non-empty folder without ``force``,
            or a missing parent folder.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise TippetopError(f"--out: expected a folder, got the file {str(p)!r}")
    if p.is_dir() and any(p.iterdir()) and not force:
        raise TippetopError(f"--out: expected a new or empty folder (or --force to write into "
                            f"it), got {str(p)!r} which is not empty")
    if not p.parent.is_dir():
        raise TippetopError(f"--out: expected an existing parent folder, got "
                            f"{str(p.parent)!r}")
    check_writable(p if p.is_dir() else p.parent)
    return p


@contextlib.contextmanager
def staged_output_dir(out: Path) -> Iterator[Path]:
    """Write a folder's files all or not at all: into a hidden sibling, then moved into ``out``.

    Yields the staging folder. On success a new ``out`` is the staging folder renamed (one
    atomic step); into an existing one (empty, or ``--force``) its files are moved, each by an
    atomic rename, next to the folder's other files. On any error or Ctrl-C the staging folder
    is removed and ``out`` is as it was. Once the files are being moved into place, Ctrl-C
    and SIGTERM are ignored for the rest of the process (:func:`.interrupt.outputs_complete`):
    the folder is whole, and what follows is the summary.
    """
    from tippetop.compare.running.interrupt import outputs_complete

    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield stage
        outputs_complete()
        if not out.exists():
            stage.chmod(0o777 & ~_umask())
            os.rename(stage, out)
            return
        for src in sorted(stage.rglob("*")):
            dst = out / src.relative_to(stage)
            if src.is_dir():
                dst.mkdir(exist_ok=True)
            else:
                os.replace(src, dst)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


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


#: The name of the lock file of an output folder (beside it: ``.<folder>.tippetop.lock``).
LOCK_SUFFIX = ".tippetop.lock"


def lock_path(folder: str | Path) -> Path:
    """The lock file of an output folder: ``.<name>.tippetop.lock`` beside it.

    Beside, not inside, so that a folder that does not exist yet can be locked and an empty
    one stays empty.
    """
    p = Path(folder).resolve()
    return p.parent / f".{p.name}{LOCK_SUFFIX}"


@contextlib.contextmanager
def locked_output_dir(folder: str | Path, *, option: str = "--out") -> Iterator[Path]:
    """Hold an exclusive lock on an output folder for as long as the ``with`` block runs.

    The lock is ``fcntl.flock`` on :func:`lock_path`, which records the holder's pid; it is
    released (and the lock file removed) on exit, and by the system if the process dies. Take
    it before any work, so that two runs never write into one folder at the same time.

    Args:
        folder: The output folder (need not exist yet; its parent must).
        option: The option named in the error message.

    Yields:
        The lock file's path.

    Raises:
        TippetopError: Another process holds the lock (the message names the folder and that
            process's pid), or the lock file cannot be created.
    """
    path = lock_path(folder)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise TippetopError(f"{option}: expected a folder that can be locked, got "
                                f"{str(folder)!r} ({path}: {exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                os.close(fd)
                raise
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            raise TippetopError(f"{option}: expected a folder no other run is writing into, got "
                                f"{str(folder)!r}, in use by another tippetop run (pid "
                                f"{holder}; lock {path})") from None
        try:  # the holder may have removed the file between our open and our lock: retry
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield path
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)  # while still locked: a waiting opener sees the inode change
        os.close(fd)


def write_table(table: pd.DataFrame, path: Path) -> None:
    """Write the observables table as CSV or Parquet (by suffix), atomically."""
    if path.suffix.lower() == ".parquet":
        write_atomic(path, lambda tmp: table.to_parquet(tmp, index=False))
    else:
        write_atomic(path, lambda tmp: table.to_csv(tmp, index=False, float_format="%.17g"))


_HELD: dict[str, contextlib.ExitStack] = {}


def hold_output_lock(folder: str | Path, *, option: str = "--out") -> None:
    """Take :func:`locked_output_dir`'s lock on ``folder`` for the rest of this command.

    For commands that check their ``--out`` folder first and write it at the end: a second
    run into the same folder is refused at its start instead of mixing its files into the
    first's. Released when the process exits (by the system, if it is killed).
    """
    key = str(Path(folder).resolve())
    if key in _HELD:
        return
    stack = contextlib.ExitStack()
    stack.enter_context(locked_output_dir(folder, option=option))
    _HELD[key] = stack
    if len(_HELD) == 1:
        import atexit

        atexit.register(_release_all)


def _release_all() -> None:
    for stack in _HELD.values():
        stack.close()
    _HELD.clear()
