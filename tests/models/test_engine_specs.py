"""Engine specs: what each form names, and one line for anything else."""

from __future__ import annotations

import pytest

from tippetop.models.engines import EngineSpec, parse_engine, parse_engines
from tippetop.models.errors import TippetopError


@pytest.mark.parametrize(("text", "want"), [
    ("mujoco", EngineSpec("mujoco", "mujoco")),
    (" mujoco==3.3.7 ", EngineSpec("mujoco==3.3.7", "mujoco", version="3.3.7")),
    ("mujoco@/opt/build/bin/python", EngineSpec("mujoco@/opt/build/bin/python", "mujoco",
                                                python="/opt/build/bin/python")),
    ("mjx", EngineSpec("mjx", "mjx")),
    ("mjx-f32", EngineSpec("mjx-f32", "mjx", precision="float32")),
    ("warp", EngineSpec("warp", "warp", precision="float32")),
])
def test_each_form(text: str, want: EngineSpec) -> None:
    assert parse_engine(text) == want
    assert parse_engine(text).in_process == (want.spec in ("ode", "mujoco"))


@pytest.mark.parametrize(("text", "says"), [
    ("mujoco==3.3", "engine: expected mujoco==X.Y.Z with a release number such as 3.3.7, "
     "got 'mujoco==3.3'"),
    ("mujoco==latest", "got 'mujoco==latest'"),
    ("mujoco@", "engine: expected ode, mujoco, mujoco==X.Y.Z, mujoco@PYTHON, mjx, mjx-f32 or "
     "warp, got 'mujoco@'"),
    ("bullet", "got 'bullet'"),
    ("MJX", "got 'MJX'"),
])
def test_anything_else_is_one_line(text: str, says: str) -> None:
    with pytest.raises(TippetopError) as info:
        parse_engine(text)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_a_list_of_specs() -> None:
    assert [s.spec for s in parse_engines("mujoco, mujoco==3.17.0,mjx")] == [
        "mujoco", "mujoco==3.17.0", "mjx"]
    with pytest.raises(TippetopError, match="expected each engine once, got mujoco twice"):
        parse_engines("mujoco,mjx,mujoco")
    with pytest.raises(TippetopError, match="expected at least one"):
        parse_engines(" , ")
