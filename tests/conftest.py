"""Shared fixtures: runs are cached per session so that several tests can read one run."""

from __future__ import annotations

import functools
import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

#: The suite's own cache and history (issue 43: the tests leave the user's state alone). Every
#: run the tests make, every history they append to and the code they compile go here, never to
#: the user's ``$TIPPETOP_CACHE`` (before: ``~/.cache/tippetop`` held the tests' matrix and
#: bisect runs in its history). Kept between sessions under the repository's gitignored build/
#: so that compiled code is reused; ``TIPPETOP_TEST_CACHE`` names another folder. Set before
#: tippetop is imported: the compiled-code cache is chosen on import.
TEST_CACHE = Path(os.environ.get("TIPPETOP_TEST_CACHE")
                  or Path(__file__).resolve().parents[1] / "build" / "test-cache")
USER_CACHE = os.environ.get("TIPPETOP_CACHE")  # the user's, for the test that it is left alone
os.environ["TIPPETOP_CACHE"] = str(TEST_CACHE)

from tippetop.models.options import OdeOptions  # noqa: E402 (after TIPPETOP_CACHE)
from tippetop.models.params import FrictionParams, InitialState, TopParams  # noqa: E402 (after TIPPETOP_CACHE)
from tippetop.models.plan import MujocoPlan  # noqa: E402 (after TIPPETOP_CACHE)
from tippetop.models.resolve import resolve_plan  # noqa: E402 (after TIPPETOP_CACHE)
from tippetop.models.scene import load_scene  # noqa: E402 (after TIPPETOP_CACHE)
from tippetop.reference_ode.solve import OdeResult, simulate_ode  # noqa: E402 (after TIPPETOP_CACHE)

if TYPE_CHECKING:
    from tippetop.mujoco_runner.results import MujocoResult

# A suite started in the background by a non-interactive shell (`bash .ci/run &`) inherits
# SIGINT ignored, and so would every command the tests start: the Ctrl-C tests would then send
# a signal nothing hears (measured: four of them failed that way). Python's own handler here;
# the processes the tests start get the default disposition on exec, as from a terminal.
signal.signal(signal.SIGINT, signal.default_int_handler)


def session_processes(sid: int) -> dict[int, tuple[int, str]]:
    """Every process of session ``sid`` (zombies too), read from /proc: pid -> (ppid, state).

    The Ctrl-C tests start their command with ``start_new_session=True``, so its session id
    is its pid and every worker it starts is in that session.
    """
    found = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # gone while we looked
            continue
        # fields: state, ppid, pgrp, session, ...
        if int(fields[3]) == sid:
            found[int(stat.parent.name)] = (int(fields[1]), fields[0])
    return found


@functools.cache
def run_scene_ode(name: str, *overrides: str) -> OdeResult:
    """Run a catalogue scene in the reference ODE (cached)."""
    s = load_scene(name, list(overrides))
    return simulate_ode(s.top, s.friction, s.init, t_end_s=s.run.t_end_s,
                        sample_dt_s=s.run.sample_dt_s, options=s.ode)


@functools.cache
def run_ode(A_over_C: float, a_over_R: float, C_factor: float = 1.0, *, law: str =
            "modified_coulomb", t_end_s: float = 5.0, rtol: float = 1e-10,
            formulation: str = "vector", sample_dt_s: float | None = None,
            **init: float) -> OdeResult:
    """Run the reference ODE for a top given by its ratios (cached)."""
    return simulate_ode(TopParams.from_ratios(A_over_C, a_over_R, C_factor),
                        FrictionParams(law=law), InitialState(**init), t_end_s=t_end_s,
                        sample_dt_s=sample_dt_s,
                        options=OdeOptions(formulation=formulation, rtol=rtol))


def mujoco_plan(*overrides: str, scene: str | None = None) -> MujocoPlan:
    """The MuJoCo plan of a scene (default: the paper's top from the Fig. 3 start) with
    ``section.key=value`` overrides, as every command makes it (a loaded top's file read)."""
    from tippetop.mujoco_runner.state import file_top

    s = load_scene(scene, list(overrides))
    loaded = file_top(s.top_mjcf) if s.top_mjcf is not None else None
    plan = resolve_plan(s, "mujoco", file_top=loaded).mujoco
    assert plan is not None
    return plan


def run_mujoco(*overrides: str, scene: str | None = None,
               progress: Callable[[float], None] | None = None) -> MujocoResult:
    """Run :func:`mujoco_plan` of the same arguments in MuJoCo."""
    from tippetop.mujoco_runner.run import simulate_plan

    return simulate_plan(mujoco_plan(*overrides, scene=scene), progress=progress)
