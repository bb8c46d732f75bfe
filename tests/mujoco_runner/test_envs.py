"""Managed environments: made once with uv from the package registry, found afterwards.

Slow (the first environment is a download): a release older than the installed MuJoCo runs a
plan through the worker; a second request finds the environment without running anything; a
release the registry does not have is one line and leaves nothing behind.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.conftest import mujoco_plan
from tippetop.models.errors import TippetopError
from tippetop.mujoco_runner import envs, remote
from tippetop.mujoco_runner.run import simulate_plan

#: An older release: its numbers need not be the installed 4.0's
OLD = "3.3.7"


@pytest.mark.slow
def test_a_managed_environment_runs_an_older_release(tmp_path: Path) -> None:
    said: list[str] = []
    python = envs.env_python(OLD, root=tmp_path, say=said.append)
    assert python.is_file() and (envs.env_folder(OLD, tmp_path) / envs.READY).is_file()
    assert "making an environment for mujoco==3.3.7" in said[0] and " MB in " in said[-1]
    # found again without making anything, in well under a second
    t0 = time.perf_counter()
    again = envs.env_python(OLD, root=tmp_path, say=said.append)
    assert again == python and time.perf_counter() - t0 < 1.0 and len(said) == 2
    # the plan runs there: the same model, the other release's own numbers
    plan = mujoco_plan("mujoco.friction=native", "run.t_end_s=0.5")
    there, info = remote.simulate_in(str(python), plan)
    here = simulate_plan(plan)
    assert info.version == OLD and there.status == "ok"
    assert there.ran == here.ran  # the plan's values, read back there
    # a different release, the same physics to within what its solver changes: theta apart
    # by at most 1e-2 rad over 0.5 s (measured 2e-4 rad over 1 s from 3.3.7 to 4.0.0)
    import numpy as np
    assert np.max(np.abs(there.table["theta"].to_numpy() - here.table["theta"].to_numpy())) \
        < 1e-2
    # a run that diverges there names the warning by that release's enum, as its text does
    # (3.3.7's code 5 is BADQVEL, 4.0's BADQACC)
    bad = mujoco_plan("mujoco.friction=paper", "effects.sliding=false", "init.n0=1e11",
                      "run.t_end_s=0.1")
    there, _ = remote.simulate_in(str(python), bad)
    assert there.status == "diverged"
    assert "MuJoCo warning mjWARN_BADQVEL (1x): Nan, Inf or huge value in QVEL" in there.message


@pytest.mark.slow
def test_a_release_the_registry_does_not_have_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(TippetopError) as info:
        envs.env_python("9.9.9", root=tmp_path)
    msg = str(info.value)
    assert msg.startswith("engine mujoco==9.9.9: expected a release uv can install")
    assert "mujoco==9.9.9" in msg.split("got: ", 1)[1] and "\n" not in msg
    assert not envs.env_folder("9.9.9", tmp_path).exists()
