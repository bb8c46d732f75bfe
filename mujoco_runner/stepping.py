"""Stepping a MuJoCo run sample by sample, recording each sample and its window (:mod:`.record`).

In :mod:`.stepper`'s compiled loop when it is available, else from Python: the same C calls.
Every step's forward pass is added to its sample's window (:mod:`.worker.windows`): ``mj_step``
taken apart (bit for bit the same), each step's pass done at the end of the step before, so
the windows cost no extra pass.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from tippetop.models.params import FrictionParams
from tippetop.models.plan import NATIVE_LAW, MujocoPlan
from tippetop.mujoco_runner import stepper
from tippetop.mujoco_runner.friction_callback import (
    LAST_OUTPUT,
    USERDATA_SIZE,
    PaperFriction,
    compiled_callback,
)
from tippetop.mujoco_runner.model import MUJOCO_WARNINGS, TopModel
from tippetop.mujoco_runner.record import STATE_SPEC, SampleRecord, WindowRecord
from tippetop.mujoco_runner.settings import settings_that_ran
from tippetop.mujoco_runner.worker.windows import (
    WindowAccumulator,
    WindowTop,
    integrator_call,
    new_windows,
)

#: Wall time between calls of the progress callback (s).
PROGRESS_INTERVAL_S = 0.2


def ran_settings(top_model: TopModel, data: mujoco.MjData, plan: MujocoPlan) -> dict[str, Any]:
    """The ``ran`` dict of a run (:attr:`~.results.MujocoResult.ran`).

    :func:`~.settings.settings_that_ran` of ``data`` at t = 0 (after a forward pass), plus
    the friction law, its mu, the row spacing and the keyframe.
    """
    model = top_model.model
    ran = settings_that_ran(top_model, data)
    law = plan.law
    ran["friction_law"] = (NATIVE_LAW if plan.friction == "native"
                           else law.law if law is not None else "none")
    if law is not None:
        ran["law_mu"] = float(law.mu)
    ran["sample_dt_s"] = plan.steps_per_sample * float(model.opt.timestep)
    ran["keyframe"] = None if plan.keyframe is None else (
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, plan.keyframe) or f"#{plan.keyframe}")
    return ran


def start_data(top_model: TopModel, plan: MujocoPlan) -> mujoco.MjData:
    """A new mjData at the plan's start: its keyframe, or its free joint's qpos and qvel."""
    model = top_model.model
    data = mujoco.MjData(model)
    if plan.keyframe is None:
        qa, va = top_model.qpos_adr, top_model.dof_adr
        data.qpos[qa:qa + 7], data.qvel[va:va + 6] = plan.start_qpos, plan.start_qvel
    else:
        mujoco.mj_resetDataKeyframe(model, data, plan.keyframe)
    return data


def window_top(top_model: TopModel) -> WindowTop:
    """What a run's windows read of its top (:class:`~.worker.windows.WindowTop`)."""
    return WindowTop(body=top_model.body_id, ball=top_model.ball_geom_id,
                     radius_m=float(top_model.top.R_m),
                     axis_body=tuple(float(v) for v in top_model.axis_body),
                     qpos_adr=top_model.qpos_adr, dof_adr=top_model.dof_adr)


def law_index(model: mujoco.MjModel, law: FrictionParams | None) -> int | None:
    """Where paper mode's callback leaves its last (Fx, Fy, N, power) in userdata.

    None: no law.
    """
    return None if law is None else model.nuserdata - USERDATA_SIZE + LAST_OUTPUT


def step_top_model(top_model: TopModel, plan: MujocoPlan, *,
                   progress: Callable[[float], None] | None = None,
                   compiled: bool | None = None,
                   ) -> tuple[SampleRecord, str | None, float, dict[str, Any]]:
    """Step a plan's run on its compiled model and record its samples and their windows.

    Starts a new mjData as the plan says (:func:`start_data`; the callback armed with the
    plan's law, a forward pass for what ran) and steps it sample by sample. Touches nothing
    shared but the process-wide callback, so runs of a thread pool may each call it on
    their own mjData (the compiled stepper runs without the GIL).

    Returns:
        ``(record, failure, wall_s, ran)``: the samples, why the stepping stopped early
        (None), its wall time and :func:`ran_settings`, for
        :func:`~.results.result_from_samples`.
    """
    model = top_model.model
    data = start_data(top_model, plan)
    callback = contextlib.ExitStack()
    if plan.law is not None:
        callback.enter_context(PaperFriction(top_model, data, plan.law, stem=plan.stem))
        compiled_callback()  # compiled (or loaded) once per process; kept out of wall_s
    mujoco.mj_forward(model, data)
    ran = ran_settings(top_model, data, plan)
    with callback:
        record, failure, wall_s = step_and_record(
            model, data, plan.steps_per_sample, plan.n_intervals, progress,
            top=window_top(top_model), law_index=law_index(model, plan.law), compiled=compiled)
    return record, failure, wall_s, ran


def integrator_split(model: mujoco.MjModel) -> tuple[int, str] | None:
    """How ``mj_step`` ends after its forward pass, for this model; None: not known.

    ``mj_step`` is ``mj_checkPos``, ``mj_checkVel``, ``mj_forward``, ``mj_checkAcc``, then the
    integrator (tests/mujoco_runner/test_record.py checks the split is bit-identical): a
    :mod:`.stepper` integrator code and the C name of a (m, d) integrator
    (:func:`~.worker.windows.integrator_call` is the same as a Python call).
    """
    if integrator_call(mujoco, model) is None:
        return None
    kind = int(model.opt.integrator)
    if kind == int(mujoco.mjtIntegrator.mjINT_RK4):
        return stepper.INTEG_RK4, "mj_Euler"
    if kind == int(mujoco.mjtIntegrator.mjINT_EULER):
        return stepper.INTEG_PLAIN, "mj_Euler"
    return stepper.INTEG_PLAIN, "mj_implicit"


def step_and_record(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                     progress: Callable[[float], None] | None, *, top: WindowTop,
                     law_index: int | None = None, compiled: bool | None = None
                     ) -> tuple[SampleRecord, str | None, float]:
    """Step ``data`` sample by sample, recording each sample and its window.

    In :mod:`.stepper`'s compiled loop when it is available (``compiled``: None, the
    default), else (or with ``compiled=False``) from Python: the same C calls either way,
    and the same windows to rounding.
    """
    if compiled is None:
        compiled = stepper.available()[0]
    if compiled:
        return step_compiled(model, data, steps, n_intervals, progress, top=top,
                             law_index=law_index)
    return step_python(model, data, steps, n_intervals, progress, top=top, law_index=law_index)


def chunk_failure(state: np.ndarray, warn: np.ndarray, nq: int, nv: int) -> int | None:
    """The first of these rows whose qpos/qvel is not finite or that has a warning, or None."""
    good = np.isfinite(state[:, 1:1 + nq + nv]).all(axis=1) & ~warn.any(axis=1)
    bad = np.flatnonzero(~good)
    return int(bad[0]) if bad.size else None


def step_compiled(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                   progress: Callable[[float], None] | None, *, top: WindowTop,
                   law_index: int | None = None) -> tuple[SampleRecord, str | None, float]:
    """:func:`step_python` in :class:`.stepper.CompiledStepper` calls of many samples each.

    Each call lasts about half of :data:`PROGRESS_INTERVAL_S` (its length adapts), so the
    checks and the progress reports keep the single loop's pace.
    """
    n_rows = n_intervals + 1
    split = integrator_split(model)
    integ, plain = split if split is not None else (stepper.INTEG_STEP, "mj_Euler")
    run = stepper.CompiledStepper(model, data, steps=steps, n_rows=n_rows, integrator=integ,
                                  plain=plain, spec=int(STATE_SPEC), top=top,
                                  law_index=law_index)
    nq, nv = model.nq, model.nv
    dt = float(model.opt.timestep)
    text = None
    wall0 = time.perf_counter()
    next_report = wall0  # report t = 0 at once
    mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
    n, chunk, first = 0, 1, True
    while n < n_rows:
        k = min(chunk, n_rows - n)
        start = time.perf_counter()
        run.advance(n, k, first=first)
        elapsed = time.perf_counter() - start
        first = False
        bad = chunk_failure(run.state[n:n + k], run.warn[n:n + k], nq, nv)
        if bad is not None:
            n += bad + 1
            if MUJOCO_WARNINGS:
                text = MUJOCO_WARNINGS[-1]
            break
        n += k
        now = time.perf_counter()
        if progress is not None and now >= next_report and n < n_rows:
            progress((n - 1) * steps * dt)
            next_report = time.perf_counter() + PROGRESS_INTERVAL_S
        chunk = max(1, min(4 * k, int(k * 0.5 * PROGRESS_INTERVAL_S / max(elapsed, 1e-9))))
    wall_s = time.perf_counter() - wall0
    state = run.state[:n]
    record = SampleRecord(time=state[:, 0], qpos=state[:, 1:1 + nq],
                          qvel=state[:, 1 + nq:1 + nq + nv],
                          qacc_warmstart=state[:, 1 + nq + nv:], qfrc_constraint=run.con[:n],
                          windows=WindowRecord(run.ints[:n], run.floats[:n]),
                          warnings=run.warn[:n], warning_text=text, path="compiled stepper")
    return record, None, wall_s


def _law_output(data: mujoco.MjData, law_index: int | None
                ) -> Callable[[], tuple[float, float, float]] | None:
    """A reader of the law's last (Fx, Fy, power) in ``data``'s userdata; None: no law."""
    if law_index is None:
        return None
    u = data.userdata

    def law_output() -> tuple[float, float, float]:
        return float(u[law_index]), float(u[law_index + 1]), float(u[law_index + 3])

    return law_output


def step_python(model: mujoco.MjModel, data: mujoco.MjData, steps: int, n_intervals: int,
                 progress: Callable[[float], None] | None, *, top: WindowTop,
                 law_index: int | None = None) -> tuple[SampleRecord, str | None, float]:
    """Step ``data`` sample by sample from Python, recording each sample and its window.

    The state (time, qpos, qvel, warm start), qfrc_constraint and the warning counters
    are copied at each sample; once per :data:`PROGRESS_INTERVAL_S` of wall time the new rows
    are checked (finite, no warning) and the stepping stops at the first failed one, which is
    kept in the record (:func:`result_from_samples` ends the run there).

    Each step is ``mj_step`` taken apart where the model's split is known
    (:func:`~.worker.windows.integrator_call`): its forward pass is done at the end of the
    step before, and added to the window there
    (:class:`~.worker.windows.WindowAccumulator`); else each ``mj_step`` is called whole and
    its pass (at the state before it, with the motion it had there) is added after it, the
    first step's being the start's (row 0's).
    """
    n_rows = n_intervals + 1
    spec = STATE_SPEC
    state = np.empty((n_rows, mujoco.mj_stateSize(model, spec)))
    con = np.empty((n_rows, model.nv))
    counts = data.warning.number  # a live view of the counters
    warn = np.zeros((n_rows, counts.size), dtype=counts.dtype)
    ints, floats = new_windows(np, n_rows)
    acc = WindowAccumulator(mujoco, np, model, data, top, _law_output(data, law_index))
    qa, va = top.qpos_adr, top.dof_adr
    nq, nv = model.nq, model.nv
    data_con = data.qfrc_constraint
    integrate = integrator_call(mujoco, model)
    wall0 = time.perf_counter()
    next_report = wall0  # report t = 0 at once
    n = 0  # rows recorded
    checked = 0  # rows checked
    text = None
    mujoco.mj_forward(model, data)  # the contact force of the initial state, for N
    get_state, step, forward = mujoco.mj_getState, mujoco.mj_step, mujoco.mj_forward
    check_pos, check_vel, check_acc = mujoco.mj_checkPos, mujoco.mj_checkVel, mujoco.mj_checkAcc

    def begin_step() -> None:  # mj_step's own start: its forward pass
        check_pos(model, data)
        check_vel(model, data)
        forward(model, data)
        check_acc(model, data)

    while True:
        if n:  # step from row n - 1 to row n, each step's pass added
            for j in range(1, steps + 1):
                if integrate is not None:
                    integrate(model, data)  # the rest of the step begun by its pass
                else:  # whole: its pass is at the state before it, kept for the window
                    motion = (data.qpos[qa:qa + 7].copy(), data.qvel[va:va + 6].copy())
                    step(model, data)
                if j == steps:
                    get_state(model, data, state[n], spec)
                    con[n] = data_con
                    warn[n] = counts
                if integrate is not None:
                    begin_step()
                    acc.add(ints, floats, n, j)
                elif n > 1 or j > 1:  # the first step's pass is the start's, row 0's already
                    acc.add(ints, floats, n, j - 1, motion)
        else:
            get_state(model, data, state[n], spec)
            con[n] = data_con
            warn[n] = counts
            if integrate is not None:
                begin_step()
            acc.add(ints, floats, n, 0)
        n += 1
        now = time.perf_counter()
        if n == n_rows or now >= next_report:
            rows = state[checked:n]
            good = (np.isfinite(rows[:, 1:1 + nq + nv]).all(axis=1)
                    & ~warn[checked:n].any(axis=1))
            bad = np.flatnonzero(~good)
            if bad.size:
                n = checked + int(bad[0]) + 1
                if MUJOCO_WARNINGS:
                    text = MUJOCO_WARNINGS[-1]
                break
            checked = n
            if n == n_rows:
                break
            if progress is not None:
                progress((n - 1) * steps * float(model.opt.timestep))
            next_report = time.perf_counter() + PROGRESS_INTERVAL_S
    wall_s = time.perf_counter() - wall0
    state = state[:n]
    record = SampleRecord(time=state[:, 0], qpos=state[:, 1:1 + nq],
                          qvel=state[:, 1 + nq:1 + nq + nv],
                          qacc_warmstart=state[:, 1 + nq + nv:], qfrc_constraint=con[:n],
                          windows=WindowRecord(ints[:n], floats[:n]),
                          warnings=warn[:n], warning_text=text, path="plain loop")
    return record, None, wall_s


__all__ = ["PROGRESS_INTERVAL_S", "chunk_failure", "integrator_split", "law_index",
           "ran_settings", "start_data", "step_and_record", "step_top_model", "window_top"]
