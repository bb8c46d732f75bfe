"""The note before runs that compile: what, where and about how long; once, on a terminal."""

from __future__ import annotations

import io

import pytest

import tippetop.compare.running.compiling as compiling
import tippetop.reference_ode._jit as jit
from tippetop.compare.running.engines import plan_for
from tippetop.models.scene import load_scene


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def _plan(engine: str, *sets: str):
    return plan_for(load_scene("fig3", list(sets)), engine)


def test_a_fresh_cache_says_what_compiles_and_how_long(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "is_compiled", lambda source: False)
    note = compiling.compile_note([_plan("ode")])
    assert note is not None
    # the scene's default, ode.method = auto, runs the Taylor method at order 12 on Fig. 3
    assert ("compiling the reference's integrator (taylor (order 12)) and the equations of "
            "motion") in note
    assert "about 16 s" in note and "rolling phase" in note
    # MuJoCo alone compiles in about 2 s: nothing to say before it
    assert compiling.compile_note([_plan("mujoco", "mujoco.friction=native")]) is None


@pytest.mark.parametrize("method", ["dop853", "vern9", "adams"])
def test_the_note_names_the_integrator_that_runs(monkeypatch: pytest.MonkeyPatch,
                                                 method: str) -> None:
    monkeypatch.setattr(jit, "is_compiled", lambda source: False)
    note = compiling.compile_note([_plan("ode", f"ode.method={method}")])
    assert note is not None and f"the reference's integrator ({method})" in note
    # a stem: auto runs the Adams method at rtol 1e-9 (the Taylor method has no stem)
    note = compiling.compile_note([_plan("ode", "effects.stem=true")])
    assert note is not None and "the reference's integrator (adams)" in note


def test_nothing_is_said_when_the_code_is_cached(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "is_compiled", lambda source: True)
    assert compiling.compile_note([_plan("ode"), _plan("mujoco")]) is None
    assert compiling.compile_s([_plan("ode"), _plan("mujoco")]) == 0.0  # the bar: no wait


def test_the_bar_waits_as_long_as_the_note_says(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "is_compiled", lambda source: False)
    plans = [_plan("ode")]
    note = compiling.compile_note(plans)
    assert note is not None and f"about {compiling.compile_s(plans):.0f} s" in note
    # MuJoCo's stepper alone: under QUIET_BELOW_S, neither a note nor a wait on the bar
    assert compiling.compile_s([_plan("mujoco", "mujoco.friction=native")]) == 0.0


def test_said_once_and_only_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "is_compiled", lambda source: False)
    monkeypatch.setattr(compiling, "_said", False)
    pipe, tty = io.StringIO(), _Tty()
    compiling.say_compile([_plan("ode")], stream=pipe)
    assert pipe.getvalue() == ""
    compiling.say_compile([_plan("ode")], stream=tty)
    compiling.say_compile([_plan("ode")], stream=tty)
    assert tty.getvalue().count("compiling") == 1


def test_the_cache_check_reads_numbas_own_folder() -> None:
    # this session has run the reference (the suite's runs before this test, or the import of
    # the integrator, which compiles its typed functions): its index files are where numba
    # keeps them, and a module never compiled has none
    import tippetop.reference_ode.dop853 as dop853

    assert jit.is_compiled(dop853.__file__)
    assert not jit.is_compiled(compiling.__file__)


def test_the_kernel_check_reads_the_drivers_cache() -> None:
    # a kernel is compiled into a module the driver writes to the cache (reference_ode/driver.py)
    from tippetop.reference_ode import dop853

    dop853.kernel()  # loaded (and compiled into the cache if it was not)
    assert compiling._kernel_compiled("dop853")
    assert not compiling._kernel_compiled("no_such_method")
