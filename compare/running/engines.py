"""Run a plan in its engine and summarise it with the shared metrics.

:func:`plan_for` turns a scene and an engine (or a mode) into the run plan, :func:`run_plan`
runs it; every summary reports what ran, read back from the engine, and the ``--set`` keys
it did not read (``unused``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import pandas as pd

from tippetop.compare.measures.friction_realised import (
    friction_realised,
    not_refit,
    window_pairs,
)
from tippetop.compare.measures.series import (
    ball_alone_end,
    flights,
    jellett_drift,
    jellett_scale,
    summary,
)
from tippetop.compare.measures.summary import FINISHED_STATUSES, RESULT_KEYS, RunSummary
from tippetop.models.engines import MUJOCO_SPEC_FORMS, EngineSpec, parse_engine
from tippetop.models.errors import TippetopError
from tippetop.models.modes import run_label
from tippetop.models.plan import RunPlan
from tippetop.models.resolve import resolve_plan
from tippetop.models.scene import Scene
from tippetop.models.spellings import GOES, new_spelling, note, old_spelling

#: Stand-in for an integration tolerance in MuJoCo's energy check: soft contacts store a
#: little elastic energy in the penetration that the table's E leaves out (about 1e-5 of E0
#: at rest).
MUJOCO_ENERGY_RTOL = 1e-6


__all__ = ["EngineRun", "engine_python", "mujoco_engine_run", "plan_for", "progress_bar",
           "run_engine", "run_plan", "run_plan_on"]


@dataclass
class EngineRun:
    """One engine's run of a plan: the observables table and its summary."""

    table: pd.DataFrame
    summary: RunSummary
    status: str
    message: str


def plan_for(scene: Scene, engine: str | EngineSpec = "ode", mode: str | None = None) -> RunPlan:
    """The run plan of ``scene`` on ``engine`` in ``mode``: where it runs and what runs.

    Args:
        scene: A validated scene.
        engine: ``ode``, ``mujoco``, ``mujoco==X.Y.Z``, ``mujoco@PYTHON``, ``mjx``,
            ``mjx-f32`` or ``warp`` (:mod:`tippetop.models.engines`). A compound name of the
            release before (``mujoco-native``) is read as its engine and mode, with a note.
        mode: How the contact force is made (:mod:`tippetop.models.modes`); None: what the
            scene's keys say.

    Raises:
        TippetopError: A bad engine or mode, or a pairing that cannot run (one line).
    """
    if isinstance(engine, str) and mode is None:
        old = old_spelling(engine)
        if old is not None and engine.strip() not in ("ode", "mujoco"):
            note(f"engine {engine.strip()!r} names an engine and a mode: now "
                 f"{new_spelling(engine.strip())} {GOES}")
            engine, mode, extra = old
            if extra:
                scene = scene.with_overrides(list(extra))
    spec = parse_engine(engine) if isinstance(engine, str) else engine
    loaded = None
    if scene.top_mjcf is not None:
        from tippetop.mujoco_runner.state import file_top

        loaded = file_top(scene.top_mjcf)
    return resolve_plan(scene, spec, mode, file_top=loaded)


@contextmanager
def progress_bar(total_s: float, label: str) -> Iterator[Callable[[float], None] | None]:
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


def _run_ode(plan: RunPlan, progress: Callable[[float], None] | None) -> EngineRun:
    from tippetop.reference_ode.solve import simulate_ode

    p = plan.ode
    assert p is not None
    res = simulate_ode(p.top, p.friction, p.init, t_end_s=p.t_end_s, sample_dt_s=p.sample_dt_s,
                       options=p.options, progress=progress, stem=p.stem)
    ran = {"friction_law": p.friction.law, "formulation": p.options.formulation,
           "method": res.method,
           "rtol": res.rtol, "atol": res.atol, "sample_dt_s": p.sample_dt_s,
           # what ran for stiff friction: "rolling" (rolling phases where the law is stiff),
           # "off", or "none (why)"; the phases themselves under "rolling_phases"
           "stiff": res.stiff}
    rolling = {"phases": len(res.rolling), "t_s": res.t_rolling_s}
    if res.status not in FINISHED_STATUSES:
        # a run that stopped short (max_steps, a step-size underflow, ...) is a failed run
        # with its reason, never numbers, as a diverged MuJoCo run; its table keeps the
        # samples before the stop (at least t = 0), which the runner's cache needs
        s = {"engine": plan.engine, "mode": plan.mode, **dict.fromkeys(RESULT_KEYS),
             "contact_lost": False, "wall_s": res.wall_s, "n_rhs": res.n_rhs}
        s.update(status=res.status, message=res.message, **ran, t_stem=res.t_stem,
                 phases=[{k: ph[k] for k in ("contact", "t_start", "t_end")}
                         for ph in res.phases], rolling_phases=rolling,
                 unused=list(plan.unused))
        return EngineRun(res.table, RunSummary.from_json(s), res.status, res.message)
    top = p.top
    s = summary(res.table, engine=plan.engine, mode=plan.mode, rtol=res.rtol,
                t_invert=res.t_invert,
                contact_lost=res.status in ("contact_lost", "hop"), wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_rhs=res.n_rhs)
    # the reference stops where the ball leaves the table (the model does not follow a flight)
    left = (float(res.table["t"].iloc[-1]) if res.status == "contact_lost"
            and res.t_stem is None else None)
    s.update(status=res.status, message=res.message, **ran, t_stem=res.t_stem,
             t_left_table=left,
             phases=[{k: ph[k] for k in ("contact", "t_start", "t_end")}
                     for ph in res.phases], rolling_phases=rolling,
             unused=list(plan.unused))
    s["friction_realised"] = friction_realised(res.table, p.friction.mu,
                                               p.friction.Lambda_mps, t_stem=res.t_stem)
    s["friction_realised"]["refit"] = not_refit("the reference itself integrates the law")
    if p.stem is not None:
        # Jellett's constant of each contact is conserved only within its phases
        drifts = [ph["J_rel_drift"] for ph in res.phases if ph["J_rel_drift"] is not None]
        s["J_rel_drift"] = max(drifts) if drifts else None
        s["stem"] = {"kind": p.stem.kind, "offset_m": p.stem.offset_m,
                     "radius_m": p.stem.radius_m}
    return EngineRun(res.table, RunSummary.from_json(s), res.status, res.message)


def _run_mujoco(plan: RunPlan, progress: Callable[[float], None] | None) -> EngineRun:
    from tippetop.mujoco_runner.run import simulate_plan

    assert plan.mujoco is not None
    return mujoco_engine_run(plan, simulate_plan(plan.mujoco, progress=progress))


def mujoco_engine_run(plan: RunPlan, res: Any) -> EngineRun:
    """The engine run (summary and table) of a MuJoCo result of ``plan``.

    Args:
        plan: A MuJoCo plan (:func:`plan_for`), on the engine that ran it.
        res: Its :class:`tippetop.mujoco_runner.results.MujocoResult`, from a single run, a
            batch (:mod:`tippetop.mujoco_runner.batch`) or a worker (``.remote``).
    """
    p = plan.mujoco
    assert p is not None
    ran = {k: v for k, v in res.ran.items() if k != "contact_source"}
    ran.update(**res.engine)  # what ran the steps, read back
    if not res.ok:
        # a diverged run is a failed run with its reason, never numbers
        s = {"engine": plan.engine, "mode": plan.mode, **dict.fromkeys(RESULT_KEYS),
             "contact_lost": "contact lost" in res.message, "wall_s": res.wall_s,
             "n_steps": res.n_steps}
        s.update(status=res.status, message=res.message, **ran,
                 t_stem=res.t_stem, phases=res.phases(), unused=list(plan.unused))
        # the table keeps the samples before the failure (the runner's cache needs a row)
        return EngineRun(res.table, RunSummary.from_json(s), res.status, res.message)
    top = p.top
    # the events located to the step (each step's forward pass is in its sample's window)
    s = summary(res.table, engine=plan.engine, mode=plan.mode, rtol=MUJOCO_ENERGY_RTOL,
                t_invert=res.t_invert, contact_lost=False,
                wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_steps=res.n_steps)
    t_stem = res.t_stem
    hops = flights(res.table["t"].to_numpy(), res.gaps(), t_stem)
    # the ball leaves the table in its first flight (HOP_MIN_S or more without contact at any
    # step, the ball risen FLIGHT_RISE_M; a shorter or lower stretch is its soft contact
    # chattering: in ``flights`` only)
    t_left = None if hops is None else hops["t_first_hop"]
    end = ball_alone_end(t_stem, t_left)
    if end is not None:
        # the table's J is the ball's (R L_z - a C n): conserved while the ball alone touches
        # (not in a flight, not on the stem)
        before = res.table[res.table["t"] < end]
        s["J_rel_drift"] = (jellett_drift(before, jellett_scale(before, top.R_m, top.A_kgm2,
                                                                top.C_kgm2))
                            if len(before) > 1 else None)
    s.update(status=res.status, message=res.message, **ran, t_stem=t_stem, t_left_table=t_left,
             flights=hops,
             phases=res.phases(), max_penetration_m=res.max_penetration_m,
             contact_energy_bound_J=res.contact_energy_bound_J, unused=list(plan.unused))
    law = p.law or p.reference_law
    # each window's mean force against its slip, weighted as the force: at any sample
    # spacing the pairs of the steps (friction_realised.window_pairs)
    pairs = window_pairs(**res.force_and_slip())
    s["friction_realised"] = (friction_realised(pairs, law.mu, law.Lambda_mps, t_stem=t_stem)
                              if law is not None else None)
    if s["friction_realised"] is not None:
        s["friction_realised"]["refit"] = not_refit(
            "one run alone: `tippetop compare` and `tippetop validate` rerun the reference "
            "with the law this run realised")
    return EngineRun(res.table, RunSummary.from_json(s), res.status, res.message)


def run_plan(plan: RunPlan, *, progress: bool | Callable[[float], None] = True,
             python: str | None = None) -> EngineRun:
    """Run a plan on the engine it names (``plan.engine``).

    The reference and the MuJoCo installed here run in this process; any other engine runs
    the plan through its worker (:func:`run_plan_on`).

    Args:
        plan: From :func:`plan_for` (or read from its JSON).
        progress: True shows a bar over simulated time when stderr is a terminal; a callable
            is called with the simulated time reached instead (the engines call it now and
            then, and at the end).
        python: The engine's interpreter, if already known (:func:`engine_python`).

    Raises:
        TippetopError: A plan whose engine cannot run it (one line).
    """
    spec = parse_engine(plan.engine)
    if spec.is_reference != plan.is_reference:
        want = "the reference's" if spec.is_reference else "a MuJoCo"
        got = "the reference's" if plan.is_reference else "a MuJoCo"
        raise TippetopError(f"plan: expected {want} plan on engine {plan.engine!r}, got {got} "
                            "plan")
    remote = not spec.in_process

    def go(tick: Callable[[float], None] | None) -> EngineRun:
        if plan.is_reference:
            return _run_ode(plan, tick)
        if remote:
            return run_plan_on(spec, plan, python=python, progress=tick)
        return _run_mujoco(plan, tick)

    if callable(progress):
        return go(progress)
    if progress:  # a run for a person: say first when it will take long (stderr only)
        from tippetop.compare.running.compiling import say_compile
        from tippetop.compare.running.cost import say_long_run

        say_compile([plan])
        say_long_run([plan])
    label = f"{plan.scene} [{run_label(plan.engine, plan.mode)}]"
    with progress_bar(plan.t_end_s if progress else 0.0, label) as tick:
        return go(tick)


def engine_python(spec: EngineSpec, say: Callable[[str], None] | None = None) -> str:
    """The interpreter that runs an engine's plans: its managed environment's, or the user's.

    A managed environment is made on first use (``say`` is told). Raises TippetopError (one
    line) for an interpreter that is not there, and for engines not run by this harness yet.
    MJX (``mjx``, ``mjx-f32``) and MuJoCo Warp (``warp``) run in managed environments of their
    own (:func:`tippetop.mujoco_runner.envs.accelerated_env_python`).
    """
    import os
    import shutil

    if spec.implementation in ("mjx", "warp") and spec.python is None:
        from tippetop.mujoco_runner.envs import accelerated_env_python

        return str(accelerated_env_python(spec.implementation, say=say))
    if spec.version is not None:
        from tippetop.mujoco_runner.envs import env_python

        return str(env_python(spec.version, say=say))
    if spec.python is not None:
        # a path, or a command on PATH (mujoco@python3.12)
        found = spec.python if os.sep in spec.python else shutil.which(spec.python)
        if not (found and os.path.isfile(found) and os.access(found, os.X_OK)):
            raise TippetopError(f"engine {spec.spec}: expected the path of a Python "
                                f"interpreter that can import mujoco, or its command on PATH, "
                                f"got {spec.python!r}")
        return found
    raise TippetopError(f"engine {spec.spec}: expected {MUJOCO_SPEC_FORMS} to run through "
                        f"a worker, got {spec.spec!r}")


def run_plan_on(spec: EngineSpec, plan: RunPlan, *, python: str | None = None,
                progress: Callable[[float], None] | None = None) -> EngineRun:
    """Run a MuJoCo plan on an engine other than this process's MuJoCo, through its worker.

    Raises:
        TippetopError: The engine cannot run it (not there, not supported), or the worker
            failed (crashed, hung, garbled): one line with the reason.
    """
    from tippetop.mujoco_runner.remote import WorkerFailed, simulate_in

    assert plan.mujoco is not None and not spec.in_process
    python = python or engine_python(spec)
    try:
        res, _info = simulate_in(python, plan.mujoco, progress=progress,
                                 engine={"implementation": spec.implementation,
                                         "precision": spec.precision})
    except WorkerFailed as exc:
        raise TippetopError(f"engine {spec.spec}: {exc}") from None
    return mujoco_engine_run(plan, res)


def run_engine(scene: Scene, engine: str | EngineSpec = "ode", mode: str | None = None, *,
               progress: bool = True) -> EngineRun:
    """Run ``scene`` on ``engine`` in ``mode`` (:func:`plan_for`): plan, then run."""
    return run_plan(plan_for(scene, engine, mode), progress=progress)
