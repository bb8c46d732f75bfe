"""Many MuJoCo runs stepped together on threads, each equal to its single run bit for bit.

:func:`iter_simulate_plans` runs many :class:`~tippetop.models.plan.MujocoPlan` on ``nthread``
threads and gives each run's :class:`~tippetop.mujoco_runner.results.MujocoResult`, the one
:func:`~tippetop.mujoco_runner.run.simulate_plan` gives, as soon as it is done: each run is
stepped whole on one thread, as the single run steps it (the compiled stepper, which releases
the GIL), so that every step's forward pass goes into its sample's window. Call it from the
main thread, never from two Python threads at once (paper mode's callback is installed
process-wide, :mod:`.friction_callback`). Why not ``mujoco.batch``, and interruption:
docs/design.md.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tippetop.models.errors import TippetopError
from tippetop.models.plan import MujocoPlan
from tippetop.mujoco_runner import stepper
from tippetop.mujoco_runner.friction_callback import callback_installed
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.record import SampleRecord
from tippetop.mujoco_runner.results import MujocoResult, result_from_samples
from tippetop.mujoco_runner.settings import build_model, check_model
from tippetop.mujoco_runner.stepping import step_top_model

#: Least wall time between the caller's ticks and progress reports (s).
TICK_S = 0.2


@dataclass
class _Sim:
    """One plan to run: its model and grid."""

    index: int
    plan: MujocoPlan
    top_model: TopModel
    steps: int
    n_intervals: int

    @property
    def n_rows(self) -> int:
        return self.n_intervals + 1


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
                n_intervals=plan.n_intervals)


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
    if not sims:
        return
    stepper.load()  # the compiled loop loaded here, before the threads step with it
    law = any(sim.plan.law is not None for sim in sims)
    # paper mode's callback installed here, on the main thread, for as long as any runs
    with callback_installed() if law else contextlib.nullcontext():
        for i, res in _run_threads(sims, nthread, progress, tick):
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


__all__ = ["TICK_S", "default_threads", "iter_simulate_plans", "simulate_plans"]
