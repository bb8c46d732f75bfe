"""Many MuJoCo runs stepped together on threads, each equal to its single run bit for bit.

:func:`iter_simulate_plans` runs many :class:`~tippetop.models.plan.MujocoPlan` on ``nthread``
threads and gives each run's :class:`~tippetop.mujoco_runner.results.MujocoResult`, the one
:func:`~tippetop.mujoco_runner.run.simulate_plan` gives, as soon as it is done. Call it from
the main thread, never from two Python threads at once (paper mode's callback is installed
process-wide, :mod:`.friction_callback`). Which runs step on threads and which in
``mujoco.batch.Batch`` objects, how a batch steps, and interruption: docs/design.md.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from tippetop.models.errors import TippetopError
from tippetop.models.params import FrictionParams
from tippetop.models.plan import MujocoPlan, samples_budget_gib
from tippetop.mujoco_runner import stepper
from tippetop.mujoco_runner.friction_callback import (
    USERDATA_SIZE,
    callback_installed,
    compiled_callback,
    userdata_block,
)
from tippetop.mujoco_runner.model import MUJOCO_WARNINGS, TopModel
from tippetop.mujoco_runner.record import SampleRecord
from tippetop.mujoco_runner.results import MujocoResult, result_from_samples
from tippetop.mujoco_runner.run import simulate_plan
from tippetop.mujoco_runner.settings import build_model, check_model
from tippetop.mujoco_runner.stepping import (
    contacts_from_steps,
    ran_settings,
    start_data,
    step_top_model,
)

#: Least wall time between the caller's ticks and progress reports (s).
TICK_S = 0.2
#: Most steps (over all simulations) in one call into the batch: about a second of one core,
#: so a Ctrl-C is seen within about that even when a sample interval is long.
MAX_CALL_STEPS = 50_000


@dataclass
class _Sim:
    """One plan being run: its model, grid, and what its stepping recorded so far."""

    index: int
    plan: MujocoPlan
    top_model: TopModel
    steps: int
    n_intervals: int
    law: FrictionParams | None
    #: rows 0..row recorded: time (n,), qpos (n, nq), qvel, qacc_warmstart,
    #: qfrc_constraint (n, nv), warning counters (n, mjNWARNING)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    row: int = 0
    stopped: bool = False
    failure: str | None = None
    warning_text: str | None = None
    ran: dict[str, Any] = field(default_factory=dict)
    #: its share of the batch's stepping time (each call's wall time over the simulations in
    #: it), so that the shares of a batch's runs add up to its wall time
    wall_s: float = 0.0

    @property
    def n_rows(self) -> int:
        return self.n_intervals + 1

    def record_bytes(self) -> int:
        m = self.top_model.model
        return self.n_rows * 8 * (1 + m.nq + 3 * m.nv + int(mujoco.mjtWarning.mjNWARNING))

    def record(self) -> SampleRecord:
        """The recorded rows as the single run's :class:`~.record.SampleRecord`."""
        n = self.row + 1
        a = {k: v[:n] for k, v in self.arrays.items()}
        return SampleRecord(time=a["time"], qpos=a["qpos"], qvel=a["qvel"],
                            qacc_warmstart=a["qacc_warmstart"],
                            qfrc_constraint=a["qfrc_constraint"], warnings=a["warnings"],
                            warning_text=self.warning_text, path="mujoco.batch")


def layout_key(model: mujoco.MjModel) -> tuple[tuple[str, int], ...]:
    """Every size of a model (its ``n*`` integers): equal keys give mjData the same layout."""
    out = []
    for name in dir(model):
        if name.startswith("n") and not name.startswith("name"):
            value = getattr(model, name, None)
            if isinstance(value, int):
                out.append((name, value))
    return tuple(out)


def default_threads() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _prepare(index: int, plan: MujocoPlan,
             models: dict[str, TopModel] | None = None) -> _Sim:
    """Compile a plan's model (raises TippetopError as the single run does).

    ``models``: models already compiled, by the MJCF text that defines them (plans that
    differ only in their start, length or sampling share one: a sweep compiles its top once).
    """
    top_model = models.get(plan.mjcf) if models is not None else None
    if top_model is None:
        top_model = build_model(plan)
        if models is not None:
            models[plan.mjcf] = top_model
    else:
        check_model(plan, top_model.model)  # as build_model checks a model it compiles
    return _Sim(index=index, plan=plan, top_model=top_model, steps=plan.steps_per_sample,
                n_intervals=plan.n_intervals, law=plan.law)


def _groups(sims: list[_Sim], budget_bytes: float) -> list[list[_Sim]]:
    """Sims that can share a batch, longest first, each group's records under the budget."""
    by_key: dict[tuple[Any, ...], list[_Sim]] = {}
    for sim in sims:
        by_key.setdefault(layout_key(sim.top_model.model), []).append(sim)
    out: list[list[_Sim]] = []
    for group in by_key.values():
        group.sort(key=lambda s: -s.n_rows)
        chunk: list[_Sim] = []
        for sim in group:  # a batch's records hold its longest run's rows for each run
            if chunk and (len(chunk) + 1) * chunk[0].record_bytes() > budget_bytes:
                out.append(chunk)
                chunk = []
            chunk.append(sim)
        out.append(chunk)
    out.sort(key=lambda g: -max(s.n_rows * s.steps for s in g))
    return out


def iter_simulate_plans(
    plans: Sequence[MujocoPlan],
    *,
    nthread: int | None = None,
    progress: Callable[[int, float], None] | None = None,
    tick: Callable[[], None] | None = None,
) -> Iterator[tuple[int, MujocoResult | TippetopError]]:
    """Run plans on a thread pool; yield ``(index, result)`` as each run ends.

    A plan that cannot run (bad settings for its model) yields its :class:`TippetopError`
    (nothing of it is simulated); the others run on. Longest runs first.

    Args:
        plans: What to run.
        nthread: Threads of each batch (default: this process's cores).
        progress: Called with ``(index, fraction of its simulated time done)`` now and then.
        tick: Called at least every :data:`TICK_S` of wall time while the batches run.
    """
    nthread = nthread or default_threads()
    sims = []
    models: dict[str, TopModel] = {}
    for i, plan in enumerate(plans):
        try:
            sims.append(_prepare(i, plan, models))
        except TippetopError as exc:
            yield i, exc
    own = [_steps_own_contacts(sim) for sim in sims]
    threaded = [sim for sim, yes in zip(sims, own, strict=True) if yes]
    budget = samples_budget_gib() * 2**30
    rest = [sim for sim, yes in zip(sims, own, strict=True) if not yes]
    runs = [_run_threads(threaded, nthread, progress, tick)] if threaded else []
    runs += [_run_group(group, nthread, progress, tick) for group in _groups(rest, budget)]
    for run in runs:
        for i, res in run:
            if progress is not None and isinstance(res, MujocoResult) and len(res.table):
                # at the end too, as the single run reports (a run may end between two ticks)
                progress(i, min(1.0, float(res.table["t"].iloc[-1]) / plans[i].t_end_s))
            yield i, res


def simulate_plans(plans: Sequence[MujocoPlan], *, nthread: int | None = None
                   ) -> list[MujocoResult | TippetopError]:
    """Run plans on a thread pool (:func:`iter_simulate_plans`); results in the plans' order."""
    out: list[MujocoResult | TippetopError | None] = [None] * len(plans)
    for i, res in iter_simulate_plans(plans, nthread=nthread):
        out[i] = res
    return [r for r in out if r is not None]


def _start(batch: Any, group: list[_Sim]) -> bool:
    """Write each sim's initial state (armed in paper mode) into its row; True if any law."""
    state = np.empty(batch.nstate)
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    any_law = False
    for j, sim in enumerate(group):
        tm, data = sim.top_model, start_data(sim.top_model, sim.plan)
        if sim.law is not None:
            any_law = True
            data.userdata[-USERDATA_SIZE:] = userdata_block(tm, sim.law, stem=sim.plan.stem)
        mujoco.mj_getState(tm.model, data, state, spec)
        batch.state[j] = state
    return any_law


def _run_group(group: list[_Sim], nthread: int, progress: Callable[[int, float], None] | None,
               tick: Callable[[], None] | None
               ) -> Iterator[tuple[int, MujocoResult | TippetopError]]:
    """Step one batch of sims to their ends, yielding each result as it is finished."""
    from mujoco import batch as mjbatch

    models = [s.top_model.model for s in group]
    nsim = len(group)
    batch = mjbatch.Batch(models[0], nsim=nsim, nthread=max(1, min(nthread, nsim)),
                          persistent=True)
    batch.set_models(models if nsim > 1 else models[0])
    any_law = _start(batch, group)
    fields = {name: batch.bind(name) for name in
              ("time", "qpos", "qvel", "qacc_warmstart", "qfrc_constraint")}
    counters = batch.warning[:, :, 1]  # mjData.warning.number of each simulation
    n_rows = max(sim.n_rows for sim in group)
    rec = {name: np.empty((nsim, n_rows, *values.shape[1:]))
           for name, values in fields.items()}
    rec["warnings"] = np.zeros((nsim, n_rows, counters.shape[1]), dtype=np.int64)
    for j, sim in enumerate(group):
        sim.arrays = {name: values[j] for name, values in rec.items()}
    steps = np.array([sim.steps for sim in group])
    n_intervals = np.array([sim.n_intervals for sim in group])
    row = np.zeros(nsim, dtype=np.int64)  # the last sample recorded
    left = steps.copy()  # steps to each one's next sample
    stopped = np.zeros(nsim, dtype=bool)
    wall = np.zeros(nsim)

    def record(ids: np.ndarray) -> None:
        rows = row[ids]
        for name, values in fields.items():
            rec[name][ids, rows] = values[ids]
        rec["warnings"][ids, rows] = counters[ids]

    if any_law:
        compiled_callback()  # loaded (or compiled) before the clock starts
    with callback_installed() if any_law else contextlib.nullcontext():
        batch.forward()  # the single run's forward pass for what ran ...
        for j, sim in enumerate(group):
            sim.ran = ran_settings(sim.top_model, batch.get_data(j), sim.plan)
        batch.forward()  # ... and the one that gives N at t = 0
        # A batch's forward pass checks the state as mj_step does (mj_forward does not): an
        # initial state MuJoCo finds bad (|qvel| > 1e10, say) is reset there and warned of.
        # Such a run fails at its first step alone; it is run alone, so the result is the same.
        running = ~counters.any(axis=1)
        for j in np.flatnonzero(~running).tolist():
            yield group[j].index, _run_alone(group[j].plan)
        record(np.flatnonzero(running))
        last_tick = time.perf_counter()
        while True:
            ended = running & (stopped | (row == n_intervals))
            done = []
            for j in np.flatnonzero(ended).tolist():
                running[j] = False
                sim = group[j]
                sim.row, sim.wall_s = int(row[j]), float(wall[j])
                done.append(sim)
            # runs that end together are finished on the batch's threads: their forward
            # passes (paper mode's N and forces, three a sample) release the GIL
            for sim, res in zip(done, _finish_all(done, nthread), strict=True):
                yield sim.index, res
            ids = np.flatnonzero(running)
            if not ids.size:
                break
            # Every running simulation advances by the same number of steps: up to the next
            # sample of the one nearest its own (runs of other timesteps share the batch), and
            # at most MAX_CALL_STEPS in all, so that Python (and Ctrl-C) comes back often.
            # mj_step(n) is n single steps: how the steps are split changes nothing.
            nstep = int(min(left[ids].min(), max(1, MAX_CALL_STEPS // ids.size)))
            t0 = time.perf_counter()
            try:
                batch.step(ids=ids, nstep=nstep)
                ok = ids
            except mjbatch.SimulationError as exc:
                failed = np.asarray(exc.ids, dtype=np.int64)
                for j in failed.tolist():  # it kept the state before the call
                    group[j].failure = f"MuJoCo error: {batch.error(j)}"
                stopped[failed] = True
                ok = np.setdiff1d(ids, failed)
            wall[ids] += (time.perf_counter() - t0) / ids.size  # each its share of the call
            left[ok] -= nstep
            hit = ok[left[ok] == 0]
            if hit.size:
                left[hit] = steps[hit]
                row[hit] += 1
                record(hit)
                # a state not finite or a MuJoCo warning ends the run; the failed row stays
                # (result_from_samples ends the run there, with the reason)
                bad = ~(np.isfinite(fields["qpos"][hit]).all(axis=1)
                        & np.isfinite(fields["qvel"][hit]).all(axis=1))
                warned = counters[hit].any(axis=1)
                stopped[hit[bad | warned]] = True
                for j in hit[warned & ~bad].tolist():
                    group[j].warning_text = MUJOCO_WARNINGS[-1] if MUJOCO_WARNINGS else None
            now = time.perf_counter()
            if now - last_tick >= TICK_S:
                last_tick = now
                if progress is not None:
                    for j in ids.tolist():
                        progress(group[j].index, row[j] / n_intervals[j])
                if tick is not None:
                    tick()

def _steps_own_contacts(sim: _Sim) -> bool:
    """Whether ``sim`` runs on :func:`_run_threads`: it reads its contacts from its own steps.

    Such a run (native mode, or paper mode without a law, on a model whose ``mj_step``
    splits) reads each sample's contacts from the forward pass that starts the next step, in
    the compiled stepper. A ``Batch`` cannot give them (mjData's contacts are not among its
    bindable fields, and ``get_data`` copies a whole mjData: 14 us a sample), so in a batch
    the post-processing would run those forward passes again, serially: 1.6x the single
    loop's rate on 2 cores for the 64-run sweep, against 2.0x on threads (benchmarks/
    bench_mujoco_batch.py).
    """
    return contacts_from_steps(sim.top_model.model, sim.law) and stepper.load()


class _Stopped(Exception):
    """Raised in a worker's progress report when the runs are being stopped."""


def _run_threads(sims: list[_Sim], nthread: int,
                 progress: Callable[[int, float], None] | None,
                 tick: Callable[[], None] | None
                 ) -> Iterator[tuple[int, MujocoResult | TippetopError]]:
    """Step each sim whole on one of ``nthread`` threads; finish them here, as they come.

    Each worker takes the longest sim not yet taken and steps it as the single run does
    (:func:`~.stepping.step_top_model`: the compiled stepper, which releases the GIL, on the
    sim's own mjData), so its record is the single run's; this thread (the caller's) turns
    the records into results (:func:`~.results.result_from_samples`, with the GIL) while the
    workers step the next ones, reports progress and calls ``tick`` every :data:`TICK_S`.
    When the caller stops (Ctrl-C, or it stops iterating), the workers stop at their next
    progress report (every :data:`~.stepping.PROGRESS_INTERVAL_S`) and are joined before this
    returns or raises.
    """
    order = sorted(sims, key=lambda s: -(s.n_rows * s.steps))
    pending = iter(order)
    take = threading.Lock()
    done: queue.SimpleQueue[tuple[_Sim, Any] | None] = queue.SimpleQueue()
    stop = threading.Event()
    done_t: dict[int, float] = {}  # sim index -> simulated time stepped (workers write)

    def work() -> None:
        while not stop.is_set():
            with take:
                sim = next(pending, None)
            if sim is None:
                break
            try:
                out: Any = _step_sim(sim, stop, done_t)
            except _Stopped:
                break
            except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
                out = exc
            done.put((sim, out))
        done.put(None)

    workers = [threading.Thread(target=work, name=f"tippetop-mujoco-{k}", daemon=True)
               for k in range(max(1, min(nthread, len(order))))]
    running = {sim.index: sim for sim in order}
    try:
        for w in workers:
            w.start()
        live, last_tick = len(workers), time.perf_counter()
        while live:
            try:
                item = done.get(timeout=TICK_S)
            except queue.Empty:
                item = ()
            if item is None:
                live -= 1
            elif item:
                sim, out = item
                running.pop(sim.index, None)
                if isinstance(out, TippetopError):
                    yield sim.index, out
                elif isinstance(out, BaseException):
                    raise out
                else:
                    yield sim.index, _result(sim, *out)
            now = time.perf_counter()
            if now - last_tick >= TICK_S:
                last_tick = now
                if progress is not None:
                    for index, t in list(done_t.items()):
                        if index in running:
                            progress(index, t / running[index].plan.t_end_s)
                if tick is not None:
                    tick()
    finally:
        stop.set()
        for w in workers:
            w.join()


def _step_sim(sim: _Sim, stop: threading.Event, done_t: dict[int, float]) -> tuple[Any, ...]:
    """The single run's stepping of ``sim`` (in a worker thread): its record, as a tuple."""
    plan = sim.plan

    def report(t: float) -> None:
        if stop.is_set():
            raise _Stopped
        done_t[sim.index] = t

    return step_top_model(sim.top_model, plan, progress=report)


def _result(sim: _Sim, record: SampleRecord, failure: str | None, wall_s: float,
            ran: dict[str, Any]) -> MujocoResult | TippetopError:
    """A sim's result from its record: the single run's own post-processing (both ways)."""
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            return result_from_samples(sim.top_model, record, sim.plan, failure=failure,
                                       wall_s=wall_s, ran=ran)
    except TippetopError as exc:
        return exc


def _finish_all(sims: list[_Sim], nthread: int) -> list[MujocoResult | TippetopError]:
    """:func:`_finish` of each sim, on up to ``nthread`` threads when there are several."""
    if len(sims) < 2 or nthread < 2:
        return [_finish(sim) for sim in sims]
    with ThreadPoolExecutor(min(nthread, len(sims)), thread_name_prefix="tippetop-finish") as pool:
        return list(pool.map(_finish, sims))


def _run_alone(plan: MujocoPlan) -> MujocoResult | TippetopError:
    try:
        return simulate_plan(plan)
    except TippetopError as exc:
        return exc


def _finish(sim: _Sim) -> MujocoResult | TippetopError:
    """A batch sim's result from the rows it recorded."""
    res = _result(sim, sim.record(), sim.failure, sim.wall_s, sim.ran)
    sim.arrays = {}  # its memory is the table's now
    return res


__all__ = ["MAX_CALL_STEPS", "TICK_S", "default_threads", "iter_simulate_plans", "layout_key",
           "simulate_plans"]
