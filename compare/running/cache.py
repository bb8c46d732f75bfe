"""The run cache: one checksummed entry per task key, written atomically off the main thread.

A task's key (:func:`task_key`) hashes its plan's physics, the code that computes a run and its
summary (:func:`code_fingerprint`) and the engine that runs it; :class:`ResultCache` holds one
JSON entry and one Parquet table per key; :class:`CacheWriter` writes them on a thread of its
own. How the key is made: docs/design.md.
"""

from __future__ import annotations

import hashlib
import json
import threading
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

import pandas as pd

from tippetop.compare.measures.summary import RunSummary
from tippetop.compare.running.io import write_atomic
from tippetop.compare.running.leftovers import clean_cache_leftovers
from tippetop.compare.running.tasks import Task
from tippetop.models.errors import TippetopError
from tippetop.models.plan import RunPlan
from tippetop.models.resources import data_path, user_cache_dir

#: The packages whose Python sources shape a cached result: the engines, and the measures a
#: run's summary is made of (the series' metrics, the realised friction law, the summary).
PACKAGES = ("tippetop.models", "tippetop.reference_ode", "tippetop.mujoco_runner",
            "tippetop.compare.measures")
#: Files outside those packages' Python sources that shape a cached result (its summary and
#: table), among them the calibrated native-friction settings that native runs use by default.
MODULES = (("tippetop.compare.running", "engines.py"), ("tippetop.compare.running", "tasks.py"),
           ("tippetop.models", "calibrated_native.toml"))


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of the source that computes a run and its summary (and of MuJoCo's version)."""
    h = hashlib.sha256()
    files = [(pkg, p) for pkg in PACKAGES for p in sorted(data_path(pkg).rglob("*.py"))]
    files += [(pkg, data_path(pkg, name)) for pkg, name in MODULES]
    for pkg, path in files:
        if not path.is_file():
            continue
        h.update(f"{pkg}/{path.relative_to(data_path(pkg)).as_posix()}".encode())
        h.update(path.read_bytes())
    try:
        h.update(metadata.version("mujoco").encode())
    except metadata.PackageNotFoundError:  # pragma: no cover - mujoco is a dependency
        pass
    return h.hexdigest()[:16]


def task_key(task: Task, plan: RunPlan | None = None) -> str:
    """The cache key of a task: its plan's physics (its MJCF text included), the code.

    And the engine that runs it, where it is not this process's own (a release, a build, MJX).
    """
    plan = plan or task.plan()
    payload: dict[str, Any] = {**plan.physics(), "code": code_fingerprint()}
    if plan.engine not in ("ode", "mujoco"):
        payload["engine"] = plan.engine
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:24]


def cacheable(task: Task) -> bool:
    """A user's own build (``mujoco@PYTHON``) changes behind its name: never cached."""
    return not task.engine.startswith("mujoco@")


def default_cache_dir() -> Path:
    """``$TIPPETOP_CACHE``, else ``~/.cache/tippetop``."""
    return user_cache_dir()


class ResultCache:
    """One JSON entry and one Parquet table per task key, written atomically and checksummed.

    The JSON file is ``{"format", "key", "summary", "summary_sha256", "table_sha256"}``: the
    task's summary, the key it was computed for, and the sha256 of the summary (as canonical
    JSON) and of the Parquet file's bytes. An entry that does not verify (a number edited, a
    file cut short or swapped, JSON of another shape such as ``{}`` or ``[]``, another key, or
    an entry written before checksums) is a miss: the task runs again and the entry is
    rewritten. The checksums catch accidents and edits, not an attacker (who can rehash).
    """

    #: The entry format; an entry of any other (or none) is recomputed.
    FORMAT = "tippetop-cache/2"

    def __init__(self, root: Path) -> None:
        self.root = root

    def _paths(self, key: str) -> tuple[Path, Path]:
        d = self.root / key[:2]
        return d / f"{key}.json", d / f"{key}.parquet"

    @staticmethod
    def _digest(summary: dict[str, Any]) -> str:
        """sha256 of the summary as canonical JSON (sorted keys)."""
        return hashlib.sha256(json.dumps(summary, sort_keys=True).encode("utf-8")).hexdigest()

    def get(self, key: str) -> tuple[RunSummary, pd.DataFrame] | None:
        """The cached summary and table if the entry verifies, else None (recompute).

        A summary of the release before is read as today's (:meth:`RunSummary.from_json`);
        one that is not a summary at all is a miss.
        """
        js, pq = self._paths(key)
        try:
            entry = json.loads(js.read_text(encoding="utf-8"))
            data = pq.read_bytes()
        except (ValueError, OSError):  # missing, unreadable, not JSON (or not UTF-8)
            return None
        if not (isinstance(entry, dict) and entry.get("format") == self.FORMAT
                and entry.get("key") == key and isinstance(entry.get("summary"), dict)):
            return None
        summary = entry["summary"]
        if (entry.get("summary_sha256") != self._digest(summary)
                or entry.get("table_sha256") != hashlib.sha256(data).hexdigest()):
            return None
        try:
            return RunSummary.from_json(summary), read_parquet_bytes(data)
        except (ValueError, OSError, TippetopError):  # (cannot happen to bytes that verify)
            return None

    def put(self, key: str, summary: RunSummary | dict[str, Any], table: pd.DataFrame) -> None:
        """Store a task's results: the table, then the entry that vouches for it."""
        import io

        if isinstance(summary, RunSummary):
            summary = summary.to_json()
        js, pq = self._paths(key)
        js.parent.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        table.to_parquet(buf, index=False)
        data = buf.getvalue()
        entry = {"format": self.FORMAT, "key": key, "summary": summary,
                 "summary_sha256": self._digest(summary),
                 "table_sha256": hashlib.sha256(data).hexdigest()}
        text = json.dumps(entry)
        write_atomic(pq, lambda tmp: tmp.write_bytes(data))
        write_atomic(js, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def read_parquet_bytes(data: bytes) -> pd.DataFrame:
    """A Parquet file's bytes as a table, read by Arrow from memory of its own, on this thread.

    Not ``pd.read_parquet(io.BytesIO(data))``: Arrow then holds the Python buffer, and one of
    its own threads may release it after the interpreter has begun to exit. Taking the GIL
    there ends that thread inside C++ and aborts the process ("terminate called without an
    active exception", exit 134 after a complete result). Measured on 2026-11-29, a warm
    cache under load, runs interleaved: 3 of 80 ``tippetop compare`` runs aborted reading
    that way, 0 of 80 this way; the core's abort in ``arrow::py::PyBuffer::~PyBuffer`` on an
    Arrow thread-pool worker.
    """
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as papq

    buf = pa.allocate_buffer(len(data))
    np.frombuffer(buf, dtype=np.uint8)[:] = np.frombuffer(data, dtype=np.uint8)
    table = papq.read_table(pa.BufferReader(buf), use_threads=False)
    return table.to_pandas(use_threads=False)


class CacheWriter:
    """Writes cache entries on a background thread, so the runs never wait for the disk.

    Entries are written in the order given; :meth:`close` waits for all of them. Each entry is
    atomic (:meth:`ResultCache.put`), so a process stopped while one is written leaves no
    partial entry. The first error (a full disk, say) is raised by the next :meth:`put` or by
    :meth:`close`.
    """

    #: Longest wait for the pending entries when the command is being stopped (s).
    STOP_WAIT_S = 2.0

    def __init__(self, cache: ResultCache) -> None:
        import queue

        self.cache = cache
        self.queue: queue.SimpleQueue[tuple[str, dict[str, Any], pd.DataFrame] | None] = \
            queue.SimpleQueue()
        self.error: BaseException | None = None
        self.thread: threading.Thread | None = None
        #: entries written (for tests)
        self.written = 0

    def put(self, key: str, summary: dict[str, Any], table: pd.DataFrame) -> None:
        """Queue one entry (the table is copied: the caller may change its own)."""
        if self.error is not None:
            raise self.error
        if self.thread is None:
            self.thread = threading.Thread(target=self._work, name="tippetop-cache-writer",
                                           daemon=True)
            self.thread.start()
        self.queue.put((key, summary, table.copy()))

    def _work(self) -> None:
        while True:
            item = self.queue.get()
            if item is None:
                return
            if self.error is not None:
                continue
            try:
                self.cache.put(*item)
                self.written += 1
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                self.error = exc

    def close(self, *, raise_error: bool = True) -> None:
        """Wait for the queued entries (briefly when stopping); raise the first error."""
        if self.thread is not None:
            self.queue.put(None)
            self.thread.join(None if raise_error else self.STOP_WAIT_S)
            self.thread = None
        if raise_error and self.error is not None:
            raise self.error


#: Age past which a temporary file in the cache is a killed run's leftover (s): a cache
#: write (a summary, a table of at most CACHED_TABLE_ROWS rows) takes well under a second.
CACHE_LEFTOVER_AGE_S = 600.0


@lru_cache(maxsize=8)
def clean_cache_once(root: str) -> None:
    """Remove a killed run's temporary files from the cache at ``root``, once per process."""
    clean_cache_leftovers(root, min_age_s=CACHE_LEFTOVER_AGE_S)


__all__ = ["CACHE_LEFTOVER_AGE_S", "MODULES", "PACKAGES", "CacheWriter", "ResultCache",
           "cacheable", "clean_cache_once", "code_fingerprint", "default_cache_dir",
           "read_parquet_bytes", "task_key"]
