"""Run a scene in an engine and summarise it with the shared metrics."""

from __future__ import annotations

import sys
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import pandas as pd

from tippetop.compare.metrics import jellett_scale, summary
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Scene

ENGINES = ("ode", "mujoco")


@dataclass
class EngineRun:
    """One engine's run of a scene: the observables table and the summary dictionary."""

    table: pd.DataFrame
    summary: dict[str, Any]
    status: str
    message: str


@contextmanager
def progress_bar(total_s: float, label: str):
    """A tqdm bar over simulated seconds on a terminal; nothing when stderr is not a terminal."""
    if not sys.stderr.isatty() or total_s <= 0:
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=total_s, desc=label, unit="sim s", leave=False,
              bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} sim s [{elapsed}<{remaining}]") as bar:

        def update(t: float) -> None:
            bar.update(t - bar.n)

        yield update


def run_ode(scene: Scene, progress: Callable[[float], None] | None = None) -> EngineRun:
    """Run the reference ODE on a scene."""
    from tippetop.reference_ode.solve import simulate_ode

    if scene.effects.torsional or scene.effects.rolling:
        raise TippetopError("effects: the reference ODE models sliding friction only, expected "
                            "torsional = false and rolling = false, got "
                            f"torsional = {scene.effects.torsional}, "
                            f"rolling = {scene.effects.rolling}")
    top = scene.top
    if scene.top_mjcf is not None:
        from tippetop.mujoco_runner.model import load_top

        top = load_top(scene.top_mjcf).top
    friction = scene.friction
    if not scene.effects.sliding:
        from dataclasses import replace

        friction = replace(friction, law="none")
    res = simulate_ode(top, friction, scene.init, t_end_s=scene.run.t_end_s,
                       sample_dt_s=scene.run.sample_dt_s, options=scene.ode, progress=progress)
    s = summary(res.table, engine="ode", rtol=res.rtol, t_invert=res.t_invert,
                contact_lost=res.status == "contact_lost", wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_rhs=res.n_rhs)
    s["status"] = res.status
    s["message"] = res.message
    return EngineRun(res.table, s, res.status, res.message)


def run_engine(scene: Scene, engine: str, *, progress: bool = True) -> EngineRun:
    """Run ``scene`` in ``engine`` (``ode`` or ``mujoco``).

    With ``progress`` a bar over simulated time is shown when stderr is a terminal.
    """
    if engine not in ENGINES:
        raise TippetopError(f"--engine: expected one of {'|'.join(ENGINES)}, got {engine!r}")
    label = f"{scene.name} [{engine}]"
    with progress_bar(scene.run.t_end_s if progress else 0.0, label) as progress:
        if engine == "ode":
            return run_ode(scene, progress)
        from tippetop.mujoco_runner.engine import run_mujoco

        return run_mujoco(scene, progress)
