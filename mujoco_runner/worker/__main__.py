"""Start the worker: ``PYTHON path/to/worker`` (this folder) answers requests on stdin.

Run by path, the folder is ``sys.path[0]``: it is taken off before anything else is imported,
and the folder is loaded as a package of its own name (:data:`NAME`), so that its modules are
reached through that package alone. None of them shadows a module of the interpreter's, and
none is shadowed by one; nothing of tippetop's is needed. ``python -m
tippetop.mujoco_runner.worker`` runs the same from tippetop.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from types import ModuleType

#: The name the folder is loaded under when it is run by path.
NAME = "_tippetop_worker"


def load(folder: str, name: str = NAME) -> ModuleType:
    """The worker's package, loaded from ``folder`` under the module name ``name``.

    Its modules import each other relatively, so they are found in ``folder`` alone, whatever
    ``sys.path`` holds.

    Raises:
        ImportError: ``folder`` holds no package (no ``__init__.py``).
    """
    init = os.path.join(folder, "__init__.py")
    spec = importlib.util.spec_from_file_location(name, init,
                                                  submodule_search_locations=[folder])
    if spec is None or spec.loader is None or not os.path.isfile(init):
        raise ImportError(f"expected the worker's package in {folder}, got no {init}")
    package = importlib.util.module_from_spec(spec)
    sys.modules[name] = package
    spec.loader.exec_module(package)
    return package


def _package() -> ModuleType:
    """The worker's package: tippetop's (``python -m``), or this folder's, loaded by path."""
    if __package__:
        return sys.modules[__package__]
    here = os.path.dirname(os.path.realpath(__file__))
    if sys.path and os.path.realpath(sys.path[0] or os.curdir) == here:
        del sys.path[0]  # the folder's modules are reached through the package alone
    return load(here)


if __name__ == "__main__":
    worker = _package()
    worker.keep_stdout_for_replies()
    raise SystemExit(worker.main())
