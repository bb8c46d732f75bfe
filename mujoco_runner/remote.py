"""Run a MuJoCo plan in another Python (another MuJoCo) through :mod:`.worker`.

:func:`simulate_in` sends the plan's model, start, grid and law to the worker (the folder
``worker/``, started by path) in the given interpreter, which needs nothing but ``mujoco`` and
``numpy``; its samples and their windows (every step's forward pass added to its sample's:
:mod:`.worker.windows`) come back in a ``.npz`` file, and this process turns them into the same
:class:`~.results.MujocoResult` as an in-process run (:func:`~.results.result_from_samples`).
A worker that crashes, hangs past its budget or answers with anything but its reply is one
failed run, with the reason (:class:`WorkerFailed`).
"""

from __future__ import annotations

import atexit
import collections
import contextlib
import json
import os
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from tippetop.models.mjcf import HARNESS_USERDATA
from tippetop.models.plan import NATIVE_LAW, MujocoPlan
from tippetop.models.resources import user_cache_dir
from tippetop.mujoco_runner import worker
from tippetop.mujoco_runner.friction_callback import law_parameters
from tippetop.mujoco_runner.model import TopModel
from tippetop.mujoco_runner.record import SampleRecord, WindowRecord
from tippetop.mujoco_runner.results import MujocoResult, result_from_samples
from tippetop.mujoco_runner.settings import build_model, friction_that_acts
from tippetop.mujoco_runner.stepping import window_top

#: The worker's folder, run by path in the other interpreter (``PYTHON -u WORKER``: its
#: ``__main__.py``).
WORKER = Path(worker.__file__).parent
#: Wall time a worker may take beyond its expected cost before it is stopped (s), and the
#: factor on the expected cost: a hung worker is a failed run, not a hung harness.
BUDGET_MIN_S = 60.0
BUDGET_FACTOR = 20.0
#: Extra wall time for an accelerated engine's setup (MJX compiles its loop: ~30 s here) (s).
BUDGET_COMPILE_S = 180.0
#: What steps a plan when the caller names nothing: MuJoCo C in float64.
DEFAULT_ENGINE = {"implementation": "mujoco", "precision": "float64"}
#: The keys of a worker's ``engine`` reply kept in a result's ``engine`` besides the five
#: every summary has (an accelerated engine's: what its windows read and where its warnings
#: come from).
ENGINE_EXTRA = ("mujoco_c_version", "device_kind", "contacts_from", "warnings", "law_applied",
                "note")


#: The arrays a worker's results hold (protocol 5): the samples' states and their windows.
WORKER_ARRAYS = frozenset({"time", "qpos", "qvel", "qacc_warmstart", "qfrc_constraint",
                           "warnings", "windows_int", "windows_float"})


class WorkerFailed(RuntimeError):
    """A worker that crashed, hung or answered with something else than its reply."""


#: The workers running now (to stop them all when the harness is stopped).
_LIVE: set[subprocess.Popen[str]] = set()
_LIVE_LOCK = threading.Lock()


def stop_workers() -> None:
    """End every worker this process started that is still running (Ctrl-C, an error)."""
    with _LIVE_LOCK:
        live = list(_LIVE)
    for proc in live:
        _kill(proc)


@dataclass(frozen=True)
class WorkerInfo:
    """What a worker says of where it ran.

    Attributes:
        executable: Its Python.
        version: ``mujoco.__version__`` there.
        python: Its Python version.
        path: How it stepped (``plain loop``).
    """

    executable: str
    version: str
    python: str
    path: str


def request(plan: MujocoPlan, top_model: TopModel, out: Path,
            engine: dict[str, str] | None = None) -> dict[str, Any]:
    """The worker's request for ``plan`` (its arrays go to ``out``).

    ``engine`` (``{"implementation": "mujoco"|"mjx"|"warp", "precision": ...}``) says what
    steps it there; default MuJoCo C in float64. Its ``top`` is whose contacts the windows
    add (:func:`~.stepping.window_top`'s fields: body, ball geom, radius, symmetry axis, the
    free joint's addresses), as this process's model has them.
    """
    start: dict[str, Any] = ({"keyframe": plan.keyframe} if plan.keyframe is not None
                             else {"qpos": list(plan.start_qpos), "qvel": list(plan.start_qvel)})
    law = None
    if plan.law is not None:
        p = law_parameters(plan.law, top_model)
        stem = plan.stem
        law = {**p,
               "R": top_model.top.R_m, "centre": [float(v) for v in top_model.centre_body_m],
               "axis": [float(v) for v in top_model.axis_body],
               "stem_kind": 0 if stem is None else 2 if stem.kind == "cylinder" else 1,
               "stem_l": 0.0 if stem is None else stem.offset_m,
               "stem_r": 0.0 if stem is None else stem.radius_m}
    w = window_top(top_model)
    top = {"body": int(w.body), "ball": int(w.ball), "radius_m": float(w.radius_m),
           "axis_body": [float(v) for v in w.axis_body], "qpos_adr": int(w.qpos_adr),
           "dof_adr": int(w.dof_adr)}
    return {"protocol": worker.PROTOCOL, "mjcf": plan.mjcf, "userdata": HARNESS_USERDATA,
            "start": start, "top": top,
            "steps_per_sample": plan.steps_per_sample,
            "n_intervals": plan.n_intervals, "law": law, "out": str(out),
            "engine": dict(engine or DEFAULT_ENGINE),
            "compile_cache": str(user_cache_dir() / "jax")}


def _name(enum_name: str, prefix: str, names: tuple[str, ...]) -> str:
    """The harness's spelling of the worker's enum value ``enum_name``.

    The worker names the value from its own release's enum: codes need not match across
    releases.
    """
    name = enum_name.removeprefix(prefix)
    return next((s for s in names if s.upper() == name.upper()), name.lower())


def _ran(reply: dict[str, Any], plan: MujocoPlan) -> dict[str, Any]:
    """The worker's read-back in the keys of :func:`~.stepping.ran_settings`."""
    from tippetop.models.mjcf import CONES, INTEGRATORS

    r = reply["ran"]
    out: dict[str, Any] = {
        "timestep_s": r["timestep_s"],
        "integrator": _name(r["integrator"], "mjINT_", INTEGRATORS),
        "cone": _name(r["cone"], "mjCONE_", CONES),
        "impratio": r["impratio"], "noslip_iterations": r["noslip_iterations"],
        "gravity_mps2": r["gravity_mps2"], "iterations": r["iterations"],
        "tolerance": r["tolerance"], "contacts": r["contacts"]}
    out.update(friction_that_acts(r["condim"], *r["coefficients"]), solref=r["solref"],
               solreffriction=r.get("solreffriction"),  # a worker of an older tippetop: none
               solimp=r["solimp"], contact_source=r["contact_source"])
    law = plan.law
    out["friction_law"] = (NATIVE_LAW if plan.friction == "native"
                           else law.law if law is not None else "none")
    if law is not None:
        out["law_mu"] = float(law.mu)
    out["sample_dt_s"] = plan.steps_per_sample * float(r["timestep_s"])
    out["keyframe"] = plan.keyframe_name
    return out


def simulate_in(python: str, plan: MujocoPlan, *, budget_s: float | None = None,
                progress: Callable[[float], None] | None = None,
                env: dict[str, str] | None = None,
                engine: dict[str, str] | None = None) -> tuple[MujocoResult, WorkerInfo]:
    """Run ``plan`` in the interpreter ``python`` (its own ``mujoco``, or MJX, or Warp).

    Args:
        python: The interpreter's path.
        plan: What to run.
        budget_s: Wall time after which the worker is stopped (default from the plan's steps).
        progress: Called with the simulated time reached, as the worker reports it.
        env: The worker's environment (default this process's, without ``PYTHONPATH``).
        engine: What steps it: ``{"implementation": "mujoco"|"mjx"|"warp", "precision":
            "float64"|"float32"}`` (default MuJoCo C in float64). The result's ``engine``
            is what the worker read back (implementation, version, precision, device).

    Returns:
        The run's result (as an in-process run's) and where the worker ran.

    Raises:
        WorkerFailed: The worker crashed, hung past its budget or did not answer as a worker.
        TippetopError: The plan's model does not compile here (nothing is run).
    """
    top_model = build_model(plan)  # this process's view of the model: geometry, observables
    if budget_s is None:
        budget_s = BUDGET_MIN_S + BUDGET_FACTOR * plan.n_steps * 65e-6
        if (engine or DEFAULT_ENGINE).get("implementation") != "mujoco":
            budget_s += BUDGET_COMPILE_S
    with tempfile.TemporaryDirectory(prefix="tippetop-worker-") as tmp:
        out = Path(tmp) / "run.npz"
        text = json.dumps(request(plan, top_model, out, engine))
        reply, lines = _converse(python, text, budget_s, progress, env)
        info = WorkerInfo(str(reply.get("executable", python)), str(reply.get("version", "?")),
                          str(reply.get("python", "?")), str(reply.get("path", "?")))
        if reply.get("status") != "ok":
            raise WorkerFailed(f"the worker in {python} failed: "
                               f"{reply.get('message', 'no reason given')}")
        try:
            with np.load(out) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise WorkerFailed(f"the worker in {python} wrote no readable results ({exc})") \
                from None
        missing = sorted(WORKER_ARRAYS - set(arrays))
        if missing:
            raise WorkerFailed(f"the worker in {python} wrote results without "
                               f"{', '.join(missing)}")
    record = SampleRecord(
        time=arrays["time"], qpos=arrays["qpos"], qvel=arrays["qvel"],
        qacc_warmstart=arrays["qacc_warmstart"], qfrc_constraint=arrays["qfrc_constraint"],
        warnings=arrays["warnings"], warning_text=reply.get("warning_text"),
        warning_names=tuple(reply["warning_names"]),
        windows=WindowRecord(arrays["windows_int"], arrays["windows_float"]),
        path=f"worker: {info.path}")
    with np.errstate(over="ignore", invalid="ignore"):
        result = result_from_samples(top_model, record, plan, wall_s=float(reply["wall_s"]),
                                     ran=_ran(reply, plan), version=info.version)
    said = reply.get("engine")
    if isinstance(said, dict):  # what stepped it, as the worker read it back
        ran_engine = {k: said.get(k, "?") for k in ("implementation", "version", "precision",
                                                    "device")}
        ran_engine["path"] = record.path
        ran_engine.update({k: said[k] for k in ENGINE_EXTRA if k in said})
        result = replace(result, engine=ran_engine)
    if progress is not None and len(result.table):
        progress(float(result.table["t"].iloc[-1]))
    return result, info


class _Worker:
    """A worker process that answers one request after another (one JSON line each).

    Kept while it answers as a worker: the start and ``import mujoco`` are paid once per
    interpreter and thread, not once per run.
    """

    def __init__(self, python: str, env: dict[str, str], key: tuple[Any, ...]) -> None:
        try:
            self.proc = subprocess.Popen([python, "-u", str(WORKER)], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                         text=True, env=env, start_new_session=True)
        except OSError as exc:
            raise WorkerFailed(f"the worker could not start {python!r}: {exc.strerror}") \
                from None
        self.key = key
        self.reused = False
        self.over_budget = False
        self.budget_s = 0.0
        self.stderr: collections.deque[str] = collections.deque(maxlen=50)
        err = self.proc.stderr
        assert err is not None
        self.reader = threading.Thread(target=lambda: self.stderr.extend(err), daemon=True)
        self.reader.start()
        with _LIVE_LOCK:
            _LIVE.add(self.proc)

    def alive(self) -> bool:
        """Still running (it may have ended after its last reply)."""
        return self.proc.poll() is None

    def end(self, *, kill: bool = True) -> None:
        """Stop it (``kill`` False: close its input and let it finish) and forget it."""
        if kill:
            _kill(self.proc)
        else:
            with contextlib.suppress(OSError, ValueError):
                assert self.proc.stdin is not None
                self.proc.stdin.close()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=2.0)
        if self.proc.poll() is None:
            _kill(self.proc)
            self.proc.wait()
        with _LIVE_LOCK:
            _LIVE.discard(self.proc)


#: Workers waiting for their next request, by (interpreter, environment).
_IDLE: dict[tuple[Any, ...], list[_Worker]] = {}
_IDLE_LOCK = threading.Lock()


def _take(python: str, env: dict[str, str], *, fresh: bool = False) -> _Worker:
    """An idle worker of ``python`` with ``env``, or a new one (``fresh``: always new)."""
    key = (python, tuple(sorted(env.items())))
    while not fresh:
        with _IDLE_LOCK:
            idle = _IDLE.get(key)
            w = idle.pop() if idle else None
        if w is None:
            break
        if w.alive():
            w.reused = True
            return w
        w.end()
    return _Worker(python, env, key)


def _give_back(w: _Worker) -> None:
    with _IDLE_LOCK:
        _IDLE.setdefault(w.key, []).append(w)


def live_workers() -> list[int]:
    """The process ids of this process's workers now running (busy or idle)."""
    with _LIVE_LOCK:
        return sorted(p.pid for p in _LIVE if p.poll() is None)


def close_workers() -> None:
    """End the idle workers (their input closed: each finishes and exits)."""
    with _IDLE_LOCK:
        idle = [w for ws in _IDLE.values() for w in ws]
        _IDLE.clear()
    for w in idle:
        w.end(kill=False)


atexit.register(close_workers)


def _converse(python: str, text: str, budget_s: float,
              progress: Callable[[float], None] | None,
              env: dict[str, str] | None) -> tuple[dict[str, Any], list[str]]:
    """Send the request to a worker and read its lines until its reply.

    The worker (one kept from an earlier request, or a new one) is stopped past the budget, or
    when it answers with anything but its reply; after a reply it waits for the next request.
    Returns the reply and the lines before it.
    """
    if env is None:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env.setdefault("MUJOCO_GL", "disable")  # the worker never draws: no GL probing
    w = _take(python, env)
    reply, lines = _ask(w, python, text, budget_s, progress)
    if reply is None and w.reused and not lines and not w.stderr:
        # a kept worker that had ended unseen (killed while idle): the request goes to a new one
        w = _take(python, env, fresh=True)
        reply, lines = _ask(w, python, text, budget_s, progress)
    if reply is None:
        raise _failure(w, python, lines)
    return reply, lines


def converse(python: str, text: str, budget_s: float,
             progress: Callable[[float], None] | None = None) -> dict[str, Any]:
    """Send one request line to a worker in ``python`` and return its reply.

    The worker is kept for the next request, stopped past ``budget_s``; a worker that ended
    without a reply is :class:`WorkerFailed`. (A probe's request goes this way:
    :mod:`.probe_run`.)
    """
    return _converse(python, text, budget_s, progress, None)[0]


def _ask(w: _Worker, python: str, text: str, budget_s: float,
         progress: Callable[[float], None] | None) -> tuple[dict[str, Any] | None, list[str]]:
    """One request to ``w``: (its reply, the lines before it), or (None, lines) if it ended.

    The worker is stopped past the budget; after a reply it goes back to the idle workers.
    """
    proc = w.proc
    assert proc.stdin is not None and proc.stdout is not None
    lines: list[str] = []
    reply: dict[str, Any] | None = None
    timer = threading.Timer(budget_s, _kill, (proc,))
    timer.start()
    t0 = time.monotonic()
    try:
        with contextlib.suppress(BrokenPipeError, OSError, ValueError):
            proc.stdin.write(text.replace("\n", " ") + "\n")
            proc.stdin.flush()
        while True:
            line = proc.stdout.readline()
            if not line:  # it ended
                break
            line = line.rstrip("\n")
            if progress is not None and line.startswith('{"t": '):
                with contextlib.suppress(ValueError, KeyError):
                    progress(float(json.loads(line)["t"]))
                continue
            with contextlib.suppress(ValueError):
                said = json.loads(line)
                if isinstance(said, dict) and "status" in said:
                    reply = said
                    break
            lines.append(line)
    except BaseException:  # Ctrl-C: the worker goes with the run
        timer.cancel()
        w.end()
        raise
    finally:
        timer.cancel()
    if reply is not None:
        _give_back(w)
        return reply, lines
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=5.0)
    w.reader.join(1.0)
    w.end()
    w.over_budget = time.monotonic() - t0 >= budget_s
    w.budget_s = budget_s
    return None, lines


def _failure(w: _Worker, python: str, lines: list[str]) -> WorkerFailed:
    """Why a worker ended without its reply, in one line."""
    proc = w.proc
    if w.over_budget and proc.returncode != 0:
        return WorkerFailed(f"the worker in {python} took longer than its budget of "
                            f"{w.budget_s:.0f} s and was stopped")
    stderr = list(w.stderr)
    tail = (stderr[-1].strip() if stderr else lines[-1] if lines else "nothing")[:200]
    how = (f"exit status {proc.returncode}" if proc.returncode
           else "no reply on its last line")
    return WorkerFailed(f"the worker in {python} ended without its reply ({how}; last "
                        f"output: {tail})")


def _kill(proc: subprocess.Popen[str]) -> None:
    """End the worker and whatever it started (its own session: a process group)."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)


__all__ = ["BUDGET_COMPILE_S", "BUDGET_FACTOR", "BUDGET_MIN_S", "DEFAULT_ENGINE", "WORKER",
           "WORKER_ARRAYS", "WorkerFailed", "WorkerInfo", "close_workers", "live_workers",
           "request", "simulate_in", "stop_workers"]
