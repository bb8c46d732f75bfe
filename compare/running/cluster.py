"""Runs on a Dask cluster: the plans sent as their JSON, the results as each ends."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from tippetop.compare.running.tasks import Task, execute_plan
from tippetop.models.errors import TippetopError
from tippetop.models.plan import RunPlan


def dispatch_dask(unique: list[tuple[str, Task]], plans: dict[str, RunPlan],
                   scheduler: str) -> Iterable[tuple[str, dict[str, Any]]]:
    """Run the tasks' plans on the Dask cluster at ``scheduler``, sent as their JSON."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_as_completed
    except ImportError:  # pragma: no cover - distributed is a dependency
        raise TippetopError("--scheduler: expected the 'distributed' package installed, got an "
                            "ImportError") from None
    if not scheduler.startswith("tcp://"):
        raise TippetopError(f"--scheduler: expected tcp://HOST:PORT, got {scheduler!r}")
    try:
        client = Client(scheduler, timeout="10s")
    except OSError as exc:
        raise TippetopError(f"--scheduler: expected a reachable Dask scheduler, got "
                            f"{scheduler!r} ({exc})") from None
    with client:
        futures = client.map(execute_plan, [plans[key].to_json() for key, _ in unique],
                             pure=False)
        keys = {f.key: k for f, (k, _) in zip(futures, unique, strict=True)}
        for fut in dask_as_completed(futures):
            yield keys[fut.key], fut.result()


__all__ = ["dispatch_dask"]
