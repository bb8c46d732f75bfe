"""Run a probe's model on an engine: in this process, or in a worker (another MuJoCo, MJX, Warp).

The same code steps it either way (:func:`.worker.probe_steps.step_probe`): in this process
for the MuJoCo installed beside tippetop, in the worker for every other engine. Every step is
recorded (:class:`ProbeTrace`); what ran (integrator, step, cone, ...) is read back from the
compiled model there, never taken from the request.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tippetop.mujoco_runner import worker
from tippetop.mujoco_runner.worker.probe_steps import PROBE_ARRAYS, step_probe
from tippetop.mujoco_runner.worker.protocol import Refused

#: Wall time a probe's worker may take (s) before it is stopped: MJX's compile included.
BUDGET_S = 300.0


class ProbeRefused(ValueError):
    """The engine cannot run the probe as asked (an integrator it does not have): one line."""


@dataclass(frozen=True)
class ProbeRequest:
    """One probe run as the engine gets it.

    Attributes:
        mjcf: The model's MJCF text.
        body: The probed body's name (its contacts are recorded).
        qpos: The start's positions.
        qvel: The start's velocities.
        duration_s: Simulated time.
        integrator: MuJoCo's integrator name (``Euler``, ``RK4``, ``implicit``,
            ``implicitfast``); None: the model's.
        timestep_s: The step; None: the model's.
        ctrl: The actuators' controls, held over the run.
        law: The paper's law at the probed ball's lowest point (``{"mu", "Lambda", "R"}``,
            MuJoCo C only), or None.
    """

    mjcf: str
    body: str
    qpos: tuple[float, ...]
    qvel: tuple[float, ...]
    duration_s: float
    integrator: str | None = None
    timestep_s: float | None = None
    ctrl: tuple[float, ...] = ()
    law: dict[str, float] | None = None

    def as_json(self, engine: dict[str, str] | None = None) -> dict[str, Any]:
        """The worker's request (its ``out`` added by the caller)."""
        return {"protocol": worker.PROTOCOL, "kind": "probe", "mjcf": self.mjcf,
                "body": self.body, "qpos": list(self.qpos), "qvel": list(self.qvel),
                "duration_s": self.duration_s, "integrator": self.integrator,
                "timestep_s": self.timestep_s, "ctrl": list(self.ctrl),
                "law": None if self.law is None else dict(self.law),
                "engine": dict(engine or {"implementation": "mujoco", "precision": "float64"})}


@dataclass(frozen=True)
class ProbeTrace:
    """Every step of a probe's run.

    Attributes:
        time: Simulated time of each row (s), the start's first.
        qpos: Positions, one row per step.
        qvel: Velocities, one row per step.
        ncon: Contacts of the probed body at each row's state (-1: not read by the engine).
        normal_N: Their summed normal force (N; NaN: not read).
        warnings: MuJoCo's warning counters at each row.
        ran: What ran, read back: integrator, timestep_s, cone, impratio, ...
        engine: What stepped it: implementation, version, precision, device, wall_s.
        warning_names: The counters' names.
    """

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    ncon: np.ndarray
    normal_N: np.ndarray
    warnings: np.ndarray
    ran: dict[str, Any]
    engine: dict[str, Any]
    warning_names: tuple[str, ...] = field(default=())

    @property
    def finished(self) -> bool:
        """Whether the last row is finite (a diverged run stops at its first non-finite row)."""
        return bool(np.isfinite(self.qpos[-1]).all() and np.isfinite(self.qvel[-1]).all())


def _trace(arrays: dict[str, np.ndarray], ran: dict, engine: dict,
           names: tuple[str, ...]) -> ProbeTrace:
    return ProbeTrace(**{k: np.asarray(arrays[k]) for k in PROBE_ARRAYS}, ran=ran,
                      engine=engine, warning_names=names)


def run_here(req: ProbeRequest, progress: Callable[[float], None] | None = None) -> ProbeTrace:
    """Run ``req`` on the MuJoCo installed beside tippetop, in this process.

    Raises:
        ProbeRefused: An integrator this MuJoCo does not have, a bad step (one line).
    """
    import mujoco

    try:
        arrays, ran, engine = step_probe(mujoco, np, req.as_json(), progress)
    except Refused as exc:
        raise ProbeRefused(str(exc)) from None
    names = tuple(mujoco.mjtWarning(i).name for i in range(arrays["warnings"].shape[1]))
    return _trace(arrays, ran, engine, names)


def run_in(python: str, req: ProbeRequest, engine: dict[str, str] | None = None, *,
           progress: Callable[[float], None] | None = None,
           budget_s: float = BUDGET_S) -> ProbeTrace:
    """Run ``req`` in the interpreter ``python`` through the worker (its own MuJoCo, MJX, Warp).

    Raises:
        ProbeRefused: The worker refused it (an integrator that release does not have).
        WorkerFailed: The worker crashed, hung or did not answer as one.
    """
    from tippetop.mujoco_runner.remote import WorkerFailed, converse

    with tempfile.TemporaryDirectory(prefix="tippetop-probe-") as tmp:
        out = Path(tmp) / "probe.npz"
        text = json.dumps({**req.as_json(engine), "out": str(out)})
        reply = converse(python, text, budget_s, progress)
        if reply.get("status") != "ok":
            message = str(reply.get("message", "no reason given"))
            if message.startswith(("integrator:", "timestep:", "duration:", "law:")):
                raise ProbeRefused(message)
            raise WorkerFailed(f"the worker in {python} failed: {message}")
        try:
            with np.load(out) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise WorkerFailed(f"the worker in {python} wrote no readable results ({exc})") \
                from None
    missing = sorted(set(PROBE_ARRAYS) - set(arrays))
    if missing:
        raise WorkerFailed(f"the worker in {python} wrote results without {', '.join(missing)}")
    return _trace(arrays, reply.get("ran", {}), reply.get("engine", {}),
                  tuple(reply.get("warning_names", ())))


__all__ = ["BUDGET_S", "ProbeRefused", "ProbeRequest", "ProbeTrace", "run_here", "run_in"]
