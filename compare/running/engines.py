"""Run a plan in its engine and summarise it with the shared metrics.

:func:`plan_for` turns a scene and an engine (or a mode) into the run plan, :func:`run_plan`
runs it; every summary reports what ran, read back from the engine, and the ``--set`` keys
it did not read (``unused``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import pandas as pd

from tippetop.compare.analysis.friction_realised import friction_realised, not_refit
from tippetop.compare.analysis.metrics import (
    first_inversion_time,
    jellett_drift,
    jellett_scale,
    summary,
)
from tippetop.models.engines import EngineSpec
from tippetop.models.errors import TippetopError, did_you_mean
from tippetop.models.modes import MODES
from tippetop.models.numbers import number_text, solver_text
from tippetop.models.plan import ENGINES, RunPlan
from tippetop.models.resolve import mode_engine, resolve_plan
from tippetop.models.scene import Scene

#: Stand-in for an integration tolerance in MuJoCo's energy check: soft contacts store a
#: little elastic energy in the penetration that the table's E leaves out (about 1e-5 of E0
#: at rest).
MUJOCO_ENERGY_RTOL = 1e-6
#: The summary keys of a failed run that would be numbers: a failed run reports none.
RESULT_KEYS = ("theta_final", "theta_asymp", "t_invert", "J_rel_drift", "energy_monotone",
               "energy_rise_rel")
#: The statuses of a run that ended as the physics says (the sphere leaving the table is an
#: end the model reports); any other status (MuJoCo's ``diverged``, the reference's
#: ``max_steps``, ``step_too_small``, ``singular``, ``chatter``, ``flat_end``) is a failed run.
FINISHED_STATUSES = ("ok", "contact_lost", "hop")


def measured_steps(summaries: Iterable[dict[str, Any] | None],
                   spec: str = "mujoco") -> list[tuple[int, float]]:
    """``(n_steps, wall_s)`` of each finished MuJoCo run on the engine ``spec``.

    The runs of that engine only (the read-back ``engine_spec``): each engine's steps cost
    what it does. For the cost model (:func:`tippetop.compare.running.cost.record_mujoco_runs`).
    """
    return [(int(s["n_steps"]), float(s["wall_s"])) for s in summaries
            if s is not None and s.get("engine") == "mujoco"
            and s.get("engine_spec") == spec and s.get("status") == "ok"
            and s.get("n_steps") and s.get("wall_s")]


def run_failed(summary: dict[str, Any]) -> bool:
    """Whether a run's summary is a failed run's (it carries no numbers, only the reason)."""
    return summary.get("status", "ok") not in FINISHED_STATUSES

__all__ = ["ENGINES", "FINISHED_STATUSES", "EngineRun", "describe_ran", "mujoco_engine_run",
           "check_engine", "engine_python", "measured_steps", "plan_for", "progress_bar",
           "run_engine", "run_failed", "run_plan", "run_plan_on"]


@dataclass
class EngineRun:
    """One engine's run of a plan: the observables table and the summary dictionary."""

    table: pd.DataFrame
    summary: dict[str, Any]
    status: str
    message: str


def describe_ran(summary: dict[str, Any]) -> str:
    """One line on what a run's summary says ran (the settings read back, not those asked for).

    Example: ``MuJoCo RK4 at dt = 2e-4 s, native friction: pyramidal cone, condim 3,
    mu 0.104, impratio 1.41, solref [0.002 s, 1], solimp [0.05, 0.95, 0.001 m, 0.5, 2]``
    (solref's time constant and solimp's width carry their units; with a negative solref,
    MuJoCo's stiffness and damping, none).
    """
    if summary.get("engine") == "ode":
        return (f"reference ODE, DOP853 on the {summary.get('formulation')} formulation at "
                f"rtol {number_text(summary.get('rtol'))}, law {summary.get('friction_law')}")
    if summary.get("timestep_s") is None:
        return "MuJoCo (no settings recorded)"
    head = f"MuJoCo {summary.get('integrator')} at dt = {number_text(summary['timestep_s'], 's')}, "
    solref, solimp = (f"{k} [{solver_text(k, summary[k])}]" if summary.get(k) is not None
                      else f"{k} -" for k in ("solref", "solimp"))
    contact = f"condim {summary.get('condim')}, {solref}, {solimp}"
    if summary.get("mode") == "paper":
        law = summary.get("friction_law")
        mu = summary.get("law_mu")
        applied = f"the paper-mode law {law}" + (f" (mu {number_text(mu)})" if mu is not None
                                                 else "")
        return f"{head}{applied} on a frictionless contact: {contact}"
    friction = [f"{summary.get('cone')} cone", f"condim {summary.get('condim')}"]
    for key, unit in (("mu", ""), ("torsional", "m"), ("rolling", "m")):
        if summary.get(key) is not None:
            friction.append(f"{key} {number_text(summary[key], unit if summary[key] else '')}")
    friction.append(f"impratio {number_text(summary.get('impratio'))}")
    friction += [solref, solimp]
    return f"{head}native friction: " + ", ".join(friction)


def mjcf_attributes(summary: dict[str, Any]) -> tuple[str, str]:
    """The contact settings a MuJoCo run ran, as MJCF to paste.

    Returns:
        The ``<option .../>`` element (timestep, integrator, cone, impratio) and the contact's
        attributes (condim, friction with its torsional and rolling parts, solref, solimp),
        read from the run's summary.
    """
    def nums(v: Any) -> str:
        return " ".join(f"{x:g}" for x in v)

    s = summary
    friction = [s.get("mu") or 0.0, s.get("torsional") or 0.005, s.get("rolling") or 0.0001]
    return ((f'<option timestep="{s["timestep_s"]:g}" integrator="{s["integrator"]}" '
             f'cone="{s["cone"]}" impratio="{s["impratio"]:g}"/>'),
            (f'condim="{s.get("condim", 3)}" friction="{nums(friction)}" '
             f'solref="{nums(s["solref"])}" solimp="{nums(s["solimp"])}"'))


def plan_for(scene: Scene, engine: str) -> RunPlan:
    """The run plan of ``scene`` in ``engine`` (``ode``, ``mujoco``, or a mode name).

    A mode (``mujoco-native-elliptic``, ...) is its engine plus the overrides that select it.
    """
    check_engine(engine)
    engine, overrides = mode_engine(engine)
    if overrides:
        scene = scene.with_overrides(list(overrides))
    loaded = None
    if scene.top_mjcf is not None:
        from tippetop.mujoco_runner.state import file_top

        loaded = file_top(scene.top_mjcf)
    return resolve_plan(scene, engine, file_top=loaded)


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
           "rtol": p.options.rtol, "atol": p.options.atol, "sample_dt_s": p.sample_dt_s,
           # what ran for stiff friction: "rolling" (rolling phases where the law is stiff),
           # "off", or "none (why)"; the phases themselves under "rolling"
           "stiff": res.stiff}
    rolling = {"phases": len(res.rolling), "t_s": res.t_rolling_s}
    if res.status not in FINISHED_STATUSES:
        # a run that stopped short (max_steps, a step-size underflow, ...) is a failed run
        # with its reason, never numbers, as a diverged MuJoCo run; its table keeps the
        # samples before the stop (at least t = 0), which the runner's cache needs
        s = {"engine": "ode", **dict.fromkeys(RESULT_KEYS), "contact_lost": False,
             "wall_s": res.wall_s, "n_rhs": res.n_rhs}
        s.update(status=res.status, message=res.message, **ran, t_stem=res.t_stem,
                 phases=[{k: ph[k] for k in ("contact", "t_start", "t_end")}
                         for ph in res.phases], rolling=rolling, unused=list(plan.unused))
        return EngineRun(res.table, s, res.status, res.message)
    top = p.top
    s = summary(res.table, engine="ode", rtol=res.rtol, t_invert=res.t_invert,
                contact_lost=res.status in ("contact_lost", "hop"), wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_rhs=res.n_rhs)
    s.update(status=res.status, message=res.message, **ran, t_stem=res.t_stem,
             phases=[{k: ph[k] for k in ("contact", "t_start", "t_end")}
                     for ph in res.phases], rolling=rolling, unused=list(plan.unused))
    s["friction_realised"] = friction_realised(res.table, p.friction.mu,
                                               p.friction.Lambda_mps, t_stem=res.t_stem)
    s["friction_realised"]["refit"] = not_refit("the reference itself integrates the law")
    if p.stem is not None:
        # Jellett's constant of each contact is conserved only within its phases
        drifts = [ph["J_rel_drift"] for ph in res.phases if ph["J_rel_drift"] is not None]
        s["J_rel_drift"] = max(drifts) if drifts else None
        s["stem"] = {"kind": p.stem.kind, "offset_m": p.stem.offset_m,
                     "radius_m": p.stem.radius_m}
    return EngineRun(res.table, s, res.status, res.message)


def _run_mujoco(plan: RunPlan, progress: Callable[[float], None] | None) -> EngineRun:
    from tippetop.mujoco_runner.run import simulate_plan

    assert plan.mujoco is not None
    return mujoco_engine_run(plan, simulate_plan(plan.mujoco, progress=progress))


def mujoco_engine_run(plan: RunPlan, res: Any, spec: str = "mujoco") -> EngineRun:
    """The engine run (summary and table) of a MuJoCo result of ``plan``.

    Args:
        plan: A MuJoCo plan (:func:`plan_for`).
        res: Its :class:`tippetop.mujoco_runner.results.MujocoResult`, from a single run, a
            batch (:mod:`tippetop.mujoco_runner.batch`) or a worker (``.remote``).
        spec: The engine spec that ran it (:mod:`tippetop.models.engines`).
    """
    p = plan.mujoco
    assert p is not None
    ran = {k: v for k, v in res.ran.items() if k != "contact_source"}
    ran.update(engine_spec=spec, **res.engine)  # what ran the steps, read back
    if not res.ok:
        # a diverged run is a failed run with its reason, never numbers
        s = {"engine": "mujoco", **dict.fromkeys(RESULT_KEYS),
             "contact_lost": "contact lost" in res.message, "wall_s": res.wall_s,
             "n_steps": res.n_steps}
        s.update(status=res.status, message=res.message, mode=p.mode, **ran,
                 t_stem=res.t_stem, phases=res.phases(), unused=list(plan.unused))
        # the table keeps the samples before the failure (the runner's cache needs a row)
        return EngineRun(res.table, s, res.status, res.message)
    top = p.top
    s = summary(res.table, engine="mujoco", rtol=MUJOCO_ENERGY_RTOL,
                t_invert=first_inversion_time(res.table), contact_lost=False,
                wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_steps=res.n_steps)
    t_stem = res.t_stem
    if t_stem is not None:
        # the table's J is the ball's (R L_z - a C n): conserved while the ball alone touches
        before = res.table[res.table["t"] < t_stem]
        s["J_rel_drift"] = (jellett_drift(before, jellett_scale(before, top.R_m, top.A_kgm2,
                                                                top.C_kgm2))
                            if len(before) > 1 else None)
    s.update(status=res.status, message=res.message, mode=p.mode, **ran, t_stem=t_stem,
             phases=res.phases(), max_penetration_m=res.max_penetration_m,
             contact_energy_bound_J=res.contact_energy_bound_J, unused=list(plan.unused))
    law = p.law or p.reference_law
    s["friction_realised"] = (friction_realised(res.table, law.mu, law.Lambda_mps,
                                                t_stem=t_stem)
                              if law is not None else None)
    if s["friction_realised"] is not None:
        s["friction_realised"]["refit"] = not_refit(
            "one run alone: `tippetop compare` and `tippetop validate` rerun the reference "
            "with the law this run realised")
    return EngineRun(res.table, s, res.status, res.message)


def run_plan(plan: RunPlan, *, progress: bool | Callable[[float], None] = True,
             spec: EngineSpec | None = None, python: str | None = None) -> EngineRun:
    """Run a plan in its engine.

    Args:
        plan: From :func:`plan_for`.
        progress: True shows a bar over simulated time when stderr is a terminal; a callable
            is called with the simulated time reached instead (the engines call it now and
            then, and at the end).
        spec: The engine a MuJoCo plan runs on (default: the MuJoCo installed here); another
            one runs it through its worker (:func:`run_plan_on`).
        python: That engine's interpreter, if already known (:func:`engine_python`).

    Raises:
        TippetopError: A reference ODE plan given another engine to run on, or an engine
            that cannot run the plan (one line).
    """
    remote = spec is not None and not spec.in_process
    if remote and plan.engine == "ode":
        raise TippetopError(f"engine {spec.spec}: expected a MuJoCo run (engine mujoco or a "
                            f"mujoco-* mode) to run on it, got the reference ODE")

    def go(tick: Callable[[float], None] | None) -> EngineRun:
        if plan.engine == "ode":
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
        say_long_run([plan], specs=[spec.spec if remote else "mujoco"])
    label = f"{plan.scene} [{plan.engine}{f' on {spec.spec}' if remote else ''}]"
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
    raise TippetopError(f"engine {spec.spec}: expected mujoco, mujoco==X.Y.Z, "
                        f"mujoco@PYTHON, mjx, mjx-f32 or warp, got {spec.spec!r}")


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
    return mujoco_engine_run(plan, res, spec.spec)


def run_engine(scene: Scene, engine: str, *, progress: bool = True) -> EngineRun:
    """Run ``scene`` in ``engine`` (``ode``, ``mujoco`` or a mode name): plan, then run."""
    return run_plan(plan_for(scene, engine), progress=progress)


def check_engine(engine: str) -> None:
    """Refuse an engine that is neither ``ode``, ``mujoco`` nor a mode name (one line)."""
    if engine not in ENGINES and engine not in MODES:
        raise TippetopError(f"--engine: expected one of {'|'.join(ENGINES)} or a mode "
                            f"({', '.join(MODES)}), got {engine!r}"
                            f"{did_you_mean(engine, (*ENGINES, *MODES))}")
