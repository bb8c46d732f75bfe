"""Many runs on engines other than this process's MuJoCo: each through its worker, side by side.

A task names the engine spec that runs its MuJoCo plan. ``mujoco@THIS_PYTHON`` is this very
MuJoCo in a worker: its summaries equal the in-process runs' (the engine's own keys aside: the
spec and the path, read back). A worker that fails is its task's row with the reason, the others
kept; a user's own build is never cached; an engine the harness cannot run is refused up front.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import pytest

from tippetop.compare.running.runner import Task, run_tasks
from tippetop.models.errors import TippetopError

SHORT = ("run.t_end_s=0.2",)
HERE = f"mujoco@{sys.executable}"
#: What says who ran a run, read back, and the wall time: the rest is the physics
_WHO = ("wall_s", "engine", "path", "message")


def _physics(summary: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in summary.items() if k not in _WHO}


def _tasks(engine: str) -> list[Task]:
    return [Task("fig3", SHORT, engine, "paper"),
            Task("fig3", (*SHORT, "init.n0=80"), engine, "native"),
            Task("fig3", SHORT, "ode")]


def test_runs_on_a_worker_equal_the_in_process_runs(tmp_path: Path) -> None:
    here = run_tasks(_tasks("mujoco"), workers=2, cache_dir=tmp_path / "a")
    there = run_tasks(_tasks(HERE), workers=2, cache_dir=tmp_path / "b")
    for a, b in zip(here, there, strict=True):
        assert a.error is None and b.error is None, (a.error, b.error)
        assert _physics(a.summary) == _physics(b.summary)
        assert a.table.equals(b.table)
    mj = there[0].summary
    assert mj["engine"] == HERE and mj["path"] == "worker: plain loop"
    assert here[0].summary["engine"] == "mujoco"
    assert there[2].summary["engine"] == "ode"  # the reference runs here, whatever the rest
    # a user's own build is never cached: run again, computed again
    again = run_tasks(_tasks(HERE)[:1], workers=2, cache_dir=tmp_path / "b")
    assert not again[0].cached


def _fake_python(tmp_path: Path) -> str:
    path = tmp_path / "python"
    path.write_text("#!/bin/sh\necho 'Segmentation fault (core dumped)' >&2\nexit 139\n")
    path.chmod(0o755)
    return str(path)


def test_a_failing_worker_is_its_row_and_the_others_run(tmp_path: Path) -> None:
    broken = f"mujoco@{_fake_python(tmp_path)}"
    tasks = [Task("fig3", SHORT, broken), Task("fig3", SHORT, "mujoco"),
             Task("fig3", SHORT, HERE)]
    bad, ok, also = run_tasks(tasks, workers=2, cache_dir=tmp_path / "c")
    assert bad.summary is None and bad.error.startswith(f"engine {broken}: the worker in ")
    assert "exit status 139" in bad.error and "Segmentation fault" in bad.error
    assert ok.error is None and also.error is None


@pytest.mark.parametrize(("spec", "says"), [
    ("mjx", "engine mujoco-mjx==3.17.0: expected a release uv can install"),
    ("mujoco@/no/such/python", "engine mujoco@/no/such/python: expected the path of a Python "
     "interpreter"),
    ("mujoco==4", "engine: expected mujoco==X.Y.Z"),
    ("mujoco@no-such-python-9", "engine mujoco@no-such-python-9: expected the path of a Python "
     "interpreter that can import mujoco, or its command on PATH"),
])
def test_an_engine_that_cannot_run_is_refused_before_any_run(tmp_path: Path, spec: str,
                                                             says: str, monkeypatch) -> None:
    from tippetop.mujoco_runner import envs

    def no_env(implementation: str, say=None):  # uv without the registry: its one line
        raise TippetopError("engine mujoco-mjx==3.17.0: expected a release uv can install "
                            "from the package registry for Python 3.11, got: no network")

    monkeypatch.setattr(envs, "accelerated_env_python", no_env)
    with pytest.raises(TippetopError, match="^" + says.replace("(", r"\(").replace(")", r"\)")):
        run_tasks([Task("fig3", SHORT, "mujoco"), Task("fig3", SHORT, spec)],
                  cache_dir=tmp_path)
    assert not any(tmp_path.rglob("*.json"))  # nothing ran, nothing cached


def test_a_users_python_is_a_path_or_a_command_on_path(tmp_path: Path, monkeypatch) -> None:
    # mujoco@python3.12 names an interpreter as a shell would find it: the worker is started
    # with the absolute path PATH gives, the spec as the user wrote it
    from tippetop.compare.running.engines import engine_python
    from tippetop.models.engines import parse_engine

    (tmp_path / "mypython").symlink_to(sys.executable)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ.get('PATH', '')}")
    assert engine_python(parse_engine("mujoco@mypython")) == str(tmp_path / "mypython")
    assert engine_python(parse_engine(f"mujoco@{tmp_path}/mypython")) == f"{tmp_path}/mypython"
